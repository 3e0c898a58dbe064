"""Animation of the plane stack over time (GIF through Pillow; MP4 through OpenCV).

Frames are built directly from the arrays (colour map + nearest-neighbour
upscaling), not by redrawing a matplotlib figure per step, so a few hundred
steps take a second or two. They are built and encoded a block of steps at a
time from the (on-disk) occupancy array, so the memory of an animation does
not grow with the length of the run.
"""

from __future__ import annotations

import warnings
from collections.abc import Mapping
from pathlib import Path

import cv2
import matplotlib
import numpy as np
from PIL import GifImagePlugin, Image

from ..grid import PlaneStack
from ..outputs._atomic import TMP_MARK

__all__ = ["stack_frames", "stack_palette_frames", "animate_stack", "PALETTE", "camera_track_frames",
           "camera_tracks_video"]


#: Palette of the animation frames: 254 levels of matplotlib's "magma" for P(occupied) 0..1, then grey
#: (unobserved cells) and white (gaps between planes, track dots).
_N_LEVELS = 254
_GREY, _WHITE = 254, 255
PALETTE = np.vstack([matplotlib.colormaps["magma"](np.linspace(0.0, 1.0, _N_LEVELS), bytes=True)[:, :3],
                     [[90, 90, 90], [255, 255, 255]]]).astype(np.uint8)


def stack_frames(
    stack: PlaneStack,
    occupancy,
    tracks: Mapping[str, np.ndarray] | None = None,
    *,
    steps=None,
    cell_px: int = 2,
    gap_px: int = 4,
) -> np.ndarray:
    """RGB frames showing every plane side by side (lowest plane left), world Y up.

    Parameters
    ----------
    stack : PlaneStack
    occupancy : ndarray, shape (T, L, ny, nx)
        P(occupied) in [0, 1]; NaN is drawn grey.
    tracks : dict of column arrays, optional
        ``step``, ``x_m``, ``y_m``: positions at a step are drawn as white dots on every plane.
    steps : ndarray of int, shape (T,), optional
        Step number of each frame (to match tracks); defaults to 0..T-1.
    cell_px : int
        Pixels per cell side.
    gap_px : int
        Pixels between planes.

    Returns
    -------
    ndarray, shape (T, ny * cell_px, L * (nx * cell_px + gap_px) - gap_px, 3), uint8
        ``PALETTE[stack_palette_frames(...)]``.
    """
    return PALETTE[stack_palette_frames(stack, occupancy, tracks, steps=steps, cell_px=cell_px, gap_px=gap_px)]


def stack_palette_frames(
    stack: PlaneStack,
    occupancy,
    tracks: Mapping[str, np.ndarray] | None = None,
    *,
    steps=None,
    cell_px: int = 2,
    gap_px: int = 4,
) -> np.ndarray:
    """The frames of :func:`stack_frames` as indices into :data:`PALETTE`, shape (T, H, W) uint8."""
    occ = np.asarray(occupancy, dtype=np.float32)
    if occ.ndim != 4 or occ.shape[1:] != stack.shape:
        raise ValueError(f"occupancy must have shape (T, {', '.join(map(str, stack.shape))}), got {occ.shape}")
    T, L, ny, nx = occ.shape
    steps = np.arange(T) if steps is None else np.asarray(steps)
    idx = np.rint(np.clip(np.nan_to_num(occ, nan=0.0), 0.0, 1.0) * (_N_LEVELS - 1)).astype(np.uint8)
    idx[np.isnan(occ)] = _GREY
    idx = idx[:, :, ::-1]  # row iy grows with world Y: flip so Y points up in the image
    big = np.repeat(np.repeat(idx, cell_px, axis=2), cell_px, axis=3)
    h, w = ny * cell_px, nx * cell_px
    frames = np.full((T, h, L * (w + gap_px) - gap_px), _WHITE, np.uint8)
    for l in range(L):
        frames[:, :, l * (w + gap_px): l * (w + gap_px) + w] = big[:, l]
    if tracks is not None and len(tracks.get("step", [])):
        ts = np.asarray(tracks["step"], float).astype(np.int64)
        iy, ix = stack.index_from_xy(np.stack([np.asarray(tracks["x_m"], float),
                                               np.asarray(tracks["y_m"], float)], -1))
        frame_of_step = {int(s): i for i, s in enumerate(steps)}
        fi = np.array([frame_of_step.get(int(s), -1) for s in ts])
        ok = (fi >= 0) & (iy >= 0)
        r = max(cell_px, 2)
        for f, y, x in zip(fi[ok], iy[ok], ix[ok]):
            v = (ny - 1 - y) * cell_px
            for l in range(L):
                u = l * (w + gap_px) + x * cell_px
                frames[f, max(v - r, 0): v + r + 1, max(u - r, 0): min(u + r + 1, l * (w + gap_px) + w)] = _WHITE
    return frames


def animate_stack(
    path: Path | str,
    stack: PlaneStack,
    occupancy,
    tracks: Mapping[str, np.ndarray] | None = None,
    *,
    fps: float = 10.0,
    max_frames: int | None = 300,
    max_width_px: int = 1200,
    block_steps: int = 16,
) -> Path:
    """Write an animation of the plane stack over time to ``path`` (``.gif`` or ``.mp4``).

    Parameters
    ----------
    occupancy : array-like, shape (T, L, ny, nx)
        An ndarray or an on-disk array (:meth:`OutputWriter.occupancy_array`); read ``block_steps`` steps
        at a time.
    tracks : dict of column arrays, optional
    fps : float
        Frames per second of the animation.
    max_frames : int or None
        Longer runs are subsampled evenly (the count dropped is warned about); None = every step.
    max_width_px : int
        Cells are drawn with as many pixels as fit this width (at least 1, at most 8).
    block_steps : int
        Frames built at once; the GIF and MP4 encoders keep no frame, so memory does not grow with the run.

    Returns
    -------
    Path
        The file written (atomically).
    """
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix not in (".gif", ".mp4"):
        raise ValueError(f"animation path must end in .gif or .mp4, got {path.name!r}")
    T = occupancy.shape[0]
    if T == 0:
        raise ValueError("occupancy has no time steps to animate")
    shown = T if max_frames is None else min(T, int(max_frames))
    idx = np.unique(np.linspace(0, T - 1, shown).round().astype(int))
    if len(idx) < T:
        warnings.warn(f"animation shows {len(idx)} of {T} steps, evenly spaced (max_frames={max_frames}; every step: "
                      "outputs.animation_max_frames: null)", stacklevel=2)
    L, ny, nx = stack.shape
    cell_px = max(1, min(8, (max_width_px - 4 * (L - 1)) // (L * nx)))

    def frames():  # palette indices, a block of steps at a time
        for a in range(0, len(idx), block_steps):
            steps = idx[a: a + block_steps]
            block = np.stack([np.asarray(occupancy[int(s)]) for s in steps])
            yield from stack_palette_frames(stack, block, tracks, steps=steps, cell_px=cell_px)

    tmp = path.with_name(f".{path.stem}{TMP_MARK}{path.suffix}")
    try:
        if suffix == ".gif":
            _write_gif(tmp, frames(), fps)
        else:
            bgr = PALETTE[:, ::-1]  # OpenCV's channel order: no conversion per frame
            _write_mp4(tmp, (bgr[f[: f.shape[0] // 2 * 2, : f.shape[1] // 2 * 2]] for f in frames()), fps)
        tmp.replace(path)
    finally:
        tmp.unlink(missing_ok=True)
    return path


def _write_gif(path: Path, frames, fps: float) -> None:
    """An animated GIF (looping, global :data:`PALETTE`), written one frame at a time: Pillow encodes each
    palette frame (``GifImagePlugin.getheader``/``getdata``), nothing is kept between frames."""
    duration_ms = int(round(1000.0 / fps))
    palette = PALETTE.ravel().tolist()
    with open(path, "wb") as fp:
        for k, f in enumerate(frames):
            im = Image.fromarray(f, mode="P")
            im.putpalette(palette)
            if k == 0:
                header, _ = GifImagePlugin.getheader(im, None, {"loop": 0, "duration": duration_ms})
                fp.write(b"".join(header))
            fp.write(b"".join(GifImagePlugin.getdata(im, duration=duration_ms)))
        fp.write(b";")  # GIF trailer


def _write_mp4(path: Path, frames, fps: float) -> None:
    """MPEG-4 through OpenCV's FFmpeg backend, one BGR frame at a time (codecs want even sizes)."""
    vw = None
    try:
        for f in frames:
            if vw is None:
                h, w = f.shape[:2]
                vw = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"mp4v"), float(fps), (w, h))
                if not vw.isOpened():
                    raise OSError(f"cannot write MP4 {path}: OpenCV has no video encoder here")
            vw.write(f)
    finally:
        if vw is not None:
            vw.release()


def camera_track_frames(camera, stream, step_times_s, tracks: Mapping[str, np.ndarray] | None, *,
                        steps=None, head_m: float = 1.7):
    """Camera frames with the tracks drawn, one per output step: BGR uint8 (H, W, 3) images, lazily.

    For each output step ``k`` (of ``steps``, all by default), the frame of ``stream`` nearest in time to
    ``step_times_s[k]``, with every track of that step as a line from its feet (z = 0) to ``head_m`` above them,
    in its colour of the figures (:func:`planefuse.viz.track_colour`) and labelled with its id, and the frame
    number, time and step written in its top-left corner.

    Parameters
    ----------
    camera : PinholeCamera
    stream : planefuse.io.CameraStream
        The camera's frames (``times_s``, ``frame(i)`` BGR).
    step_times_s : ndarray, shape (T,)
        Times of the output steps [s].
    tracks : dict of column arrays
        ``step``, ``track_id``, ``x_m``, ``y_m`` (the run's ``tracks.csv``).
    """
    from ._figures import _rows_at, track_colour

    step_times_s = np.asarray(step_times_s, float)
    frame_times = np.asarray(stream.times_s, float)
    steps = range(len(step_times_s)) if steps is None else steps
    for k in steps:
        i = int(np.argmin(np.abs(frame_times - step_times_s[k])))
        img = np.ascontiguousarray(stream.frame(i)).copy()
        ids, xy = _rows_at(tracks, int(k))
        for tid, p in zip(ids, xy):
            uv = camera.project(np.array([[p[0], p[1], 0.0], [p[0], p[1], head_m]]))
            if not np.isfinite(uv).all() or np.abs(uv).max() > 1e5:
                continue
            r, g, b = (int(255 * c) for c in track_colour(tid)[:3])
            a, z = (tuple(int(round(v)) for v in q) for q in uv)
            cv2.line(img, a, z, (b, g, r), 2, cv2.LINE_AA)
            cv2.putText(img, str(int(tid)), (z[0] - 4, z[1] - 4), cv2.FONT_HERSHEY_SIMPLEX, 0.4, (b, g, r), 1,
                        cv2.LINE_AA)
        label = f"{camera.name} frame {i} t={frame_times[i]:.2f}s step {int(k)}"
        cv2.putText(img, label, (4, 14), cv2.FONT_HERSHEY_SIMPLEX, 0.4, (0, 0, 0), 3, cv2.LINE_AA)
        cv2.putText(img, label, (4, 14), cv2.FONT_HERSHEY_SIMPLEX, 0.4, (255, 255, 255), 1, cv2.LINE_AA)
        yield img


def camera_tracks_video(path: Path | str, camera, stream, step_times_s, tracks: Mapping[str, np.ndarray] | None, *,
                        fps: float = 5.0, max_frames: int | None = None, head_m: float = 1.7) -> Path:
    """Write an MP4 of ``camera``'s frames with the tracks drawn (:func:`camera_track_frames`), one frame per
    output step (at most ``max_frames``, evenly spaced; None = every step), atomically to ``path``.

    Raises
    ------
    ValueError
        ``path`` does not end in ``.mp4``, or there is no output step.
    OSError
        OpenCV has no video encoder here.
    """
    path = Path(path)
    if path.suffix.lower() != ".mp4":
        raise ValueError(f"camera video path must end in .mp4, got {path.name!r}")
    T = len(step_times_s)
    if T == 0:
        raise ValueError("no output step to draw")
    shown = T if max_frames is None else min(T, int(max_frames))
    steps = np.unique(np.linspace(0, T - 1, shown).round().astype(int))
    frames = camera_track_frames(camera, stream, step_times_s, tracks, steps=steps, head_m=head_m)
    tmp = path.with_name(f".{path.stem}{TMP_MARK}{path.suffix}")
    try:
        _write_mp4(tmp, (f[: f.shape[0] // 2 * 2, : f.shape[1] // 2 * 2] for f in frames), fps)
        tmp.replace(path)
    finally:
        tmp.unlink(missing_ok=True)
    return path
