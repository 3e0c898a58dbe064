"""ROS messages -> planefuse values: the tf tree and sensor poses, images, camera calibrations, laser ranges and
point-cloud slices (for :func:`planefuse.io.import_bag`). Messages are ``rosbags``' deserialised ROS 1 or ROS 2
messages; nothing here reads a file."""

from __future__ import annotations

import cv2
import numpy as np

from ..geometry._transforms import rotation_from_roll_pitch_yaw, transform_from_quaternion, \
    transform_from_rotation_translation

__all__ = ["image_from_msg", "points_from_pointcloud2", "scan_ranges_from_points", "static_transform"]

# A /tf edge that moves more than this over the bag is refused: planefuse's sensors have fixed poses.
_TF_MOVE_TOL_M = 1e-3
_TF_MOVE_TOL_RAD = 1e-3


def static_transform(text: str) -> tuple[str, str, np.ndarray]:
    """``PARENT,CHILD,X,Y,Z,YAW,PITCH,ROLL`` (metres, radians; ROS ``static_transform_publisher``'s order) ->
    ``(parent, child, T_parent_child (4, 4))``.

    Raises
    ------
    ValueError
        Not eight comma-separated fields, or numbers that are not finite.
    """
    parts = [p.strip() for p in text.split(",")]
    if len(parts) != 8 or not parts[0] or not parts[1]:
        raise ValueError(f"--tf {text!r}: expected PARENT,CHILD,X,Y,Z,YAW,PITCH,ROLL (m, rad)")
    try:
        x, y, z, yaw, pitch, roll = (float(p) for p in parts[2:])
    except ValueError:
        raise ValueError(f"--tf {text!r}: X,Y,Z,YAW,PITCH,ROLL must be numbers (m, rad)") from None
    if not np.isfinite([x, y, z, yaw, pitch, roll]).all():
        raise ValueError(f"--tf {text!r}: values must be finite")
    R = rotation_from_roll_pitch_yaw(roll, pitch, yaw)
    return parts[0].lstrip("/"), parts[1].lstrip("/"), transform_from_rotation_translation(R, [x, y, z])


def scan_ranges_from_points(points, *, z_band_m: tuple[float, float], n_beams: int, range_min_m: float,
                            range_max_m: float) -> np.ndarray:
    """A 2-D scan (B,) [m] sliced from a point cloud, as ROS's ``pointcloud_to_laserscan`` does.

    Beam ``i`` looks at azimuth ``-pi + i * 2 pi / n_beams`` (counter-clockwise from the sensor's x axis); its
    range is that of the nearest point, in the x-y plane (``hypot(x, y)``), among the finite points whose z lies in
    ``z_band_m`` and whose azimuth is nearest that beam's. A beam with no such point within
    ``[range_min_m, range_max_m]`` has no return (``inf``).

    Parameters
    ----------
    points : array_like (N, 3)
        x, y, z [m] in the sensor frame (x forward, z up).
    z_band_m : (z_min, z_max)
        The slice's heights in the sensor frame [m].
    """
    p = np.asarray(points, dtype=float).reshape(-1, 3)
    z0, z1 = z_band_m
    r = np.hypot(p[:, 0], p[:, 1])
    keep = np.isfinite(p).all(axis=1) & (p[:, 2] >= z0) & (p[:, 2] <= z1) & (r >= range_min_m) & (r <= range_max_m)
    inc = 2 * np.pi / n_beams
    i = np.round((np.arctan2(p[keep, 1], p[keep, 0]) + np.pi) / inc).astype(np.int64) % n_beams
    out = np.full(n_beams, np.inf)
    np.minimum.at(out, i, r[keep])
    return out


# -- transforms -------------------------------------------------------------------------------------------------
class _TfTree:
    """Parent -> child transforms; each child has one parent. ``/tf`` edges keep their first value and the
    largest change over the bag (a moving edge is refused when a sensor's pose uses it)."""

    def __init__(self) -> None:
        self.parent: dict[str, tuple[str, np.ndarray]] = {}
        self.moved: dict[str, tuple[float, float]] = {}

    def add(self, parent: str, child: str, T_parent_child: np.ndarray, dynamic: bool = False) -> None:
        parent, child = parent.lstrip("/"), child.lstrip("/")
        if child in self.parent:
            p0, T0 = self.parent[child]
            if p0 != parent:
                raise ValueError(f"tf frame {child!r} has two parents, {p0!r} and {parent!r}")
            if dynamic:
                d_m = float(np.linalg.norm(T_parent_child[:3, 3] - T0[:3, 3]))
                c = np.clip((np.trace(T0[:3, :3].T @ T_parent_child[:3, :3]) - 1) / 2, -1.0, 1.0)
                old = self.moved.get(child, (0.0, 0.0))
                self.moved[child] = (max(old[0], d_m), max(old[1], float(np.arccos(c))))
            return
        self.parent[child] = (parent, T_parent_child)

    def chain(self, frame: str) -> list[str]:
        out, f = [frame], frame
        while f in self.parent:
            f = self.parent[f][0]
            if f in out:
                raise ValueError(f"tf frames form a cycle through {f!r}")
            out.append(f)
        return out

    def roots(self) -> list[str]:
        return sorted({p for p, _ in self.parent.values() if p not in self.parent})

    def T_world_frame(self, world: str, frame: str, what: str) -> np.ndarray:
        if frame == world:
            return np.eye(4)
        chain = self.chain(frame)
        if world not in chain:
            top = chain[-1]  # the frame without a parent: its transform is what is missing
            via = f" (frame {frame!r} is below it)" if top != frame else ""
            raise ValueError(f"the bag has no transform of frame {top!r}{via} ({what}) to the world frame {world!r} in "
                             f"/tf_static or /tf (tf frames: {sorted(set(self.parent) | set(self.roots()))}); give it "
                             f"with --tf {world},{top},X,Y,Z,YAW,PITCH,ROLL or choose --world-frame")
        T = np.eye(4)
        for f in chain[: chain.index(world)]:
            parent, T_parent_f = self.parent[f]
            if f in self.moved and (self.moved[f][0] > _TF_MOVE_TOL_M or self.moved[f][1] > _TF_MOVE_TOL_RAD):
                d_m, d_rad = self.moved[f]
                raise ValueError(f"tf frame {f!r} (on the way from {world!r} to {frame!r}, {what}) moves in /tf by "
                                 f"up to {d_m:.3f} m and {d_rad:.4f} rad; planefuse's sensors have fixed poses")
            T = T_parent_f @ T
        return T


def _T_from_msg(tr) -> np.ndarray:
    q = tr.rotation
    t = tr.translation
    return transform_from_quaternion([q.x, q.y, q.z, q.w], [t.x, t.y, t.z])


# -- messages -----------------------------------------------------------------------------------------------------
def _stamp_ns(msg) -> int:
    return int(msg.header.stamp.sec) * 1_000_000_000 + int(msg.header.stamp.nanosec)


_CHANNELS = {"bgr8": (3, None), "rgb8": (3, cv2.COLOR_RGB2BGR), "mono8": (1, cv2.COLOR_GRAY2BGR),
             "bgra8": (4, cv2.COLOR_BGRA2BGR), "rgba8": (4, cv2.COLOR_RGBA2BGR), "8UC1": (1, cv2.COLOR_GRAY2BGR),
             "8UC3": (3, None)}


def image_from_msg(msg, topic: str) -> np.ndarray:
    """``sensor_msgs/Image`` -> (H, W, 3) uint8 BGR. Encodings: bgr8, rgb8, mono8, bgra8, rgba8 (8 bit).

    Raises
    ------
    ValueError
        Another encoding, or data shorter than ``step * height``, naming the topic.
    """
    enc = str(msg.encoding)
    if enc not in _CHANNELS:
        raise ValueError(f"topic {topic}: image encoding {enc!r} is not supported (8-bit {sorted(_CHANNELS)})")
    ch, conv = _CHANNELS[enc]
    h, w, step = int(msg.height), int(msg.width), int(msg.step)
    data = np.asarray(msg.data, dtype=np.uint8)
    if step < w * ch or data.size < step * h:
        raise ValueError(f"topic {topic}: image data of {data.size} bytes, step {step}, for {w}x{h} {enc}")
    img = data[: step * h].reshape(h, step)[:, : w * ch].reshape(h, w, ch)
    img = img[..., 0] if ch == 1 else img
    return np.ascontiguousarray(img) if conv is None else cv2.cvtColor(img, conv)


def _compressed_suffix(data: np.ndarray, topic: str) -> str:
    head = bytes(data[:8])
    if head[:3] == b"\xff\xd8\xff":
        return "jpg"
    if head == b"\x89PNG\r\n\x1a\n":
        return "png"
    raise ValueError(f"topic {topic}: CompressedImage is neither JPEG nor PNG (starts with {head!r})")


def _k_d(info) -> tuple[list[float], list[float]]:
    """CameraInfo's K (9) and D: ``k``, ``d`` in ROS 2, ``K``, ``D`` in ROS 1."""
    k = info.k if hasattr(info, "k") else info.K
    d = info.d if hasattr(info, "d") else info.D
    return [float(v) for v in k], [float(v) for v in d]


def _intrinsics(info, topic: str) -> tuple[int, int, list[list[float]], list[float]]:
    k, d = _k_d(info)
    K = np.asarray(k, dtype=float).reshape(3, 3)
    model = str(info.distortion_model)
    if model not in ("plumb_bob", "rational_polynomial", "") or (model == "" and any(d)):
        raise ValueError(f"topic {topic}: distortion model {model!r} is not supported (plumb_bob: k1 k2 p1 p2 k3)")
    d = (d + [0.0] * 5)[:5] if len(d) <= 5 else d
    if len(d) > 5:
        if any(d[5:]):
            raise ValueError(f"topic {topic}: rational_polynomial distortion with k4..k6 = {d[5:8]} is not supported "
                             "(planefuse's model is OpenCV's k1 k2 p1 p2 k3)")
        d = d[:5]
    if not (np.isfinite(K).all() and K[0, 0] > 0 and K[1, 1] > 0):
        raise ValueError(f"topic {topic}: camera matrix K {K.tolist()} is not a calibration (uncalibrated camera?)")
    return int(info.width), int(info.height), K.tolist(), d


def _laser_ranges(msg) -> np.ndarray:
    """Ranges (B,) float64 of a LaserScan in planefuse's convention: NaN invalid, inf no return."""
    r = np.asarray(msg.ranges, dtype=np.float64)
    out = r.copy()
    invalid = np.isnan(r) | (r == -np.inf) | (r < float(msg.range_min))
    out[invalid] = np.nan
    out[~invalid & (r > float(msg.range_max))] = np.inf
    return out


_PC2_DTYPES = {1: "i1", 2: "u1", 3: "i2", 4: "u2", 5: "i4", 6: "u4", 7: "f4", 8: "f8"}


def points_from_pointcloud2(msg) -> np.ndarray:
    """x, y, z (N, 3) float64 [m] of a deserialised ``sensor_msgs/PointCloud2`` message.

    Raises
    ------
    ValueError
        When a field x, y or z is missing or has an unknown datatype, or the data are too short.
    """
    fields = {f.name: f for f in msg.fields}
    missing = [k for k in "xyz" if k not in fields]
    if missing:
        raise ValueError(f"PointCloud2 lacks fields {missing} (has {sorted(fields)})")
    endian = ">" if msg.is_bigendian else "<"
    names, formats, offsets = [], [], []
    for k in "xyz":
        f = fields[k]
        if f.datatype not in _PC2_DTYPES:
            raise ValueError(f"PointCloud2 field {k!r} has unknown datatype {f.datatype}")
        names.append(k)
        formats.append(endian + _PC2_DTYPES[f.datatype])
        offsets.append(f.offset)
    dt = np.dtype({"names": names, "formats": formats, "offsets": offsets, "itemsize": msg.point_step})
    n = int(msg.width) * int(msg.height)
    data = np.asarray(msg.data, dtype=np.uint8)
    if msg.row_step * msg.height > data.size or n * msg.point_step > data.size:
        raise ValueError(f"PointCloud2 data has {data.size} bytes, fewer than {n} points x {msg.point_step} bytes")
    if msg.row_step != msg.width * msg.point_step:  # padded rows: take each row separately
        rows = data[: msg.row_step * msg.height].reshape(msg.height, msg.row_step)[:, : msg.width * msg.point_step]
        data = np.ascontiguousarray(rows).reshape(-1)
    rec = np.frombuffer(data[: n * msg.point_step].tobytes(), dtype=dt, count=n)
    return np.column_stack([rec["x"], rec["y"], rec["z"]]).astype(float)
