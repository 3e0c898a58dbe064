"""ROS bags as recordings: camera, IMU and laser topics of a ROS 2 bag (sqlite3 or MCAP storage) or a ROS 1
bag, with the sensors' poses from ``/tf_static`` and ``/tf``, written as a planefuse recording folder.

Read with ``rosbags`` (pure Python, no ROS installation); the messages are converted by ``_bag_messages``. See
``docs/recording-format.md``, "Importing a ROS bag".

Times are the messages' header stamps, on the recording clock ``(stamp_ns - origin_ns) / 1e9`` [s] with the
origin the earliest stamp of the imported topics (integer nanoseconds, so a stamp of ``k / rate`` seconds past
the origin reads back as the float ``k / rate``). Messages of a topic that arrive out of order (by header stamp),
duplicated (a stamp already seen on the topic) or missing (gaps longer than 1.5 nominal periods) are counted per
topic in :class:`TopicReport`; out-of-order messages are put in stamp order and duplicates are left out, both
counted and reported, never silently.
"""

from __future__ import annotations

import functools
import inspect
import shutil
import warnings
from dataclasses import dataclass, field
from pathlib import Path

import cv2
import numpy as np
import yaml

from ..geometry import check_transform, invert_transform
from ._bag_messages import _TfTree, _T_from_msg, _compressed_suffix, _intrinsics, _k_d, _laser_ranges, _stamp_ns, \
    image_from_msg, points_from_pointcloud2, scan_ranges_from_points, static_transform
from ._manifest import MANIFEST_NAME, CameraEntry, ImuEntry, LaserEntry, RecordingManifest
from ._paths import check_name
from ._streams import IMU_COLUMNS, LaserScans, write_laser_npz
from ._timestamps import write_csv

__all__ = [
    "BagTopic",
    "BagImport",
    "TopicReport",
    "BAG_SENSOR_TYPES",
    "bag_topics",
    "import_bag",
    "scan_ranges_from_points",
    "select_bag_topics",
    "static_transform",
]

IMAGE_TYPES = ("sensor_msgs/msg/Image", "sensor_msgs/msg/CompressedImage")
INFO_TYPE = "sensor_msgs/msg/CameraInfo"
IMU_TYPE = "sensor_msgs/msg/Imu"
SCAN_TYPE = "sensor_msgs/msg/LaserScan"
CLOUD_TYPE = "sensor_msgs/msg/PointCloud2"
TF_TYPE = "tf2_msgs/msg/TFMessage"
TF_TYPES = (TF_TYPE, "tf/msg/tfMessage")  # the second: older ROS 1 bags (tf before tf2)
#: Message types :func:`import_bag` turns into planefuse streams, and into what.
BAG_SENSOR_TYPES = {
    "sensor_msgs/msg/Image": "camera frames (with the CameraInfo topic beside it)",
    "sensor_msgs/msg/CompressedImage": "camera frames (JPEG/PNG bytes kept as they are)",
    "sensor_msgs/msg/CameraInfo": "camera intrinsics (K, plumb_bob distortion), size",
    "sensor_msgs/msg/Imu": "IMU (gyroscope, accelerometer) attached to a camera",
    "sensor_msgs/msg/LaserScan": "2-D laser scans",
    "sensor_msgs/msg/PointCloud2": "a 2-D scan sliced from the cloud (--cloud, --cloud-band)",
    "tf2_msgs/msg/TFMessage": "sensor poses (/tf_static, /tf)",
    "tf/msg/tfMessage": "sensor poses (/tf of older ROS 1 bags)",
}
_LASER_CHUNK = 400


@dataclass(frozen=True)
class BagTopic:
    """One topic of a bag: ``topic``, ROS 2 ``msgtype`` (``sensor_msgs/msg/Image``), message ``count``, and what
    planefuse makes of it (``use``, empty when nothing)."""

    topic: str
    msgtype: str
    count: int
    use: str = ""


@dataclass
class TopicReport:
    """What the import did with one sensor topic.

    Attributes
    ----------
    topic, sensor, kind : str
        The bag topic, the planefuse sensor it became, and its kind ("camera", "imu", "laser").
    n_messages : int
        Messages of the topic in the bag.
    n_written : int
        Messages written (``n_messages - n_duplicate``).
    n_out_of_order : int
        Messages whose header stamp is earlier than one before it in the bag (put in stamp order).
    n_duplicate : int
        Messages whose header stamp an earlier message of the topic already had (left out; the first is kept).
    n_missing : int
        Messages missing in the gaps longer than 1.5 nominal periods, at the nominal rate (about).
    rate_hz : float
        Nominal rate: 1 / median period of the written stamps [Hz].
    frame_id : str
        The header's frame.
    """

    topic: str
    sensor: str
    kind: str
    n_messages: int = 0
    n_written: int = 0
    n_out_of_order: int = 0
    n_duplicate: int = 0
    n_missing: int = 0
    rate_hz: float = 0.0
    frame_id: str = ""

    def line(self) -> str:
        """One line for a person: counts and rate."""
        return (f"{self.topic} -> {self.kind} {self.sensor!r} ({self.frame_id}): {self.n_written} of "
                f"{self.n_messages} written at {self.rate_hz:.3f} Hz; out of order {self.n_out_of_order}, "
                f"duplicated {self.n_duplicate}, missing {self.n_missing}")


@dataclass
class BagImport:
    """The result of :func:`import_bag`: the manifest written, a report per topic, the clock's origin."""

    manifest: RecordingManifest
    topics: list[TopicReport]
    origin_ns: int
    world_frame: str
    notes: list[str] = field(default_factory=list)


def _reader(path: Path):
    from rosbags.highlevel import AnyReader
    from rosbags.typesys import Stores, get_typestore

    if not path.exists():
        raise ValueError(f"bag {path} does not exist")
    return AnyReader([path], default_typestore=get_typestore(Stores.ROS2_HUMBLE))


def _open(path: Path):
    r = _reader(path)
    try:
        r.open()
    except Exception as err:  # rosbags raises its own error classes per storage format
        raise ValueError(f"cannot read bag {path}: {type(err).__name__}: {err}") from err
    return r


def bag_topics(path: str | Path) -> list[BagTopic]:
    """Every topic of a ROS 1 bag, ROS 2 bag folder (sqlite3 or MCAP storage), with type, count and use.

    Raises
    ------
    ValueError
        A missing path or one that is not a bag (rosbags' error named).
    """
    r = _open(Path(path))
    try:
        return sorted((BagTopic(c.topic, c.msgtype, c.msgcount, BAG_SENSOR_TYPES.get(c.msgtype, ""))
                       for c in r.connections), key=lambda t: t.topic)
    finally:
        r.close()


def _sensor_name(topic: str) -> str:
    parts = [p for p in topic.strip("/").split("/") if p]
    generic = {"image_raw", "image", "image_color", "image_rect", "image_rect_color", "compressed", "data", "raw",
               "scan", "imu", "camera_info"}
    keep = [p for p in parts if p not in generic] or parts[-1:]
    name = "_".join(keep)
    name = "".join(ch if ch.isalnum() or ch in "_.-" else "_" for ch in name).lstrip("_.-") or "sensor"
    return check_name(name[:64], f"sensor name of topic {topic!r}")


def _info_topic_for(image_topic: str, infos: list[str]) -> str | None:
    """The CameraInfo topic of an image topic: the one in the deepest common namespace (``/cam/image_raw`` ->
    ``/cam/camera_info``; ``/cam/image_raw/compressed`` too)."""
    ns = image_topic.rstrip("/").split("/")
    best, depth = None, 0
    for t in infos:
        other = t.rstrip("/").split("/")[:-1]
        d = len(other) if ns[: len(other)] == other else 0
        if d > depth:
            best, depth = t, d
    return best


def select_bag_topics(topics: list[BagTopic]) -> tuple[dict[str, tuple[str, str | None]], dict[str, str],
                                                       dict[str, str]]:
    """Every camera (image topic with its CameraInfo topic), IMU and LaserScan topic of a bag, named after the
    topic (``/cam0/image_raw`` -> ``cam0``): ``(cameras {name: (image, info)}, imus {name: topic},
    lasers {name: topic})``. An image topic without a CameraInfo topic in its namespace is left out."""
    infos = [t.topic for t in topics if t.msgtype == INFO_TYPE]
    cameras: dict[str, tuple[str, str | None]] = {}
    imus, lasers = {}, {}
    for t in topics:
        if t.msgtype in IMAGE_TYPES:
            info = _info_topic_for(t.topic, infos)
            if info is not None:
                cameras[_sensor_name(info.rsplit("/", 1)[0] or t.topic)] = (t.topic, info)
        elif t.msgtype == IMU_TYPE:
            imus[_sensor_name(t.topic) + ("_imu" if not t.topic.rstrip("/").endswith("imu") else "")] = t.topic
        elif t.msgtype == SCAN_TYPE:
            lasers[_sensor_name(t.topic)] = t.topic
    return cameras, imus, lasers


@dataclass
class _Stamps:
    """Header stamps of one topic in bag order, and what the import keeps: ``order`` (indices into the bag
    order, by stamp, duplicates left out)."""

    ns: list[int] = field(default_factory=list)

    def order(self, report: TopicReport) -> np.ndarray:
        ns = np.asarray(self.ns, dtype=np.int64)
        report.n_messages = len(ns)
        if not len(ns):
            return np.zeros(0, dtype=np.int64)
        running = np.maximum.accumulate(ns)
        report.n_out_of_order = int(np.sum(ns[1:] < running[:-1]))
        idx = np.argsort(ns, kind="stable")
        keep = np.ones(len(idx), dtype=bool)
        keep[1:] = ns[idx][1:] != ns[idx][:-1]
        report.n_duplicate = int(np.sum(~keep))
        idx = idx[keep]
        report.n_written = len(idx)
        d = np.diff(ns[idx])
        if d.size:
            period_ns = float(np.median(d))
            report.rate_hz = 1e9 / period_ns
            big = d > 1.5 * period_ns
            report.n_missing = int(np.sum(np.round(d[big] / period_ns) - 1))
        return idx


def _check_stamp(ns: int, topic: str, k: int) -> None:
    if ns <= 0:
        raise ValueError(f"topic {topic}: message {k} has header stamp {ns} ns; planefuse times sensors by their "
                         "header stamps")


# -- the import ---------------------------------------------------------------------------------------------------
def _removes_its_output_when_refused(fn):
    """``fn(path, out_dir, *, ..., overwrite)`` refusing a non-empty ``out_dir`` without ``overwrite``, and removing
    what it wrote when it raises: the output folder if it made it, its entries if it was empty (a folder that held
    files is left as it is)."""
    signature = inspect.signature(fn)

    @functools.wraps(fn)
    def wrapper(*args, **kwargs):
        given = signature.bind(*args, **kwargs)
        given.apply_defaults()
        root, overwrite = Path(given.arguments["out_dir"]), given.arguments["overwrite"]
        existed = root.exists()
        if existed and any(root.iterdir()) and not overwrite:
            raise ValueError(f"{root}: output folder is not empty (pass overwrite=True / --overwrite)")
        fresh = not existed or not any(root.iterdir())
        try:
            return fn(*args, **kwargs)
        except BaseException:
            if fresh and root.is_dir():  # what this import wrote, and nothing else
                if existed:
                    for p in root.iterdir():
                        shutil.rmtree(p) if p.is_dir() else p.unlink()
                else:
                    shutil.rmtree(root)
            raise

    return wrapper


@_removes_its_output_when_refused
def import_bag(path: str | Path, out_dir: str | Path, *, cameras: dict[str, tuple[str, str | None]] | None = None,
              imus: dict[str, str] | None = None, imu_cameras: dict[str, str] | None = None,
              lasers: dict[str, str] | None = None, clouds: dict[str, str] | None = None,
              cloud_band_m: tuple[float, float] = (-0.1, 0.1), cloud_beams: int = 1440,
              cloud_range_m: tuple[float, float] = (0.1, 100.0), world_frame: str | None = None,
              extra_transforms: list[tuple[str, str, np.ndarray]] = (),
              planes_heights_m: list[float] = (0.0, 0.5, 1.0, 1.5),
              room_xy_m: tuple[float, float, float, float] | None = None, overwrite: bool = False) -> BagImport:
    """Write a planefuse recording folder (``docs/recording-format.md``) from topics of a ROS bag.

    Parameters
    ----------
    path : path
        ROS 2 bag folder (``metadata.yaml``; sqlite3 or MCAP storage), bare ``.mcap`` file of ROS 2 messages, or
        ROS 1 ``.bag`` file.
    out_dir : path
        The recording folder; must be empty unless ``overwrite``.
    cameras : dict name -> (image topic, CameraInfo topic)
        ``sensor_msgs/Image`` (8-bit bgr8/rgb8/mono8/bgra8/rgba8, written as BMP) or ``CompressedImage`` (JPEG/PNG,
        the bytes written as they are) topics, each with the CameraInfo topic that gives its intrinsics (the first
        message; a calibration that changes during the bag is refused). The image header's frame is the optical
        frame (x right, y down, z forward). None: every image topic with a CameraInfo topic in its namespace
        (:func:`select_bag_topics`); ``{}``: none.
    imus : dict name -> Imu topic
        Gyroscope [rad/s] and accelerometer [m/s^2] in the header's frame. None: every Imu topic.
    imu_cameras : dict IMU name -> camera name
        The camera each IMU is attached to (the manifest's ``attached_to``); default the only camera, else the
        camera whose frame is nearest the IMU's (printed in ``notes``).
    lasers : dict name -> LaserScan topic
        Scans in the header's frame (x forward, z up, beams counter-clockwise). Ranges: NaN, ``-inf`` and values
        below ``range_min`` (0.0 included) -> NaN (invalid); ``+inf`` and values above ``range_max`` -> ``inf``
        (no return). None: every LaserScan topic.
    clouds : dict name -> PointCloud2 topic
        Each cloud becomes a laser whose scans are sliced from it (:func:`scan_ranges_from_points`: the points with
        z in ``cloud_band_m`` [m] of the cloud's frame, ``cloud_beams`` beams over 360 deg, ranges in
        ``cloud_range_m`` [m]); the cloud's frame must be level (x forward, z up). None or ``{}``: none (a slice is
        a choice, never made for the user).
    world_frame : str, optional
        The tf frame of planefuse's world (z up against gravity, floor at z = 0, metres). Default: the root of the
        tf tree (there must be one), or, without any transform, the frame of the single sensor.
    extra_transforms : list of (parent, child, T_parent_child)
        Transforms the bag lacks (:func:`static_transform` parses ``--tf``); they are added to ``/tf_static``'s.
    planes_heights_m, room_xy_m
        The manifest's suggested planes [m] and monitored area [m].

    Returns
    -------
    BagImport

    Raises
    ------
    ValueError
        One line: a missing or unreadable bag, a topic it does not hold or of another type, a camera without
        CameraInfo, an unsupported image encoding or distortion model, a header stamp of 0, a sensor frame with no
        transform to the world frame (the frame named), a tf frame that moves, no sensor topic at all, a non-empty
        output folder. A refused import leaves no folder behind (the output folder is removed if the import made
        it, emptied if it was empty).
    """
    path, root = Path(path), Path(out_dir)
    listing = bag_topics(path)
    by_topic = {t.topic: t for t in listing}
    auto = select_bag_topics(listing)
    cameras = auto[0] if cameras is None else dict(cameras)
    skipped = []
    if imus is None:
        imus = auto[1] if cameras else {}
        skipped = [f"IMU topics {sorted(auto[1].values())} not imported: no camera to attach them to"] \
            if auto[1] and not cameras else []
    lasers = auto[2] if lasers is None else dict(lasers)
    infos = [t.topic for t in listing if t.msgtype == INFO_TYPE]
    for name, (img, info) in list(cameras.items()):
        check_name(name, "camera name")
        _expect(by_topic, img, IMAGE_TYPES, path)
        info = info or _info_topic_for(img, infos)
        if info is None:
            raise ValueError(f"camera {name!r}: bag {path} has no CameraInfo topic beside {img}; name one "
                             f"(CameraInfo topics: {infos})")
        _expect(by_topic, info, (INFO_TYPE,), path)
        cameras[name] = (img, info)
    for name, t in imus.items():
        check_name(name, "IMU name")
        _expect(by_topic, t, (IMU_TYPE,), path)
    for name, t in lasers.items():
        check_name(name, "laser name")
        _expect(by_topic, t, (SCAN_TYPE,), path)
    clouds = dict(clouds or {})
    for name, t in clouds.items():
        check_name(name, "laser name")
        _expect(by_topic, t, (CLOUD_TYPE,), path)
    if clouds and not (cloud_band_m[0] < cloud_band_m[1] and 0 <= cloud_range_m[0] < cloud_range_m[1]
                       and int(cloud_beams) >= 3):
        raise ValueError(f"cloud slice: need z_min < z_max (got {cloud_band_m}), 0 <= range_min < range_max (got "
                         f"{cloud_range_m}) and >= 3 beams (got {cloud_beams})")
    names = list(cameras) + list(imus) + list(lasers) + list(clouds)
    if not names:
        raise ValueError(f"bag {path}: no camera (image + CameraInfo), Imu or LaserScan topic to import; topics: "
                         f"{ {t.topic: t.msgtype for t in listing} }")
    dup = sorted({n for n in names if names.count(n) > 1})
    if dup:
        raise ValueError(f"sensor names must be unique, repeated: {dup}")
    if imus and not cameras:
        raise ValueError(f"IMU topics {sorted(imus.values())} need a camera to be attached to (planefuse's IMUs "
                         "are a camera's); import a camera too, or leave the IMUs out")
    root.mkdir(parents=True, exist_ok=True)

    sensor_of = {}
    for name, (img, info) in cameras.items():
        sensor_of[img] = ("camera", name)
        sensor_of.setdefault(info, ("info", name))
    sensor_of.update({t: ("imu", n) for n, t in imus.items()})
    sensor_of.update({t: ("laser", n) for n, t in lasers.items()})
    sensor_of.update({t: ("cloud", n) for n, t in clouds.items()})
    reports = {t: TopicReport(t, n, "laser" if k == "cloud" else k)
               for t, (k, n) in sensor_of.items() if k != "info"}
    stamps = {t: _Stamps() for t in reports}
    info_of: dict[str, object] = {}
    imu_rows: dict[str, list] = {n: [] for n in imus}
    scans: dict[str, list] = {n: [] for n in list(lasers) + list(clouds)}
    scan_model: dict[str, tuple] = {}
    image_files: dict[str, list[str]] = {n: [] for n in cameras}
    image_size: dict[str, tuple[int, int]] = {}
    tree = _TfTree()
    for parent, child, T in extra_transforms:
        tree.add(parent, child, check_transform(np.asarray(T, dtype=float), f"--tf {parent},{child}"))

    r = _open(path)
    try:
        tf_conns = [c for c in r.connections if c.msgtype in TF_TYPES and c.topic in ("/tf_static", "/tf", "tf_static",
                                                                                     "tf")]
        want = [c for c in r.connections if c.topic in sensor_of] + tf_conns
        for conn, _, raw in r.messages(connections=want):
            msg = r.deserialize(raw, conn.msgtype)
            if conn.msgtype in TF_TYPES:
                dynamic = conn.topic.lstrip("/") == "tf"
                for tr in msg.transforms:
                    tree.add(tr.header.frame_id, tr.child_frame_id, _T_from_msg(tr.transform), dynamic)
                continue
            kind, name = sensor_of[conn.topic]
            if kind == "info":
                first = info_of.setdefault(name, msg)
                if first is not msg and (_k_d(first) != _k_d(msg) or (first.width, first.height) != (msg.width,
                                                                                                     msg.height)):
                    raise ValueError(f"topic {conn.topic}: the calibration changes during the bag (K, D or size); "
                                     "planefuse's cameras have one calibration")
                continue
            rep, st = reports[conn.topic], stamps[conn.topic]
            ns = _stamp_ns(msg)
            _check_stamp(ns, conn.topic, len(st.ns))
            k = len(st.ns)
            st.ns.append(ns)
            rep.frame_id = rep.frame_id or str(msg.header.frame_id).lstrip("/")
            if kind == "camera":
                image_files[name].append(_write_image(root, name, k, msg, conn.msgtype, conn.topic, image_size))
            elif kind == "imu":
                w, a = msg.angular_velocity, msg.linear_acceleration
                imu_rows[name].append((w.x, w.y, w.z, a.x, a.y, a.z, msg.angular_velocity_covariance[0],
                                       msg.linear_acceleration_covariance[0]))
            elif kind == "cloud":
                n = int(cloud_beams)
                scan_model.setdefault(name, (-np.pi, 2 * np.pi / n, n, float(cloud_range_m[0]),
                                             float(cloud_range_m[1]), 0.0))
                try:
                    pts = points_from_pointcloud2(msg)
                except ValueError as err:
                    raise ValueError(f"topic {conn.topic}: message {k}: {err}") from None
                scans[name].append(scan_ranges_from_points(pts, z_band_m=cloud_band_m, n_beams=n,
                                                           range_min_m=cloud_range_m[0], range_max_m=cloud_range_m[1]))
            else:
                model = (float(msg.angle_min), float(msg.angle_increment), len(msg.ranges), float(msg.range_min),
                         float(msg.range_max), float(msg.time_increment))
                m0 = scan_model.setdefault(name, model)
                if model[:5] != m0[:5]:
                    raise ValueError(f"topic {conn.topic}: message {k} has another beam layout (angle_min, "
                                     f"increment, beams, range_min, range_max = {model[:5]}) than the first {m0[:5]}")
                scans[name].append(_laser_ranges(msg))
    except ValueError:
        raise
    except Exception as err:  # rosbags' own error classes (truncated file, unknown type...)
        raise ValueError(f"cannot read bag {path}: {type(err).__name__}: {err}") from err
    finally:
        r.close()

    orders = {t: stamps[t].order(rep) for t, rep in reports.items()}
    empty = [t for t, rep in reports.items() if rep.n_written == 0]
    if empty:
        raise ValueError(f"bag {path}: topics {empty} have no messages")
    origin_ns = min(int(np.asarray(stamps[t].ns, dtype=np.int64).min()) for t in reports)

    def times_s(topic: str) -> np.ndarray:
        ns = np.asarray(stamps[topic].ns, dtype=np.int64)[orders[topic]]
        return (ns - origin_ns) / 1e9  # integer difference first: exact nanoseconds

    world = world_frame.lstrip("/") if world_frame else None
    if world is None:
        roots = tree.roots()
        frames = {rep.frame_id for rep in reports.values()}
        if len(roots) == 1:
            world = roots[0]
        elif not roots and len(frames) == 1:
            world = next(iter(frames))
        else:
            raise ValueError(f"bag {path}: cannot tell the world frame (tf roots: {roots}, sensor frames: "
                             f"{sorted(frames)}); give --world-frame")
    notes = [f"world frame {world!r}; time 0 = header stamp {origin_ns} ns"] + skipped
    T_world = {n: tree.T_world_frame(world, reports[t].frame_id, f"{reports[t].kind} {n!r}, topic {t}")
               for t, (k, n) in sensor_of.items() if k != "info"}
    sensors: list = []
    ends = []
    for name, (img, info_topic) in cameras.items():
        if name not in info_of:
            raise ValueError(f"camera {name!r}: CameraInfo topic {info_topic} has no message")
        w, h, K, dist = _intrinsics(info_of[name], info_topic)
        if image_size[name] != (w, h):
            raise ValueError(f"camera {name!r}: images of {img} are {image_size[name][0]}x{image_size[name][1]} px, "
                             f"its CameraInfo ({info_topic}) says {w}x{h}")
        t, rep = times_s(img), reports[img]
        files = [image_files[name][i] for i in orders[img]]
        kept = set(files)
        for f in image_files[name]:
            if f not in kept:
                (root / "cameras" / name / f).unlink()  # a duplicate's file (counted in the report)
        rows = "".join(f"{repr(float(ti))},{f}\n" for ti, f in zip(t, files))
        (root / "cameras" / name / "times.csv").write_text("time_s,image_file\n" + rows)
        sensors.append(CameraEntry(type="camera", name=name, width_px=w, height_px=h, K=K, dist=dist,
                                   T_world_cam=T_world[name].tolist(), rate_hz=_rate(rep), n_frames=len(files),
                                   times_file=f"cameras/{name}/times.csv"))
        ends.append(t[-1] + 1 / _rate(rep))
    cam_names = list(cameras)
    for name, topic in imus.items():
        rep = reports[topic]
        cam = (imu_cameras or {}).get(name)
        if cam is None:
            dist_m = {c: float(np.linalg.norm(T_world[c][:3, 3] - T_world[name][:3, 3])) for c in cam_names}
            cam = min(dist_m, key=dist_m.get)
            if len(cam_names) > 1:
                notes.append(f"IMU {name!r} attached to the nearest camera {cam!r} ({dist_m[cam]:.3f} m)")
        elif cam not in cameras:
            raise ValueError(f"IMU {name!r} is attached to camera {cam!r}, which is not imported ({cam_names})")
        rows = np.asarray(imu_rows[name], dtype=float)[orders[topic]]
        t = times_s(topic)
        rel = f"imu/{name}.csv"
        write_csv(root / rel, IMU_COLUMNS, np.column_stack([t, rows[:, :6]]))
        T_cam_imu = invert_transform(T_world[cam]) @ T_world[name]
        sensors.append(ImuEntry(type="imu", name=name, attached_to=cam, T_cam_imu=T_cam_imu.tolist(),
                                rate_hz=_rate(rep), n_samples=len(t), file=rel,
                                gyro_noise_rad_s=float(np.sqrt(max(rows[0, 6], 0.0))),
                                accel_noise_m_s2=float(np.sqrt(max(rows[0, 7], 0.0)))))
        ends.append(t[-1] + 1 / _rate(rep))
    for name, topic in {**lasers, **clouds}.items():
        rep = reports[topic]
        a0, inc, n, rmin, rmax, t_inc = scan_model[name]
        ranges = np.asarray(scans[name], dtype=float)[orders[topic]]
        t = times_s(topic)
        angles = a0 + inc * np.arange(n)
        files = []
        for c, a in enumerate(range(0, len(t), _LASER_CHUNK)):
            rel = f"laser/{name}/scans_{c:06d}.npz"
            b = a + _LASER_CHUNK
            write_laser_npz(root / rel, LaserScans(t[a:b], angles, ranges[a:b], np.zeros(len(t[a:b]))))
            files.append(rel)
        device = {"scanner": {"angle_min_rad": a0, "angle_increment_rad": inc, "n_beams": n, "range_min_m": rmin,
                              "range_max_m": rmax, "name": name},
                  "scan_duration_s": t_inc * n if t_inc > 0 else None}
        sensors.append(LaserEntry(type="laser", name=name, T_world_laser=T_world[name].tolist(), rate_hz=_rate(rep),
                                  n_scans=len(t), files=files, model=device))
        ends.append(t[-1] + 1 / _rate(rep))
    manifest = RecordingManifest(duration_s=float(max(ends)), planes_heights_m=list(planes_heights_m),
                                 room_xy_m=room_xy_m, sensors=sensors, clock_origin_ns=origin_ns,
                                 source=f"planefuse import-bag {path.name} (world frame {world}, time 0 = header "
                                        f"stamp {origin_ns} ns)")
    text = yaml.safe_dump(manifest.model_dump(mode="json", exclude_none=True), sort_keys=False, width=120)
    (root / MANIFEST_NAME).write_text(text)
    for rep in reports.values():
        if rep.n_out_of_order or rep.n_duplicate or rep.n_missing:
            warnings.warn(rep.line(), stacklevel=2)
    return BagImport(manifest, list(reports.values()), origin_ns, world, notes)


def _rate(rep: TopicReport) -> float:
    return rep.rate_hz if rep.rate_hz > 0 else 1.0  # a single message: any rate; 1 Hz


def _expect(by_topic: dict[str, BagTopic], topic: str, types: tuple[str, ...], path: Path) -> None:
    if topic not in by_topic:
        raise ValueError(f"bag {path} has no topic {topic!r}; topics: {sorted(by_topic)}")
    if by_topic[topic].msgtype not in types:
        raise ValueError(f"topic {topic} of bag {path} is a {by_topic[topic].msgtype}, not {' or '.join(types)}")


def _write_image(root: Path, name: str, k: int, msg, msgtype: str, topic: str,
                 size: dict[str, tuple[int, int]]) -> str:
    """Write message ``k`` of a camera topic under ``cameras/<name>/frames/``; its file name relative to
    ``cameras/<name>/``."""
    folder = root / "cameras" / name / "frames"
    folder.mkdir(parents=True, exist_ok=True)
    if msgtype == "sensor_msgs/msg/Image":
        img = image_from_msg(msg, topic)
        rel = f"frames/{k:06d}.bmp"
        if not cv2.imwrite(str(root / "cameras" / name / rel), img):
            raise ValueError(f"{root / 'cameras' / name / rel}: could not write the image")
        wh = (img.shape[1], img.shape[0])
    else:
        data = np.asarray(msg.data, dtype=np.uint8)
        rel = f"frames/{k:06d}.{_compressed_suffix(data, topic)}"
        (root / "cameras" / name / rel).write_bytes(data.tobytes())
        wh = size.get(name)
        if wh is None:  # decode the first frame only: its size against the CameraInfo's
            img = cv2.imdecode(data, cv2.IMREAD_COLOR)
            if img is None:
                raise ValueError(f"topic {topic}: message {k}: cannot decode the compressed image")
            wh = (img.shape[1], img.shape[0])
    if size.setdefault(name, wh) != wh:
        raise ValueError(f"topic {topic}: message {k} is {wh[0]}x{wh[1]} px, the first {size[name][0]}x"
                         f"{size[name][1]} px")
    return rel
