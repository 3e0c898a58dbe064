"""Inertial measurements of a camera-mounted IMU, static or turning: gravity, rotation rate, building vibration,
bias and noise."""

from __future__ import annotations

import numpy as np

from ..io import ImuData
from ._config import ImuSpec

__all__ = ["R_cam_imu", "T_cam_imu", "simulate_imu", "simulate_static_imu"]

#: IMU axes in the camera frame: x_imu = optical axis (z_cam), y_imu = left (-x_cam), z_imu = image up (-y_cam).
R_cam_imu = np.array([[0.0, -1.0, 0.0], [0.0, 0.0, -1.0], [1.0, 0.0, 0.0]])
R_cam_imu.setflags(write=False)


def T_cam_imu() -> np.ndarray:
    """``T_cam_imu`` (4, 4): the IMU sits at the camera centre with axes :data:`R_cam_imu`."""
    T = np.eye(4)
    T[:3, :3] = R_cam_imu
    return T


def simulate_static_imu(R_world_imu, times_s, spec: ImuSpec, rng: np.random.Generator) -> ImuData:
    """Accelerometer and gyroscope samples of an IMU that does not rotate (:func:`simulate_imu` at rest)."""
    R = np.asarray(R_world_imu, dtype=float)
    if R.shape != (3, 3):
        raise ValueError(f"R_world_imu must have shape (3, 3), got {R.shape}")
    return simulate_imu(R, times_s, spec, rng)


def simulate_imu(R_world_imu, times_s, spec: ImuSpec, rng: np.random.Generator, omega_imu_rad_s=None) -> ImuData:
    """Accelerometer and gyroscope samples of an IMU turning about its own centre.

    The accelerometer measures specific force ``f = a - g`` in the IMU frame: ``R_world_imu(t)^T (0, 0, g)``
    plus a small vertical building vibration, a constant per-axis bias and white noise (the IMU turns about
    its centre: no linear acceleration); the gyroscope measures the body rate ``omega_imu_rad_s`` plus bias
    and noise.

    Parameters
    ----------
    R_world_imu : array_like, shape (3, 3) or (N, 3, 3)
        Attitude of the IMU in the world (z up against gravity), fixed or per sample.
    times_s : array_like, shape (N,)
        Sample times [s].
    spec : ImuSpec
        Noise, bias and vibration figures.
    rng : numpy.random.Generator
    omega_imu_rad_s : array_like, shape (N, 3), optional
        True angular rate in the IMU frame [rad/s]; zero when None.

    Returns
    -------
    ImuData
        ``gyro_rad_s`` (N, 3) and ``accel_m_s2`` (N, 3) in the IMU frame.
    """
    R = np.asarray(R_world_imu, dtype=float)
    t = np.asarray(times_s, dtype=float)
    n = len(t)
    if R.shape not in ((3, 3), (n, 3, 3)):
        raise ValueError(f"R_world_imu must have shape (3, 3) or ({n}, 3, 3), got {R.shape}")
    f_world = np.zeros((n, 3))
    f_world[:, 2] = spec.gravity_m_s2
    f_world[:, 2] += spec.vibration_m_s2 * np.sin(2 * np.pi * spec.vibration_hz * t + rng.uniform(0, 2 * np.pi))
    accel = f_world @ R if R.ndim == 2 else np.einsum("nij,ni->nj", R, f_world)  # rows: R^T f
    accel += rng.normal(0.0, spec.accel_bias_m_s2, size=3) + rng.normal(0.0, spec.accel_noise_m_s2, size=(n, 3))
    gyro = rng.normal(0.0, spec.gyro_bias_rad_s, size=3) + rng.normal(0.0, spec.gyro_noise_rad_s, size=(n, 3))
    if omega_imu_rad_s is not None:
        w = np.asarray(omega_imu_rad_s, dtype=float)
        if w.shape != (n, 3):
            raise ValueError(f"omega_imu_rad_s must have shape ({n}, 3), got {w.shape}")
        gyro = gyro + w
    return ImuData(t, gyro, accel)
