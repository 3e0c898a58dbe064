"""Camera attitude relative to gravity from an IMU (accelerometer + gyroscope).

The recursive orientation filters come from the ``ahrs`` package (Mahony,
Madgwick, EKF) or from ``imufusion`` (x-io Fusion AHRS); planefuse only feeds
them, converts their quaternions and applies the camera-IMU extrinsic rotation.

Frames
------
{G}, the gravity frame of a filter: z points up (against gravity), x and y are
horizontal with an arbitrary heading (whatever the filter started from: without
a magnetometer, yaw about gravity is not observable). ``R_gravity_body`` maps
body-frame vectors into {G}; its last row is the "up" direction seen in the
body frame, which is all the inclination (roll and pitch) there is.
The world {W} differs from {G} by a rotation about z only,
``R_world_cam = Rz(yaw_rad) @ R_gravity_cam``; the yaw comes from calibration
(a known heading, or :func:`yaw_from_ground_points`).
"""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

from ._checks import check_finite, check_intrinsics_matrix, check_points, check_rotation

__all__ = [
    "ATTITUDE_METHODS",
    "DEFAULT_ATTITUDE_FILTER",
    "IMUFUSION_DEFAULTS",
    "attitude_from_imu",
    "inclination_error_rad",
    "still_samples",
    "R_world_cam_from_attitude",
    "yaw_from_ground_points",
]

#: Filters accepted by :func:`attitude_from_imu`; the first is the default. imufusion (x-io Fusion, C) with a
#: gain schedule (gain 0.5 while moving, 5 while still), its gyroscope offset tracking and its acceleration
#: rejection: it has the lowest mean inclination RMSE over the tuning sets of scripts/imu_filter_selection.py
#: (simulated fast rotations up to 10 and 25 rad/s, seeds 1-3; BROAD trial 02's first half) and holds on the
#: held-out ones (seeds 4-8: 0.70 and 1.47 deg; BROAD 02's second half: 0.46 deg); Madgwick, the former
#: default, 0.81 / 1.64 / 0.66 deg. Mahony's integral term winds up in fast rotation (x-io log: ~20 deg off at
#: rest afterwards). See docs/results.md.
ATTITUDE_METHODS = ("imufusion", "madgwick", "mahony", "ekf")
#: The default filter (method of :func:`attitude_from_imu`); its parameters' defaults are the selected ones.
DEFAULT_ATTITUDE_FILTER = ATTITUDE_METHODS[0]
#: Defaults of the imufusion parameters (see :func:`attitude_from_imu`).
IMUFUSION_DEFAULTS = {"gain": 0.5, "gyroscope_range_deg_s": 2000.0, "acceleration_rejection_deg": 10.0,
                      "rejection_timeout_s": 5.0, "gyro_bias": True, "rest_gain": 5.0}

_G_M_S2 = 9.80665

# Filter parameters each method accepts (ahrs' constructors swallow unknown keywords silently).
# "rest_gain" (with "rest_rate_rad_s", "rest_accel_tolerance") is planefuse's gain schedule around the library's
# filter: the gain while the IMU is still (:func:`still_samples`), the method's own gain while it moves.
_SCHEDULE = {"rest_gain", "rest_rate_rad_s", "rest_accel_tolerance"}
_PARAMS = {
    "madgwick": {"gain"} | _SCHEDULE,
    "mahony": {"k_P", "k_I"},
    "ekf": {"noises", "var_acc", "var_gyr", "P"},
    "imufusion": {"gain", "gyroscope_range_deg_s", "acceleration_rejection_deg", "rejection_timeout_s",
                  "gyro_bias"} | _SCHEDULE,
}


def still_samples(gyro_rad_s: np.ndarray, accel_m_s2: np.ndarray, rate_rad_s: float = 0.1,
                  accel_tolerance: float = 0.05) -> np.ndarray:
    """Samples (N,) bool where the IMU is still: ``|gyro| < rate_rad_s`` [rad/s] and ``|acc|`` within
    ``accel_tolerance`` (fraction) of 1 g, so that the accelerometer reads gravity alone."""
    return (np.linalg.norm(gyro_rad_s, axis=1) < rate_rad_s) \
        & (np.abs(np.linalg.norm(accel_m_s2, axis=1) / _G_M_S2 - 1.0) < accel_tolerance)


def _schedule(params: dict, gyr: np.ndarray, acc: np.ndarray, gain: float,
              rest_gain: float | None = None) -> np.ndarray | None:
    """Per-sample gain of the schedule (None without ``rest_gain``, or with 0); removes the schedule's keys
    from ``params``. ``rest_gain`` is the method's default."""
    rest_gain = params.pop("rest_gain", rest_gain)
    rate = float(params.pop("rest_rate_rad_s", 0.1))
    tol = float(params.pop("rest_accel_tolerance", 0.05))
    if not rest_gain:
        return None
    return np.where(still_samples(gyr, acc, rate, tol), float(rest_gain), gain)


def _check_imu_streams(time_s, gyro_rad_s, accel_m_s2) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    t = np.asarray(time_s, dtype=float)
    if t.ndim != 1 or t.size < 2:
        raise ValueError(f"time_s must have shape (N,) with N >= 2, got {t.shape}")
    check_finite(t, "time_s")
    dt = np.diff(t)
    if np.any(dt <= 0):
        k = int(np.flatnonzero(dt <= 0)[0])
        raise ValueError(
            f"time_s must be strictly increasing: time_s[{k + 1}]={t[k + 1]} s <= time_s[{k}]={t[k]} s"
        )
    gyr = check_points(gyro_rad_s, 3, "gyro_rad_s")
    acc = check_points(accel_m_s2, 3, "accel_m_s2")
    for name, a in (("gyro_rad_s", gyr), ("accel_m_s2", acc)):
        if a.shape != (t.size, 3):
            raise ValueError(f"{name} must have shape ({t.size}, 3) to match time_s, got {a.shape}")
    if np.any(np.linalg.norm(acc, axis=1) == 0):
        raise ValueError("accel_m_s2 has all-zero samples: gravity direction undefined")
    return t, gyr, acc


def _run_ahrs(method: str, dt: np.ndarray, gyr: np.ndarray, acc: np.ndarray, params: dict) -> np.ndarray:
    """Run an ``ahrs`` filter sample by sample (per-sample dt); quaternions [w, x, y, z] (N, 4)."""
    from ahrs.common.orientation import acc2q
    from ahrs.filters import EKF, Madgwick, Mahony

    fs_hz = 1.0 / float(np.median(dt))
    gains = _schedule(params, gyr, acc, float(params.get("gain", 0.033))) if method == "madgwick" else None
    if method == "mahony":
        flt = Mahony(frequency=fs_hz, **params)
        step = flt.updateIMU
    elif method == "madgwick":
        flt = Madgwick(frequency=fs_hz, **params)
        step = flt.updateIMU
    else:
        # ahrs' EKF compares the normalised accelerometer with a_ref = (0, 0, 1) when frame="NED" and with
        # (0, 0, -1) for "ENU"; the specific force at rest points up, so "NED" is the setting whose
        # quaternion maps the body into a z-up frame like the other filters (checked on BROAD: 0.65 deg vs 179 deg).
        flt = EKF(frequency=fs_hz, frame="NED", **params)

        def step(q, g, a, dt):
            return flt.update(q, g, a, dt=dt)

    Q = np.empty((gyr.shape[0], 4))
    Q[0] = acc2q(acc[0])
    # The filters are recursive: one update per sample is the algorithm (ahrs' own batch mode loops the same way).
    for k in range(1, gyr.shape[0]):
        if gains is not None:
            flt.gain = gains[k]
        Q[k] = step(Q[k - 1], gyr[k], acc[k], dt=dt[k - 1])
    return Q


def _run_imufusion(dt: np.ndarray, gyr: np.ndarray, acc: np.ndarray, params: dict) -> np.ndarray:
    """Run ``imufusion.Ahrs`` (NWU, z up) without magnetometer; quaternions [w, x, y, z] (N, 4)."""
    import imufusion
    from ahrs.common.orientation import acc2q

    settings = imufusion.AhrsSettings()
    settings.convention = imufusion.CONVENTION_NWU
    settings.sample_rate = 1.0 / float(np.median(dt))
    params = {**IMUFUSION_DEFAULTS, **params}
    settings.gain = float(params["gain"])
    settings.gyroscope_range = float(params["gyroscope_range_deg_s"])
    settings.acceleration_rejection = float(params["acceleration_rejection_deg"])
    settings.rejection_timeout = float(params["rejection_timeout_s"])
    gains = _schedule(params, gyr, acc, settings.gain)
    ahrs = imufusion.Ahrs()
    ahrs.set_settings(settings)
    # start level with the first sample's gravity, as the ahrs filters do, and skip imufusion's start-up
    # ramp: while it lasts (3 s), update_no_magnetometer pins the heading to 0, so a camera that pans then
    # is not followed
    ahrs.set_quaternion(acc2q(acc[0]))
    ahrs.skip_startup()
    gyr_deg_s = np.degrees(gyr)
    if params["gyro_bias"]:  # imufusion's own gyroscope offset tracking while still
        bias = imufusion.Bias()
        bias_settings = imufusion.BiasSettings()
        bias_settings.sample_rate = settings.sample_rate
        bias.set_settings(bias_settings)
        gyr_deg_s = np.array([bias.update(g) for g in gyr_deg_s])
    acc_g = acc / _G_M_S2
    dts = np.concatenate([[np.median(dt)], dt])
    Q = np.empty((gyr.shape[0], 4))
    for k in range(gyr.shape[0]):
        if gains is not None and (k == 0 or gains[k] != gains[k - 1]):
            settings.gain = float(gains[k])
            ahrs.set_settings(settings)
        ahrs.set_sample_period(float(dts[k]))
        ahrs.update_no_magnetometer(gyr_deg_s[k], acc_g[k])
        Q[k] = ahrs.get_quaternion()
    return Q


def attitude_from_imu(
    time_s,
    gyro_rad_s,
    accel_m_s2,
    *,
    method: str = DEFAULT_ATTITUDE_FILTER,
    R_imu_cam=None,
    params: dict | None = None,
) -> np.ndarray:
    """Attitude of a camera (or of the IMU itself) relative to gravity, per IMU sample.

    Parameters
    ----------
    time_s : array_like, shape (N,)
        Sample times [s], strictly increasing (steps may vary).
    gyro_rad_s : array_like, shape (N, 3)
        Angular rate in the IMU frame [rad/s].
    accel_m_s2 : array_like, shape (N, 3)
        Specific force in the IMU frame [m/s^2]; reads about +9.81 along the
        up axis at rest.
    method : {"imufusion", "madgwick", "mahony", "ekf"}
        Filter: ``ahrs.filters.Mahony`` / ``Madgwick`` / ``EKF``, or
        ``imufusion.Ahrs`` (gyro in deg/s and accel in g are converted here).
    R_imu_cam : array_like, shape (3, 3), optional
        Camera-IMU extrinsic rotation (maps camera-frame vectors into the IMU
        frame); identity (the IMU's own attitude) by default.
    params : dict, optional
        Filter parameters passed to the ``ahrs`` constructor (``gain`` for
        Madgwick; ``k_P``, ``k_I`` for Mahony; ``noises``, ``var_acc``,
        ``var_gyr``, ``P`` for the EKF); for ``imufusion`` (defaults
        :data:`IMUFUSION_DEFAULTS`): ``gain`` (0.5), ``gyroscope_range_deg_s``
        (2000), ``acceleration_rejection_deg`` (10), ``rejection_timeout_s``
        (5), 0 disables these three; ``gyro_bias`` (True): imufusion's
        gyroscope offset tracking while still. Madgwick and imufusion take a
        gain schedule: ``rest_gain`` (imufusion 5, Madgwick none; 0 = none),
        the gain while the IMU is still (:func:`still_samples` with
        ``rest_rate_rad_s``, default 0.1, and ``rest_accel_tolerance``,
        default 0.05), the method's gain otherwise.

    Returns
    -------
    ndarray, shape (N, 3, 3)
        ``R_gravity_cam[k] = R_gravity_imu[k] @ R_imu_cam``: camera axes in the
        gravity frame {G} (z up; heading arbitrary, see the module docstring).
        Every filter starts from the inclination of the first accelerometer
        sample (the heading of {G} is the first sample's).

    Raises
    ------
    ValueError
        Non-increasing or non-finite ``time_s``, mismatched shapes, NaN samples,
        an all-zero accelerometer sample, an unknown method or parameter, or a
        bad ``R_imu_cam``.
    """
    t, gyr, acc = _check_imu_streams(time_s, gyro_rad_s, accel_m_s2)
    R_ic = np.eye(3) if R_imu_cam is None else check_rotation(R_imu_cam, "R_imu_cam")
    if R_ic.shape != (3, 3):
        raise ValueError(f"R_imu_cam must have shape (3, 3), got {R_ic.shape}")
    if method not in ATTITUDE_METHODS:
        raise ValueError(f"method must be one of {ATTITUDE_METHODS}, got {method!r}")
    dt = np.diff(t)
    params = dict(params or {})
    unknown = set(params) - _PARAMS[method]
    if unknown:
        raise ValueError(f"params {sorted(unknown)} unknown for method {method!r}; accepted: {sorted(_PARAMS[method])}")
    if method == "imufusion":
        Q_wxyz = _run_imufusion(dt, gyr, acc, params)
    else:
        Q_wxyz = _run_ahrs(method, dt, gyr, acc, params)
    if not np.isfinite(Q_wxyz).all():
        raise ValueError(f"{method} filter diverged (non-finite quaternion); check the input units")
    R_gravity_imu = Rotation.from_quat(Q_wxyz[:, [1, 2, 3, 0]]).as_matrix()
    return R_gravity_imu @ R_ic


def inclination_error_rad(R_est, R_true) -> np.ndarray:
    """Angle between the gravity directions two attitudes imply in the body frame (yaw-free).

    Parameters
    ----------
    R_est, R_true : array_like, shape (..., 3, 3)
        ``R_gravity_body`` rotations (body -> a z-up frame); their headings may
        differ arbitrarily.

    Returns
    -------
    ndarray, shape (...)
        Inclination (roll/pitch) error [rad] in [0, pi].
    """
    A = check_rotation(R_est, "R_est")
    B = check_rotation(R_true, "R_true")
    up_a = A[..., 2, :]
    up_b = B[..., 2, :]
    cross = np.linalg.norm(np.cross(up_a, up_b), axis=-1)
    dot = np.sum(up_a * up_b, axis=-1)
    return np.arctan2(cross, dot)


def R_world_cam_from_attitude(R_gravity_cam, yaw_rad) -> np.ndarray:
    """Camera attitude in the world: ``R_world_cam = Rz(yaw_rad) @ R_gravity_cam`` (..., 3, 3).

    Parameters
    ----------
    R_gravity_cam : array_like, shape (..., 3, 3)
        Camera attitude relative to gravity (from :func:`attitude_from_imu`).
    yaw_rad : float or array_like, shape (...)
        Rotation about the vertical from the filter's gravity frame {G} to the
        world {W} [rad], from calibration (see :func:`yaw_from_ground_points`).
    """
    R = check_rotation(R_gravity_cam, "R_gravity_cam")
    yaw = np.asarray(yaw_rad, dtype=float)
    check_finite(yaw, "yaw_rad")
    c, s = np.cos(yaw), np.sin(yaw)
    Rz = np.zeros(yaw.shape + (3, 3))
    Rz[..., 0, 0] = c
    Rz[..., 0, 1] = -s
    Rz[..., 1, 0] = s
    Rz[..., 1, 1] = c
    Rz[..., 2, 2] = 1.0
    return Rz @ R


def yaw_from_ground_points(K, R_gravity_cam, camera_center_world, uv, xy_world) -> float:
    """Yaw about gravity from >= 2 ground points (z = 0) seen at known pixels.

    Each pixel's ray, rotated into the gravity frame with ``R_gravity_cam``,
    meets pi_ref at a horizontal offset ``p_k`` from the camera centre; the yaw
    is the rotation about z that best maps these offsets onto the known world
    offsets ``w_k = xy_world_k - c_xy`` (2-D orthogonal Procrustes, least squares):
    ``yaw = atan2(sum p_k x w_k, sum p_k . w_k)``.

    Parameters
    ----------
    K : array_like, shape (3, 3)
        Camera intrinsics [px]; ``uv`` must be undistorted pixels.
    R_gravity_cam : array_like, shape (3, 3)
        Camera attitude relative to gravity.
    camera_center_world : array_like, shape (3,)
        Optical centre in {W} [m], above pi_ref.
    uv : array_like, shape (N, 2)
        Undistorted pixels of the ground points, N >= 2.
    xy_world : array_like, shape (N, 2)
        Their world XY on z = 0 [m].

    Returns
    -------
    float
        ``yaw_rad`` such that ``R_world_cam = Rz(yaw_rad) @ R_gravity_cam``.

    Raises
    ------
    ValueError
        Fewer than 2 points, mismatched shapes, a pixel whose ray does not reach
        the ground in front of the camera, or a camera centre at/below z = 0.
    """
    Kc = check_intrinsics_matrix(K, "K")
    R = check_rotation(R_gravity_cam, "R_gravity_cam")
    if R.shape != (3, 3):
        raise ValueError(f"R_gravity_cam must have shape (3, 3), got {R.shape}")
    c = np.asarray(camera_center_world, dtype=float)
    if c.shape != (3,):
        raise ValueError(f"camera_center_world must have shape (3,), got {c.shape}")
    check_finite(c, "camera_center_world")
    if c[2] <= 0:
        raise ValueError(f"camera_center_world z={c[2]} m must be above pi_ref (z=0)")
    px = check_points(uv, 2, "uv")
    xy = check_points(xy_world, 2, "xy_world")
    if px.ndim != 2 or xy.shape != px.shape:
        raise ValueError(f"uv and xy_world must both have shape (N, 2), got {px.shape} and {xy.shape}")
    if px.shape[0] < 2:
        raise ValueError(f"yaw needs >= 2 ground points, got {px.shape[0]}")
    d = np.c_[px, np.ones(len(px))] @ np.linalg.inv(Kc).T @ R.T
    down = d[:, 2] < -1e-12
    if not down.all():
        raise ValueError(f"rays of uv rows {np.flatnonzero(~down).tolist()} do not reach the ground z=0")
    p = d[:, :2] * (-c[2] / d[:, 2])[:, None]
    w = xy - c[:2]
    cross = np.sum(p[:, 0] * w[:, 1] - p[:, 1] * w[:, 0])
    dot = np.sum(p * w)
    return float(np.arctan2(cross, dot))
