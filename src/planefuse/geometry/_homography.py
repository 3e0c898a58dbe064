"""Image <-> plane homographies: the calibration route and the inertial (IMU) route.

Seed paper (Aliakbarpour et al. 2010), section 5.1 and 5.4:

* eq. 1 -- ``x_plane ~ H_plane_virtual @ H_virtual_image @ x_image``;
* eq. 2 -- inertial-compensated infinite homography ``H_virtual_image = K' R K^-1``
  where ``R = R_virtual_cam`` is the rotation of the real camera relative to a
  virtual camera with the same centre whose optical axis is the gravity vector;
* eq. 3 -- planar homology in axis/vertex/cross-ratio form
  ``H = I + (mu - 1) v a^T / (v^T a)``;
* eq. 4 -- its parallel-plane special case with ``a = (0, 0, 1)``, ``v = (v_x, v_y, 1)``.

For plane z = h the virtual camera sees the plane fronto-parallel at distance
``d_h = z_c - h``. Two parallel planes' virtual images differ by a scaling about
the nadir point (the principal point of the virtual camera): this is the
homology of eq. 4 with vertex ``v = K' (0, 0, 1)`` and ``mu = d_0 / d_h``.
``H_plane_virtual(h) = S_ref @ H_homology(mu_h)``, with ``S_ref`` the metric
similarity from the virtual view of pi_ref (z = 0) to world XY in metres.
The calibration route (Khan & Shah) takes columns ``[p1, p2, h p3 + p4]`` of
``P``; both routes give the same homography up to scale (tested to 1e-9).
"""

from __future__ import annotations

import numpy as np

from ._camera import PinholeCamera
from ._checks import check_homography, check_intrinsics_matrix, check_points, check_rotation

__all__ = [
    "apply_homography",
    "normalize_homography",
    "R_world_virtual",
    "R_virtual_cam_from_R_world_cam",
    "infinite_homography",
    "homology",
    "parallel_plane_homology",
    "mu_from_heights",
    "H_world_refview",
    "H_plane_virtual",
    "H_plane_image_imu",
    "H_image_plane_from_projection",
    "H_plane_image_from_projection",
    "H_plane_image_calibrated",
]

#: Rotation of the gravity-aligned virtual camera in the world: x' = X, y' = -Y,
#: z' = -Z (optical axis along gravity, right-handed).
R_world_virtual = np.diag([1.0, -1.0, -1.0])
R_world_virtual.setflags(write=False)


def apply_homography(H, points) -> np.ndarray:
    """Map 2-D points through a homography.

    Parameters
    ----------
    H : array_like, shape (..., 3, 3)
        Homography from the points' frame to the target frame.
    points : array_like, shape (..., N, 2)
        Inhomogeneous points (pixels or metres).

    Returns
    -------
    ndarray, shape (..., N, 2)
        Mapped points, never inf: NaN where the point is mapped to infinity -- its homogeneous scale ``w`` is 0
        relative to ``H`` and the point (``|w| <= 1e-14 max|H| (1 + max|p|)``: e.g. the horizon line of an image
        mapped to a ground plane) -- or beyond the float64 range (a coordinate that would overflow). A NaN row
        means "no finite image of this point"; callers test ``np.isfinite(out).all(axis=-1)``.
    """
    H = check_homography(H, "H")
    p = check_points(points, 2, "points")
    with np.errstate(over="ignore", invalid="ignore"):
        ph = p @ np.swapaxes(H[..., :2], -1, -2) + H[..., None, :, 2]
    w = ph[..., 2:3]
    scale = np.abs(H).max(axis=(-1, -2))[..., None, None] if H.ndim > 2 else np.abs(H).max()
    with np.errstate(over="ignore"):
        tiny = np.abs(w) <= 1e-14 * scale * (1.0 + np.abs(p).max(axis=-1, keepdims=True))
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        out = ph[..., :2] / w
    at_infinity = tiny | ~np.isfinite(out).all(axis=-1, keepdims=True)
    return np.where(at_infinity, np.nan, out)


def normalize_homography(H) -> np.ndarray:
    """Scale ``H`` (..., 3, 3) to unit Frobenius norm with a non-negative H[2, 2] (for comparisons)."""
    H = check_homography(H, "H")
    n = np.linalg.norm(H, axis=(-2, -1), keepdims=True)
    s = np.sign(H[..., 2:3, 2:3])
    s = np.where(s == 0, 1.0, s)
    return H / n * s


def R_virtual_cam_from_R_world_cam(R_world_cam) -> np.ndarray:
    """Rotation (..., 3, 3) from the real camera to its gravity-aligned virtual camera.

    ``R_virtual_cam = R_world_virtual^T @ R_world_cam``. Only roll and pitch
    (from the IMU) and yaw (from calibration) enter through ``R_world_cam``.
    """
    R = check_rotation(R_world_cam, "R_world_cam")
    return R_world_virtual.T @ R


def infinite_homography(K_virtual, R_virtual_cam, K) -> np.ndarray:
    """Seed eq. 2: ``H_virtual_image = K' R K^-1`` (..., 3, 3).

    Parameters
    ----------
    K_virtual : array_like, shape (3, 3)
        Intrinsics K' of the virtual camera [px].
    R_virtual_cam : array_like, shape (..., 3, 3)
        Rotation of the real camera in the virtual camera frame.
    K : array_like, shape (3, 3)
        Intrinsics of the real camera [px].
    """
    Kv = check_intrinsics_matrix(K_virtual, "K_virtual")
    K = check_intrinsics_matrix(K, "K")
    R = check_rotation(R_virtual_cam, "R_virtual_cam")
    return Kv @ R @ np.linalg.inv(K)


def homology(vertex, axis, mu: float) -> np.ndarray:
    """Seed eq. 3: planar homology ``H = I + (mu - 1) v a^T / (v^T a)`` (3, 3).

    Parameters
    ----------
    vertex : array_like, shape (3,)
        Homogeneous vertex v (the fixed point).
    axis : array_like, shape (3,)
        Homogeneous axis line a (a line of fixed points).
    mu : float
        Characteristic cross-ratio; ``mu = 1`` gives the identity.
    """
    v = np.asarray(vertex, dtype=float)
    a = np.asarray(axis, dtype=float)
    if v.shape != (3,) or a.shape != (3,):
        raise ValueError(f"vertex and axis must have shape (3,), got {v.shape} and {a.shape}")
    if not (np.isfinite(v).all() and np.isfinite(a).all() and np.isfinite(mu)):
        raise ValueError("vertex, axis and mu must be finite")
    va = float(v @ a)
    if abs(va) <= 1e-12 * np.linalg.norm(v) * np.linalg.norm(a):
        raise ValueError("vertex lies on the axis (v^T a = 0): the homology is undefined")
    if mu == 0:
        raise ValueError("mu = 0 gives a singular homology")
    return np.eye(3) + (mu - 1.0) * np.outer(v, a) / va


def parallel_plane_homology(v_x: float, v_y: float, mu: float) -> np.ndarray:
    """Seed eq. 4: ``[[1, 0, (mu-1) v_x], [0, 1, (mu-1) v_y], [0, 0, mu]]``.

    The special case of :func:`homology` with ``a = (0, 0, 1)`` and
    ``v = (v_x, v_y, 1)``: a scaling by ``1/mu`` about the vertex (v_x, v_y).
    """
    if not (np.isfinite(v_x) and np.isfinite(v_y) and np.isfinite(mu)) or mu == 0:
        raise ValueError(f"v_x, v_y, mu must be finite and mu != 0, got {v_x}, {v_y}, {mu}")
    return np.array([[1.0, 0.0, (mu - 1.0) * v_x], [0.0, 1.0, (mu - 1.0) * v_y], [0.0, 0.0, mu]])


def mu_from_heights(camera_height_m: float, plane_height_m: float) -> float:
    """Cross-ratio ``mu = d_0 / d_h`` relating the virtual views of z = h and z = 0.

    ``d_0 = camera_height_m`` is the camera centre's height above pi_ref and
    ``d_h = camera_height_m - plane_height_m`` its height above the plane [m].

    Raises
    ------
    ValueError
        If the plane is at or above the camera centre, or the camera is at or below pi_ref.
    """
    d0 = float(camera_height_m)
    dh = d0 - float(plane_height_m)
    if not np.isfinite(dh):
        raise ValueError("camera and plane heights must be finite")
    if dh <= 0:
        raise ValueError(
            f"plane z={plane_height_m} m is at or above the camera centre (z={camera_height_m} m): "
            "the camera cannot see it from above"
        )
    if d0 <= 0:
        raise ValueError(f"camera centre z={camera_height_m} m must be above pi_ref (z=0)")
    return d0 / dh


def H_world_refview(K_virtual, camera_center_world) -> np.ndarray:
    """Similarity (3, 3) from the virtual camera's view of pi_ref (pixels) to world XY [m].

    ``X = c_x + d_0 x_n``, ``Y = c_y - d_0 y_n`` with ``(x_n, y_n, 1) = K'^-1 (u, v, 1)``.
    """
    Kv = check_intrinsics_matrix(K_virtual, "K_virtual")
    c = np.asarray(camera_center_world, dtype=float)
    if c.shape != (3,) or not np.isfinite(c).all():
        raise ValueError(f"camera_center_world must be a finite (3,) vector, got {c}")
    if c[2] <= 0:
        raise ValueError(f"camera centre z={c[2]} m must be above pi_ref (z=0)")
    flip = np.array([[1.0, 0.0, c[0]], [0.0, -1.0, c[1]], [0.0, 0.0, 1.0]])
    return flip @ np.diag([c[2], c[2], 1.0]) @ np.linalg.inv(Kv)


def H_plane_virtual(K_virtual, camera_center_world, height_m: float) -> np.ndarray:
    """Homography (3, 3) from the virtual image to plane z = ``height_m`` (world XY, metres).

    ``H_plane_virtual = S_ref @ H_homology(mu)``, seed eq. 4 with vertex at the
    virtual principal point and ``mu = mu_from_heights(c_z, h)``.
    """
    Kv = check_intrinsics_matrix(K_virtual, "K_virtual")
    c = np.asarray(camera_center_world, dtype=float)
    mu = mu_from_heights(c[2], height_m)
    H_ref_virtual = parallel_plane_homology(Kv[0, 2], Kv[1, 2], mu)
    return H_world_refview(Kv, c) @ H_ref_virtual


def H_plane_image_imu(
    K,
    R_world_cam,
    camera_center_world,
    height_m: float,
    K_virtual=None,
) -> np.ndarray:
    """Seed eq. 1, IMU route: image pixels -> plane z = ``height_m`` (world XY, metres).

    Parameters
    ----------
    K : array_like, shape (3, 3)
        Real camera intrinsics [px] (pixels must be undistorted).
    R_world_cam : array_like, shape (3, 3)
        Camera attitude: roll/pitch from the IMU (gravity), yaw from calibration.
    camera_center_world : array_like, shape (3,)
        Optical centre in {W} [m]; its z is the height above pi_ref.
    height_m : float
        Plane height [m].
    K_virtual : array_like, shape (3, 3), optional
        Virtual camera intrinsics K'; defaults to ``K``.

    Returns
    -------
    ndarray, shape (3, 3)
        ``H_plane_image = H_plane_virtual @ H_virtual_image``.
    """
    Kv = K if K_virtual is None else K_virtual
    H_virtual_image = infinite_homography(Kv, R_virtual_cam_from_R_world_cam(R_world_cam), K)
    return H_plane_virtual(Kv, camera_center_world, height_m) @ H_virtual_image


def H_image_plane_from_projection(P_image_world, height_m) -> np.ndarray:
    """Calibration route (Khan & Shah): plane z = h (world XY, metres) -> undistorted pixels.

    Columns ``[p1, p2, h p3 + p4]`` of the projection matrix ``P`` (3, 4).
    ``height_m`` may be an array (L,), giving (L, 3, 3).
    """
    P = np.asarray(P_image_world, dtype=float)
    if P.shape != (3, 4):
        raise ValueError(f"P_image_world must have shape (3, 4), got {P.shape}")
    if not np.isfinite(P).all():
        raise ValueError("P_image_world has non-finite entries")
    h = np.asarray(height_m, dtype=float)
    if not np.isfinite(h).all():
        raise ValueError("height_m must be finite")
    H = np.empty(h.shape + (3, 3))
    H[..., :, 0] = P[:, 0]
    H[..., :, 1] = P[:, 1]
    H[..., :, 2] = h[..., None] * P[:, 2] + P[:, 3]
    return H


def H_plane_image_from_projection(P_image_world, height_m) -> np.ndarray:
    """Inverse of :func:`H_image_plane_from_projection`: undistorted pixels -> plane z = h.

    Raises
    ------
    ValueError
        If the homography is singular: the camera centre lies on the plane, so
        the plane is seen edge-on (a camera looking parallel to it from inside it).
    """
    H = H_image_plane_from_projection(P_image_world, height_m)
    try:
        check_homography(H, f"image->plane homography for height {height_m} m")
    except ValueError as exc:
        raise ValueError(f"{exc}: the camera centre lies on the plane z={height_m} m (edge-on view)") from None
    return np.linalg.inv(H)


def _check_sees_plane(camera: PinholeCamera, height_m: float) -> None:
    c = camera.center_world
    if c[2] <= height_m:
        raise ValueError(
            f"{camera.name}: plane z={height_m} m is at or above the camera centre (z={c[2]:.3f} m)"
        )
    w, h = camera.intrinsics.width_px, camera.intrinsics.height_px
    border = np.array(
        [[u, v] for u in np.linspace(0, w - 1, 9) for v in np.linspace(0, h - 1, 9)], dtype=float
    )
    if camera.intrinsics.has_distortion:
        d = camera.rays(border)
    else:
        xy = np.c_[border, np.ones(len(border))] @ np.linalg.inv(camera.K).T
        d = xy @ camera.R_world_cam.T
    if not np.any(d[:, 2] < -1e-9):
        raise ValueError(
            f"{camera.name}: no pixel ray points down to plane z={height_m} m "
            "(camera looks parallel to or away from the plane)"
        )


def H_plane_image_calibrated(camera: PinholeCamera, height_m: float, *, route: str = "projection") -> np.ndarray:
    """Undistorted pixels -> plane z = ``height_m`` [m] for a calibrated camera.

    Parameters
    ----------
    camera : PinholeCamera
    height_m : float
    route : {"projection", "imu"}
        ``"projection"``: columns of P (Khan & Shah). ``"imu"``: seed eq. 1 with
        the camera's attitude as the IMU+yaw rotation. Both agree.

    Raises
    ------
    ValueError
        If the plane is at/above the camera, or no image ray reaches it.
    """
    _check_sees_plane(camera, height_m)
    if route == "projection":
        return H_plane_image_from_projection(camera.P_image_world, height_m)
    if route == "imu":
        return H_plane_image_imu(camera.K, camera.R_world_cam, camera.center_world, height_m)
    raise ValueError(f"route must be 'projection' or 'imu', got {route!r}")
