"""A camera known only by its ground-plane homography: a pinhole model that reproduces it.

A homography ``H_image_ground`` (ground XY in metres -> pixels) is ``K [r1 r2 t]`` up to scale. With square
pixels, no skew and the principal point at the image centre, the two constraints ``r1 . r2 = 0`` and
``|r1| = |r2|`` give the focal length (least squares in ``1/f^2``); ``r3 = r1 x r2`` completes the rotation.
The resulting camera maps the ground exactly as ``H`` does when those assumptions hold (the residual is
returned) and registers planes above the ground only as well as they hold: prefer a full calibration.
"""

from __future__ import annotations

import numpy as np

from ..geometry._camera import CameraIntrinsics, PinholeCamera
from ..geometry._checks import check_homography
from ..geometry._homography import apply_homography
from ..geometry._transforms import invert_transform, transform_from_rotation_translation

__all__ = ["camera_from_ground_homography"]


def camera_from_ground_homography(H_ground_image, width_px: int, height_px: int, *,
                                  name: str = "camera") -> tuple[PinholeCamera, float]:
    """Pinhole camera (no distortion) reproducing an image -> ground homography.

    Parameters
    ----------
    H_ground_image : array_like, shape (3, 3)
        Pixels (u right, v down) -> ground XY [m] of a right-handed world with z up.
    width_px, height_px : int
        Image size [px]; the principal point is put at its centre.
    name : str

    Returns
    -------
    (PinholeCamera, float)
        The camera and the largest distance [px] between ``H`` and the camera's ground projection over a 9x9
        grid of image points whose rays reach the ground.

    Raises
    ------
    ValueError
        ``H`` singular or non-finite; no positive focal length fits (``H`` is not a perspective view of a
        plane with square pixels); or the camera comes out below the ground, which happens when the ground
        frame is left-handed (one ground axis flipped, as in EPFL's top views).
    """
    H_ground_image = check_homography(H_ground_image, f"{name}: ground homography")
    A = np.linalg.inv(H_ground_image)  # ground -> image
    cx, cy = (width_px - 1) / 2.0, (height_px - 1) / 2.0
    B = np.array([[1.0, 0.0, -cx], [0.0, 1.0, -cy], [0.0, 0.0, 1.0]]) @ A
    B /= np.linalg.norm(B)
    h1, h2 = B[:, 0], B[:, 1]
    # r1.r2 = 0 and |r1| = |r2| with K^-1 B = [h_x / f, h_y / f, h_z]: linear in x = 1 / f^2.
    M = np.array([[h1[0] * h2[0] + h1[1] * h2[1]], [h1[0] ** 2 + h1[1] ** 2 - h2[0] ** 2 - h2[1] ** 2]])
    b = -np.array([h1[2] * h2[2], h1[2] ** 2 - h2[2] ** 2])
    x = float(np.linalg.lstsq(M, b, rcond=None)[0][0])
    if not (np.isfinite(x) and x > 0):
        raise ValueError(f"{name}: no positive focal length fits the ground homography (1/f^2 = {x:.3g}): not a "
                         "perspective view of the ground with square pixels and a centred principal point")
    f = 1.0 / np.sqrt(x)
    K = np.array([[f, 0.0, cx], [0.0, f, cy], [0.0, 0.0, 1.0]])
    G = np.linalg.inv(K) @ A
    lam = 2.0 / (np.linalg.norm(G[:, 0]) + np.linalg.norm(G[:, 1]))
    # The ground point under the image's bottom centre must lie in front of the camera.
    g = apply_homography(H_ground_image, np.array([[cx, height_px - 1.0]]))[0]
    if (lam * G @ np.array([g[0], g[1], 1.0]))[2] < 0:
        lam = -lam
    r1, r2, t = lam * G[:, 0], lam * G[:, 1], lam * G[:, 2]
    U, _, Vt = np.linalg.svd(np.column_stack([r1, r2, np.cross(r1, r2)]))
    R = U @ Vt
    if np.linalg.det(R) < 0:
        R = U @ np.diag([1.0, 1.0, -1.0]) @ Vt
    T_world_cam = invert_transform(transform_from_rotation_translation(R, t))
    cam = PinholeCamera(CameraIntrinsics(K, width_px, height_px), T_world_cam, name)
    if cam.center_world[2] <= 0:
        raise ValueError(f"{name}: the camera comes out {-cam.center_world[2]:.2f} m below the ground: the "
                         "homography's ground frame is left-handed (flip one ground axis, e.g. EPFL's v)")
    uv = np.array([[u, v] for u in np.linspace(0, width_px - 1, 9) for v in np.linspace(0, height_px - 1, 9)])
    xy = apply_homography(H_ground_image, uv)
    ok = np.isfinite(cam.backproject_to_height(uv, 0.0)).all(axis=1)
    err = np.linalg.norm(cam.project(np.c_[xy[ok], np.zeros(ok.sum())]) - uv[ok], axis=1)
    return cam, float(np.max(err)) if err.size else float("nan")
