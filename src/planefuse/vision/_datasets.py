"""Camera inputs from data-set folders: EPFL POM, WILDTRACK, planefuse recordings.

Each reader returns what :func:`~planefuse.vision.camera_detections` needs: one
:class:`~planefuse.registration.ImagePlaneLookup` per camera, and an iterator of
``(time_s, images)`` with ``None`` for a missing frame.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path
from typing import Iterator

import cv2
import numpy as np

from ..calib import (
    H_WORLD_TOPVIEW_TERRACE,
    EpflBoxes,
    EpflGroundHomography,
    load_epfl_boxes,
    load_epfl_homography,
    load_wildtrack_rig,
)
from ..geometry import apply_homography
from ..grid import PlaneStack
from ..registration import ImagePlaneLookup
from ._foreground import foreground_from_boxes, read_mot_detections

__all__ = [
    "EpflSequence",
    "epfl_box_frames",
    "epfl_ground_truth",
    "epfl_ground_truth_from_cameras",
    "epfl_lookups",
    "epfl_sequences",
    "image_folder_frames",
    "load_epfl_sequence",
    "read_epfl_detections",
    "camera_instants",
    "recording_frames",
    "wildtrack_frames",
]

EPFL_SIZE_PX = (360, 288)  # width, height of every EPFL view
EPFL_FPS = 25.0


@dataclass(frozen=True)
class EpflSequence:
    """One EPFL POM sequence: per camera a ground homography and its box annotations.

    Attributes
    ----------
    names : list of str
        Camera folder names (``terrace1-c0``...).
    homographies : list of EpflGroundHomography
        Image -> ground [m].
    boxes : list of EpflBoxes
        Rows of each camera's ``gt/gt.txt``.
    """

    names: list[str]
    homographies: list[EpflGroundHomography]
    boxes: list[EpflBoxes]

    @property
    def frames(self) -> np.ndarray:
        """Sorted 0-based frame indices annotated in any camera."""
        return np.unique(np.concatenate([b.frame for b in self.boxes]))


def epfl_sequences(root) -> dict[str, int]:
    """EPFL sequences under ``root``: name -> number of ``<name>-c<k>/Homography.txt`` camera folders."""
    found: dict[str, int] = {}
    for h in Path(root).rglob("Homography.txt"):
        m = re.fullmatch(r"(.+)-c\d+", h.parent.name)
        if m:
            found[m.group(1)] = found.get(m.group(1), 0) + 1
    return dict(sorted(found.items()))


def load_epfl_sequence(root, sequence: str = "terrace1", *, ground_unit_m: float | None = None) -> EpflSequence:
    """Read ``<root>/<sequence>-c*/Homography.txt`` and ``gt/gt.txt``, ground in metres.

    ``root`` may be the data-set folder or its ``EPFL-Terrace`` / ``EPFL-Laboratory`` sub-folder.

    Parameters
    ----------
    ground_unit_m : float, optional
        Metres per top-view unit of the homographies (top-view axes kept). Terrace sequences default to
        :data:`planefuse.calib.H_WORLD_TOPVIEW_TERRACE` (the Tsai world, ~2.19 cm per unit); any other sequence
        must give it (EPFL's files carry no unit; the laboratory's is 0.02 according to Al-Sa'd et al.).

    Raises
    ------
    ValueError
        ``root`` is not a folder, holds no camera folder of ``sequence`` (the message lists the sequences it
        holds), a sequence other than the terrace comes without ``ground_unit_m``, or a homography /
        ``gt.txt`` does not load.
    """
    root = Path(root)
    if not root.is_dir():
        raise ValueError(f"{root}: not a folder (EPFL data: <sequence>-c<k>/Homography.txt and gt/gt.txt)")
    dirs = sorted(p for p in root.rglob(f"{sequence}-c*") if p.is_dir() and (p / "Homography.txt").is_file())
    if not dirs:
        there = epfl_sequences(root)
        if there:
            what = "it holds " + ", ".join(f"{k} ({n} cameras)" for k, n in there.items())
        else:
            entries = sorted(p.name for p in root.iterdir())[:8]
            what = f"it holds no EPFL camera folder at all (entries: {entries})"
        raise ValueError(f"{root}: no '{sequence}-c*/Homography.txt' camera folders; {what}")
    if ground_unit_m is not None:
        if not (np.isfinite(ground_unit_m) and ground_unit_m > 0):
            raise ValueError(f"ground_unit_m must be a positive length [m], got {ground_unit_m}")
        W = np.diag([ground_unit_m, ground_unit_m, 1.0])
    elif sequence.startswith("terrace"):
        W = H_WORLD_TOPVIEW_TERRACE
    else:
        raise ValueError(f"{dirs[0] / 'Homography.txt'}: the ground unit of sequence {sequence!r} is unknown (EPFL's "
                         "files carry none): give it in metres (ground_unit_m / --ground-unit-m)")
    homs = [load_epfl_homography(d / "Homography.txt", H_world_topview=W) for d in dirs]
    boxes = [load_epfl_boxes(d / "gt" / "gt.txt") for d in dirs]
    return EpflSequence([d.name for d in dirs], homs, boxes)


def epfl_lookups(seq: EpflSequence, stack: PlaneStack) -> list[ImagePlaneLookup]:
    """Ground-plane lookups from the EPFL homographies (a one-plane stack at z = 0).

    The files give only the ground homography, so ``stack`` must be that one
    plane. The homography's overall sign is fixed so that the bottom-centre pixel
    of each view (surely on the visible ground) has positive scale.
    """
    if stack.heights_m != (0.0,):
        raise ValueError(f"EPFL Homography.txt is the ground plane only: stack must have heights (0.0,), "
                         f"got {stack.heights_m}")
    w, h = EPFL_SIZE_PX
    out = []
    for hom in seq.homographies:
        H_image_plane = hom.H_image_plane
        xy = apply_homography(hom.H_plane_image, np.array([[w / 2, h - 1.0]]))[0]
        if H_image_plane[2] @ np.array([xy[0], xy[1], 1.0]) < 0:
            H_image_plane = -H_image_plane
        out.append(ImagePlaneLookup.from_homographies(H_image_plane[None], w, h, stack))
    return out


def epfl_box_frames(seq: EpflSequence, frames=None, *, boxes: list[dict[int, np.ndarray]] | None = None,
                    foot_fraction: float = 1.0, floor: float = 0.02,
                    ceiling: float = 0.98) -> Iterator[tuple[float, list[np.ndarray]]]:
    """Filled person boxes per view as foreground likelihoods.

    Parameters
    ----------
    seq : EpflSequence
    frames : iterable of int, optional
        Frames to render (all annotated frames by default).
    boxes : list of dict, optional
        Per camera ``frame -> (N, 5) [left, top, width, height, conf]`` from a
        detector (:func:`read_mot_detections`); default: the visible (not
        ``lost``) ground-truth boxes.
    foot_fraction : float
        Fill only the bottom ``foot_fraction`` of each box's height (1 = the
        whole box). With a ground-plane-only stack (all EPFL's homographies
        give), the body above the feet only casts ghosts on the ground, so a
        small fraction (the feet) is the useful foreground there.

    Yields
    ------
    (time_s, list of (288, 360) float32)
        ``time_s = frame / 25``.
    """
    if not 0.0 < foot_fraction <= 1.0:
        raise ValueError(f"foot_fraction must be in (0, 1], got {foot_fraction}")
    w, h = EPFL_SIZE_PX
    if boxes is None:
        boxes = []
        for b in seq.boxes:
            vis = ~b.lost
            xyxy = b.box_xyxy_px[vis]
            ltwh = np.c_[xyxy[:, :2], xyxy[:, 2:] - xyxy[:, :2] + 1, np.ones(len(xyxy))]
            fr = b.frame[vis]
            order = np.argsort(fr, kind="stable")
            splits = np.flatnonzero(np.diff(fr[order])) + 1
            boxes.append({int(fr[i[0]]): ltwh[i] for i in np.split(order, splits) if len(i)})
    empty = np.zeros((0, 5))
    for f in (seq.frames if frames is None else frames):
        imgs = []
        for per_cam in boxes:
            b = per_cam.get(int(f), empty).copy()
            if foot_fraction < 1.0:
                b[:, 1] += (1.0 - foot_fraction) * b[:, 3]
                b[:, 3] *= foot_fraction
            imgs.append(foreground_from_boxes(b[:, :4], w, h, np.clip(b[:, 4], 0, 1), floor=floor, ceiling=ceiling))
        yield int(f) / EPFL_FPS, imgs


def epfl_ground_truth(seq: EpflSequence, min_views: int = 2) -> dict[int, tuple[np.ndarray, np.ndarray]]:
    """Ground-truth feet from the multi-view consensus of box bottoms.

    Every visible box's bottom centre is mapped to the ground through its
    camera's homography; a person's position is the per-axis median over the
    cameras that see them.

    Returns
    -------
    dict
        ``frame -> (gt_xy (G, 2), ignore_xy (I, 2))``: people seen by at least
        ``min_views`` cameras, and people seen by fewer (to be ignored by the
        evaluation: one view cannot place them on the ground reliably).
    """
    rows = []
    for hom, b in zip(seq.homographies, seq.boxes):
        vis = ~b.lost
        xy = apply_homography(hom.H_plane_image, b.foot_uv()[vis])
        rows.append(np.c_[b.frame[vis], b.track_id[vis], xy])
    a = np.concatenate(rows)
    key = a[:, 0] * 100_000 + a[:, 1]
    order = np.argsort(key, kind="stable")
    a, key = a[order], key[order]
    starts = np.flatnonzero(np.r_[True, np.diff(key) != 0])
    counts = np.diff(np.r_[starts, len(a)])
    med = np.stack([np.median(a[s:s + c, 2:4], axis=0) for s, c in zip(starts, counts)])
    frames = a[starts, 0].astype(int)
    out: dict[int, tuple[np.ndarray, np.ndarray]] = {int(f): (np.zeros((0, 2)), np.zeros((0, 2))) for f in seq.frames}
    for f in np.unique(frames):
        sel = frames == f
        out[int(f)] = (med[sel & (counts >= min_views)], med[sel & (counts < min_views)])
    return out


def epfl_ground_truth_from_cameras(seq: EpflSequence, cameras, scored_cameras, frames=None
                                   ) -> dict[int, tuple[np.ndarray, np.ndarray, np.ndarray]]:
    """Ground-truth feet from every camera's boxes back-projected through calibrated camera models.

    A person's position is the per-axis median, over the cameras whose box is visible, of the box's bottom
    centre back-projected to the ground (z = 0) through that camera's model (lens distortion included). A
    person seen by none of ``scored_cameras`` (the cameras whose frames the system gets) cannot be detected
    from them: it is returned apart, to be ignored by the scoring.

    Parameters
    ----------
    seq : EpflSequence
        Boxes of every camera (:func:`load_epfl_sequence`), in the order of ``cameras``.
    cameras : sequence of PinholeCamera
        One per camera of ``seq`` (e.g. :func:`planefuse.calib.pinhole_from_tsai` of ``EPFL_TERRACE_TSAI``), world in metres.
    scored_cameras : sequence of int
        Indices (into ``cameras``) of the cameras the evaluated system sees.
    frames : iterable of int, optional
        Frames wanted (default: every annotated frame).

    Returns
    -------
    dict
        ``frame -> (ids (G,), xy_m (G, 2), ignore_xy_m (I, 2))``, world XY [m].
    """
    if len(cameras) != len(seq.boxes):
        raise ValueError(f"cameras: expected one per camera of the sequence ({len(seq.boxes)}), got {len(cameras)}")
    rows = []
    for i, (cam, b) in enumerate(zip(cameras, seq.boxes)):
        vis = ~b.lost
        xy = cam.backproject_to_height(b.foot_uv()[vis], 0.0)[:, :2]
        rows.append(np.c_[b.frame[vis], b.track_id[vis], xy, np.full(int(vis.sum()), i)])
    a = np.concatenate(rows)
    a = a[np.isfinite(a[:, 2:4]).all(axis=1)]
    wanted = seq.frames if frames is None else np.unique(np.asarray(list(frames), dtype=int))
    a = a[np.isin(a[:, 0], wanted)]
    key = a[:, 0] * 100_000 + a[:, 1]
    order = np.argsort(key, kind="stable")
    a, key = a[order], key[order]
    starts = np.flatnonzero(np.r_[True, np.diff(key) != 0]) if len(a) else np.zeros(0, int)
    bounds = np.r_[starts, len(a)]
    empty = (np.zeros(0, int), np.zeros((0, 2)), np.zeros((0, 2)))
    out: dict[int, tuple[np.ndarray, np.ndarray, np.ndarray]] = {int(f): empty for f in wanted}
    per_frame: dict[int, list] = {}
    for s, e in zip(bounds[:-1], bounds[1:]):
        r = a[s:e]
        scored = bool(np.isin(r[:, 4], list(scored_cameras)).any())
        per_frame.setdefault(int(r[0, 0]), []).append((int(r[0, 1]), np.median(r[:, 2:4], axis=0), scored))
    for f, people in per_frame.items():
        ids = np.array([p for p, _, sc in people if sc], dtype=int)
        xy = np.array([m for _, m, sc in people if sc]).reshape(-1, 2)
        ign = np.array([m for _, m, sc in people if not sc]).reshape(-1, 2)
        out[f] = (ids, xy, ign)
    return out


def read_epfl_detections(seq_root, names: list[str], filename: str = "det/det.txt") -> list[dict[int, np.ndarray]]:
    """Per-camera MOTChallenge detections ``<root>/<camera>/<filename>`` (1-based frames -> 0-based)."""
    out = []
    for n in names:
        det = read_mot_detections(Path(seq_root) / n / filename)
        out.append({f - 1: b for f, b in det.items()})
    return out


_NUM = re.compile(r"(\d+)")


def image_folder_frames(folders, *, fps: float = 25.0) -> Iterator[tuple[float, list[np.ndarray | None]]]:
    """Synchronised frames from one image folder per camera, matched by the number in the file name.

    A number present in some folders but not others yields ``None`` for the
    cameras lacking it (a missing frame). Time = number / ``fps``.
    """
    per_cam: list[dict[int, Path]] = []
    for folder in folders:
        files = {}
        for p in sorted(Path(folder).iterdir()):
            m = _NUM.findall(p.stem)
            if p.suffix.lower() in (".png", ".jpg", ".jpeg", ".bmp") and m:
                files[int(m[-1])] = p
        if not files:
            raise ValueError(f"{folder}: no numbered image files")
        per_cam.append(files)
    for k in sorted(set().union(*per_cam)):
        imgs = [cv2.imread(str(f[k]), cv2.IMREAD_COLOR) if k in f else None for f in per_cam]
        yield k / fps, imgs


def wildtrack_frames(root, *, fps: float = 2.0):
    """Cameras (``C1``..``C7``, metres, with distortion) and frames of a WILDTRACK folder.

    Frames are read from ``<root>/Image_subsets/C<i>/*.png`` (the data set's
    layout), numbered by file name; WILDTRACK's annotated subsets are at 2 fps.

    Returns
    -------
    cameras : list of PinholeCamera
    frames : iterator of (time_s, list of images or None)
    """
    rig = load_wildtrack_rig(root)
    names = sorted(rig)
    sub = Path(root) / "Image_subsets"
    if not sub.is_dir():
        held = sorted(p.name for p in Path(root).iterdir())
        raise ValueError(f"{root}: no 'Image_subsets/C<i>/' frame sequences (it holds {held}); background "
                         "subtraction needs frames over time, single images per camera are not enough")
    return [rig[n] for n in names], image_folder_frames([sub / n for n in names], fps=fps)


def camera_instants(recording, stride: int = 1, max_rate_hz: float | None = None) -> np.ndarray:
    """The synchronised camera instants of a recording [s], shape (T,), increasing.

    The union of all cameras' frame times, whatever the cameras' order: times closer than half the shortest
    frame period are one instant (taken at its earliest frame time). A frame dropped by one camera is thus
    still an instant of the others, and a missing frame of the camera that lacks it. With ``stride`` k > 1,
    every k-th of these instants from the first (:attr:`planefuse.vision.CameraParams.frame_stride`). With
    ``max_rate_hz`` [Hz] (:attr:`planefuse.vision.CameraParams.max_rate_hz`), of those the first at or after each
    multiple of ``1 / max_rate_hz`` from the first instant (a quarter of the shortest frame period early counts:
    time stamps jitter), so at most ``max_rate_hz`` instants per second, evenly spaced where the cameras' rate is
    a multiple of it (25 Hz cameras at 5 Hz: every 5th frame).
    """
    if not (isinstance(stride, (int, np.integer)) and stride >= 1):
        raise ValueError(f"stride must be an integer >= 1, got {stride!r}")
    if max_rate_hz is not None and not (np.isfinite(max_rate_hz) and max_rate_hz > 0):
        raise ValueError(f"max_rate_hz must be finite and > 0 [Hz] or None, got {max_rate_hz!r}")
    streams = [recording.camera(c.name) for c in recording.cameras]
    times = np.sort(np.concatenate([np.asarray(s.times_s, dtype=float) for s in streams] or [np.zeros(0)]))
    if times.size == 0:
        return times
    frame_s = 1.0 / max(s.rate_hz for s in streams)
    starts = [times[0]]
    for t in times[1:]:
        if t - starts[-1] > 0.5 * frame_s:
            starts.append(t)
    instants = np.asarray(starts)[::stride]
    if max_rate_hz is None:
        return instants
    period_s, early_s = 1.0 / max_rate_hz, 0.25 * frame_s
    kept, t0, due = [], instants[0], instants[0]
    for t in instants:
        if t >= due - early_s:
            kept.append(t)
            due = t0 + (np.floor((t + early_s - t0) / period_s) + 1) * period_s
    return np.asarray(kept)


def recording_frames(recording, *, masks: bool = False, start: int = 0, stride: int = 1,
                     max_rate_hz: float | None = None) -> Iterator[tuple[float, list[np.ndarray | None]]]:
    """Synchronised frames of a :class:`planefuse.io.Recording` (simulated or read from disk).

    Instants are :func:`camera_instants` (the union of all cameras' frame times); each camera contributes
    its frame nearest in time when that is within half of its own frame period, else ``None`` (a missing
    frame, which :func:`camera_detections` counts on that camera).
    ``masks=True`` yields the exact foreground masks (uint8 0/255) instead of the images.
    ``start`` skips the first instants (their frames are not read); ``stride`` k > 1 and ``max_rate_hz`` read the
    instants ``camera_instants(recording, stride, max_rate_hz)`` only (``start`` then counts those).
    """
    streams = [recording.camera(c.name) for c in recording.cameras]
    for t in camera_instants(recording, stride, max_rate_hz)[int(start):]:
        imgs: list[np.ndarray | None] = []
        for s in streams:
            j = frame_at(s, t)
            if j is None:
                imgs.append(None)
            else:
                imgs.append(np.where(s.mask(j) > 0, np.uint8(255), np.uint8(0)) if masks else s.frame(j))
        yield float(t), imgs


def frame_at(stream, time_s: float) -> int | None:
    """Index of ``stream``'s frame at the camera instant ``time_s`` [s]: its nearest frame when within half of
    its frame period, else None (a missing frame)."""
    if not len(stream):
        return None
    j = int(np.argmin(np.abs(stream.times_s - time_s)))
    return j if abs(stream.times_s[j] - time_s) <= 0.5 / stream.rate_hz else None
