"""Tsai camera models (EPFL's calibration format) as :class:`~planefuse.geometry.PinholeCamera`.

Tsai's model (world in mm, ``X_cam = R X_world + T`` with ``R = Rz(rz) Ry(ry) Rx(rx)``)::

    (x_u, y_u) = f (X_cam / Z_cam, Y_cam / Z_cam)               undistorted sensor coordinates [mm]
    (x_u, y_u) = (x_d, y_d) (1 + kappa1 r_d^2)                  radial model, r_d^2 = x_d^2 + y_d^2 [mm^2]
    u = sx x_d / dpx + Cx,  v = y_d / dpy + Cy                  pixels of the calibrated image size

The radial model maps *distorted* to undistorted coordinates, OpenCV's the other way round, so
:func:`pinhole_from_tsai` fits OpenCV's ``(k1, k2, k3)`` to the inverse of Tsai's model over the image (the
residual is reported in :attr:`TsaiCamera.distortion_fit_px`). ``scale`` resizes the image (0.5: EPFL's
720 x 576 calibration for its 360 x 288 videos).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..geometry import CameraIntrinsics, PinholeCamera
from ..geometry._transforms import invert_transform

__all__ = ["TsaiParams", "TERRACE_TSAI", "pinhole_from_tsai", "terrace_cameras"]


@dataclass(frozen=True)
class TsaiParams:
    """One camera's Tsai parameters (EPFL ``calibration-*.txt`` / Tsai XML layout).

    Attributes
    ----------
    focal_mm, kappa1_per_mm2 : float
        Focal length [mm] and radial distortion [1/mm^2] (distorted -> undistorted, see module notes).
    cx_px, cy_px : float
        Principal point [px] of the calibrated image.
    rx_rad, ry_rad, rz_rad : float
        Euler angles, ``R_cam_world = Rz(rz) Ry(ry) Rx(rx)``.
    tx_mm, ty_mm, tz_mm : float
        ``T`` in ``X_cam = R X_world + T`` [mm].
    width_px, height_px : int
        Calibrated image size.
    dpx_mm, dpy_mm : float
        Sensor pixel pitch [mm].
    sx : float
        Horizontal scale factor.
    """

    focal_mm: float
    kappa1_per_mm2: float
    cx_px: float
    cy_px: float
    rx_rad: float
    ry_rad: float
    rz_rad: float
    tx_mm: float
    ty_mm: float
    tz_mm: float
    width_px: int = 720
    height_px: int = 576
    dpx_mm: float = 0.023
    dpy_mm: float = 0.023
    sx: float = 1.0

    def __post_init__(self) -> None:
        vals = np.array([getattr(self, f) for f in self.__dataclass_fields__], dtype=float)
        if not np.isfinite(vals).all():
            raise ValueError(f"TsaiParams has non-finite entries: {vals}")
        if self.focal_mm <= 0 or self.dpx_mm <= 0 or self.dpy_mm <= 0 or self.sx <= 0:
            raise ValueError("TsaiParams: focal_mm, dpx_mm, dpy_mm and sx must be > 0, got "
                             f"{self.focal_mm}, {self.dpx_mm}, {self.dpy_mm}, {self.sx}")

    @property
    def R_cam_world(self) -> np.ndarray:
        """``Rz(rz) Ry(ry) Rx(rx)`` (3, 3)."""
        def rot(axis: int, a: float) -> np.ndarray:
            c, s = np.cos(a), np.sin(a)
            i, j = [(1, 2), (2, 0), (0, 1)][axis]
            R = np.eye(3)
            R[i, i], R[i, j], R[j, i], R[j, j] = c, -s, s, c
            return R

        return rot(2, self.rz_rad) @ rot(1, self.ry_rad) @ rot(0, self.rx_rad)


#: EPFL terrace cameras c0..c3 (720 x 576 calibration; the values of ../shared/data/epfl_pom/SOURCE.md).
TERRACE_TSAI = (
    TsaiParams(20.161920, 5.720865e-4, 366.514507, 305.832552, 1.9007833770, 0.49730769727, 0.18415452559,
               -4844.1913843, 551.09448682, 4966.7438357),
    TsaiParams(19.529144, 5.184242e-4, 360.228130, 255.166919, 1.9347282363, -0.70418616982, -0.23783238362,
               -65.433635, 1594.811988, 2113.640844),
    TsaiParams(19.903218, 3.511557e-4, 355.506436, 241.205640, -1.8289537286, 0.37748154985, 3.0218614321,
               1978.2813424, -940.27627332, 12397.750058),
    TsaiParams(20.047015, 4.347668e-4, 349.154019, 245.786168, -1.8418460467, -0.46728290805, -3.0205552749,
               4673.7509054, -25.743341287, 8415.5952460),
)


def pinhole_from_tsai(p: TsaiParams, scale: float = 1.0, name: str = "camera") -> PinholeCamera:
    """A :class:`PinholeCamera` (world in metres, OpenCV distortion) equivalent to a Tsai camera.

    Parameters
    ----------
    p : TsaiParams
    scale : float
        Image resize factor (0.5 for EPFL's 360 x 288 videos of a 720 x 576 calibration); pixel centres map as
        ``u' = scale (u + 0.5) - 0.5``.
    name : str

    Returns
    -------
    PinholeCamera
        ``T_world_cam`` in metres; ``dist = (k1, k2, 0, 0, k3)`` least-squares fit of the inverse of Tsai's
        radial model over the image (about 0.01 px for EPFL's lenses).
    """
    if not scale > 0:
        raise ValueError(f"scale must be > 0, got {scale}")
    fx = p.focal_mm * p.sx / p.dpx_mm
    fy = p.focal_mm / p.dpy_mm
    # distorted normalised coordinates over the image -> undistorted by Tsai; fit x_d = x_u (1 + k1 r^2 + ...)
    u, v = np.meshgrid(np.linspace(0, p.width_px - 1, 40), np.linspace(0, p.height_px - 1, 32))
    xd = (u.ravel() - p.cx_px) / fx
    yd = (v.ravel() - p.cy_px) / fy
    factor = 1.0 + p.kappa1_per_mm2 * p.focal_mm ** 2 * (xd * xd + yd * yd)
    xu, yu = xd * factor, yd * factor
    r2 = xu * xu + yu * yu
    A = np.concatenate([np.c_[xu * r2, xu * r2 ** 2, xu * r2 ** 3], np.c_[yu * r2, yu * r2 ** 2, yu * r2 ** 3]])
    b = np.concatenate([xd - xu, yd - yu])
    k, *_ = np.linalg.lstsq(A, b, rcond=None)
    K = np.array([[scale * fx, 0.0, scale * (p.cx_px + 0.5) - 0.5],
                  [0.0, scale * fy, scale * (p.cy_px + 0.5) - 0.5], [0.0, 0.0, 1.0]])
    T_cam_world = np.eye(4)
    T_cam_world[:3, :3] = p.R_cam_world
    T_cam_world[:3, 3] = np.array([p.tx_mm, p.ty_mm, p.tz_mm]) * 1e-3
    intr = CameraIntrinsics(K, int(round(p.width_px * scale)), int(round(p.height_px * scale)),
                            np.array([k[0], k[1], 0.0, 0.0, k[2]]))
    return PinholeCamera(intr, invert_transform(T_cam_world), name)


def terrace_cameras(indices=(0, 1), scale: float = 0.5) -> list[PinholeCamera]:
    """The EPFL terrace cameras ``c<i>`` as :class:`PinholeCamera` (world = Tsai world in metres, z up)."""
    return [pinhole_from_tsai(TERRACE_TSAI[i], scale, f"c{i}") for i in indices]
