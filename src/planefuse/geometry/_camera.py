"""Pinhole camera with OpenCV lens distortion (k1, k2, p1, p2, k3).

Frames: the camera frame {C} has x right, y down, z forward (optical axis),
metres; pixels have u right, v down, with the centre of the top-left pixel at
(0, 0). ``T_world_cam`` maps camera coordinates into the world {W}.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import cv2
import numpy as np

from ._checks import check_finite, check_intrinsics_matrix, check_points, check_transform
from ._transforms import invert_transform

__all__ = ["CameraIntrinsics", "PinholeCamera", "distort_normalized", "distortion_problem", "intrinsics_problem",
           "MAX_DISTORTION_FRACTION"]

#: Largest displacement of the lens distortion at the image's edges, as a fraction of the undistorted radius
#: (``distortion_problem``): Wildtrack's seven calibrated cameras move their edge midpoints by 5-16 %, the EPFL
#: terrace's four by 2-4 %; k1 = 5 on a 360 x 288 image of 300 px focal length by 66 %, k1 = 50 by 200 %.
MAX_DISTORTION_FRACTION = 0.5


def distort_normalized(xy, dist) -> np.ndarray:
    """Apply the OpenCV radial-tangential model to normalised coordinates.

    Parameters
    ----------
    xy : ndarray, shape (..., N, 2)
        Undistorted normalised image coordinates (x/z, y/z), unitless.
    dist : ndarray, shape (5,)
        ``(k1, k2, p1, p2, k3)``.

    Returns
    -------
    ndarray, shape (..., N, 2)
        Distorted normalised coordinates.
    """
    k1, k2, p1, p2, k3 = dist
    x = xy[..., 0]
    y = xy[..., 1]
    r2 = x * x + y * y
    radial = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3))
    xd = x * radial + 2.0 * p1 * x * y + p2 * (r2 + 2.0 * x * x)
    yd = y * radial + p1 * (r2 + 2.0 * y * y) + 2.0 * p2 * x * y
    return np.stack([xd, yd], axis=-1)


def _fold_radius(dist: np.ndarray) -> float:
    """Smallest normalised radius r > 0 where d/dr [r (1 + k1 r^2 + k2 r^4 + k3 r^6)] <= 0, or inf."""
    k1, k2, _, _, k3 = dist
    r = np.linspace(0.0, 10.0, 20001)
    r2 = r * r
    slope = 1.0 + 3.0 * k1 * r2 + 5.0 * k2 * r2 * r2 + 7.0 * k3 * r2 * r2 * r2
    bad = np.nonzero(slope <= 0)[0]
    return float(r[bad[0]]) if bad.size else float(np.inf)


def _radial(r: np.ndarray, dist: np.ndarray) -> np.ndarray:
    k1, k2, _, _, k3 = dist
    r2 = r * r
    return r * (1.0 + r2 * (k1 + r2 * (k2 + r2 * k3)))


def distortion_problem(intrinsics: "CameraIntrinsics") -> str | None:
    """Why the lens distortion of ``intrinsics`` is implausible over the image (None where it is plausible).

    The rule, over the largest radius of the image's edge midpoints from the principal point (``r_edge``, in
    normalised coordinates of the distorted image):

    - the radial distortion ``r_d = r (1 + k1 r^2 + k2 r^4 + k3 r^6)`` stays monotonic up to ``r_edge``: a model
      that folds back inside the image maps two directions onto one pixel there (beyond the edge midpoints, in the
      image's corners, a real calibration may fold: Wildtrack's cameras C1 and C6 do);
    - the distortion (radial and tangential) moves the points at that radius by at most
      :data:`MAX_DISTORTION_FRACTION` of their undistorted radius, on 64 directions.

    Parameters
    ----------
    intrinsics : CameraIntrinsics

    Returns
    -------
    str or None
        One line: the coefficients and what is wrong.
    """
    d = intrinsics.dist
    if not np.any(d != 0):
        return None
    K, w, h = intrinsics.K, intrinsics.width_px, intrinsics.height_px
    mid = np.array([[0.0, K[1, 2]], [w - 1.0, K[1, 2]], [K[0, 2], 0.0], [K[0, 2], h - 1.0]])
    xy_d = (mid - K[:2, 2]) @ np.linalg.inv(K[:2, :2]).T
    r_edge = float(np.hypot(xy_d[:, 0], xy_d[:, 1]).max())
    coeffs = f"k1 k2 p1 p2 k3 = {' '.join(f'{v:g}' for v in d)}"
    r_fold = intrinsics.max_radius
    if np.isfinite(r_fold) and _radial(np.array(r_fold), d) <= r_edge:
        return (f"lens distortion ({coeffs}) folds back inside the image (the radial distortion stops increasing at "
                f"{_radial(np.array(r_fold), d):.3g} of the {r_edge:.3g} normalised radius of the image's edges): "
                "not a plausible calibration")
    # undistorted radius whose radial distortion reaches r_edge (bisection on the monotonic branch)
    lo, hi = 0.0, min(r_fold, 10.0 * r_edge + 10.0)
    if _radial(np.array(hi), d) < r_edge:
        return (f"lens distortion ({coeffs}) shrinks the image's edges to less than a tenth of their radius: "
                "not a plausible calibration")
    for _ in range(60):
        mid_r = 0.5 * (lo + hi)
        lo, hi = (mid_r, hi) if _radial(np.array(mid_r), d) < r_edge else (lo, mid_r)
    r_u = 0.5 * (lo + hi)
    a = np.linspace(0.0, 2.0 * np.pi, 64, endpoint=False)
    xy = r_u * np.stack([np.cos(a), np.sin(a)], axis=-1)
    moved = float(np.max(np.hypot(*(distort_normalized(xy, d) - xy).T)) / r_u)
    if moved > MAX_DISTORTION_FRACTION:
        return (f"lens distortion ({coeffs}) moves the image's edges by {moved:.0%} of their radius (at most "
                f"{MAX_DISTORTION_FRACTION:.0%} is plausible for this lens model): not a plausible calibration; "
                "are the coefficients of another model or in other units?")
    return None


def intrinsics_problem(intrinsics: "CameraIntrinsics") -> str | None:
    """Why ``intrinsics`` is not a plausible calibration of its image (None where it is): the principal point
    outside the image, pixels more than 3 times as tall as wide (or wide as tall), a horizontal field of view over
    170 degrees (``fx < 0.044 W``, not a pinhole lens) or under 0.5 degree (``fx > 115 W``: a focal length in other
    units than pixels), or an implausible lens distortion (:func:`distortion_problem`)."""
    K, w, h = intrinsics.K, intrinsics.width_px, intrinsics.height_px
    fx, fy, cx, cy = K[0, 0], K[1, 1], K[0, 2], K[1, 2]
    if not (-0.5 <= cx <= w - 0.5 and -0.5 <= cy <= h - 0.5):
        return f"principal point ({cx:.4g}, {cy:.4g}) px lies outside the {w}x{h} px image: not a plausible calibration"
    if not 1.0 / 3.0 <= fy / fx <= 3.0:
        return f"fy / fx = {fy / fx:.3g} (fx {fx:.4g}, fy {fy:.4g} px): pixels 3 times taller or wider than square"
    fov_deg = float(np.degrees(2.0 * np.arctan2(0.5 * w, fx)))
    if not 0.5 <= fov_deg <= 170.0:
        return (f"fx = {fx:.4g} px gives a {fov_deg:.3g} degree horizontal field of view over {w} px: not a pinhole "
                "lens's (is the focal length in millimetres or metres instead of pixels?)")
    return distortion_problem(intrinsics)


@dataclass(frozen=True)
class CameraIntrinsics:
    """Intrinsic parameters of a pinhole camera.

    Attributes
    ----------
    K : ndarray, shape (3, 3)
        Camera matrix [[fx, s, cx], [0, fy, cy], [0, 0, 1]] in pixels.
    dist : ndarray, shape (5,)
        OpenCV distortion ``(k1, k2, p1, p2, k3)``; zeros for an ideal pinhole.
    width_px, height_px : int
        Image size in pixels.
    """

    K: np.ndarray
    width_px: int
    height_px: int
    dist: np.ndarray = field(default_factory=lambda: np.zeros(5))

    def __post_init__(self) -> None:
        K = check_intrinsics_matrix(self.K, "K")
        d = np.asarray(self.dist, dtype=float).ravel()
        if d.size not in (4, 5):
            raise ValueError(f"dist must have 4 or 5 coefficients (k1 k2 p1 p2 [k3]), got {d.size}")
        if d.size == 4:
            d = np.append(d, 0.0)
        check_finite(d, "dist")
        if int(self.width_px) <= 0 or int(self.height_px) <= 0:
            raise ValueError(f"image size must be positive, got {self.width_px}x{self.height_px}")
        K.setflags(write=False)
        d.setflags(write=False)
        object.__setattr__(self, "K", K)
        object.__setattr__(self, "dist", d)
        object.__setattr__(self, "width_px", int(self.width_px))
        object.__setattr__(self, "height_px", int(self.height_px))
        object.__setattr__(self, "max_radius", _fold_radius(d))

    #: Largest undistorted normalised radius where the radial distortion is still
    #: monotonic (set in ``__post_init__``); points beyond it fold back into the
    #: image and are reported as NaN by :meth:`pixels_from_normalized`.
    max_radius: float = field(init=False, default=np.inf)

    @property
    def has_distortion(self) -> bool:
        """True if any distortion coefficient is non-zero."""
        return bool(np.any(self.dist != 0))

    def pixels_from_normalized(self, xy) -> np.ndarray:
        """Distort normalised coordinates (..., N, 2) and map them to pixels (..., N, 2)."""
        xy = np.asarray(xy, dtype=float)
        fold = None
        if self.has_distortion:
            if np.isfinite(self.max_radius):
                with np.errstate(invalid="ignore"):
                    fold = np.hypot(xy[..., 0], xy[..., 1]) > self.max_radius
            xy = distort_normalized(xy, self.dist)
        K = self.K
        u = K[0, 0] * xy[..., 0] + K[0, 1] * xy[..., 1] + K[0, 2]
        v = K[1, 1] * xy[..., 1] + K[1, 2]
        uv = np.stack([u, v], axis=-1)
        if fold is not None:
            uv[fold] = np.nan
        return uv

    def normalized_from_pixels(self, uv) -> np.ndarray:
        """Undistorted normalised coordinates (..., N, 2) of pixels (..., N, 2).

        Uses OpenCV's ``undistortPoints`` with termination criteria (iterative inversion of the distortion model,
        to 1e-12 or 100 iterations), after removing the skew ``K[0, 1]``, which OpenCV ignores.
        """
        uv = check_points(uv, 2, "uv")
        flat = uv.reshape(-1, 1, 2)
        if flat.shape[0] == 0:
            return uv.copy()
        K = self.K
        if K[0, 1] != 0:
            # OpenCV ignores the skew K[0, 1]: take it out of u first (u = fx x_d + s y_d + cx, y_d = (v - cy) / fy)
            flat = flat.copy()
            flat[..., 0] -= K[0, 1] * (flat[..., 1] - K[1, 2]) / K[1, 1]
            K = K.copy()
            K[0, 1] = 0.0
        if self.has_distortion:
            crit = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 100, 1e-12)
            if hasattr(cv2, "undistortPointsIter"):  # OpenCV 4.x
                xy = cv2.undistortPointsIter(flat, K, self.dist, None, None, crit)
            else:  # OpenCV 5 folded the criteria into undistortPoints
                xy = cv2.undistortPoints(flat, K, self.dist, R=None, P=None, criteria=crit)
        else:
            xy = cv2.undistortPoints(flat, K, None)
        return xy.reshape(uv.shape)

    def undistort_pixels(self, uv) -> np.ndarray:
        """Pixels (..., N, 2) of the distorted image -> pixels of the ideal pinhole image with the same K."""
        xy = self.normalized_from_pixels(uv)
        h = np.concatenate([xy, np.ones(xy.shape[:-1] + (1,))], axis=-1)
        out = h @ self.K.T
        return out[..., :2]

    def contains(self, uv) -> np.ndarray:
        """Boolean mask (..., N): pixel inside [-0.5, W-0.5) x [-0.5, H-0.5) (NaN -> False)."""
        uv = np.asarray(uv, dtype=float)
        with np.errstate(invalid="ignore"):
            return (
                (uv[..., 0] >= -0.5)
                & (uv[..., 0] < self.width_px - 0.5)
                & (uv[..., 1] >= -0.5)
                & (uv[..., 1] < self.height_px - 0.5)
            )


@dataclass(frozen=True)
class PinholeCamera:
    """A calibrated camera placed in the world.

    Attributes
    ----------
    intrinsics : CameraIntrinsics
    T_world_cam : ndarray, shape (4, 4)
        Maps camera-frame coordinates [m] into the world frame {W}.
    name : str
        Identifier used in logs and errors.
    """

    intrinsics: CameraIntrinsics
    T_world_cam: np.ndarray
    name: str = "camera"

    def __post_init__(self) -> None:
        T = check_transform(self.T_world_cam, f"{self.name}.T_world_cam").copy()
        T.setflags(write=False)
        object.__setattr__(self, "T_world_cam", T)

    # -- derived quantities -------------------------------------------------
    @property
    def K(self) -> np.ndarray:
        """Camera matrix (3, 3) in pixels."""
        return self.intrinsics.K

    @property
    def T_cam_world(self) -> np.ndarray:
        """Maps world coordinates into the camera frame (4, 4)."""
        return invert_transform(self.T_world_cam)

    @property
    def R_world_cam(self) -> np.ndarray:
        """Rotation (3, 3) of the camera axes expressed in the world."""
        return self.T_world_cam[:3, :3].copy()

    @property
    def center_world(self) -> np.ndarray:
        """Optical centre in the world frame (3,) [m]."""
        return self.T_world_cam[:3, 3].copy()

    @property
    def P_image_world(self) -> np.ndarray:
        """Projection matrix (3, 4) ``K [R_cam_world | t_cam_world]`` for *undistorted* pixels."""
        return self.K @ self.T_cam_world[:3, :]

    # -- projection -----------------------------------------------------------
    def project(self, p_world) -> np.ndarray:
        """Project world points to (distorted) pixels.

        Parameters
        ----------
        p_world : array_like, shape (..., N, 3)
            Points in {W} [m].

        Returns
        -------
        ndarray, shape (..., N, 2)
            Pixel coordinates (u, v). Points at or behind the camera's principal
            plane (z_cam <= 0) are NaN: they have no image. So are points beyond
            the radius where the lens distortion model folds back
            (:attr:`CameraIntrinsics.max_radius`).
        """
        p = check_points(p_world, 3, "p_world")
        T = self.T_cam_world
        pc = p @ T[:3, :3].T + T[:3, 3]
        z = pc[..., 2]
        with np.errstate(divide="ignore", invalid="ignore"):
            xy = pc[..., :2] / z[..., None]
        uv = self.intrinsics.pixels_from_normalized(xy)
        uv[z <= 0] = np.nan
        return uv

    def rays(self, uv) -> np.ndarray:
        """Unit viewing directions in the world (..., N, 3) for pixels (..., N, 2).

        The rays start at :attr:`center_world`; lens distortion is removed first.
        """
        xy = self.intrinsics.normalized_from_pixels(uv)
        d_cam = np.concatenate([xy, np.ones(xy.shape[:-1] + (1,))], axis=-1)
        d_cam /= np.linalg.norm(d_cam, axis=-1, keepdims=True)
        return d_cam @ self.R_world_cam.T

    def backproject_to_height(self, uv, height_m: float) -> np.ndarray:
        """Intersect pixel rays with the horizontal plane z = ``height_m``.

        Returns
        -------
        ndarray, shape (..., N, 3)
            World points [m]. Rays that do not reach the plane in front of the
            camera (parallel, or pointing away from it) are NaN.
        """
        d = self.rays(uv)
        c = self.center_world
        with np.errstate(divide="ignore", invalid="ignore"):
            s = (height_m - c[2]) / d[..., 2]
        s = np.where(np.isfinite(s) & (s > 0), s, np.nan)
        return c + s[..., None] * d
