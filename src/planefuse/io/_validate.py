"""Geometric checks of a recording's cameras against its plane stack and its own reference points.

:func:`geometry_findings` is what ``planefuse check`` adds for an imported recording: every plane must lie
below every camera (a plane at or above a camera centre has no image), each camera must look down at the
ground, control points (pixels of known world points) must reproject onto their pixels, and ground-truth
positions should fall inside the images of the cameras that were used to place them.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from ..geometry import PinholeCamera
from ._groundtruth import PeopleTruth
from ._import import ControlPoints

__all__ = ["Finding", "geometry_findings", "REPROJECTION_WARN_PX", "REPROJECTION_ERROR_PX"]

#: Control-point reprojection errors above these [px] give a warning / an error.
REPROJECTION_WARN_PX = 3.0
REPROJECTION_ERROR_PX = 10.0

Finding = tuple[str, str, str]  # (level "error" | "warning" | "info", subject, message)


def geometry_findings(cameras: Sequence[PinholeCamera], heights_m: Sequence[float], *,
                      control_points: ControlPoints | None = None, people: PeopleTruth | None = None,
                      warn_px: float = REPROJECTION_WARN_PX, error_px: float = REPROJECTION_ERROR_PX) -> list[Finding]:
    """Check cameras against a plane stack, control points and ground truth.

    Parameters
    ----------
    cameras : sequence of PinholeCamera
        World frame z up, ground z = 0, metres.
    heights_m : sequence of float
        Plane heights [m].
    control_points : ControlPoints, optional
        Reprojected with their camera; the largest error per camera is an error above ``error_px``, a warning
        above ``warn_px``.
    people : PeopleTruth, optional
        Ground-truth positions; the fraction of them that projects into each image (at z = 0) is reported.

    Returns
    -------
    list of (level, subject, message)
    """
    out: list[Finding] = []
    top = max(heights_m) if len(heights_m) else 0.0
    for cam in cameras:
        z = float(cam.center_world[2])
        if z <= top:
            above = [h for h in heights_m if h >= z]
            out.append(("error", cam.name, f"plane(s) at {', '.join(f'{h:g}' for h in above)} m are at or above the "
                        f"camera centre (z = {z:.3f} m): they have no image in this camera"))
        axis_z = float(cam.R_world_cam[2, 2])  # world z of the optical axis
        if axis_z >= 0:
            out.append(("warning", cam.name, f"the optical axis points {'up' if axis_z > 0 else 'horizontally'} "
                        f"(world z component {axis_z:+.2f}): the ground is only at the image's edge, if at all"))
    by_name = {c.name: c for c in cameras}
    if control_points is not None and len(control_points.camera):
        for name in sorted(set(control_points.camera)):
            sel = control_points.camera == name
            if name not in by_name:
                out.append(("error", name, f"{int(sel.sum())} control points name a camera the recording lacks"))
                continue
            uv = by_name[name].project(control_points.xyz_m[sel])
            err = np.linalg.norm(uv - control_points.uv_px[sel], axis=1)
            behind = ~np.isfinite(err)
            if behind.any():
                out.append(("error", name, f"{int(behind.sum())} of {int(sel.sum())} control points are behind the "
                            "camera"))
            if (~behind).any():
                e = err[~behind]
                level = "error" if e.max() > error_px else "warning" if e.max() > warn_px else "info"
                out.append((level, name, f"control points reproject within {e.max():.2f} px (rms "
                            f"{np.sqrt(np.mean(e**2)):.2f} px, {e.size} points)"))
    if people is not None:
        xy = people.xy_m.reshape(-1, 2)
        xy = xy[np.isfinite(xy).all(axis=1)]
        if xy.size:
            p = np.c_[xy, np.zeros(len(xy))]
            for cam in cameras:
                inside = cam.intrinsics.contains(cam.project(p))
                out.append(("info", cam.name, f"{inside.mean():.0%} of the {len(xy)} ground-truth positions project "
                            "into the image"))
    return out
