"""Build a recording folder (format version 2) from what an installation has: per camera a video file or a
folder of images, a calibration (any format of :func:`planefuse.calib.load_cameras`), ignore regions, and
optionally ground truth (box files through the cameras' ground mapping, or positions on the ground) and
control points (pixels of known ground points). See ``docs/recording-format.md`` ("Importing").

:func:`import_recording` writes the folder; the readers below turn users' files into what it takes. Every
input is checked on the way in and every refusal is one ``ValueError`` line naming the input.
"""

from __future__ import annotations

import csv
import os
import re
import shutil
from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path

import cv2
import numpy as np
import yaml

from ..calib import load_epfl_boxes
from ..geometry import PinholeCamera, apply_homography
from ._groundtruth import GroundTruth, PeopleTruth
from ._manifest import MANIFEST_NAME, CameraEntry, GroundTruthEntry, RecordingManifest
from ._paths import check_name
from ._timestamps import TimeChecker, write_csv
from ._video import VideoFrames, video_info

__all__ = [
    "VIDEO_SUFFIXES",
    "IMAGE_SUFFIXES",
    "CONTROL_POINT_COLUMNS",
    "CameraInput",
    "ControlPoints",
    "ImportReport",
    "probe_camera_input",
    "people_from_boxes",
    "frame_times_of",
    "read_ground_positions",
    "read_control_points",
    "import_recording",
]

VIDEO_SUFFIXES = (".mp4", ".avi", ".mkv", ".mov", ".m4v", ".webm", ".mpg", ".mpeg", ".wmv")
IMAGE_SUFFIXES = (".png", ".jpg", ".jpeg", ".bmp", ".tif", ".tiff")
CONTROL_POINT_COLUMNS = ["camera", "u_px", "v_px", "x_m", "y_m", "z_m"]
#: Most frames a median background estimate reads (evenly spread over its window).
MEDIAN_MAX_FRAMES = 31
#: Fewest frames a median background estimate accepts.
MEDIAN_MIN_FRAMES = 3
_NUMBER = re.compile(r"(\d+)")


@dataclass(frozen=True)
class CameraInput:
    """One camera's frames as the user has them.

    Attributes
    ----------
    name : str
        Camera name (must match its calibration).
    path : Path
        A video file (suffix in :data:`VIDEO_SUFFIXES`) or a folder of images (:data:`IMAGE_SUFFIXES`, ordered by
        the last number in their names).
    times_file : Path, optional
        Video: CSV ``time_s,frame_index`` (the recorded frames, a subset allowed). Images: CSV
        ``time_s,image_file`` (names inside ``path``). Without it frame ``k`` is at ``start_time_s + k / rate_hz``.
    rate_hz : float, optional
        Frame rate [Hz]; a video's container rate by default; required for images without ``times_file``.
    start_time_s : float
        Time of frame 0 [s] when there is no ``times_file``.
    ignore_rects_px : tuple of (u_min, v_min, u_max, v_max)
        Pixels that are not evidence (max exclusive).
    ignore_mask : Path, optional
        8-bit image of the frame size, non-zero = not evidence.
    background : Path, optional
        Image of the empty scene (colour, the frames' size): primes the camera's background model.
    background_median_s : float, optional
        Without an empty-scene image: estimate one as the per-pixel median of the camera's imported frames in
        their first ``background_median_s`` seconds (at most :data:`MEDIAN_MAX_FRAMES`, evenly spread). People who
        walk are removed; people who stay in one place for more than half the window are not.
    """

    name: str
    path: Path
    times_file: Path | None = None
    rate_hz: float | None = None
    start_time_s: float = 0.0
    ignore_rects_px: tuple[tuple[int, int, int, int], ...] = ()
    ignore_mask: Path | None = None
    background: Path | None = None
    background_median_s: float | None = None


@dataclass
class _Probe:
    """What :func:`probe_camera_input` found: size, frame times and the frames to copy."""

    width_px: int
    height_px: int
    times_s: np.ndarray
    rate_hz: float
    video: Path | None = None
    frame_index: np.ndarray | None = None  # video frames holding the recorded frames
    images: list[Path] = field(default_factory=list)
    note: str = ""


def _times_csv(path: Path, second: str, what: str) -> tuple[np.ndarray, list[str]]:
    if not path.is_file():
        raise ValueError(f"{path}: times file of camera {what!r} not found")
    with open(path, newline="") as fh:
        reader = csv.reader(fh)
        header = [c.strip() for c in next(reader, [])]
        if header != ["time_s", second]:
            raise ValueError(f"{path}:1: header must be time_s,{second}, got {','.join(header)!r}")
        times, col = [], []
        for row in reader:
            if len(row) != 2:
                raise ValueError(f"{path}:{reader.line_num}: expected 2 fields, got {len(row)}")
            try:
                times.append(float(row[0]))
            except ValueError:
                raise ValueError(f"{path}:{reader.line_num}: time_s {row[0]!r} is not a number") from None
            col.append(row[1].strip())
    if not times:
        raise ValueError(f"{path}: times file of camera {what!r} has no rows")
    return np.array(times), col


def _decodable_frames(path: Path, stop: int | None = None) -> int:
    """Frames OpenCV actually decodes from the video (up to ``stop``): containers' frame counts can be wrong."""
    cap = cv2.VideoCapture(str(path))
    n = 0
    try:
        while (stop is None or n < stop) and cap.grab():
            n += 1
    finally:
        cap.release()
    return n


def _image_size(path: Path, camera: str) -> tuple[int, int]:
    """``(width, height)`` [px] of an image file from its header (Pillow reads no pixel)."""
    from PIL import Image, UnidentifiedImageError

    try:
        with Image.open(path) as img:
            return int(img.size[0]), int(img.size[1])
    except (OSError, UnidentifiedImageError, ValueError) as exc:
        raise ValueError(f"{path}: cannot read the image (camera {camera!r}): {exc}") from None


def _common_size(images: list[Path], camera: str) -> tuple[int, int]:
    """The size [px] every image of a camera has (each file's header is read); an image of another size than most is
    an error naming it (a run would fail on it later)."""
    sizes = [_image_size(path, camera) for path in images]
    common = Counter(sizes).most_common(1)[0][0]
    odd = [k for k, size in enumerate(sizes) if size != common]
    if odd:
        k = odd[0]
        raise ValueError(f"{images[k]}: camera {camera!r} image is {sizes[k][0]}x{sizes[k][1]} px, "
                         f"{len(images) - len(odd)} of its {len(images)} images are {common[0]}x{common[1]} px"
                         + (f" ({len(odd)} of other sizes)" if len(odd) > 1 else "")
                         + ": every frame of a camera must have one size")
    return common


def _numbered_images(folder: Path, inp: CameraInput) -> tuple[list[Path], np.ndarray, str]:
    """The images of a folder without a times file, in the order of the last number in their names, each dated by
    its number: image number ``n`` is at ``start_time_s + (n - n_first) / rate_hz``, so that images missing from the
    numbering (frames the capture dropped) leave their gap in time instead of every later frame being dated early.

    Returns ``(images, times_s, note)``; the note says how many numbers are missing, and where first.

    Raises
    ------
    ValueError
        No image; no rate; some images with a number and some without; two images with one number; numbers that
        do not step by 1 (the median step: numbers that are time stamps or every n-th frame need a times file).
    """
    images = [x for x in folder.iterdir() if x.suffix.lower() in IMAGE_SUFFIXES]
    if not images:
        raise ValueError(f"{folder}: camera {inp.name!r}: no images ({', '.join(IMAGE_SUFFIXES)}) in this folder")
    if inp.rate_hz is None:
        raise ValueError(f"{folder}: camera {inp.name!r}: an image folder needs a frame rate (--rate NAME=HZ) or "
                         "a times file (--times NAME=CSV)")
    numbers = {x: _NUMBER.findall(x.stem) for x in images}
    unnumbered = sorted(x.name for x, n in numbers.items() if not n)
    if unnumbered:
        if len(unnumbered) < len(images):
            raise ValueError(f"{folder / unnumbered[0]}: camera {inp.name!r}: this image has no number in its name, "
                             "the others have: they cannot be put in order; remove it or give a times file")
        images = sorted(images, key=lambda x: x.name)  # no numbers at all: name order, one frame each
        return images, inp.start_time_s + np.arange(len(images)) / inp.rate_hz, \
            " (no numbers in the names: in name order, one frame period apart)"
    images = sorted(images, key=lambda x: (int(numbers[x][-1]), x.name))
    k = np.array([int(numbers[x][-1]) for x in images], dtype=np.int64)
    step = np.diff(k)
    if np.any(step == 0):
        i = int(np.argmax(step == 0))
        raise ValueError(f"{images[i + 1]}: camera {inp.name!r}: has the number {k[i]} of {images[i].name}: "
                         "two images of one frame; remove one")
    if step.size and np.median(step) != 1:
        raise ValueError(f"{folder}: camera {inp.name!r}: the image numbers step by {int(np.median(step))} "
                         f"({images[0].name}, {images[1].name}, ...): are they time stamps or every n-th frame? "
                         "Give a times file (--times NAME=CSV) with each image's time")
    times = inp.start_time_s + (k - k[0]) / inp.rate_hz
    missing = int(k[-1] - k[0] + 1 - len(k))
    note = ""
    if missing:
        i = int(np.argmax(step > 1))
        note = (f"; warning: {missing} image number(s) missing ({step[step > 1].size} gap(s), the first "
                f"{k[i] + 1}..{k[i + 1] - 1} after {images[i].name}): each image is dated by its number, the "
                "camera has no frame in the gaps")
    return images, times, note


def probe_camera_input(inp: CameraInput) -> _Probe:
    """Check one camera's frames and work out their times (videos are decoded through once, to count frames).

    Raises
    ------
    ValueError
        A missing path, an unknown suffix, an empty folder, an image of another size than the first (each one's
        header is read; naming it), image numbers that cannot date the images (:func:`_numbered_images`), a bad
        times file, a video shorter than its times file, or a missing rate.
    """
    check_name(inp.name, "camera name")
    p = Path(inp.path)
    if inp.rate_hz is not None and not (np.isfinite(inp.rate_hz) and inp.rate_hz > 0):
        raise ValueError(f"camera {inp.name!r}: rate_hz must be positive, got {inp.rate_hz}")
    if p.is_file() and p.suffix.lower() in VIDEO_SUFFIXES:
        n_header, fps, w, h = video_info(p)
        if inp.times_file is not None:
            times, col = _times_csv(Path(inp.times_file), "frame_index", inp.name)
            try:
                index = np.array([int(c) for c in col], dtype=np.int64)
            except ValueError:
                raise ValueError(f"{inp.times_file}: frame_index must be integers") from None
            n = _decodable_frames(p, int(index.max()) + 1)
            if index.min() < 0 or index.max() >= n:
                k = int(np.argmax(index >= n)) if index.max() >= n else int(np.argmin(index))
                raise ValueError(f"{p}: camera {inp.name!r} video has {n} decodable frames, shorter than its times "
                                 f"{inp.times_file}: row {k + 2} asks for video frame {index[k]} (t={times[k]!r} s)")
            rate = inp.rate_hz or (1.0 / float(np.median(np.diff(times))) if len(times) > 1 else fps)
        else:
            n = _decodable_frames(p)
            rate = inp.rate_hz or fps
            if not (np.isfinite(rate) and rate > 0):
                raise ValueError(f"{p}: camera {inp.name!r}: the container gives no frame rate; give rate_hz "
                                 "(--rate NAME=HZ) or a times file")
            index = np.arange(n)
            times = inp.start_time_s + index / rate
        note = f"{inp.name}: {p.name}, {w}x{h} px, {n} frames decoded"
        if n_header and n_header != n and inp.times_file is None:
            note += f" (the container says {n_header})"
        if n == 0:
            raise ValueError(f"{p}: camera {inp.name!r}: OpenCV decodes no frame from this video")
        return _Probe(w, h, times, float(rate), video=p, frame_index=index, note=note)
    if p.is_dir():
        if inp.times_file is not None:
            times, names = _times_csv(Path(inp.times_file), "image_file", inp.name)
            images = [p / n for n in names]
            missing = [str(x) for x in images if not x.is_file()]
            if missing:
                raise ValueError(f"{inp.times_file}: {len(missing)} image(s) listed are not in {p}, first {missing[0]}")
            rate = inp.rate_hz or (1.0 / float(np.median(np.diff(times))) if len(times) > 1 else 1.0)
            gap_note = ""
        else:
            images, times, gap_note = _numbered_images(p, inp)
            rate = inp.rate_hz
        width, height = _common_size(images, inp.name)
        note = f"{inp.name}: {len(images)} images in {p}, {width}x{height} px" + gap_note
        return _Probe(width, height, times, float(rate), images=images, note=note)
    if p.exists():
        raise ValueError(f"{p}: camera {inp.name!r}: not a video ({', '.join(VIDEO_SUFFIXES)}) nor a folder of images")
    raise ValueError(f"{p}: camera {inp.name!r}: no such video file or image folder")


# --------------------------------------------------------------------------- ground truth
def _read_boxes(path: Path, fmt: str) -> tuple[np.ndarray, np.ndarray, np.ndarray, int]:
    """``frame (0-based), person_id, foot (N, 2) px`` of visible boxes, and the number of rows left out."""
    if fmt == "vatic":
        b = load_epfl_boxes(path)
        vis = ~b.lost
        return b.frame[vis], b.track_id[vis], b.foot_uv()[vis], int((~vis).sum())
    if fmt == "mot":
        if not Path(path).is_file():
            raise ValueError(f"{path}: box file not found")
        try:
            a = np.loadtxt(path, delimiter=",", ndmin=2, usecols=range(6))
        except ValueError as exc:
            raise ValueError(f"{path}: expected MOTChallenge rows 'frame,id,left,top,width,height[,conf,...]' "
                             f"({exc})") from None
        try:  # MOTChallenge ground truth marks rows to ignore with a 0 in column 7
            flag = np.loadtxt(path, delimiter=",", ndmin=2, usecols=[6])[:, 0]
        except (ValueError, IndexError):
            flag = np.ones(len(a))
        keep = flag != 0
        a = a[keep]
        if not np.isfinite(a).all():
            raise ValueError(f"{path}: non-finite values in the boxes")
        foot = np.c_[a[:, 2] + 0.5 * a[:, 4], a[:, 3] + a[:, 5]]
        return a[:, 0].astype(np.int64) - 1, a[:, 1].astype(np.int64), foot, int((~keep).sum())
    raise ValueError(f"box format {fmt!r} is unknown; use 'mot' (MOTChallenge) or 'vatic' (EPFL/Vatic gt.txt)")


def people_from_boxes(cameras: dict[str, PinholeCamera], box_files: dict[str, Path], fmt: str, *,
                      frame_times_s, H_ground_image: dict[str, np.ndarray] | None = None,
                      ) -> tuple[PeopleTruth, list[str]]:
    """Ground-truth positions from per-camera person boxes with identities shared by the cameras.

    Each box's bottom centre (the feet) is mapped to the ground z = 0 through its camera; a person's position
    in a frame is the per-axis median over the cameras that see them. Frame ``k`` (0-based; MOTChallenge's
    1-based frames are shifted) is at ``frame_times_s[k]``.

    Parameters
    ----------
    cameras : dict of str -> PinholeCamera
        Every camera that has a box file (cameras without video are allowed: their boxes still place people).
    box_files : dict of str -> Path
    fmt : {"mot", "vatic"}
        MOTChallenge ``frame,id,left,top,width,height,flag,...`` (rows with flag 0 are left out) or EPFL/Vatic
        ``id xmin ymin xmax ymax frame lost occluded generated label`` (``lost`` rows are left out).
    frame_times_s : array_like, shape (F,)
        Time [s] of each (video) frame number of the recording, NaN for frames it does not hold (see
        :func:`frame_times_of`); boxes of other frames are left out and counted.
    H_ground_image : dict of str -> ndarray (3, 3), optional
        Cameras whose feet go to the ground through this homography (pixels -> ground XY [m]) rather than through
        the camera model: cameras calibrated by a ground homography alone keep its exact mapping.

    Returns
    -------
    (PeopleTruth, list of str)
        Positions (heading, speed and height NaN: boxes do not give them) and notes counting what was left out.
    """
    rows, notes = [], []
    times = np.asarray(frame_times_s, dtype=float)
    for name, path in box_files.items():
        if name not in cameras:
            raise ValueError(f"{path}: boxes of camera {name!r}, which has no calibration")
        frame, pid, foot, dropped = _read_boxes(Path(path), fmt)
        if H_ground_image and name in H_ground_image:
            xy = apply_homography(H_ground_image[name], foot)
        else:
            xy = cameras[name].backproject_to_height(foot, 0.0)[:, :2]
        ok = np.isfinite(xy).all(axis=1)
        recorded = np.zeros(len(frame), dtype=bool)
        inside = (frame >= 0) & (frame < len(times))
        recorded[inside] = np.isfinite(times[frame[inside]])
        ok &= recorded
        if (~recorded).any():
            notes.append(f"{name}: {int((~recorded).sum())} boxes of frames the recording does not hold (it has "
                         f"{int(np.isfinite(times).sum())} of frames 0..{len(times) - 1}) left out")
        if dropped:
            notes.append(f"{name}: {dropped} box rows marked lost/ignored left out")
        if (~np.isfinite(xy).all(axis=1)).any():
            notes.append(f"{name}: {int((~np.isfinite(xy).all(axis=1)).sum())} boxes whose feet do not reach the ground "
                         "left out")
        rows.append(np.c_[frame[ok], pid[ok], xy[ok]])
    a = np.concatenate(rows) if rows else np.zeros((0, 4))
    if not len(a):
        raise ValueError(f"no usable box in {', '.join(map(str, box_files.values()))}")
    key = a[:, 0] * (a[:, 1].max() + 1) + a[:, 1]
    order = np.lexsort((a[:, 1], a[:, 0]))
    a, key = a[order], key[order]
    starts = np.flatnonzero(np.r_[True, np.diff(key) != 0])
    med = np.stack([np.median(seg[:, 2:4], axis=0) for seg in np.split(a, starts[1:])])
    frames, pids = a[starts, 0], a[starts, 1]
    out = np.full((len(starts), 7), np.nan)
    out[:, 0] = times[frames.astype(np.int64)]
    out[:, 1] = pids
    out[:, 2:4] = med
    return PeopleTruth.from_rows(out, "boxes"), notes


def frame_times_of(probe: _Probe) -> np.ndarray:
    """Time [s] of each video frame number (NaN where the recording skips it), or of each image, of a probed
    camera: what :func:`people_from_boxes` dates box frames with."""
    if probe.frame_index is None:
        return probe.times_s.copy()
    out = np.full(int(probe.frame_index.max()) + 1, np.nan)
    out[probe.frame_index] = probe.times_s
    return out


def read_ground_positions(path: Path, unit_m: float, *, rate_hz: float | None = None,
                          start_time_s: float = 0.0) -> PeopleTruth:
    """Ground-truth positions from a CSV ``time_s,person_id,x,y`` or ``frame,person_id,x,y`` (0-based frames at
    ``start_time_s + frame / rate_hz``), ``x, y`` on the ground in the unit ``unit_m`` metres."""
    p = Path(path)
    if not p.is_file():
        raise ValueError(f"{p}: ground-truth positions file not found")
    header = p.read_text().splitlines()[0].strip().split(",") if p.stat().st_size else []
    if header not in (["time_s", "person_id", "x", "y"], ["frame", "person_id", "x", "y"]):
        raise ValueError(f"{p}:1: header must be time_s,person_id,x,y or frame,person_id,x,y, got {','.join(header)!r}")
    try:
        a = np.loadtxt(p, delimiter=",", skiprows=1, ndmin=2)
    except ValueError as exc:
        raise ValueError(f"{p}: {exc}") from None
    if a.shape[1] != 4 or not np.isfinite(a).all():
        raise ValueError(f"{p}: expected 4 finite numbers per row")
    if header[0] == "frame":
        if rate_hz is None:
            raise ValueError(f"{p}: frames need a frame rate to become times")
        a[:, 0] = start_time_s + a[:, 0] / rate_hz
    a = a[np.lexsort((a[:, 1], a[:, 0]))]
    out = np.full((len(a), 7), np.nan)
    out[:, :2] = a[:, :2]
    out[:, 2:4] = a[:, 2:4] * unit_m
    return PeopleTruth.from_rows(out, str(p))


# --------------------------------------------------------------------------- control points
@dataclass(frozen=True)
class ControlPoints:
    """Pixels of known world points (surveyed marks, tape crosses): ``camera`` (N,) names, ``uv_px`` (N, 2),
    ``xyz_m`` (N, 3) world [m]. ``planefuse check`` reprojects them."""

    camera: np.ndarray
    uv_px: np.ndarray
    xyz_m: np.ndarray

    def write(self, path: Path) -> None:
        path.parent.mkdir(parents=True, exist_ok=True)
        with open(path, "w", newline="") as fh:
            w = csv.writer(fh)
            w.writerow(CONTROL_POINT_COLUMNS)
            for c, uv, xyz in zip(self.camera, self.uv_px, self.xyz_m):
                w.writerow([c, *(repr(float(x)) for x in (*uv, *xyz))])


def read_control_points(path: Path, unit_m: float = 1.0, *, columns: list[str] | None = None) -> ControlPoints:
    """Control points from a CSV ``camera,u_px,v_px,x,y,z`` (lengths in ``unit_m`` metres; a recording's own
    ``calibration/points.csv`` has ``x_m,y_m,z_m``).

    Raises
    ------
    ValueError
        Missing file, wrong header, or a malformed row (file and line named).
    """
    p = Path(path)
    cols = columns or ["camera", "u_px", "v_px", "x", "y", "z"]
    if not p.is_file():
        raise ValueError(f"{p}: control points file not found")
    cams, vals = [], []
    with open(p, newline="") as fh:
        reader = csv.reader(fh)
        header = [c.strip() for c in next(reader, [])]
        if header != cols:
            raise ValueError(f"{p}:1: header must be {','.join(cols)}, got {','.join(header)!r}")
        for row in reader:
            try:
                v = [float(x) for x in row[1:]]
            except ValueError:
                v = []
            if len(row) != len(cols) or len(v) != 5 or not np.isfinite(v).all():
                raise ValueError(f"{p}:{reader.line_num}: expected camera name and 5 finite numbers, got {row}")
            cams.append(row[0].strip())
            vals.append(v)
    a = np.array(vals, dtype=float).reshape(-1, 5)
    return ControlPoints(np.array(cams, dtype=object), a[:, :2], a[:, 2:] * unit_m)


# --------------------------------------------------------------------------- writing
@dataclass
class ImportReport:
    """What :func:`import_recording` wrote: the manifest, and notes (frame counts, left-out rows, fit errors)."""

    manifest: RecordingManifest
    notes: list[str] = field(default_factory=list)


def _place(src: Path, dst: Path) -> None:
    """Hard link ``src`` to ``dst`` (same file system) or copy it: the recording must hold its own files."""
    dst.parent.mkdir(parents=True, exist_ok=True)
    if dst.exists() or dst.is_symlink():  # --overwrite: replace, never write through an old link into the source
        dst.unlink()
    try:
        os.link(src, dst)
    except OSError:
        shutil.copy2(src, dst)


def _matrix(a) -> list[list[float]]:
    return np.asarray(a, dtype=float).tolist()


def import_recording(out_dir: str | Path, inputs: list[CameraInput], cameras: dict[str, PinholeCamera], *,
                     planes_heights_m=(0.0, 0.5, 1.0, 1.5), room_xy_m=None, people: PeopleTruth | None = None,
                     control_points: ControlPoints | None = None, overwrite: bool = False,
                     source: str = "planefuse import", probes: dict | None = None) -> ImportReport:
    """Write a recording folder (format 2) from users' frames and calibrated cameras.

    Videos and images are hard-linked into the folder where the file system allows, else copied; the folder is
    self-contained. Times files are rewritten in the recording's layout; ``scene.yaml`` is written last.

    Parameters
    ----------
    out_dir : path
        Created; must be empty unless ``overwrite``.
    inputs : list of CameraInput
        One per camera stream.
    cameras : dict of str -> PinholeCamera
        Calibrations in metres, keyed by camera name; every input needs one, of its frames' size.
    planes_heights_m : sequence of float
        Suggested plane stack [m].
    room_xy_m : (x_min, x_max, y_min, y_max), optional
        Monitored area [m].
    people : PeopleTruth, optional
        Ground-truth positions.
    control_points : ControlPoints, optional
        Known world points and their pixels, kept for ``planefuse check``.
    overwrite : bool
    source : str
        Free text kept in the manifest (e.g. the command line).
    probes : dict, optional
        :func:`probe_camera_input` results already computed for ``inputs`` (by name), not to decode videos twice.

    Raises
    ------
    ValueError
        A camera without calibration or of another size, duplicate names, control points of unknown cameras,
        a non-empty output folder, or any input error (see :func:`probe_camera_input`).
    """
    names = [i.name for i in inputs]
    if not names:
        raise ValueError("no camera input: give at least one camera's video or image folder")
    dup = sorted({n for n in names if names.count(n) > 1})
    if dup:
        raise ValueError(f"camera names must be unique, repeated: {dup}")
    missing = [n for n in names if n not in cameras]
    if missing:
        raise ValueError(f"camera {missing[0]!r} has frames but no calibration (calibrated: {', '.join(sorted(cameras))})")
    if control_points is not None:
        unknown = sorted(set(control_points.camera) - set(cameras))
        if unknown:
            raise ValueError(f"control points name camera {unknown[0]!r}, which has no calibration")
    root = Path(out_dir)
    if root.exists() and any(root.iterdir()) and not overwrite:
        raise ValueError(f"{root}: output folder is not empty (pass overwrite=True / --overwrite)")
    probes = {i.name: (probes or {}).get(i.name) or probe_camera_input(i) for i in inputs}
    notes = [pr.note for pr in probes.values()]
    for inp in inputs:
        cam, pr = cameras[inp.name], probes[inp.name]
        size = (cam.intrinsics.width_px, cam.intrinsics.height_px)
        if size != (pr.width_px, pr.height_px):
            raise ValueError(f"{inp.path}: camera {inp.name!r} frames are {pr.width_px}x{pr.height_px} px, its "
                             f"calibration {size[0]}x{size[1]} px")
        TimeChecker(str(inp.times_file or inp.path), pr.rate_hz).check(pr.times_s)
    masks = {inp.name: _read_ignore_mask(inp, probes[inp.name]) for inp in inputs}
    backgrounds = {inp.name: _background(inp, probes[inp.name]) for inp in inputs}
    notes += [f"{inp.name}: background = median of {backgrounds[inp.name][1]} frames in the first "
              f"{inp.background_median_s:g} s" for inp in inputs if inp.background_median_s is not None]
    root.mkdir(parents=True, exist_ok=True)
    sensors = [_write_camera(root, inp, cameras[inp.name], probes[inp.name], masks[inp.name],
                             backgrounds[inp.name][0]) for inp in inputs]
    gt = None
    if people is not None:
        gt = GroundTruthEntry(**GroundTruth(people=people).write(root))
    points_rel = None
    if control_points is not None:
        points_rel = "calibration/points.csv"
        control_points.write(root / points_rel)
    t0 = min(float(pr.times_s[0]) for pr in probes.values())
    t1 = max(float(pr.times_s[-1]) + 1.0 / pr.rate_hz for pr in probes.values())
    manifest = RecordingManifest(duration_s=t1 - min(t0, 0.0), planes_heights_m=list(planes_heights_m),
                                 room_xy_m=room_xy_m, sensors=sensors, groundtruth=gt, source=source,
                                 calibration_points_file=points_rel)
    text = yaml.safe_dump(manifest.model_dump(mode="json", exclude_none=True), sort_keys=False, width=120)
    (root / MANIFEST_NAME).write_text(text)
    return ImportReport(manifest, notes)


def _read_ignore_mask(inp: CameraInput, pr: _Probe) -> np.ndarray | None:
    """The camera's ignore mask (height_px, width_px) bool, checked against its frames' size, or None."""
    if inp.ignore_mask is None:
        return None
    mask = cv2.imread(str(inp.ignore_mask), cv2.IMREAD_GRAYSCALE)
    if mask is None:
        raise ValueError(f"{inp.ignore_mask}: cannot read the ignore mask of camera {inp.name!r}")
    if mask.shape != (pr.height_px, pr.width_px):
        raise ValueError(f"{inp.ignore_mask}: ignore mask of camera {inp.name!r} is {mask.shape[1]}x{mask.shape[0]} "
                         f"px, its frames {pr.width_px}x{pr.height_px} px")
    return mask > 0


def _background(inp: CameraInput, pr: _Probe) -> tuple[np.ndarray | None, int]:
    """The camera's empty-scene image (H, W, 3) uint8 BGR -- the user's, or the median estimate -- or None,
    with the number of frames the estimate took (0 otherwise)."""
    if inp.background is not None and inp.background_median_s is not None:
        raise ValueError(f"camera {inp.name!r}: give an empty-scene image or a median estimate "
                         "(background_median_s), not both")
    if inp.background is not None:
        img = cv2.imread(str(inp.background), cv2.IMREAD_COLOR)
        if img is None:
            raise ValueError(f"{inp.background}: cannot read the background image of camera {inp.name!r}")
        if img.shape[:2] != (pr.height_px, pr.width_px):
            raise ValueError(f"{inp.background}: background of camera {inp.name!r} is {img.shape[1]}x{img.shape[0]} "
                             f"px, its frames {pr.width_px}x{pr.height_px} px")
        return img, 0
    if inp.background_median_s is None:
        return None, 0
    window_s = float(inp.background_median_s)
    if not (np.isfinite(window_s) and window_s > 0):
        raise ValueError(f"camera {inp.name!r}: background_median_s must be a positive number of seconds, got "
                         f"{inp.background_median_s}")
    within = np.flatnonzero(pr.times_s < pr.times_s[0] + window_s)
    if len(within) < MEDIAN_MIN_FRAMES:
        raise ValueError(f"camera {inp.name!r}: only {len(within)} frame(s) in the first {window_s:g} s, a median "
                         f"background needs at least {MEDIAN_MIN_FRAMES} (a longer background_median_s)")
    pick = np.unique(np.round(np.linspace(0, len(within) - 1, min(len(within), MEDIAN_MAX_FRAMES))).astype(int))
    if pr.video is not None:
        video = VideoFrames(pr.video, pr.frame_index, pr.times_s, inp.name, pr.width_px, pr.height_px)
        try:
            frames = [video(int(within[k])) for k in pick]
        finally:
            video.close()
    else:
        frames = []
        for k in pick:
            img = cv2.imread(str(pr.images[within[k]]), cv2.IMREAD_COLOR)
            if img is None or img.shape[:2] != (pr.height_px, pr.width_px):
                raise ValueError(f"{pr.images[within[k]]}: cannot decode image of {pr.width_px}x{pr.height_px} px "
                                 f"(camera {inp.name!r}, median background)")
            frames.append(img)
    return np.median(np.stack(frames), axis=0).round().astype(np.uint8), len(frames)


def _write_camera(root: Path, inp: CameraInput, cam: PinholeCamera, pr: _Probe, mask: np.ndarray | None,
                  background: np.ndarray | None = None) -> CameraEntry:
    base = root / "cameras" / inp.name
    rel = f"cameras/{inp.name}"
    common = dict(type="camera", name=inp.name, width_px=pr.width_px, height_px=pr.height_px, K=_matrix(cam.K),
                  dist=cam.intrinsics.dist.tolist(), T_world_cam=_matrix(cam.T_world_cam), rate_hz=pr.rate_hz,
                  n_frames=len(pr.times_s), ignore_rects_px=[tuple(int(x) for x in r) for r in inp.ignore_rects_px])
    if mask is not None:
        base.mkdir(parents=True, exist_ok=True)
        cv2.imwrite(str(base / "ignore.png"), mask.astype(np.uint8) * 255)
        common["ignore_mask_file"] = f"{rel}/ignore.png"
    if background is not None:
        base.mkdir(parents=True, exist_ok=True)
        if not cv2.imwrite(str(base / "background.png"), background):
            raise ValueError(f"{base / 'background.png'}: cannot write the background of camera {inp.name!r}")
        common["background_file"] = f"{rel}/background.png"
    if pr.video is not None:
        video_rel = f"{rel}/video{pr.video.suffix.lower()}"
        _place(pr.video, root / video_rel)
        if inp.times_file is None:
            return CameraEntry(video_file=video_rel, start_time_s=inp.start_time_s, **common)
        write_csv(base / "times.csv", ["time_s", "frame_index"], np.c_[pr.times_s, pr.frame_index])
        return CameraEntry(video_file=video_rel, times_file=f"{rel}/times.csv", **common)
    rows = []
    for k, (t, img) in enumerate(zip(pr.times_s, pr.images)):
        name = f"frames/{k:06d}{img.suffix.lower()}"
        _place(img, base / name)
        rows.append(f"{float(t)!r},{name}\n")
    (base / "times.csv").write_text("time_s,image_file\n" + "".join(rows))
    return CameraEntry(times_file=f"{rel}/times.csv", **common)
