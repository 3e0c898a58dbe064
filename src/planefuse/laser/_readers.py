"""Readers for real laser data: CARMEN logs, ROS 1/2 bags (rosbags), XYZ text point clouds."""

from __future__ import annotations

import gzip
import warnings
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..geometry._transforms import transform_from_rotation_translation
from ..io._bag_messages import points_from_pointcloud2  # the message parser sits with the bag import (io)
from ._scanner import LaserScan

__all__ = [
    "CarmenLog",
    "read_carmen_log",
    "T_world_laser_from_pose_2d",
    "PointCloudFrame",
    "read_laser_scans",
    "read_rosbag",
    "read_rosbag_topics",
    "points_from_pointcloud2",
    "read_xyz",
    "read_transform_yaml",
    "NonMonotonicTimeWarning",
    "SUPPORTED_TYPES",
]


class NonMonotonicTimeWarning(UserWarning):
    """Time stamps of a log go backwards (the data are kept, in file order)."""


def T_world_laser_from_pose_2d(x_m, y_m, theta_rad, z_m: float = 0.0) -> np.ndarray:
    """``T_world_laser`` (..., 4, 4) of a laser with 2-D pose(s) ``(x, y, theta)`` at height ``z_m``.

    ``theta_rad`` is counter-clockwise from world +x (yaw about +z).
    """
    x, y, th = np.broadcast_arrays(*(np.asarray(v, dtype=float) for v in (x_m, y_m, theta_rad)))
    c, s = np.cos(th), np.sin(th)
    R = np.zeros(th.shape + (3, 3))
    R[..., 0, 0], R[..., 0, 1], R[..., 1, 0], R[..., 1, 1], R[..., 2, 2] = c, -s, s, c, 1.0
    t = np.stack([x, y, np.full_like(x, z_m)], axis=-1)
    return transform_from_rotation_translation(R, t)


@dataclass(frozen=True)
class CarmenLog:
    """The FLASER records of a CARMEN log.

    Attributes
    ----------
    time_s : ndarray (K,)
        Time stamps (``t_ipc``) [s], in file order (not necessarily monotonic).
    angles_rad : ndarray (n,)
        Beam angles in the laser frame: ``-pi/2 + i pi / n`` [rad].
    ranges_m : ndarray (K, n)
        Ranges [m].
    pose_xy_theta : ndarray (K, 3)
        Laser pose in the map frame: x, y [m], theta [rad] counter-clockwise from +x.
    range_max_m : float
        Readings at or beyond this are max-range ("no return") readings [m].
    params : dict
        ``PARAM`` name -> value string.
    time_backwards_at : ndarray (B,) int
        Record indices ``k`` with ``time_s[k] < time_s[k - 1]`` (reported, not dropped).
    source : str
        File the log came from.
    """

    time_s: np.ndarray
    angles_rad: np.ndarray
    ranges_m: np.ndarray
    pose_xy_theta: np.ndarray
    range_max_m: float
    params: dict = field(default_factory=dict)
    time_backwards_at: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))
    source: str = ""

    def __len__(self) -> int:
        return len(self.time_s)

    @property
    def n_time_backwards(self) -> int:
        """Number of times the time stamps go backwards."""
        return int(self.time_backwards_at.size)

    def T_world_laser(self, z_m: float = 0.0) -> np.ndarray:
        """Laser poses (K, 4, 4) in the map frame, the laser at height ``z_m`` [m]."""
        p = self.pose_xy_theta
        return T_world_laser_from_pose_2d(p[:, 0], p[:, 1], p[:, 2], z_m)

    def returns_world_xy(self, pose_xy_theta=None) -> np.ndarray:
        """World XY (M, 2) [m] of every real return (``0 < r < range_max_m``), all scans stacked.

        Parameters
        ----------
        pose_xy_theta : array_like (K, 3), optional
            Poses to register with instead of the log's (e.g. perturbed ones).
        """
        pose = self.pose_xy_theta if pose_xy_theta is None else np.asarray(pose_xy_theta, dtype=float)
        if pose.shape != self.pose_xy_theta.shape:
            raise ValueError(f"pose_xy_theta must have shape {self.pose_xy_theta.shape}, got {pose.shape}")
        ok = (self.ranges_m > 0) & (self.ranges_m < self.range_max_m)
        k, i = np.nonzero(ok)
        a = self.angles_rad[i] + pose[k, 2]
        r = self.ranges_m[k, i]
        return np.column_stack([pose[k, 0] + r * np.cos(a), pose[k, 1] + r * np.sin(a)])

    def scans(self, z_m: float = 0.0) -> list[LaserScan]:
        """One :class:`LaserScan` per record, with its ``T_world_laser`` at height ``z_m`` [m]."""
        T = self.T_world_laser(z_m)
        return [LaserScan(float(t), self.angles_rad, r, 0.0, 0.0, self.range_max_m, T[k])
                for k, (t, r) in enumerate(zip(self.time_s, self.ranges_m))]


def _open_text(path: Path):
    with open(path, "rb") as f:
        magic = f.read(2)
    if magic == b"\x1f\x8b":
        return gzip.open(path, "rt", encoding="ascii", errors="strict")
    return open(path, encoding="ascii", errors="strict")


def read_carmen_log(path, range_max_m: float = 80.0) -> CarmenLog:
    """Read the ``FLASER`` records (ranges + corrected pose) of a CARMEN log (plain or gzip).

    Parameters
    ----------
    path : str or Path
        ``.log`` or ``.log.gz`` file.
    range_max_m : float
        Readings ``>= range_max_m`` are max-range readings [m] (CARMEN writes about 81.9 m).

    Returns
    -------
    CarmenLog
        Records in file order. Time stamps that go backwards are kept and reported in
        ``time_backwards_at`` with a :class:`NonMonotonicTimeWarning`.

    Raises
    ------
    ValueError
        Malformed FLASER line (wrong field count, non-numeric field, beam count changing),
        naming the line, or a file without FLASER records.
    """
    path = Path(path)
    times, ranges, poses, params = [], [], [], {}
    n_beams = None
    try:
        with _open_text(path) as f:
            for lineno, line in enumerate(f, 1):
                tok = line.split()
                if not tok or tok[0].startswith("#"):
                    continue
                if tok[0] == "PARAM" and len(tok) >= 3:
                    params[tok[1]] = tok[2]
                    continue
                if tok[0] != "FLASER":
                    continue
                try:
                    n = int(tok[1])
                    if len(tok) != 2 + n + 9:
                        raise ValueError(f"expected {2 + n + 9} fields for {n} beams, got {len(tok)}")
                    vals = np.array(tok[2:2 + n + 6], dtype=float)
                    t = float(tok[2 + n + 6])
                except (ValueError, IndexError) as err:
                    raise ValueError(f"{path}:{lineno}: malformed FLASER record: {err}") from None
                if n_beams is None:
                    n_beams = n
                elif n != n_beams:
                    raise ValueError(f"{path}:{lineno}: FLASER has {n} beams, earlier records had {n_beams}")
                ranges.append(vals[:n])
                poses.append(vals[n:n + 3])
                times.append(t)
    except (OSError, EOFError, UnicodeDecodeError, gzip.BadGzipFile) as err:
        raise ValueError(f"cannot read CARMEN log {path}: {err}") from err
    if not times:
        raise ValueError(f"{path}: no FLASER records found")
    time_s = np.array(times)
    back = np.flatnonzero(np.diff(time_s) < 0) + 1
    if back.size:
        warnings.warn(
            f"{path.name}: FLASER time stamps go backwards {back.size} times (records {back.tolist()[:10]}); "
            "kept in file order, see CarmenLog.time_backwards_at", NonMonotonicTimeWarning, stacklevel=2)
    n = n_beams
    angles = -np.pi / 2 + np.arange(n) * np.pi / n
    return CarmenLog(time_s, angles, np.array(ranges), np.array(poses), float(range_max_m), params, back, str(path))


# -- ROS bags ------------------------------------------------------------------------------------


@dataclass(frozen=True)
class PointCloudFrame:
    """One ``sensor_msgs/PointCloud2`` message.

    Attributes
    ----------
    time_s : float
        Header stamp [s].
    frame_id : str
        Frame the points are expressed in.
    points : ndarray (N, 3)
        x, y, z [m]; rows with non-finite coordinates are kept (``n_nonfinite`` counts them).
    """

    time_s: float
    frame_id: str
    points: np.ndarray

    @property
    def n_nonfinite(self) -> int:
        """Rows with NaN/inf coordinates (ROS marks missing points so)."""
        return int(np.sum(~np.isfinite(self.points).all(axis=1)))


def _stamp_s(msg) -> float:
    return msg.header.stamp.sec + 1e-9 * msg.header.stamp.nanosec


def _convert(msg, msgtype: str):
    if msgtype == "sensor_msgs/msg/LaserScan":
        r = np.asarray(msg.ranges, dtype=float)
        angles = msg.angle_min + msg.angle_increment * np.arange(r.size)
        return LaserScan(_stamp_s(msg), angles, r, 0.0, float(msg.range_min), float(msg.range_max))
    if msgtype == "sensor_msgs/msg/PointCloud2":
        return PointCloudFrame(_stamp_s(msg), msg.header.frame_id, points_from_pointcloud2(msg))
    if msgtype == "geometry_msgs/msg/PoseArray":
        return np.array([[p.position.x, p.position.y, p.position.z] for p in msg.poses]).reshape(-1, 3)
    raise AssertionError(msgtype)  # unreachable: types are checked before


#: Message types :func:`read_rosbag` converts, and into what.
SUPPORTED_TYPES = {
    "sensor_msgs/msg/LaserScan": "LaserScan",
    "sensor_msgs/msg/PointCloud2": "PointCloudFrame",
    "geometry_msgs/msg/PoseArray": "ndarray (P, 3) of positions",
}


def _reader(paths):
    from rosbags.highlevel import AnyReader
    from rosbags.typesys import Stores, get_typestore

    paths = [Path(p) for p in (paths if isinstance(paths, (list, tuple)) else [paths])]
    for p in paths:
        if not p.exists():
            raise ValueError(f"bag {p} does not exist")
    return AnyReader(paths, default_typestore=get_typestore(Stores.ROS1_NOETIC))


def read_rosbag_topics(path) -> dict[str, tuple[str, int]]:
    """Topics of a ROS 1 bag / ROS 2 bag folder: ``{topic: (msgtype, count)}``.

    Raises
    ------
    ValueError
        If the bag is missing or cannot be opened (corrupt / not a bag).
    """
    try:
        with _reader(path) as r:
            return {c.topic: (c.msgtype, c.msgcount) for c in r.connections}
    except ValueError:
        raise
    except Exception as err:  # rosbags raises its own error classes per format
        raise ValueError(f"cannot read bag {path}: {type(err).__name__}: {err}") from err


def read_rosbag(path, topic: str) -> tuple[np.ndarray, list]:
    """All messages of one topic of a ROS 1 / ROS 2 bag, converted (via ``rosbags.highlevel.AnyReader``).

    Parameters
    ----------
    path : str or Path
        ROS 1 ``.bag`` file or ROS 2 bag folder.
    topic : str
        Topic name; its type must be one of :data:`SUPPORTED_TYPES` (``LaserScan`` ->
        :class:`LaserScan` with the header stamp as ``time_s``, ranges as recorded -- 0 / inf /
        NaN are kept and classified by the scan's masks; ``PointCloud2`` ->
        :class:`PointCloudFrame`; ``PoseArray`` -> (P, 3) positions).

    Returns
    -------
    bag_time_s : ndarray (M,)
        Bag (receive) time of each message [s], in bag order.
    messages : list
        Converted messages, in bag order.

    Raises
    ------
    ValueError
        Missing / corrupt bag, unknown topic (the error lists the topics), or a topic type
        that is not supported (names the type and the supported ones).
    """
    try:
        with _reader(path) as r:
            conns = [c for c in r.connections if c.topic == topic]
            if not conns:
                have = {c.topic: c.msgtype for c in r.connections}
                raise ValueError(f"bag {path} has no topic {topic!r}; topics: {have}")
            msgtype = conns[0].msgtype
            if msgtype not in SUPPORTED_TYPES:
                raise ValueError(f"topic {topic!r} has type {msgtype}, not one of {sorted(SUPPORTED_TYPES)}")
            times, out = [], []
            for c, t_ns, raw in r.messages(connections=conns):
                out.append(_convert(r.deserialize(raw, c.msgtype), c.msgtype))
                times.append(t_ns * 1e-9)
    except ValueError:
        raise
    except Exception as err:  # rosbags raises its own error classes per format
        raise ValueError(f"cannot read bag {path}: {type(err).__name__}: {err}") from err
    return np.array(times), out


def read_xyz(path) -> np.ndarray:
    """Points (N, 3) [m] of a text point cloud with ``x y z`` per line (extra columns rejected).

    Raises
    ------
    ValueError
        Unreadable file, a line that is not three numbers (numpy names it), or no points.
        Non-finite coordinates are kept (count them with ``~np.isfinite(p).all(1)``).
    """
    try:
        p = np.loadtxt(path, dtype=float, ndmin=2)
    except (OSError, ValueError) as err:
        raise ValueError(f"cannot read XYZ cloud {path}: {err}") from err
    if p.shape[0] == 0 or p.shape[1] != 3:
        raise ValueError(f"XYZ cloud {path} must have 3 columns and >= 1 row, got shape {p.shape}")
    return p


def read_transform_yaml(path) -> np.ndarray:
    """``T_a_b`` (4, 4) from a YAML file with ``R`` (3x3 rows) and ``t`` (3,) [m]: ``p_a = R p_b + t``.

    (The layout of ``T_camera_laser_stage*.yaml`` of ``lrf3d_camera_lcct``.)

    Raises
    ------
    ValueError
        Missing keys, wrong shapes, or ``R`` not a rotation.
    """
    from ..io._yaml import YamlFileError, read_yaml

    try:
        d, _ = read_yaml(path)  # safe YAML: no alias bomb, no duplicate key
    except YamlFileError as err:
        raise ValueError(f"cannot read R and t from {err}") from None
    try:
        R, t = np.asarray(d["R"], dtype=float), np.asarray(d["t"], dtype=float)
    except (KeyError, TypeError, ValueError) as err:
        raise ValueError(f"cannot read R and t from {path}: {type(err).__name__}: {err}") from err
    if R.shape != (3, 3) or t.shape != (3,):
        raise ValueError(f"{path}: R must be 3x3 and t 3 numbers, got {R.shape} and {t.shape}")
    return transform_from_rotation_translation(R, t)


#: First bytes of a ROS 1 bag file.
_ROSBAG1_MAGIC = b"#ROSBAG V2.0"


def _laser_topics(path) -> dict[str, tuple[str, int]]:
    return {t: v for t, v in read_rosbag_topics(path).items() if v[0] == "sensor_msgs/msg/LaserScan"}


def read_laser_scans(path, topic: str | None = None) -> tuple[list[LaserScan], str]:
    """2-D laser scans of a CARMEN log (``FLASER``, with poses) or of a LaserScan topic of a ROS bag.

    Parameters
    ----------
    path : path-like
        CARMEN ``.log`` / ``.log.gz`` file, ROS 1 ``.bag`` file, or ROS 2 bag folder (``metadata.yaml``).
    topic : str, optional
        Bag topic of type ``sensor_msgs/LaserScan``; default: the bag's only one.

    Returns
    -------
    scans : list of LaserScan
        In file order; CARMEN scans carry their ``T_world_laser`` (corrected pose, z = 0).
    source : str
        What was read: the topic name, or ``"FLASER"``.

    Raises
    ------
    ValueError
        One line naming what was found: a folder that is not a ROS 2 bag, a file that is neither a bag nor a
        CARMEN log, a bag without a LaserScan topic (its topics listed), several of them and no ``topic``.
    """
    path = Path(path)
    if path.is_dir():
        if not (path / "metadata.yaml").is_file():
            found = sorted(p.name for p in path.iterdir())[:10]
            raise ValueError(f"folder {path} is not a ROS 2 bag (no metadata.yaml); it holds {found}")
        is_bag = True
    elif not path.is_file():
        raise ValueError(f"laser input {path} does not exist")
    else:
        with open(path, "rb") as f:
            head = f.read(len(_ROSBAG1_MAGIC))
        is_bag = head == _ROSBAG1_MAGIC
    if not is_bag:
        if topic:
            raise ValueError(f"--topic {topic!r} given but {path} is not a ROS bag")
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", NonMonotonicTimeWarning)  # reported by the caller from the log
                log = read_carmen_log(path)
        except ValueError as err:
            raise ValueError(f"{path} is neither a ROS bag nor a CARMEN log ({err})") from None
        return log.scans(), "FLASER"
    topics = _laser_topics(path)
    if topic is None:
        if len(topics) != 1:
            kind = "no" if not topics else f"{len(topics)}"
            raise ValueError(f"bag {path} has {kind} sensor_msgs/LaserScan topics ({sorted(topics)}); "
                             f"all topics: {read_rosbag_topics(path)}" + ("; choose one with a topic" if topics else ""))
        topic = next(iter(topics))
    elif topic not in topics:
        raise ValueError(f"bag {path} has no LaserScan topic {topic!r}; LaserScan topics: {sorted(topics)}")
    return read_rosbag(path, topic)[1], topic
