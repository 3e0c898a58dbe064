"""A recording: all sensor streams on one clock plus ground truth; write it to / read it from a folder."""

from __future__ import annotations

import heapq
from collections import deque
from collections.abc import Iterator
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
from pathlib import Path

import cv2
import numpy as np
import soundfile as sf
import yaml

from ..geometry import PinholeCamera
from ._groundtruth import GroundTruth
from ._import import CONTROL_POINT_COLUMNS, ControlPoints, read_control_points
from ._manifest import (
    MANIFEST_NAME,
    BinauralEntry,
    CameraEntry,
    GroundTruthEntry,
    ImuEntry,
    LaserEntry,
    RecordingManifest,
    load_manifest,
)
from ._streams import IMU_COLUMNS, AudioStream, CameraStream, ImuData, ImuStream, LaserStream, write_laser_npz
from ._paths import resolve_inside
from ._timestamps import write_csv
from ._yaml import _safe_load

__all__ = ["DEFAULT_IMAGE_FORMAT", "Event", "Recording", "read_recording", "write_recording"]

_PNG = [cv2.IMWRITE_PNG_COMPRESSION, 1, cv2.IMWRITE_PNG_STRATEGY, cv2.IMWRITE_PNG_STRATEGY_RLE]
_IMAGE_PARAMS = {"bmp": [], "png": _PNG, "jpg": [cv2.IMWRITE_JPEG_QUALITY, 95]}
#: the camera frames' file format :func:`write_recording` (and ``planefuse simulate``) writes by default
DEFAULT_IMAGE_FORMAT = "bmp"


def _png_params(compression: int) -> list[int]:
    """``cv2.imwrite`` parameters of a PNG frame at zlib level ``compression`` (0-9). Level 0 is stored: no
    deflate and no row filter (where OpenCV can be told), so reading a frame is a copy of its pixels."""
    if not (isinstance(compression, int) and 0 <= compression <= 9):
        raise ValueError(f"png_compression must be an integer in 0..9, got {compression!r}")
    if compression == 0:
        none = [cv2.IMWRITE_PNG_FILTER, cv2.IMWRITE_PNG_FILTER_NONE] if hasattr(cv2, "IMWRITE_PNG_FILTER") else []
        return [cv2.IMWRITE_PNG_COMPRESSION, 0, *none]
    return [cv2.IMWRITE_PNG_COMPRESSION, compression, cv2.IMWRITE_PNG_STRATEGY, cv2.IMWRITE_PNG_STRATEGY_RLE]


@dataclass
class Recording:
    """Synchronised sensor streams and ground truth, in memory (simulated) or backed by files (read).

    Attributes
    ----------
    duration_s : float
    camera_streams : dict of str -> CameraStream
    imus : dict of str -> ImuStream
    lasers : dict of str -> LaserStream
    audio : dict of str -> AudioStream
    groundtruth : GroundTruth or None
    planes_heights_m : list of float
        Suggested plane stack heights [m].
    room_xy_m : (x_min, x_max, y_min, y_max) or None
        Extent of the monitored area [m].
    wall_height_m : float or None
    source : str
        Free text: what produced the recording.
    provenance : dict or None
        The simulator's scene configuration, written as ``simulation.yaml``.
    calibration_points : ControlPoints or None
        Pixels of known world points (from ``planefuse import``), reprojected by ``planefuse check``.
    root : Path or None
        Folder the recording was read from.
    clock_origin_ns : int or None
        Time 0 on the source's clock [ns] (a ROS bag's header stamps), or None.
    """

    duration_s: float
    camera_streams: dict[str, CameraStream] = field(default_factory=dict)
    imus: dict[str, ImuStream] = field(default_factory=dict)
    lasers: dict[str, LaserStream] = field(default_factory=dict)
    audio: dict[str, AudioStream] = field(default_factory=dict)
    groundtruth: GroundTruth | None = None
    planes_heights_m: list[float] = field(default_factory=lambda: [0.0, 0.5, 1.0, 1.5])
    room_xy_m: tuple[float, float, float, float] | None = None
    wall_height_m: float | None = None
    source: str = ""
    provenance: dict | None = None
    calibration_points: ControlPoints | None = None
    root: Path | None = None
    clock_origin_ns: int | None = None

    @property
    def cameras(self) -> list[PinholeCamera]:
        """The calibrated cameras, in stream order."""
        return [s.camera for s in self.camera_streams.values()]

    def camera(self, name: str) -> CameraStream:
        """The frames of camera ``name``."""
        return _get(self.camera_streams, name, "camera")

    def imu(self, name: str) -> ImuStream:
        return _get(self.imus, name, "imu")

    def imu_for(self, camera_name: str) -> ImuStream:
        """The IMU attached to camera ``camera_name``."""
        for s in self.imus.values():
            if s.attached_to == camera_name:
                return s
        raise ValueError(f"no IMU is attached to camera {camera_name!r}")

    def laser(self, name: str | None = None) -> LaserStream:
        """Laser ``name`` (or the only one)."""
        return _get(self.lasers, name, "laser")

    def binaural(self, name: str | None = None) -> AudioStream:
        """Binaural head ``name`` (or the only one)."""
        return _get(self.audio, name, "binaural head")

    def events(self, kinds=("camera", "imu", "laser", "binaural"), audio_block_s: float = 0.04) -> Iterator[Event]:
        """All measurements of the chosen sensor kinds merged in time order (lazily, stream by stream).

        Yields :class:`Event` ``(time_s, kind, name, data)`` with ``data`` a :class:`CameraFrame`, an
        :class:`ImuData` of one sample, a :class:`LaserScans` of one scan, or an audio block
        ``(n, 2)`` float32 of ``audio_block_s`` starting at ``time_s``. Ties keep the order of ``kinds``.
        """
        known = {"camera", "imu", "laser", "binaural"}
        if not set(kinds) <= known:
            raise ValueError(f"kinds must be among {sorted(known)}, got {list(kinds)}")
        gens = []
        for rank, kind in enumerate(kinds):
            if kind == "camera":
                gens += [_camera_events(cs, rank) for cs in self.camera_streams.values()]
            elif kind == "imu":
                gens += [_imu_events(s, rank) for s in self.imus.values()]
            elif kind == "laser":
                gens += [_laser_events(s, rank) for s in self.lasers.values()]
            else:
                gens += [_audio_events(s, rank, audio_block_s) for s in self.audio.values()]
        for _, _, ev in heapq.merge(*gens, key=lambda x: (x[0], x[1])):
            yield ev

    def write(self, out_dir: str | Path, *, overwrite: bool = False, masks: bool = True,
              image_format: str = DEFAULT_IMAGE_FORMAT, png_compression: int = 0) -> RecordingManifest:
        """Write every stream, the ground truth and ``scene.yaml`` to ``out_dir``; see :func:`write_recording`."""
        return write_recording(self, out_dir, overwrite=overwrite, masks=masks, image_format=image_format,
                               png_compression=png_compression)


@dataclass(frozen=True)
class Event:
    """One measurement in a time-ordered merge of streams (see :meth:`Recording.events`)."""

    time_s: float
    kind: str
    name: str
    data: object


def _camera_events(cs: CameraStream, rank: int):
    for fr in cs:
        yield fr.time_s, rank, Event(fr.time_s, "camera", cs.name, fr)


def _imu_events(s: ImuStream, rank: int):
    for c in s.chunks():
        for i in range(len(c)):
            t = float(c.times_s[i])
            yield t, rank, Event(t, "imu", s.name, ImuData(c.times_s[i : i + 1], c.gyro_rad_s[i : i + 1],
                                                          c.accel_m_s2[i : i + 1]))


def _laser_events(s: LaserStream, rank: int):
    for c in s.chunks():
        for i in range(len(c)):
            t = float(c.times_s[i])
            yield t, rank, Event(t, "laser", s.name, c.slice(i, i + 1))


def _audio_events(s: AudioStream, rank: int, block_s: float):
    n = max(1, int(round(block_s * s.fs_hz)))
    for t, block in s.blocks(n):
        yield t, rank, Event(t, "binaural", s.name, block)


def _get(d: dict, name: str | None, what: str):
    if name is None:
        if len(d) != 1:
            raise ValueError(f"the recording has {len(d)} {what}s {sorted(d)}; name one")
        return next(iter(d.values()))
    if name not in d:
        raise ValueError(f"no {what} named {name!r}; the recording has {sorted(d)}")
    return d[name]


def _matrix(a: np.ndarray) -> list[list[float]]:
    return np.asarray(a, dtype=float).tolist()


def write_recording(rec: Recording, out_dir: str | Path, *, overwrite: bool = False,
                    masks: bool = True, image_format: str = DEFAULT_IMAGE_FORMAT,
                    png_compression: int = 0) -> RecordingManifest:
    """Write ``rec`` in the planefuse recording format (``docs/recording-format.md``).

    Parameters
    ----------
    rec : Recording
    out_dir : path
        Created if needed; must be empty unless ``overwrite``.
    overwrite : bool
        Allow writing into a non-empty folder (files of the same name are replaced).
    masks : bool
        Also write the cameras' ground-truth label masks (always PNG, lossless).
    image_format : {"bmp", "png", "jpg"}
        Camera frames as uncompressed BMP (the default: exact round trip, read about 10x faster than a stored
        PNG of the same bytes, 0.08 instead of 0.8 ms per 360x288 frame, as it needs no checksums or row
        filters; docs/benchmarks.md, "Real-time factor"), lossless PNG (exact round trip), or JPEG quality 95
        (lossy, about 10x smaller; the pixel noise of simulated frames makes PNG compression expensive and weak).
    png_compression : int
        zlib level of PNG frames, 0-9. 0 (the default) stores them uncompressed: the same pixels, about
        1.7x the bytes of level 1 on simulated frames, but written about 15x and read about 3x faster.
        Masks, background and ignore images are always compressed PNG (they compress well).

    Returns
    -------
    RecordingManifest
        What was written as ``scene.yaml`` (written last, so a folder without it is incomplete).
    """
    if image_format not in _IMAGE_PARAMS:
        raise ValueError(f"image_format must be one of {sorted(_IMAGE_PARAMS)}, got {image_format!r}")
    png = _png_params(png_compression)
    frame_params = png if image_format == "png" else _IMAGE_PARAMS[image_format]
    root = Path(out_dir)
    if root.exists() and any(root.iterdir()) and not overwrite:
        raise ValueError(f"{root}: output folder is not empty (pass overwrite=True / --overwrite)")
    root.mkdir(parents=True, exist_ok=True)
    sensors: list = []
    with ThreadPoolExecutor(max_workers=2) as pool:
        for name, cs in rec.camera_streams.items():
            sensors.append(_write_camera(root, name, cs, masks and cs.has_masks, image_format, frame_params, pool))
    for s in rec.imus.values():
        d = s.read()
        rel = f"imu/{s.name}.csv"
        write_csv(root / rel, IMU_COLUMNS, np.column_stack([d.times_s, d.gyro_rad_s, d.accel_m_s2]))
        sensors.append(ImuEntry(type="imu", name=s.name, attached_to=s.attached_to, T_cam_imu=_matrix(s.T_cam_imu),
                                rate_hz=s.rate_hz, n_samples=len(d), file=rel, gyro_noise_rad_s=s.gyro_noise_rad_s,
                                accel_noise_m_s2=s.accel_noise_m_s2, gravity_m_s2=s.gravity_m_s2))
    for s in rec.lasers.values():
        files, n = [], 0
        for k, chunk in enumerate(s.chunks()):
            rel = f"laser/{s.name}/scans_{k:06d}.npz"
            write_laser_npz(root / rel, chunk)
            files.append(rel)
            n += len(chunk)
        sensors.append(LaserEntry(type="laser", name=s.name, T_world_laser=_matrix(s.T_world_laser), rate_hz=s.rate_hz,
                                  n_scans=n, files=files, model=s.model))
    for s in rec.audio.values():
        rel = f"audio/{s.name}.wav"
        (root / "audio").mkdir(exist_ok=True)
        n = 0
        with sf.SoundFile(root / rel, "w", samplerate=s.fs_hz, channels=2, subtype="FLOAT") as f:
            for _, block in s.blocks(1 << 18):
                f.write(np.asarray(block, dtype=np.float32))
                n += len(block)
        sensors.append(BinauralEntry(type="binaural", name=s.name, T_world_head=_matrix(s.T_world_head),
                                     fs_hz=s.fs_hz, start_time_s=s.start_time_s, n_samples=n, file=rel,
                                     head_radius_m=s.head_radius_m, hrtf_sofa=s.hrtf_sofa))
    gt = GroundTruthEntry(**rec.groundtruth.write(root)) if rec.groundtruth is not None else None
    points_rel = None
    if rec.calibration_points is not None:
        points_rel = "calibration/points.csv"
        rec.calibration_points.write(root / points_rel)
    if rec.provenance is not None:
        (root / "simulation.yaml").write_text(yaml.safe_dump(rec.provenance, sort_keys=False))
    manifest = RecordingManifest(duration_s=rec.duration_s, planes_heights_m=list(rec.planes_heights_m),
                                 room_xy_m=rec.room_xy_m, wall_height_m=rec.wall_height_m, sensors=sensors,
                                 groundtruth=gt, calibration_points_file=points_rel, source=rec.source,
                                 clock_origin_ns=rec.clock_origin_ns)
    text = yaml.safe_dump(manifest.model_dump(mode="json", exclude_none=True), sort_keys=False, width=120)
    (root / MANIFEST_NAME).write_text(text)
    return manifest


def _wait(path: Path, job) -> None:
    if not job.result():
        raise ValueError(f"{path}: could not write the image (disk full or unwritable folder?)")


def _write_camera(root: Path, name: str, cs: CameraStream, masks: bool, image_format: str,
                  frame_params: list[int], pool: ThreadPoolExecutor) -> CameraEntry:
    base = root / "cameras" / name
    (base / "frames").mkdir(parents=True, exist_ok=True)
    if masks:
        (base / "masks").mkdir(exist_ok=True)
    rows = []
    pending: deque = deque()

    def put(path: Path, img: np.ndarray, params: list[int]) -> None:
        # Bounded queue: encoding runs beside rendering without holding every frame in memory.
        pending.append((path, pool.submit(cv2.imwrite, str(path), img, params)))
        while len(pending) > 8:
            _wait(*pending.popleft())

    for fr in cs:
        img_rel = f"frames/{fr.index:06d}.{image_format}"
        put(base / img_rel, fr.image, frame_params)
        row = [repr(float(fr.time_s)), img_rel]
        if masks:
            mask_rel = f"masks/{fr.index:06d}.png"
            put(base / mask_rel, fr.mask, _PNG)
            row.append(mask_rel)
        rows.append(",".join(row))
    while pending:
        _wait(*pending.popleft())
    bg_rel = None
    if cs.has_background:
        bg_rel = f"cameras/{name}/background.png"
        if not cv2.imwrite(str(root / bg_rel), cs.background(), _PNG):
            raise ValueError(f"{root / bg_rel}: could not write the image")
    ignore_rel = None
    if cs.ignore_mask is not None:
        ignore_rel = f"cameras/{name}/ignore.png"
        if not cv2.imwrite(str(root / ignore_rel), cs.ignore_mask.astype(np.uint8) * 255, _PNG):
            raise ValueError(f"{root / ignore_rel}: could not write the image")
    header = "time_s,image_file,mask_file" if masks else "time_s,image_file"
    (base / "times.csv").write_text(header + "\n" + "".join(r + "\n" for r in rows))
    cam = cs.camera
    return CameraEntry(type="camera", name=name, width_px=cam.intrinsics.width_px, height_px=cam.intrinsics.height_px,
                       K=_matrix(cam.K), dist=cam.intrinsics.dist.tolist(), T_world_cam=_matrix(cam.T_world_cam),
                       rate_hz=cs.rate_hz, n_frames=len(rows), times_file=f"cameras/{name}/times.csv",
                       background_file=bg_rel, ignore_mask_file=ignore_rel)


def read_recording(path: str | Path) -> Recording:
    """Open a recording folder lazily: the manifest and the small index files are read and checked now,
    images, IMU samples, laser scans and audio when accessed (streamed in chunks).

    Raises
    ------
    ValueError
        A missing or invalid ``scene.yaml`` (file, line and field named), a missing stream file, or a
        malformed index (file and line named). Stream data are checked as they are read.
    """
    root = Path(path)
    if not root.is_dir():
        raise ValueError(f"{root}: recording folder not found")
    m = load_manifest(root / MANIFEST_NAME)
    rec = Recording(duration_s=m.duration_s, planes_heights_m=list(m.planes_heights_m),
                    room_xy_m=m.room_xy_m, wall_height_m=m.wall_height_m, source=m.source, root=root,
                    clock_origin_ns=m.clock_origin_ns)
    for e in m.entries("camera"):
        rec.camera_streams[e.name] = CameraStream.from_files(root, e)
    for e in m.entries("imu"):
        rec.imus[e.name] = ImuStream.from_entry(root, e)
    for e in m.entries("laser"):
        rec.lasers[e.name] = LaserStream.from_entry(root, e)
    for e in m.entries("binaural"):
        rec.audio[e.name] = AudioStream.from_entry(root, e)
    if m.groundtruth is not None:
        g = m.groundtruth
        rec.groundtruth = GroundTruth.read(root, g.people_file, g.bodies_file, g.sound_sources_file)
    if m.calibration_points_file is not None:
        rec.calibration_points = read_control_points(
            resolve_inside(root, m.calibration_points_file, "calibration_points_file"), columns=CONTROL_POINT_COLUMNS)
    sim = root / "simulation.yaml"
    if sim.is_file():
        rec.provenance = _safe_load(sim.read_text())  # libyaml: 30x faster than the pure-Python parser
    return rec
