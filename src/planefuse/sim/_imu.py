"""Inertial measurements of a camera-mounted IMU, static or turning: gravity, rotation rate, building vibration,
bias and noise."""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

from ..io import ImuData
from ._config import ImuSpec

__all__ = ["R_cam_imu", "T_cam_imu", "simulate_imu", "simulate_rotating_imu", "simulate_static_imu"]

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


def simulate_rotating_imu(times_s, spec: ImuSpec, rng: np.random.Generator, *, max_rate_rad_s: float = 10.0,
                          lever_arm_m=(0.0, 0.0, 0.0), rest_s: tuple[float, float] = (0.5, 2.0),
                          move_s: tuple[float, float] = (0.5, 2.0), gyro_scale_error: float = 0.0,
                          substeps: int = 10
                          ) -> tuple[ImuData, np.ndarray]:
    """An IMU turned by hand: fast rotations about changing axes between short rests, with ground truth.

    The body rate alternates rests (zero rate, ``rest_s`` seconds, uniform) and moves (``move_s`` seconds):
    during a move ``omega_imu(t) = peak sin^2(pi s) a(s)``, ``s`` the fraction of the move done, ``peak``
    uniform in [0.3, 1] x ``max_rate_rad_s``, ``a(s)`` the unit vector between two random axes (IMU frame).
    The attitude is this rate integrated exactly over ``substeps`` steps per sample (rate held per
    substep), from a random inclination of up to 60 deg. The IMU sits ``lever_arm_m`` (IMU frame) from the
    point it turns about (a hand, a pan-tilt head), so the accelerometer also reads
    ``alpha x r + omega x (omega x r)``; gravity, vibration, biases and noise as :func:`simulate_imu`. The
    gyroscope's per-axis scale factors are off by ``gyro_scale_error`` (std, fraction): at fast rotation
    this, not the noise, is what a real MEMS gyroscope gets most wrong (1 % of a turn is 3.6 deg).

    Parameters
    ----------
    times_s : array_like, shape (N,)
        Sample times [s], increasing.
    spec : ImuSpec
    rng : numpy.random.Generator
    max_rate_rad_s : float
        Largest peak rate of a move [rad/s].
    lever_arm_m : array_like, shape (3,)
        IMU position relative to the centre of rotation, IMU frame [m].
    rest_s, move_s : (float, float)
        Ranges of the rests' and moves' durations [s].
    gyro_scale_error : float
        Standard deviation of the gyroscope's per-axis scale-factor error (0.01 = 1 %).
    substeps : int
        Integration substeps per sample.

    Returns
    -------
    (ImuData, ndarray (N, 3, 3))
        The samples and the true ``R_world_imu`` (world z up) at each.
    """
    t = np.asarray(times_s, dtype=float)
    if t.ndim != 1 or t.size < 2 or np.any(np.diff(t) <= 0):
        raise ValueError(f"times_s must be increasing with shape (N,), N >= 2, got shape {t.shape}")
    r = np.asarray(lever_arm_m, dtype=float)
    if r.shape != (3,):
        raise ValueError(f"lever_arm_m must have shape (3,), got {r.shape}")
    # fine time grid: every sample and `substeps` points between consecutive samples
    frac = np.arange(substeps) / substeps
    fine = np.concatenate([(t[:-1, None] + np.diff(t)[:, None] * frac).ravel(), t[-1:]])
    omega = np.zeros((fine.size, 3))
    s0 = t[0] + rng.uniform(*rest_s)
    while s0 < t[-1]:
        d = rng.uniform(*move_s)
        a0, a1 = rng.normal(size=(2, 3))
        inside = (fine >= s0) & (fine < s0 + d)
        s = (fine[inside] - s0) / d
        axis = a0[None] * (1 - s[:, None]) + a1[None] * s[:, None]
        axis /= np.linalg.norm(axis, axis=1, keepdims=True)
        omega[inside] = (rng.uniform(0.3, 1.0) * max_rate_rad_s * np.sin(np.pi * s) ** 2)[:, None] * axis
        s0 += d + rng.uniform(*rest_s)
    tilt = Rotation.from_rotvec(np.r_[rng.normal(size=2), 0.0] / np.sqrt(2) * np.radians(rng.uniform(0, 60)))
    R = np.empty((fine.size, 3, 3))
    R[0] = (tilt * Rotation.from_euler("z", rng.uniform(-np.pi, np.pi))).as_matrix()
    steps = Rotation.from_rotvec(omega[:-1] * np.diff(fine)[:, None]).as_matrix()
    for k in range(fine.size - 1):  # R_{k+1} = R_k exp(omega_k dt): the body rate, held over the substep
        R[k + 1] = R[k] @ steps[k]
    keep = np.arange(t.size) * substeps
    alpha = np.gradient(omega, fine, axis=0)
    w = omega[keep]
    lever = np.cross(alpha[keep], r) + np.cross(w, np.cross(w, r))
    data = simulate_imu(R[keep], t, spec, rng, w)
    gyro = data.gyro_rad_s + w * rng.normal(0.0, gyro_scale_error, size=3)
    return ImuData(t, gyro, data.accel_m_s2 + lever), R[keep]
