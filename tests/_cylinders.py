"""Test scenes: people as vertical cylinders rendered into exact silhouette masks by ray casting."""

from __future__ import annotations

import numpy as np


def render_cylinder_mask(camera, people_xy, heights_m, radius_m: float = 0.2) -> np.ndarray:
    """Boolean (H, W) silhouette of vertical cylinders standing on z = 0 seen by ``camera``."""
    w, h = camera.intrinsics.width_px, camera.intrinsics.height_px
    u, v = np.meshgrid(np.arange(w, dtype=float), np.arange(h, dtype=float))
    d = camera.rays(np.stack([u.ravel(), v.ravel()], axis=-1))
    o = camera.center_world
    mask = np.zeros(len(d), dtype=bool)
    a = d[:, 0] ** 2 + d[:, 1] ** 2
    xy = np.asarray(people_xy, float).reshape(-1, 2)
    for (cx, cy), top in zip(xy, np.broadcast_to(heights_m, (len(xy),))):
        ox, oy = o[0] - cx, o[1] - cy
        b = 2 * (ox * d[:, 0] + oy * d[:, 1])
        c = ox * ox + oy * oy - radius_m**2
        disc = b * b - 4 * a * c
        with np.errstate(invalid="ignore", divide="ignore"):
            t = (-b - np.sqrt(disc)) / (2 * a)
            z = o[2] + t * d[:, 2]
            side = (disc >= 0) & (t > 0) & (z >= 0) & (z <= top)
            tc = (top - o[2]) / d[:, 2]
            px, py = ox + tc * d[:, 0], oy + tc * d[:, 1]
            cap = (tc > 0) & (px * px + py * py <= radius_m**2)
        mask |= side | cap
    return mask.reshape(h, w)
