"""Helpers to place cameras: look-at poses and a default ring of cameras around a room."""

from __future__ import annotations

import numpy as np

from ._camera import CameraIntrinsics, PinholeCamera
from ._transforms import transform_from_rotation_translation

__all__ = ["T_world_cam_look_at", "default_camera_ring"]


def T_world_cam_look_at(center_world, target_world, up_world=(0.0, 0.0, 1.0)) -> np.ndarray:
    """``T_world_cam`` (4, 4) of a camera at ``center_world`` whose optical axis points at ``target_world``.

    Camera axes: z forward (towards the target), x right, y down; the image's
    "up" is as close as possible to ``up_world``.
    """
    c = np.asarray(center_world, dtype=float)
    t = np.asarray(target_world, dtype=float)
    up = np.asarray(up_world, dtype=float)
    z = t - c
    nz = np.linalg.norm(z)
    if nz == 0 or not np.isfinite(nz):
        raise ValueError("center_world and target_world must be distinct finite points")
    z /= nz
    x = np.cross(z, up)
    if np.linalg.norm(x) < 1e-9:
        raise ValueError("viewing direction is parallel to up_world; choose another up vector")
    x /= np.linalg.norm(x)
    y = np.cross(z, x)
    return transform_from_rotation_translation(np.stack([x, y, z], axis=1), c)


def default_camera_ring(
    n_cameras: int = 4,
    room_size_m: float = 10.0,
    heights_m=(3.0, 2.8, 3.3, 2.6),
    width_px: int = 360,
    height_px: int = 288,
    hfov_deg: float = 90.0,
    dist=(-0.05, 0.01, 0.0, 0.0, 0.0),
) -> list[PinholeCamera]:
    """Cameras in the corners of a square room [0, L] x [0, L], looking at its centre floor.

    Parameters
    ----------
    n_cameras : int
        Number of cameras (placed at corners, then wall mid-points).
    room_size_m : float
        Side of the room [m].
    heights_m : sequence of float
        Camera heights [m], cycled.
    width_px, height_px : int
        Image size [px].
    hfov_deg : float
        Horizontal field of view [deg].
    dist : sequence of 5 float
        OpenCV distortion coefficients applied to every camera.
    """
    L = room_size_m
    m = 0.3
    spots = [(m, m), (L - m, m), (L - m, L - m), (m, L - m), (L / 2, m), (L - m, L / 2), (L / 2, L - m), (m, L / 2)]
    f = 0.5 * width_px / np.tan(np.radians(hfov_deg) / 2)
    K = np.array([[f, 0, (width_px - 1) / 2], [0, f, (height_px - 1) / 2], [0, 0, 1.0]])
    intr = CameraIntrinsics(K, width_px, height_px, np.asarray(dist, dtype=float))
    cams = []
    for i in range(n_cameras):
        x, y = spots[i % len(spots)]
        h = heights_m[i % len(heights_m)]
        # Aim a little past the centre so that the near floor is in view too.
        target = (L / 2 + 0.15 * (L / 2 - x), L / 2 + 0.15 * (L / 2 - y), 0.0)
        cams.append(PinholeCamera(intr, T_world_cam_look_at((x, y, h), target), name=f"cam{i}"))
    return cams
