"""Figures of a run (matplotlib): each function takes plain arrays and returns a Figure.

Figures are built with matplotlib's object API (``Figure``, no pyplot), so
importing this module changes no global backend and works without a display.

Floor-plan axes are world X (right) and Y (up) in metres; grids are drawn with
``origin="lower"`` and ``extent=stack.extent_m`` so that cell ``[iy, ix]`` sits
at its world position (see :mod:`planefuse.grid`).
"""

from __future__ import annotations

import contextlib
import io
from collections.abc import Mapping
from dataclasses import dataclass, field

import matplotlib
import numpy as np
from matplotlib.figure import Figure
from matplotlib.patches import Rectangle

from ..geometry import PinholeCamera
from ..grid import PlaneStack

__all__ = [
    "FigureInputs",
    "plot_plane_occupancy",
    "plot_camera_grid",
    "plot_camera_tracks",
    "track_colour",
    "plot_saliency",
    "plot_laser_points",
    "plot_metrics",
    "png_bytes",
    "run_figures",
    "grid_lines_world",
    "occupancy_mean",
]


@dataclass
class FigureInputs:
    """Optional material for the figures of a run, beyond what :class:`~planefuse.outputs.OutputWriter` holds.

    Attributes
    ----------
    cameras : list of PinholeCamera
        Calibrated cameras (world frame).
    camera_images : dict of str -> ndarray
        One frame per camera name, (H, W) gray or (H, W, 3) RGB uint8; cameras
        without an image are drawn on a blank frame.
    laser_points_world : ndarray, shape (N, 3)
        Laser hits in the world frame [m] (e.g. one scan per laser).
    saliency : ndarray, shape (T, A)
        Auditory saliency per frame and azimuth bin (any non-negative scale).
    saliency_times_s : ndarray, shape (T,)
        Times of the saliency frames [s].
    saliency_azimuth_rad : ndarray, shape (A,)
        Azimuths of the bins [rad], in the microphone pair's frame.
    ground_truth : dict of str -> ndarray
        Ground-truth table with columns ``step``, ``track_id``, ``x_m``, ``y_m`` (drawn dashed).
    ignore_masks : dict of str -> ndarray
        Per camera name, its ignore regions, (H, W) bool (pixels that are not scene evidence), drawn on its frame.
    camera_image_labels : dict of str -> str
        Per camera name, which frame ``camera_images`` holds ("frame 12, t = 2.40 s").
    camera_frames : dict of str -> list of (int, float, ndarray)
        Per camera name, a few frames ``(frame index, time [s], image RGB (H, W, 3) uint8)`` on which the tracks
        of the output step nearest in time are drawn (``camera_<name>_tracks``).
    camera_streams : dict of str -> planefuse.io.CameraStream
        Per camera name, all its frames (for ``outputs.camera_videos``).
    """

    cameras: list[PinholeCamera] = field(default_factory=list)
    camera_images: dict[str, np.ndarray] = field(default_factory=dict)
    laser_points_world: np.ndarray | None = None
    saliency: np.ndarray | None = None
    saliency_times_s: np.ndarray | None = None
    saliency_azimuth_rad: np.ndarray | None = None
    ground_truth: dict[str, np.ndarray] | None = None
    ignore_masks: dict[str, np.ndarray] = field(default_factory=dict)
    camera_image_labels: dict[str, str] = field(default_factory=dict)
    camera_frames: dict[str, list] = field(default_factory=dict)
    camera_streams: dict[str, object] = field(default_factory=dict)


def png_bytes(fig: Figure, dpi: int = 100) -> bytes:
    """Render ``fig`` to PNG bytes (Agg)."""
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=dpi, bbox_inches="tight")
    return buf.getvalue()


def _plane_axes(n: int, size_in: float = 3.2) -> tuple[Figure, np.ndarray]:
    cols = min(n, 4)
    rows = -(-n // cols)
    fig = Figure(figsize=(size_in * cols, size_in * rows + 0.4), layout="constrained")
    axes = fig.subplots(rows, cols, squeeze=False)
    for ax in axes.ravel()[n:]:
        ax.set_visible(False)
    return fig, axes.ravel()


def track_colour(track_id) -> tuple:
    """The colour of a track (or ground-truth person) ``track_id`` in every figure: tab10 by id."""
    return matplotlib.colormaps["tab10"](int(track_id) % 10)


def _legend(fig: Figure, ax) -> None:
    """Every labelled line of ``ax`` in one legend under the figure (as many columns as fit)."""
    handles, labels = ax.get_legend_handles_labels()
    if handles:
        fig.legend(handles, labels, loc="outside lower center", ncol=min(8, len(labels)), fontsize=7)


def _track_lines(ax, tracks: Mapping[str, np.ndarray] | None, upto_step: float, style: str = "-",
                 label: str = "track") -> None:
    if not tracks or len(tracks.get("step", [])) == 0:
        return
    steps = np.asarray(tracks["step"], float)
    ids = np.asarray(tracks["track_id"])
    xy = np.stack([np.asarray(tracks["x_m"], float), np.asarray(tracks["y_m"], float)], axis=-1)
    keep = steps <= upto_step
    for tid in np.unique(ids[keep]):
        m = keep & (ids == tid)
        order = np.argsort(steps[m])
        path = xy[m][order]
        ax.plot(path[:, 0], path[:, 1], style, color=track_colour(tid), lw=1.2, label=f"{label} {int(tid)}")
        ax.plot(path[-1, 0], path[-1, 1], "o", color=track_colour(tid), ms=4)


def plot_plane_occupancy(
    stack: PlaneStack,
    occupancy,
    *,
    time_s: float | None = None,
    detections_xy_m=None,
    tracks: Mapping[str, np.ndarray] | None = None,
    step: int | None = None,
    ground_truth: Mapping[str, np.ndarray] | None = None,
) -> Figure:
    """Occupancy of every plane over the floor plan, with detections and tracks.

    Parameters
    ----------
    stack : PlaneStack
    occupancy : ndarray, shape (L, ny, nx)
        P(occupied) per cell in [0, 1] (NaN drawn as unknown).
    time_s : float, optional
        Shown in the title [s].
    detections_xy_m : ndarray, shape (N, 2), optional
        Ground-plane detections [m], drawn as crosses on every plane.
    tracks : dict of column arrays, optional
        Table with ``step``, ``track_id``, ``x_m``, ``y_m``; rows with ``step``
        up to ``step`` (all if None) are drawn as lines.
    ground_truth : dict of column arrays, optional
        Same columns, drawn dashed.
    """
    occ = np.asarray(occupancy, dtype=float)
    if occ.shape != stack.shape:
        raise ValueError(f"occupancy must have shape {stack.shape} (L, ny, nx), got {occ.shape}")
    fig, axes = _plane_axes(stack.n_planes)
    upto = np.inf if step is None else step
    im = None
    for l, ax in enumerate(axes[: stack.n_planes]):
        im = ax.imshow(occ[l], origin="lower", extent=stack.extent_m, vmin=0, vmax=1, cmap="magma",
                       interpolation="nearest")
        ax.set_title(f"plane z = {stack.heights_m[l]:g} m", fontsize=9)
        ax.set_xlabel("x [m]")
        ax.set_ylabel("y [m]")
        if detections_xy_m is not None and len(detections_xy_m):
            d = np.asarray(detections_xy_m, float).reshape(-1, 2)
            ax.plot(d[:, 0], d[:, 1], "x", color="cyan", ms=6, label="detection")
        _track_lines(ax, ground_truth, upto, "--", "truth")
        _track_lines(ax, tracks, upto)
        ax.set_xlim(stack.extent_m[:2])
        ax.set_ylim(stack.extent_m[2:])
    _legend(fig, axes[0])
    fig.colorbar(im, ax=list(axes[: stack.n_planes]), shrink=0.8, label="P(occupied)")
    at = [f"step {step}" if step is not None else "", f"t = {time_s:.2f} s" if time_s is not None else ""]
    at = ", ".join(a for a in at if a)
    fig.suptitle("Occupancy per plane" + (f" at {at}" if at else ""))
    return fig


def grid_lines_world(stack: PlaneStack, plane: int, spacing_m: float = 1.0, samples: int = 100) -> np.ndarray:
    """World polylines of the grid of one plane: lines x = const and y = const every ``spacing_m``.

    Returns
    -------
    ndarray, shape (K, samples, 3)
        K polylines of ``samples`` points each, on z = ``stack.heights_m[plane]`` [m]; sampled
        densely so that lens distortion shows once projected.
    """
    x0, x1, y0, y1 = stack.extent_m
    z = stack.heights_m[plane]
    xs = np.unique(np.r_[np.arange(x0, x1 + 1e-9, spacing_m), x1])
    ys = np.unique(np.r_[np.arange(y0, y1 + 1e-9, spacing_m), y1])
    t = np.linspace(0.0, 1.0, samples)
    vert = [np.stack([np.full_like(t, x), y0 + t * (y1 - y0), np.full_like(t, z)], -1) for x in xs]
    horiz = [np.stack([x0 + t * (x1 - x0), np.full_like(t, y), np.full_like(t, z)], -1) for y in ys]
    return np.stack(vert + horiz)


def plot_camera_grid(camera: PinholeCamera, stack: PlaneStack, image=None, spacing_m: float = 1.0,
                     ignore_mask=None, image_label: str = "") -> Figure:
    """A camera frame with the grid of every plane projected through the camera (lens distortion included).

    Parameters
    ----------
    camera : PinholeCamera
    stack : PlaneStack
    image : ndarray, shape (H, W) or (H, W, 3), optional
        The frame to draw under the grid; blank when omitted.
    spacing_m : float
        Distance between drawn grid lines [m].
    ignore_mask : ndarray, shape (H, W), bool, optional
        The camera's ignore regions (pixels that are not scene evidence), drawn hatched in red.
    image_label : str
        Which frame ``image`` is (its number and time), shown in the title.
    """
    w, h = camera.intrinsics.width_px, camera.intrinsics.height_px
    fig = Figure(figsize=(5.0, 5.0 * h / w + 0.3), layout="constrained")
    ax = fig.subplots()
    image = np.full((h, w), 235, np.uint8) if image is None else np.asarray(image)
    scale = {"vmin": 0, "vmax": 255} if image.dtype == np.uint8 else {}
    ax.imshow(image, cmap="gray" if image.ndim == 2 else None, extent=(-0.5, w - 0.5, h - 0.5, -0.5), **scale)
    if ignore_mask is not None and np.any(ignore_mask):
        m = np.asarray(ignore_mask, bool).astype(float)
        ax.contourf(np.arange(w), np.arange(h), m, levels=[0.5, 1.5], colors="none", hatches=["////"])
        ax.contour(np.arange(w), np.arange(h), m, levels=[0.5], colors="red", linewidths=0.8)
        ax.plot([], [], "-", color="red", lw=0.8, label="ignored (no evidence)")
    cmap = matplotlib.colormaps["viridis"]
    for l in range(stack.n_planes):
        color = cmap(l / max(stack.n_planes - 1, 1))
        lines = grid_lines_world(stack, l, spacing_m)
        uv = camera.project(lines)
        for k, line in enumerate(uv):
            ax.plot(line[:, 0], line[:, 1], "-", color=color, lw=0.7,
                    label=f"z = {stack.heights_m[l]:g} m" if k == 0 else None)
    ax.set_xlim(-0.5, w - 0.5)
    ax.set_ylim(h - 0.5, -0.5)
    ax.set_xlabel("u [px]")
    ax.set_ylabel("v [px]")
    ax.set_title(f"{camera.name}: registered planes (grid every {spacing_m:g} m)"
                 + (f"\n{image_label}" if image_label else ""), fontsize=9)
    ax.legend(fontsize=7, loc="lower right")
    return fig


def _rows_at(table: Mapping[str, np.ndarray] | None, step: int) -> tuple[np.ndarray, np.ndarray]:
    """``track_id`` (or -1s) and ``(x_m, y_m)`` of the rows of ``table`` at output step ``step``."""
    if not table or len(table.get("step", [])) == 0:
        return np.zeros(0, int), np.zeros((0, 2))
    m = np.asarray(table["step"]) == step
    ids = np.asarray(table["track_id"])[m] if "track_id" in table else np.full(int(m.sum()), -1)
    xy = np.stack([np.asarray(table["x_m"], float)[m], np.asarray(table["y_m"], float)[m]], -1)
    return ids, xy


def plot_camera_tracks(camera: PinholeCamera, frames, times_s, tracks: Mapping[str, np.ndarray] | None,
                       detections: Mapping[str, np.ndarray] | None = None, *, ignore_mask=None,
                       head_m: float = 1.7, boxes: Mapping[str, np.ndarray] | None = None) -> Figure:
    """Camera frames with the tracks of the output step nearest each frame drawn as feet-to-head lines.

    Parameters
    ----------
    camera : PinholeCamera
    frames : sequence of (int, float, ndarray)
        ``(frame index, time [s], image (H, W, 3) RGB uint8)``, one panel each.
    times_s : ndarray, shape (T,)
        Times of the output steps [s].
    tracks, detections : dict of column arrays
        The run's tables (``step``, ``track_id``, ``x_m``, ``y_m``); each track is a vertical segment from its
        ground position to ``head_m`` above it, in its colour of the floor-plan figures (:func:`track_colour`),
        labelled with its id; detections are grey crosses at the feet.
    ignore_mask : ndarray, shape (H, W), bool, optional
    head_m : float
        Height of the drawn segment [m].
    boxes : dict of column arrays, optional
        The person detector's boxes (:data:`planefuse.outputs.BOX_COLUMNS`: ``step``, ``camera``, ``left_px``,
        ``top_px``, ``width_px``, ``height_px``, ``score``); this camera's boxes of the panel's step are drawn as
        white rectangles with their score.
    """
    w, h = camera.intrinsics.width_px, camera.intrinsics.height_px
    mine = None
    if boxes is not None and len(boxes.get("step", [])):
        mine = np.asarray(boxes["camera"]) == camera.name
    n = len(frames)
    cols = min(n, 2)
    rows = -(-n // cols)
    fig = Figure(figsize=(4.2 * cols, 4.2 * rows * h / w + 0.8), layout="constrained")
    axes = np.atleast_1d(fig.subplots(rows, cols, squeeze=False)).ravel()
    times_s = np.asarray(times_s, float)
    for ax, (index, t, image) in zip(axes, frames):
        step = int(np.argmin(np.abs(times_s - t)))
        ax.imshow(np.asarray(image), extent=(-0.5, w - 0.5, h - 0.5, -0.5))
        if ignore_mask is not None and np.any(ignore_mask):
            ax.contour(np.arange(w), np.arange(h), np.asarray(ignore_mask, float), levels=[0.5], colors="red",
                       linewidths=0.6)
        n_boxes = 0
        if mine is not None:
            at = mine & (np.asarray(boxes["step"]) == step)
            n_boxes = int(at.sum())
            for left, top, bw, bh, sc in zip(*(np.asarray(boxes[k], float)[at] for k in
                                               ("left_px", "top_px", "width_px", "height_px", "score"))):
                ax.add_patch(Rectangle((left - 0.5, top - 0.5), bw, bh, fill=False, ec="white", lw=1.0, ls="--"))
                ax.annotate(f"{sc:.2f}", (left, top + bh), color="white", fontsize=6, va="top")
        _, dxy = _rows_at(detections, step)
        if len(dxy):
            uv = camera.project(np.c_[dxy, np.zeros(len(dxy))])
            ax.plot(uv[:, 0], uv[:, 1], "x", color="0.8", ms=5, mew=1.2)
        ids, xy = _rows_at(tracks, step)
        for tid, p in zip(ids, xy):
            uv = camera.project(np.array([[p[0], p[1], 0.0], [p[0], p[1], head_m]]))
            if not np.isfinite(uv).all():
                continue
            ax.plot(uv[:, 0], uv[:, 1], "-", color=track_colour(tid), lw=2.5)
            ax.annotate(str(int(tid)), uv[1], color=track_colour(tid), fontsize=8, fontweight="bold",
                        ha="center", va="bottom")
        ax.set_xlim(-0.5, w - 0.5)
        ax.set_ylim(h - 0.5, -0.5)
        ax.set_axis_off()
        found = f", {n_boxes} person boxes" if mine is not None else ""
        ax.set_title(f"frame {index}, t = {t:.2f} s (step {step}): {len(ids)} tracks{found}", fontsize=8)
    for ax in axes[n:]:
        ax.set_visible(False)
    fig.suptitle(f"{camera.name}: tracks (feet to {head_m:g} m, colours as the floor plan), detections x"
                 + (", the person detector's boxes dashed" if mine is not None else ""), fontsize=9)
    return fig


def plot_saliency(times_s, azimuth_rad, saliency) -> Figure:
    """Auditory saliency over time and azimuth (azimuth shown in degrees).

    Parameters
    ----------
    times_s : ndarray, shape (T,)
    azimuth_rad : ndarray, shape (A,)
    saliency : ndarray, shape (T, A)
    """
    t = np.asarray(times_s, float)
    az = np.asarray(azimuth_rad, float)
    s = np.asarray(saliency, float)
    if s.shape != (t.size, az.size):
        raise ValueError(f"saliency must have shape (T, A) = ({t.size}, {az.size}), got {s.shape}")
    fig = Figure(figsize=(7, 3.2), layout="constrained")
    ax = fig.subplots()
    m = ax.pcolormesh(t, np.degrees(az), s.T, shading="nearest", cmap="viridis")
    ax.set_xlabel("time [s]")
    ax.set_ylabel("azimuth [deg]")
    ax.set_title("Auditory saliency map")
    fig.colorbar(m, ax=ax, label="saliency")
    return fig


def plot_laser_points(stack: PlaneStack, points_world) -> Figure:
    """Laser hits assigned to each plane by height band (``stack.plane_index_from_z``).

    Parameters
    ----------
    points_world : ndarray, shape (N, 3)
        Hits in the world frame [m]; those outside every band are counted in the title.
    """
    p = np.asarray(points_world, float).reshape(-1, 3)
    k = stack.plane_index_from_z(p[:, 2])
    fig, axes = _plane_axes(stack.n_planes, 2.8)
    for l, ax in enumerate(axes[: stack.n_planes]):
        q = p[k == l]
        ax.plot(q[:, 0], q[:, 1], ".", ms=2, color="tab:red")
        ax.set_xlim(stack.extent_m[:2])
        ax.set_ylim(stack.extent_m[2:])
        ax.set_aspect("equal")
        lo, hi = stack.band_edges_m[l], stack.band_edges_m[l + 1]
        ax.set_title(f"z = {stack.heights_m[l]:g} m ({lo:g}-{hi:g} m): {len(q)} pts", fontsize=8)
        ax.set_xlabel("x [m]")
        ax.set_ylabel("y [m]")
    fig.suptitle(f"Laser points per plane ({int(np.sum(k < 0))} of {len(p)} outside all bands)")
    return fig


def plot_metrics(metrics: Mapping[str, object]) -> Figure | None:
    """Scalar metrics as a bar chart and per-step series (lists) as lines; None if there is nothing to plot."""
    scalars = {k: float(v) for k, v in metrics.items()
               if isinstance(v, (int, float, np.number)) and not isinstance(v, bool) and np.isfinite(v)}
    series = {k: np.asarray(v, float) for k, v in metrics.items()
              if isinstance(v, (list, tuple, np.ndarray)) and len(v) > 1
              and all(isinstance(x, (int, float, np.number)) or x is None for x in v)}
    n = bool(scalars) + bool(series)
    if n == 0:
        return None
    fig = Figure(figsize=(5.5 * n, 3.2), layout="constrained")
    axes = fig.subplots(1, n, squeeze=False)
    axes = list(axes.ravel())
    if scalars:
        ax = axes.pop(0)
        ax.barh(list(scalars), list(scalars.values()), color="tab:blue")
        for i, v in enumerate(scalars.values()):
            ax.text(v, i, f" {v:.3g}", va="center", fontsize=8)
        ax.set_title("Metrics")
    if series:
        ax = axes.pop(0)
        for k, v in series.items():
            ax.plot(v, label=k)
        ax.set_xlabel("step")
        ax.legend(fontsize=7)
        ax.set_title("Per-step metrics")
    return fig


def run_figures(
    stack: PlaneStack,
    occupancy,
    times_s,
    detections: Mapping[str, np.ndarray],
    tracks: Mapping[str, np.ndarray],
    metrics: Mapping[str, object],
    inputs: FigureInputs,
    *,
    dpi: int = 100,
    progress=None,
    camera_boxes: Mapping[str, np.ndarray] | None = None,
) -> dict[str, bytes]:
    """Every figure of a run as PNG bytes, keyed by a file-name stem.

    Parameters
    ----------
    occupancy : array-like, shape (T, L, ny, nx)
        P(occupied) over time: an ndarray or an on-disk array read one block of steps at a time
        (:meth:`OutputWriter.occupancy_array`), so the figures of a long run need memory for a block of
        steps only, not for the whole run.
    times_s : ndarray, shape (T,)
    detections, tracks : dict of column arrays
        As returned by :meth:`OutputWriter.detections_table` / ``tracks_table``.
    metrics : dict
    inputs : FigureInputs
    progress : ProgressReporter, optional
    camera_boxes : dict of column arrays, optional
        The person detector's boxes (:meth:`OutputWriter.camera_boxes_table`), drawn on the camera figures.
    """
    occ = occupancy
    jobs: list[tuple[str, object]] = []
    if occ.shape[0]:
        last = occ.shape[0] - 1
        dstep = np.asarray(detections.get("step", []), float)
        det_xy = np.stack([np.asarray(detections["x_m"], float)[dstep == last],
                           np.asarray(detections["y_m"], float)[dstep == last]], -1) if dstep.size else None
        jobs.append(("occupancy_last", lambda: plot_plane_occupancy(
            stack, occ[last], time_s=float(times_s[last]), step=last, detections_xy_m=det_xy, tracks=tracks,
            ground_truth=inputs.ground_truth)))
        jobs.append(("occupancy_mean", lambda: _mean_fig(stack, occ, tracks, inputs.ground_truth, times_s)))
    for cam in inputs.cameras:
        jobs.append((f"camera_{cam.name}", lambda cam=cam: plot_camera_grid(
            cam, stack, inputs.camera_images.get(cam.name), ignore_mask=inputs.ignore_masks.get(cam.name),
            image_label=inputs.camera_image_labels.get(cam.name, ""))))
        if inputs.camera_frames.get(cam.name) and len(times_s):
            jobs.append((f"camera_{cam.name}_tracks", lambda cam=cam: plot_camera_tracks(
                cam, inputs.camera_frames[cam.name], times_s, tracks, detections,
                ignore_mask=inputs.ignore_masks.get(cam.name), boxes=camera_boxes)))
    if inputs.saliency is not None:
        jobs.append(("saliency", lambda: plot_saliency(inputs.saliency_times_s, inputs.saliency_azimuth_rad,
                                                       inputs.saliency)))
    if inputs.laser_points_world is not None:
        jobs.append(("laser_points", lambda: plot_laser_points(stack, inputs.laser_points_world)))
    if metrics:
        jobs.append(("metrics", lambda: plot_metrics(metrics)))
    out: dict[str, bytes] = {}
    step = progress.step("figures", total=len(jobs), unit="figures") if progress is not None \
        else contextlib.nullcontext(lambda n=1: None)
    with step as advance:
        for name, make in jobs:
            fig = make()
            if fig is not None:
                out[name] = png_bytes(fig, dpi)
            advance(1)
    return out


def occupancy_mean(occupancy, block_steps: int = 16) -> np.ndarray:
    """Mean over time of every cell's P(occupied), ignoring NaN (unobserved) steps, read block by block.

    Parameters
    ----------
    occupancy : array-like, shape (T, L, ny, nx)
        Any array indexable by a slice of steps (ndarray, zarr array), T >= 1.
    block_steps : int
        Steps read at once: memory is ``block_steps`` steps, whatever T.

    Returns
    -------
    ndarray, shape (L, ny, nx), float64
        The mean of the non-NaN steps of each cell; NaN where a cell was never observed.
    """
    T = occupancy.shape[0]
    total = np.zeros(occupancy.shape[1:], np.float64)
    count = np.zeros(occupancy.shape[1:], np.int64)
    for a in range(0, T, block_steps):
        block = np.asarray(occupancy[a: a + block_steps])
        seen = ~np.isnan(block)
        total += np.sum(block, axis=0, dtype=np.float64, where=seen)  # summed in float64, no float64 copy
        count += seen.sum(axis=0)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(count > 0, total / np.maximum(count, 1), np.nan)


def _mean_fig(stack: PlaneStack, occ, tracks, ground_truth, times_s=None) -> Figure:
    fig = plot_plane_occupancy(stack, occupancy_mean(occ), tracks=tracks, ground_truth=ground_truth)
    span = f" (steps 0-{occ.shape[0] - 1}, t = {times_s[0]:.2f}-{times_s[-1]:.2f} s)" \
        if times_s is not None and len(times_s) else ""
    fig.suptitle(f"Mean occupancy over {occ.shape[0]} steps{span}, with all tracks")
    return fig
