"""Sensor streams: the same accessors for simulated (in memory) and recorded (on disk, lazy) data.

* :class:`CameraStream` -- ``camera`` (PinholeCamera), ``times_s``, ``frame(i)``, ``mask(i)``, iteration
  yields :class:`CameraFrame`; files are read one at a time.
* :class:`ImuStream` -- ``chunks()`` of :class:`ImuData`, or ``read()`` for everything.
* :class:`LaserStream` -- ``chunks()`` of :class:`LaserScans` (one NPZ file per chunk), or ``read()``.
* :class:`AudioStream` -- ``blocks(n)`` of (start time, samples (n, 2)), or ``read()``.
"""

from __future__ import annotations

import csv
import functools
import os
import stat
import zipfile
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import cv2
import numpy as np
import soundfile as sf

from ..geometry import CameraIntrinsics, PinholeCamera, intrinsics_problem
from ._manifest import BinauralEntry, CameraEntry, ImuEntry, LaserEntry
from ._paths import PathArray, resolve_all_inside, resolve_inside
from ._timestamps import Gap, TimeChecker, read_csv_chunks
from ._video import VideoFrames

__all__ = [
    "CameraFrame",
    "CameraStream",
    "ImuData",
    "ImuStream",
    "LaserScans",
    "LaserStream",
    "AudioStream",
    "IMU_COLUMNS",
    "camera_from_entry",
    "ignore_mask_from_entry",
    "image_file_problem",
]

IMU_COLUMNS = ["time_s", "gyro_x_rad_s", "gyro_y_rad_s", "gyro_z_rad_s", "accel_x_m_s2", "accel_y_m_s2", "accel_z_m_s2"]


def camera_from_entry(e: CameraEntry) -> PinholeCamera:
    """The :class:`PinholeCamera` a manifest entry describes.

    Raises
    ------
    ValueError
        Naming the camera: its intrinsics are implausible for its image (:func:`planefuse.geometry.intrinsics_problem`:
        principal point outside the image, a field of view over 170 or under 0.5 degrees, very non-square pixels, a
        lens distortion that folds back or moves the image's edges by more than half their radius).
    """
    intr = CameraIntrinsics(np.asarray(e.K, dtype=float), e.width_px, e.height_px, np.asarray(e.dist, dtype=float))
    problem = intrinsics_problem(intr)
    if problem is not None:
        raise ValueError(f"camera {e.name!r}: {problem}")
    return PinholeCamera(intr, np.asarray(e.T_world_cam, dtype=float), name=e.name)


# --------------------------------------------------------------------------- cameras
@dataclass(frozen=True)
class CameraFrame:
    """One camera frame: ``image`` (H, W, 3) uint8 BGR; ``mask`` (H, W) uint8 labels (0 background,
    ``pid + 1`` person ``pid``) or None when the stream has no ground-truth masks."""

    index: int
    time_s: float
    image: np.ndarray
    mask: np.ndarray | None


class CameraStream:
    """Frames of one camera.

    Parameters
    ----------
    camera : PinholeCamera
    times_s : ndarray, shape (F,)
        Frame times on the recording clock [s].
    get : callable ``i -> (image, mask or None)``
        Produces frame ``i`` (renders it, or reads its files); the mask may be a function that reads it.
    has_masks : bool
    rate_hz : float
        Nominal frame rate.
    gaps : list of Gap, optional
        Gaps found in the time stamps.
    get_background : callable ``() -> image``, optional
        An image of the empty scene (a "background plate"), if the recording has one.

    Attributes
    ----------
    ignore_mask : ndarray, shape (height_px, width_px), bool, or None
        Pixels that are not scene evidence (watermark, privacy zone...): the camera's sensor model treats
        the cells they see as unobserved. None when every pixel counts.
    frame_files : sequence of Path
        The image file of every frame of a stream recorded as images (a :class:`PathArray`; empty for a video or
        a simulated stream); ``planefuse check`` verifies them with :func:`image_file_problem` without decoding.
    """

    def __init__(self, camera: PinholeCamera, times_s, get: Callable[[int], tuple], has_masks: bool,
                 rate_hz: float, gaps: list[Gap] | None = None,
                 get_background: Callable[[], np.ndarray] | None = None) -> None:
        self.camera = camera
        self.times_s = np.asarray(times_s, dtype=float)
        self._get = get
        self.has_masks = has_masks
        self.rate_hz = float(rate_hz)
        self.gaps = gaps or []
        self._cache: tuple[int, tuple] | None = None
        self._get_background = get_background
        self.ignore_mask: np.ndarray | None = None
        self.frame_files: Sequence[Path] = []  # image files of a recorded stream (empty: video or in memory)

    @property
    def has_background(self) -> bool:
        return self._get_background is not None

    def background(self) -> np.ndarray:
        """Image (H, W, 3) uint8 BGR of the empty scene (no people), e.g. to initialise background subtraction."""
        if self._get_background is None:
            raise ValueError(f"{self.name}: this stream has no background image")
        return self._get_background()

    @property
    def name(self) -> str:
        return self.camera.name

    def __len__(self) -> int:
        return len(self.times_s)

    def _item(self, i: int) -> tuple:
        if not -len(self) <= i < len(self):
            raise IndexError(f"{self.name}: frame {i} out of range (0..{len(self) - 1})")
        i = i % len(self)
        if self._cache is None or self._cache[0] != i:
            self._cache = (i, self._get(i))
        return self._cache[1]

    def frame(self, i: int) -> np.ndarray:
        """Image ``i`` (H, W, 3) uint8 BGR."""
        return self._item(i)[0]

    def mask(self, i: int) -> np.ndarray:
        """Ground-truth label mask ``i`` (H, W) uint8: 0 background, ``pid + 1`` for person ``pid``."""
        if not self.has_masks:
            raise ValueError(f"{self.name}: this stream has no ground-truth masks")
        return _resolve(self._item(i)[1])

    def __iter__(self) -> Iterator[CameraFrame]:
        for i in range(len(self)):
            img, mask = self._item(i)
            yield CameraFrame(i, float(self.times_s[i]), img, _resolve(mask))

    @classmethod
    def from_files(cls, root: Path, entry: CameraEntry) -> CameraStream:
        """Open a recorded camera: reads ``times_file`` now (checking timestamps), images on demand
        (image files, or frames decoded from ``video_file``)."""
        files: Sequence[Path] = []
        if entry.video_file is not None:
            times, get, has_masks, source = _video_frames(root, entry)
        else:
            times, get, has_masks, source, files = _image_frames(root, entry)
        checker = TimeChecker(source, entry.rate_hz)
        checker.check(np.array(times), first_line=2)  # one row per line after the header
        if len(times) != entry.n_frames:
            raise ValueError(f"{source}: manifest says n_frames = {entry.n_frames}, file lists {len(times)} "
                             "(truncated?)")
        bg = None
        if entry.background_file is not None:
            bg_path = resolve_inside(root, entry.background_file, f"background_file of camera {entry.name!r}")
            if not bg_path.is_file():
                raise ValueError(f"{bg_path}: file not found (background of camera {entry.name!r})")

            def bg() -> np.ndarray:
                return _read_png(bg_path, cv2.IMREAD_COLOR)

        stream = cls(camera_from_entry(entry), times, get, has_masks, entry.rate_hz, checker.gaps, bg)
        stream.ignore_mask = ignore_mask_from_entry(root, entry)
        stream.frame_files = files
        return stream


def ignore_mask_from_entry(root: Path, entry: CameraEntry) -> np.ndarray | None:
    """The camera's ignored pixels (height_px, width_px) bool from its rectangles and mask file, or None."""
    if not entry.ignore_rects_px and entry.ignore_mask_file is None:
        return None
    mask = np.zeros((entry.height_px, entry.width_px), dtype=bool)
    for u0, v0, u1, v1 in entry.ignore_rects_px:
        mask[v0:v1, u0:u1] = True
    if entry.ignore_mask_file is not None:
        path = resolve_inside(root, entry.ignore_mask_file, f"ignore_mask_file of camera {entry.name!r}")
        img = _read_png(path, cv2.IMREAD_GRAYSCALE)
        if img.shape != mask.shape:
            raise ValueError(f"{path}: ignore mask of camera {entry.name!r} is "
                             f"{img.shape[1]}x{img.shape[0]} px, the camera {entry.width_px}x{entry.height_px} px")
        mask |= img > 0
    return mask


def _read_times(path: Path, headers: list[list[str]], what: str) -> tuple[list[str], list[list[str]]]:
    """Header and rows of a camera's times CSV, every row as long as the header."""
    if not path.is_file():
        raise ValueError(f"{path}: file not found (missing stream of camera {what!r})")
    with open(path, newline="") as fh:
        reader = csv.reader(fh)
        header = next(reader, None)
        if header not in headers:
            raise ValueError(f"{path}:1: header must be {' or '.join(','.join(h) for h in headers)}, got {header}")
        rows = []
        for row in reader:
            if len(row) != len(header):
                raise ValueError(f"{path}:{reader.line_num}: expected {len(header)} fields, got {len(row)} "
                                 "(truncated?)")
            rows.append(row)
    return header, rows


def _number(path: Path, line: int, name: str, text: str, kind=float):
    try:
        return kind(text)
    except ValueError:
        raise ValueError(f"{path}:{line}: {name} {text!r} is not a{'n integer' if kind is int else ' number'}") from None


def _image_frames(root: Path, entry: CameraEntry):
    path = resolve_inside(root, entry.times_file, f"times_file of camera {entry.name!r}")
    header, rows = _read_times(path, [["time_s", "image_file"], ["time_s", "image_file", "mask_file"]], entry.name)
    times = [_number(path, k + 2, "time_s", r[0]) for k, r in enumerate(rows)]
    rel = Path(entry.times_file).parent  # frame files are relative to the times file's folder
    images = PathArray(resolve_all_inside(root, [(rel / r[1]).as_posix() for r in rows],
                                          lambda k: f"{path}:{k + 2}: image_file"))
    masks = PathArray(resolve_all_inside(root, [(rel / r[2]).as_posix() for r in rows],
                                         lambda k: f"{path}:{k + 2}: mask_file")) if len(header) > 2 else None

    def get(i: int) -> tuple:
        # the path as a str: a Path per frame read would intern every file name
        img = _read_png(images.fspath(i), cv2.IMREAD_COLOR)
        # masks are read only when asked for (the pipeline never needs them)
        mask = functools.partial(_read_png, masks.fspath(i), cv2.IMREAD_UNCHANGED) if masks else None
        return img, mask

    return times, get, masks is not None, str(path), images


def _video_frames(root: Path, entry: CameraEntry):
    video = resolve_inside(root, entry.video_file, f"video_file of camera {entry.name!r}")
    if entry.times_file is not None:
        path = resolve_inside(root, entry.times_file, f"times_file of camera {entry.name!r}")
        _, rows = _read_times(path, [["time_s", "frame_index"]], entry.name)
        times = [_number(path, k + 2, "time_s", r[0]) for k, r in enumerate(rows)]
        index = [_number(path, k + 2, "frame_index", r[1], int) for k, r in enumerate(rows)]
        source = str(path)
    else:
        index = list(range(entry.n_frames))
        times = [entry.start_time_s + k / entry.rate_hz for k in index]
        source = str(video)
    frames = VideoFrames(video, index, times, entry.name, entry.width_px, entry.height_px)

    def get(i: int) -> tuple:
        return frames(i), None

    return times, get, False, source


def _resolve(mask):
    """A mask, or the function that reads it (file-backed streams read masks on demand)."""
    return mask() if callable(mask) else mask


_JPEG_START, _JPEG_END = b"\xff\xd8\xff", b"\xff\xd9"
_PNG_START, _PNG_END = b"\x89PNG\r\n\x1a\n", b"IEND\xaeB`\x82"
_BMP_START = b"BM"


def image_file_problem(path: str | os.PathLike) -> str | None:
    """What is wrong with an image file, without decoding it: missing, empty, or -- for JPEG, PNG and BMP -- not
    starting with the format's signature (garbage) or not ending with its end marker, for BMP not of the size
    its header declares (truncated). None when nothing is (other formats are checked for existence and size
    only)."""
    try:
        st = os.stat(path)
        size = st.st_size
        if not stat.S_ISREG(st.st_mode):
            return "not a file"
        if size == 0:
            return "empty file"
        with open(path, "rb") as f:
            head = f.read(8)
            f.seek(max(0, size - 32))
            tail = f.read()
    except FileNotFoundError:
        return "file not found (missing frame)"
    except OSError as exc:
        return f"cannot read ({exc.strerror or exc})"
    return _content_problem(path, head, tail, size)


def _content_problem(path: str | os.PathLike, head: bytes, tail: bytes, size: int) -> str | None:
    """:func:`image_file_problem`'s check of a non-empty file of ``size`` bytes from its first 8 and last 32."""
    suffix = os.path.splitext(path)[1].lower()
    if suffix in (".jpg", ".jpeg"):
        if not head.startswith(_JPEG_START):
            return "not a JPEG file (corrupt file)"
        if _JPEG_END not in tail:
            return "JPEG end marker missing (truncated file)"
    elif suffix == ".png":
        if not head.startswith(_PNG_START):
            return "not a PNG file (corrupt file)"
        if _PNG_END not in tail:
            return "PNG end chunk missing (truncated file)"
    elif suffix == ".bmp":
        if not head.startswith(_BMP_START) or len(head) < 6:
            return "not a BMP file (corrupt file)"
        declared = int.from_bytes(head[2:6], "little")  # the file's size in bytes, from its header
        if size < declared:
            return f"{size} bytes of the {declared} its header declares (truncated file)"
    return None


def _read_png(path: str | os.PathLike, flags: int) -> np.ndarray:
    """The image file decoded (any format OpenCV reads), after :func:`image_file_problem`'s checks; the file is
    read once, checked in memory and decoded from there."""
    try:
        data = np.fromfile(path, np.uint8)
    except OSError:  # missing, a folder, unreadable: the check names it
        data = None
    problem = (image_file_problem(path) or "cannot read") if data is None or data.size == 0 else \
        _content_problem(path, data[:8].tobytes(), data[-32:].tobytes(), data.size)
    if problem is not None:
        raise ValueError(f"{path}: {problem}")
    img = cv2.imdecode(data, flags)
    if img is None:
        raise ValueError(f"{path}: cannot decode image (truncated or corrupt file)")
    return img


# --------------------------------------------------------------------------- IMU
@dataclass(frozen=True)
class ImuData:
    """IMU samples: ``times_s`` (N,), ``gyro_rad_s`` (N, 3), ``accel_m_s2`` (N, 3), in the IMU frame."""

    times_s: np.ndarray
    gyro_rad_s: np.ndarray
    accel_m_s2: np.ndarray

    def __len__(self) -> int:
        return len(self.times_s)


def _check_imu_finite(d: ImuData, source: str, where) -> None:
    """Raise naming ``source`` and ``where(i)`` for the first sample whose gyroscope or accelerometer is not
    finite (an attitude filter would carry a NaN through every later sample)."""
    for name, a in (("gyro_rad_s", d.gyro_rad_s), ("accel_m_s2", d.accel_m_s2)):
        bad = np.flatnonzero(~np.isfinite(a).all(axis=1))
        if bad.size:
            raise ValueError(f"{source}: {where(int(bad[0]))}: {name} is not finite ({a[bad[0]].tolist()}); "
                             f"{bad.size} such samples in this chunk")


@dataclass
class ImuStream:
    """An IMU attached to a camera. ``T_cam_imu`` (4, 4) maps IMU coordinates into the camera frame.

    Use :meth:`chunks` to stream, :meth:`read` to load everything.
    """

    name: str
    attached_to: str
    T_cam_imu: np.ndarray
    rate_hz: float
    n_samples: int
    gyro_noise_rad_s: float = 0.0
    accel_noise_m_s2: float = 0.0
    gravity_m_s2: float = 9.81
    data: ImuData | None = None
    path: Path | None = None
    gaps: list[Gap] = field(default_factory=list)

    def chunks(self, max_rows: int = 100_000) -> Iterator[ImuData]:
        """Consecutive pieces of at most ``max_rows`` samples: time stamps checked (finite, increasing; gaps
        longer than 1.5 periods recorded in :attr:`gaps`), gyroscope and accelerometer finite."""
        if self.data is not None:
            d = self.data
            checker = TimeChecker(f"imu {self.name!r}", self.rate_hz)
            for a in range(0, len(d), max_rows):
                piece = ImuData(d.times_s[a : a + max_rows], d.gyro_rad_s[a : a + max_rows],
                                d.accel_m_s2[a : a + max_rows])
                checker.check(piece.times_s)
                _check_imu_finite(piece, f"imu {self.name!r}", lambda i, a=a: f"sample {a + i}")
                yield piece
            self.gaps = checker.gaps
            return
        checker = TimeChecker(str(self.path), self.rate_hz)
        n = 0
        for rows, line in read_csv_chunks(self.path, IMU_COLUMNS, max_rows):
            checker.check(rows[:, 0], line)
            piece = ImuData(rows[:, 0], rows[:, 1:4], rows[:, 4:7])
            _check_imu_finite(piece, str(self.path), lambda i, line=line: f"line {line + i}")
            n += len(rows)
            yield piece
        self.gaps = checker.gaps
        if n != self.n_samples:
            raise ValueError(f"{self.path}: manifest says n_samples = {self.n_samples}, file has {n} rows (truncated?)")

    def read(self) -> ImuData:
        """All samples at once (checked as :meth:`chunks` checks them)."""
        if self.data is not None:
            for _ in self.chunks():
                pass
            return self.data
        parts = list(self.chunks())
        if not parts:
            return ImuData(np.zeros(0), np.zeros((0, 3)), np.zeros((0, 3)))
        return ImuData(*(np.concatenate([getattr(p, f) for p in parts]) for f in ("times_s", "gyro_rad_s", "accel_m_s2")))

    @classmethod
    def from_entry(cls, root: Path, e: ImuEntry) -> ImuStream:
        path = resolve_inside(root, e.file, f"file of imu {e.name!r}")
        if not path.is_file():
            raise ValueError(f"{path}: file not found (missing stream of imu {e.name!r})")
        return cls(e.name, e.attached_to, np.asarray(e.T_cam_imu, dtype=float), e.rate_hz, e.n_samples,
                   e.gyro_noise_rad_s, e.accel_noise_m_s2, e.gravity_m_s2, path=path)


# --------------------------------------------------------------------------- laser
@dataclass(frozen=True)
class LaserScans:
    """A batch of S scans of B beams.

    Attributes
    ----------
    times_s : ndarray, shape (S,)
        Start time of each scan [s].
    angles_rad : ndarray, shape (B,)
        Beam angles in the scanner's plane, counter-clockwise from its x axis [rad].
    ranges_m : ndarray, shape (S, B)
        Ranges [m]; ``inf`` where there is no return within the maximum range, NaN for an invalid
        return (closer than the minimum range), as in :class:`planefuse.laser.LaserScan`.
    tilt_rad : ndarray, shape (S,) or (S, B)
        Nodding angle of the scanner for each scan (or each beam) [rad].
    extra : dict of str -> ndarray
        Further per-scan arrays (leading dimension S), e.g. ``T_world_scanner`` (S, 4, 4).
    """

    times_s: np.ndarray
    angles_rad: np.ndarray
    ranges_m: np.ndarray
    tilt_rad: np.ndarray
    extra: dict[str, np.ndarray] = field(default_factory=dict)

    def __post_init__(self) -> None:
        S, B = len(self.times_s), len(self.angles_rad)
        if np.shape(self.ranges_m) != (S, B):
            raise ValueError(f"ranges_m must have shape (S, B) = {(S, B)}, got {np.shape(self.ranges_m)}")
        if np.shape(self.tilt_rad) not in ((S,), (S, B)):
            raise ValueError(f"tilt_rad must have shape (S,) or (S, B) = {(S, B)}, got {np.shape(self.tilt_rad)}")
        for k, v in self.extra.items():
            if len(v) != S:
                raise ValueError(f"extra array {k!r} must have leading dimension S = {S}, got {np.shape(v)}")

    def __len__(self) -> int:
        return len(self.times_s)

    def slice(self, a: int, b: int) -> LaserScans:
        return LaserScans(self.times_s[a:b], self.angles_rad, self.ranges_m[a:b], self.tilt_rad[a:b],
                          {k: v[a:b] for k, v in self.extra.items()})

    @staticmethod
    def concatenate(parts: list[LaserScans]) -> LaserScans:
        p0 = parts[0]
        return LaserScans(
            np.concatenate([p.times_s for p in parts]), p0.angles_rad, np.concatenate([p.ranges_m for p in parts]),
            np.concatenate([p.tilt_rad for p in parts]),
            {k: np.concatenate([p.extra[k] for p in parts]) for k in p0.extra},
        )


_LASER_KEYS = ("time_s", "angles_rad", "ranges_m", "tilt_rad")


@dataclass
class LaserStream:
    """A laser range finder on a nodding unit. ``T_world_laser`` (4, 4): pose of the untilted scanner."""

    name: str
    T_world_laser: np.ndarray
    rate_hz: float
    n_scans: int
    model: dict = field(default_factory=dict)
    data: LaserScans | None = None
    paths: list[Path] = field(default_factory=list)
    gaps: list[Gap] = field(default_factory=list)
    generate: Callable[[int, int], Iterator[LaserScans]] | None = None

    def chunks(self, max_scans: int = 400, start: int = 0) -> Iterator[LaserScans]:
        """Consecutive batches of scans (one NPZ file each when reading from disk), timestamps checked.

        In-memory streams slice ``data``; simulated streams call ``generate(max_scans, start)`` (ray casting
        on demand). ``start`` skips the first scans (a resumed run): files before it are read for their
        timestamps only, simulated scans before it are not cast.
        """
        if int(start) < 0:
            raise ValueError(f"laser {self.name!r}: start must be >= 0, got {start}")
        start = int(start)
        if self.data is not None:
            for a in range(start, len(self.data), max_scans):
                yield self.data.slice(a, a + max_scans)
            return
        if self.generate is not None:
            yield from self.generate(max_scans, start)
            return
        checker = TimeChecker(self.name, self.rate_hz)
        n = 0
        angles = None
        for p in self.paths:
            scans = _read_laser_npz(p)
            if angles is not None and not np.array_equal(scans.angles_rad, angles):
                raise ValueError(f"{p}: field angles_rad differs from the previous chunk's")
            angles = scans.angles_rad
            checker.source = str(p)
            checker.check(scans.times_s)
            n0, n = n, n + len(scans)
            if n > start:
                yield scans if n0 >= start else scans.slice(start - n0, len(scans))
        self.gaps = checker.gaps
        if n != self.n_scans:
            raise ValueError(f"laser {self.name!r}: manifest says n_scans = {self.n_scans}, files hold {n} (truncated?)")

    def read(self) -> LaserScans:
        """All scans at once."""
        if self.data is not None:
            return self.data
        return LaserScans.concatenate(list(self.chunks()))

    @classmethod
    def from_entry(cls, root: Path, e: LaserEntry) -> LaserStream:
        paths = [resolve_inside(root, f, f"files of laser {e.name!r}") for f in e.files]
        for p in paths:
            if not p.is_file():
                raise ValueError(f"{p}: file not found (missing stream of laser {e.name!r})")
        return cls(e.name, np.asarray(e.T_world_laser, dtype=float), e.rate_hz, e.n_scans, e.model.model_dump(), paths=paths)


def _read_laser_npz(path: Path) -> LaserScans:
    try:
        with np.load(path, allow_pickle=False) as z:
            arrays = {k: z[k] for k in z.files}
    except (zipfile.BadZipFile, EOFError, OSError, ValueError) as exc:
        raise ValueError(f"{path}: cannot read NPZ (truncated or corrupt file): {exc}") from None
    for k in _LASER_KEYS:
        if k not in arrays:
            raise ValueError(f"{path}: field {k!r} is missing (has {sorted(arrays)})")
    extra = {k: v for k, v in arrays.items() if k not in _LASER_KEYS}
    try:
        return LaserScans(arrays["time_s"], arrays["angles_rad"], arrays["ranges_m"], arrays["tilt_rad"], extra)
    except ValueError as exc:
        raise ValueError(f"{path}: {exc}") from None


def write_laser_npz(path: Path, scans: LaserScans) -> None:
    """One chunk of scans as an uncompressed NPZ (fields as in :class:`LaserScans`)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    np.savez(path, time_s=scans.times_s, angles_rad=scans.angles_rad, ranges_m=scans.ranges_m,
             tilt_rad=scans.tilt_rad, **scans.extra)


# --------------------------------------------------------------------------- audio
@dataclass
class AudioStream:
    """A binaural head's two ear signals (left, right), float32, sample ``i`` at ``start_time_s + i / fs_hz``.

    ``T_world_head`` (4, 4): head frame x forward, y left, z up. ``hrtf_sofa``: the SOFA file used to
    simulate it, or None for the spherical head model of radius ``head_radius_m``.
    """

    name: str
    T_world_head: np.ndarray
    fs_hz: int
    start_time_s: float
    n_samples: int
    head_radius_m: float = 0.0875
    hrtf_sofa: str | None = None
    data: np.ndarray | None = None
    path: Path | None = None

    @property
    def times_s(self) -> np.ndarray:
        """Sample times (N,) [s]."""
        return self.start_time_s + np.arange(self.n_samples) / self.fs_hz

    def blocks(self, block_size: int = 16000, start: int = 0) -> Iterator[tuple[float, np.ndarray]]:
        """Yield ``(time_s of the block's first sample, samples (n, 2) float32)``, from sample ``start``."""
        if int(start) < 0:
            raise ValueError(f"audio {self.name!r}: start must be >= 0, got {start}")
        start = int(start)
        if self.data is not None:
            for a in range(start, len(self.data), block_size):
                yield self.start_time_s + a / self.fs_hz, self.data[a : a + block_size]
            return
        n = start
        with self._open() as f:
            if start:
                f.seek(min(start, f.frames))
            for block in f.blocks(blocksize=block_size, dtype="float32", always_2d=True):
                yield self.start_time_s + n / self.fs_hz, block
                n += len(block)
        if n != self.n_samples:
            raise ValueError(f"{self.path}: manifest says n_samples = {self.n_samples}, file has {n} (truncated?)")

    def read(self) -> np.ndarray:
        """All samples (N, 2) float32."""
        if self.data is not None:
            return self.data
        parts = [b for _, b in self.blocks(1 << 20)]
        return np.concatenate(parts) if parts else np.zeros((0, 2), np.float32)

    def _open(self) -> sf.SoundFile:
        try:
            f = sf.SoundFile(self.path)
        except (sf.LibsndfileError, RuntimeError) as exc:
            raise ValueError(f"{self.path}: cannot read WAV (truncated or corrupt file): {exc}") from None
        if f.samplerate != self.fs_hz or f.channels != 2:
            f.close()
            raise ValueError(
                f"{self.path}: expected 2 channels at fs_hz = {self.fs_hz}, got {f.channels} at {f.samplerate}"
            )
        if f.frames != self.n_samples:
            f.close()
            raise ValueError(f"{self.path}: manifest says n_samples = {self.n_samples}, file has {f.frames} (truncated?)")
        return f

    @classmethod
    def from_entry(cls, root: Path, e: BinauralEntry) -> AudioStream:
        path = resolve_inside(root, e.file, f"file of binaural head {e.name!r}")
        if not path.is_file():
            raise ValueError(f"{path}: file not found (missing stream of binaural head {e.name!r})")
        s = cls(e.name, np.asarray(e.T_world_head, dtype=float), e.fs_hz, e.start_time_s, e.n_samples,
                e.head_radius_m, e.hrtf_sofa, path=path)
        s._open().close()  # header checks now, samples later
        return s
