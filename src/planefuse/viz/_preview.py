"""Pictures of an installation before a run (``planefuse check --figures DIR``): where the ground, the monitored area
and the planes lie on each camera's image, and how many cameras see each cell of the area.

Each function takes plain arrays and returns a matplotlib ``Figure`` (no pyplot, no display needed).
"""

from __future__ import annotations

from collections.abc import Sequence

import matplotlib
import numpy as np
from matplotlib.colors import BoundaryNorm, ListedColormap
from matplotlib.figure import Figure

from ..geometry import PinholeCamera
from ..grid import PlaneStack

__all__ = ["area_outline_world", "ground_grid_world", "installation_preview", "plot_camera_preview", "plot_coverage"]


def area_outline_world(stack: PlaneStack, height_m: float, samples: int = 50) -> np.ndarray:
    """The border of the stack's area on the plane z = ``height_m``, a closed polyline (4 samples + 1, 3) [m],
    sampled densely (``samples`` points per side) so that lens distortion shows once projected."""
    x0, x1, y0, y1 = stack.extent_m
    t = np.linspace(0.0, 1.0, samples, endpoint=False)
    sides = [np.stack([x0 + t * (x1 - x0), np.full_like(t, y0)], -1),
             np.stack([np.full_like(t, x1), y0 + t * (y1 - y0)], -1),
             np.stack([x1 - t * (x1 - x0), np.full_like(t, y1)], -1),
             np.stack([np.full_like(t, x0), y1 - t * (y1 - y0)], -1)]
    xy = np.concatenate(sides + [np.array([[x0, y0]])])
    return np.concatenate([xy, np.full((len(xy), 1), float(height_m))], axis=1)


def ground_grid_world(stack: PlaneStack, spacing_m: float = 1.0, samples: int = 60) -> np.ndarray:
    """Lines of a ground grid (z = 0) every ``spacing_m`` metres, on the multiples of ``spacing_m`` inside the
    stack's area: (K, samples, 3) [m]."""
    x0, x1, y0, y1 = stack.extent_m
    xs = np.arange(np.ceil(x0 / spacing_m), np.floor(x1 / spacing_m) + 1) * spacing_m
    ys = np.arange(np.ceil(y0 / spacing_m), np.floor(y1 / spacing_m) + 1) * spacing_m
    t = np.linspace(0.0, 1.0, samples)
    lines = [np.stack([np.full_like(t, x), y0 + t * (y1 - y0), np.zeros_like(t)], -1) for x in xs]
    lines += [np.stack([x0 + t * (x1 - x0), np.full_like(t, y), np.zeros_like(t)], -1) for y in ys]
    return np.stack(lines) if lines else np.zeros((0, samples, 3))


def plot_camera_preview(camera: PinholeCamera, stack: PlaneStack, image=None, *, ignore_mask=None,
                        spacing_m: float = 1.0, title: str = "") -> Figure:
    """A camera's image with the ground grid every ``spacing_m`` (z = 0), the monitored area's border on the
    ground (thick) and on every plane of the stack (its height's colour), and the ignored pixels.

    Parameters
    ----------
    camera : PinholeCamera
    stack : PlaneStack
        The monitored area (x, y extent) and the planes' heights.
    image : ndarray, shape (H, W, 3) RGB or (H, W) gray, uint8, optional
        The frame to draw on; blank when omitted.
    ignore_mask : ndarray, shape (H, W), bool, optional
        Pixels that are not scene evidence, hatched in red.
    spacing_m : float
        Grid spacing [m].
    title : str
        What the image is (its frame number and time); the camera's name is added.

    Notes
    -----
    Points behind the camera have no image (NaN) and are not drawn, so a plane whose border passes behind the
    camera is drawn in pieces.
    """
    w, h = camera.intrinsics.width_px, camera.intrinsics.height_px
    fig = Figure(figsize=(6.0, 6.0 * h / w + 0.5), layout="constrained")
    ax = fig.subplots()
    image = np.full((h, w), 235, np.uint8) if image is None else np.asarray(image)
    ax.imshow(image, cmap="gray" if image.ndim == 2 else None, vmin=0, vmax=255,
              extent=(-0.5, w - 0.5, h - 0.5, -0.5))
    if ignore_mask is not None and np.any(ignore_mask):
        m = np.asarray(ignore_mask, bool).astype(float)
        ax.contourf(np.arange(w), np.arange(h), m, levels=[0.5, 1.5], colors="none", hatches=["////"])
        ax.contour(np.arange(w), np.arange(h), m, levels=[0.5], colors="red", linewidths=0.8)
        ax.plot([], [], "-", color="red", lw=0.8, label="ignored pixels")
    for k, line in enumerate(camera.project(ground_grid_world(stack, spacing_m))):
        ax.plot(line[:, 0], line[:, 1], "-", color="white", lw=0.6, alpha=0.8,
                label=f"ground grid, {spacing_m:g} m" if k == 0 else None)
    cmap = matplotlib.colormaps["plasma"]
    for l, z in enumerate(stack.heights_m):
        uv = camera.project(area_outline_world(stack, z)[None])[0]
        ax.plot(uv[:, 0], uv[:, 1], "--", color=cmap(0.15 + 0.7 * l / max(stack.n_planes - 1, 1)), lw=1.0,
                label=f"plane z = {z:g} m")
    uv = camera.project(area_outline_world(stack, 0.0)[None])[0]
    ax.plot(uv[:, 0], uv[:, 1], "-", color="lime", lw=2.0, label="monitored area (ground)")
    ax.set_xlim(-0.5, w - 0.5)
    ax.set_ylim(h - 0.5, -0.5)
    ax.set_xlabel("u [px]")
    ax.set_ylabel("v [px]")
    ax.set_title(f"{camera.name}: {title}" if title else camera.name, fontsize=9)
    ax.legend(fontsize=7, loc="upper right", framealpha=0.7)
    return fig


def plot_coverage(cameras: Sequence[PinholeCamera], stack: PlaneStack, counts, *, title: str = "") -> Figure:
    """Top view of the monitored area: how many cameras see each cell, with each camera's centre and viewing
    direction.

    Parameters
    ----------
    cameras : sequence of PinholeCamera
    stack : PlaneStack
    counts : ndarray, shape (ny, nx), int
        Cameras per cell (:func:`planefuse.registration.cameras_per_cell` of one plane).
    title : str
    """
    counts = np.asarray(counts)
    n = max(len(cameras), 1)
    fig = Figure(figsize=(6.0, 5.0), layout="constrained")
    ax = fig.subplots()
    colours = ["#d9d9d9", "#fdae61"] + [matplotlib.colormaps["Greens"](0.4 + 0.5 * k / max(n - 2, 1))
                                        for k in range(max(n - 1, 1))]
    cmap = ListedColormap(colours[: n + 1])
    norm = BoundaryNorm(np.arange(-0.5, n + 1.5), cmap.N)
    im = ax.imshow(counts, origin="lower", extent=stack.extent_m, cmap=cmap, norm=norm, interpolation="nearest")
    cb = fig.colorbar(im, ax=ax, ticks=np.arange(0, n + 1), shrink=0.8)
    cb.set_label("cameras seeing the cell")
    x0, x1, y0, y1 = stack.extent_m
    ax.plot([x0, x1, x1, x0, x0], [y0, y0, y1, y1, y0], "-", color="lime", lw=2.0, label="monitored area")
    for cam in cameras:
        c = cam.center_world
        d = cam.R_world_cam[:2, 2]
        norm_d = np.linalg.norm(d)
        ax.plot(c[0], c[1], "k^", ms=7)
        if norm_d > 1e-6:
            d = d / norm_d * 0.15 * max(x1 - x0, y1 - y0)
            ax.annotate("", xy=(c[0] + d[0], c[1] + d[1]), xytext=(c[0], c[1]),
                        arrowprops={"arrowstyle": "->", "color": "k"})
        ax.annotate(f"{cam.name} ({c[2]:.1f} m)", (c[0], c[1]), textcoords="offset points", xytext=(4, 4),
                    fontsize=8)
    fractions = ", ".join(f">= {k}: {np.mean(counts >= k):.0%}" for k in (1, 2))
    ax.set_title((title + "\n" if title else "") + f"ground seen by {fractions} of the area", fontsize=9)
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.set_aspect("equal")
    ax.legend(fontsize=7, loc="lower right")
    return fig


def installation_preview(rec, stack: PlaneStack, *, frame_index: int = 0, spacing_m: float = 1.0,
                         dpi: int = 100) -> dict[str, bytes]:
    """The pictures ``planefuse check --figures`` writes, as PNG bytes keyed by a file-name stem.

    ``camera_<name>``: frame ``frame_index`` of each camera of ``rec`` (:func:`plot_camera_preview`, its frame
    number and time in the title); ``coverage``: cameras per cell of the ground plane (:func:`plot_coverage`,
    people smaller than :data:`planefuse.registration.MIN_PERSON_PX` not counted as seen).

    Parameters
    ----------
    rec : planefuse.io.Recording
    stack : PlaneStack
        The plane stack the run would use (:func:`planefuse.pipeline.stack_for_recording`).
    frame_index : int
        Which frame of each camera to draw on (the recording's index; negative counts from the end).
    """
    from ..registration import cameras_per_cell
    from ._figures import png_bytes

    out: dict[str, bytes] = {}
    for name, stream in rec.camera_streams.items():
        i = int(frame_index) % len(stream) if len(stream) else 0
        image = stream.frame(i)[..., ::-1] if len(stream) else None
        title = f"recording frame {i} (t = {stream.times_s[i]:.2f} s)" if len(stream) else "no frame"
        out[f"camera_{name}"] = png_bytes(plot_camera_preview(
            stream.camera, stack, image, ignore_mask=stream.ignore_mask, spacing_m=spacing_m, title=title), dpi)
    ground = PlaneStack(stack.heights_m[:1], stack.x_min_m, stack.y_min_m, stack.cell_size_m, stack.nx, stack.ny)
    cams = rec.cameras
    if cams:
        counts = cameras_per_cell(cams, ground)[0]
        out["coverage"] = png_bytes(plot_coverage(cams, ground, counts, title=f"plane z = {stack.heights_m[0]:g} m"),
                                    dpi)
    return out
