"""Which ground the cameras see: cameras per cell, a proposed monitored area, and the views' weak points.

``planefuse config init`` proposes the monitored area of a recording imported without one
(:func:`proposed_area_xy_m`); ``planefuse check`` draws :func:`cameras_per_cell` and reports
:func:`camera_view_findings`.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from ..geometry._camera import PinholeCamera
from ..grid._stack import PlaneStack
from ._lookup import ImagePlaneLookup

__all__ = ["PERSON_HEIGHT_M", "MIN_PERSON_PX", "cameras_per_cell", "max_useful_range_m", "proposed_area_xy_m",
           "camera_view_findings"]

#: Height of a standing person [m] used to judge how large people look in an image.
PERSON_HEIGHT_M = 1.7
#: A person smaller than this in an image [px] is not counted as seen (background subtraction's blobs of a few
#: pixels are speckle-sized; the EPFL terrace's 360 x 288 px people are 40-120 px tall).
MIN_PERSON_PX = 20.0
#: Camera height [m] below which people hide each other in the views (warned about).
LOW_CAMERA_M = 2.5
#: Depression of the optical axis below the horizon [deg] under which a camera looks nearly horizontally.
SHALLOW_AXIS_DEG = 12.0


def max_useful_range_m(camera: PinholeCamera, min_person_px: float = MIN_PERSON_PX) -> float:
    """Distance [m] from ``camera``'s centre beyond which a standing person (:data:`PERSON_HEIGHT_M`) is smaller
    than ``min_person_px`` pixels (pinhole, vertical focal length)."""
    return float(camera.K[1, 1] * PERSON_HEIGHT_M / min_person_px)


def cameras_per_cell(cameras: Sequence[PinholeCamera], stack: PlaneStack,
                     min_person_px: float | None = MIN_PERSON_PX) -> np.ndarray:
    """How many cameras see each cell.

    Parameters
    ----------
    cameras : sequence of PinholeCamera
        World frame, metres.
    stack : PlaneStack
    min_person_px : float or None
        A cell farther from a camera than :func:`max_useful_range_m` does not count as seen by it; None = any
        distance.

    Returns
    -------
    ndarray, shape (L, ny, nx), int32
        Cameras whose image holds the cell's centre (and near enough), per plane.
    """
    out = np.zeros(stack.shape, dtype=np.int32)
    centres = stack.cell_centers_world()
    for cam in cameras:
        vis = ImagePlaneLookup.from_camera(cam, stack).visible
        if min_person_px is not None:
            vis &= np.linalg.norm(centres - cam.center_world, axis=-1) <= max_useful_range_m(cam, min_person_px)
        out += vis
    return out


def proposed_area_xy_m(cameras: Sequence[PinholeCamera], *, min_cameras: int = 2, cell_size_m: float = 0.25,
                       min_person_px: float = MIN_PERSON_PX, round_m: float = 0.5
                       ) -> tuple[float, float, float, float] | None:
    """A monitored area for cameras that came without one: the box around the ground seen by ``min_cameras``.

    Candidate ground is every point within :func:`max_useful_range_m` of a camera; of it, the cells (of
    ``cell_size_m``) on the ground plane z = 0 that at least ``min_cameras`` cameras see (:func:`cameras_per_cell`)
    are kept, and their bounding box, rounded outwards to ``round_m``, is returned.

    Returns
    -------
    (x_min, x_max, y_min, y_max) [m], or None
        None when no ground cell is seen by ``min_cameras`` cameras (or there are fewer cameras).
    """
    if len(cameras) < max(min_cameras, 1):
        return None
    centres = np.array([c.center_world[:2] for c in cameras])
    reach = np.array([max_useful_range_m(c, min_person_px) for c in cameras])
    x0, x1 = float((centres[:, 0] - reach).min()), float((centres[:, 0] + reach).max())
    y0, y1 = float((centres[:, 1] - reach).min()), float((centres[:, 1] + reach).max())
    stack = PlaneStack.from_extent((0.0,), (x0, x1), (y0, y1), cell_size_m)
    seen = cameras_per_cell(cameras, stack, min_person_px)[0] >= min_cameras
    if not seen.any():
        return None
    xy = stack.cell_centers_xy()[seen]
    h = cell_size_m / 2
    lo = np.floor((xy.min(axis=0) - h) / round_m) * round_m
    hi = np.ceil((xy.max(axis=0) + h) / round_m) * round_m
    return float(lo[0]), float(hi[0]), float(lo[1]), float(hi[1])


def camera_view_findings(cameras: Sequence[PinholeCamera], stack: PlaneStack,
                         min_person_px: float = MIN_PERSON_PX) -> list[tuple[str, str, str]]:
    """What the cameras' placement costs: low or nearly horizontal cameras, barely overlapping views, ground seen by
    fewer than two cameras.

    Parameters
    ----------
    cameras : sequence of PinholeCamera
    stack : PlaneStack
        The monitored area (its first plane is judged).
    min_person_px : float
        See :func:`cameras_per_cell`.

    Returns
    -------
    list of (level, subject, message)
        ``level`` "warning" or "info".
    """
    out: list[tuple[str, str, str]] = []
    ground = PlaneStack(stack.heights_m[:1], stack.x_min_m, stack.y_min_m, stack.cell_size_m, stack.nx, stack.ny)
    per_cam = []
    for cam in cameras:
        height = float(cam.center_world[2])
        axis = cam.R_world_cam[:, 2]
        depression_deg = float(np.degrees(np.arcsin(np.clip(-axis[2], -1.0, 1.0))))
        if height < LOW_CAMERA_M:
            out.append(("warning", cam.name, f"camera {height:.1f} m above the ground (< {LOW_CAMERA_M:g} m): "
                        "people in front hide those behind, and a person's silhouette covers the ground far behind "
                        "them; mount it higher where you can"))
        if depression_deg < SHALLOW_AXIS_DEG:
            # how far along the ground a person's silhouette reaches behind their feet (ray over the head)
            d = float(np.hypot(*(cam.center_world[:2] - np.array(ground.cell_centers_xy().reshape(-1, 2).mean(0)))))
            smear = d * PERSON_HEIGHT_M / max(height - PERSON_HEIGHT_M, 1e-3) if height > PERSON_HEIGHT_M else np.inf
            smear_txt = f"{smear:.0f} m" if np.isfinite(smear) else "to the horizon"
            out.append(("warning", cam.name, f"looks nearly horizontally ({depression_deg:.0f} deg below the horizon, "
                        f"< {SHALLOW_AXIS_DEG:g}): every person smears along the viewing rays (at the area's centre a "
                        f"silhouette covers ground {smear_txt} behind the feet), so positions along the rays are "
                        "uncertain; another camera across the area, or a steeper one, fixes them"))
        per_cam.append(cameras_per_cell([cam], ground, min_person_px)[0] > 0)
    if not cameras:
        return out
    count = np.sum(per_cam, axis=0)
    for i in range(len(cameras)):
        for j in range(i + 1, len(cameras)):
            a, b = per_cam[i], per_cam[j]
            union = int((a | b).sum())
            iou = (a & b).sum() / union if union else 0.0
            if iou < 0.2:
                out.append(("warning", f"{cameras[i].name}+{cameras[j].name}", f"the two views barely overlap "
                            f"({iou:.0%} of the ground either sees): people there are seen by one of them only"))
    one = float((count == 1).mean())
    none = float((count == 0).mean())
    if one + none > 0.1:
        out.append(("warning", "cameras", f"{one:.0%} of the monitored area is seen by one camera only and {none:.0%} "
                    "by none: one view cannot tell how far along its rays a person stands (positions there are "
                    "uncertain by metres, and the generative model cannot remove ghosts); shrink planes.x_range_m / "
                    "y_range_m to the ground two cameras see, or add a camera"))
    return out
