"""IMU attitude: ahrs/imufusion filters on synthetic motion and on real BROAD / x-io recordings; yaw from ground points."""

from __future__ import annotations

import h5py
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

from conftest import shared_data
from planefuse.geometry import (
    ATTITUDE_METHODS,
    CameraIntrinsics,
    PinholeCamera,
    R_world_cam_from_attitude,
    T_world_cam_look_at,
    attitude_from_imu,
    inclination_error_rad,
    yaw_from_ground_points,
)

G = 9.80665
BROAD_TRIALS = {"02": "02_undisturbed_slow_rotation_B.hdf5", "07": "07_undisturbed_fast_rotation_B.hdf5"}


def Rz(yaw):
    c, s = np.cos(yaw), np.sin(yaw)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def synthetic_imu(n=2000, fs_hz=100.0):
    """Body rocking about a tilted axis: exact gyro (body frame) and specific force R^T (0, 0, g)."""
    t = np.arange(n) / fs_hz
    angle = 0.5 * np.sin(2 * np.pi * 0.2 * t)  # rad
    axis = np.array([1.0, 0.4, 0.2]) / np.linalg.norm([1.0, 0.4, 0.2])
    R0 = Rotation.from_euler("xyz", [0.3, -0.2, 1.0])
    R_true = R0 * Rotation.from_rotvec(angle[:, None] * axis)
    omega_body = (2 * np.pi * 0.2 * 0.5 * np.cos(2 * np.pi * 0.2 * t))[:, None] * axis
    acc = R_true.inv().apply([0.0, 0.0, G])
    return t, omega_body, acc, R_true.as_matrix()


def read_broad(path):
    """BROAD trial -> time, gyro, accel, R_enu_imu (NaN rows kept), movement mask, count of NaN rows."""
    with h5py.File(path, "r") as f:
        fs_hz = float(f.attrs["sampling_rate"])
        gyr = f["imu_gyr"][:]
        acc = f["imu_acc"][:]
        q_wxyz = f["opt_quat"][:]
        movement = f["movement"][:].astype(bool)
    nan_rows = np.isnan(q_wxyz).any(axis=1)
    R_true = np.full((len(q_wxyz), 3, 3), np.nan)
    R_true[~nan_rows] = Rotation.from_quat(q_wxyz[~nan_rows][:, [1, 2, 3, 0]]).as_matrix()
    return np.arange(len(gyr)) / fs_hz, gyr, acc, R_true, movement, nan_rows


# --- synthetic --------------------------------------------------------------------
@pytest.mark.parametrize("method", ATTITUDE_METHODS)
def test_every_filter_tracks_synthetic_inclination(method):
    t, gyr, acc, R_true = synthetic_imu()
    R = attitude_from_imu(t, gyr, acc, method=method)
    err_deg = np.degrees(inclination_error_rad(R, R_true))
    assert R.shape == (len(t), 3, 3)
    if method != "imufusion":  # imufusion ramps its gain down over a start-up period instead
        assert err_deg[0] < 1e-6  # initialised from the accelerometer
    settled = t >= 3.0
    assert err_deg[settled].max() < 1.0, f"{method}: max inclination error {err_deg[settled].max():.3f} deg"


def test_camera_imu_extrinsic_is_applied(rng):
    t, gyr, acc, R_true = synthetic_imu(n=500)
    R_imu_cam = Rotation.random(random_state=1).as_matrix()
    R_imu = attitude_from_imu(t, gyr, acc)
    R_cam = attitude_from_imu(t, gyr, acc, R_imu_cam=R_imu_cam)
    np.testing.assert_allclose(R_cam, R_imu @ R_imu_cam, atol=1e-12)
    assert np.degrees(inclination_error_rad(R_cam, R_true @ R_imu_cam)).max() < 1.0


def test_irregular_time_steps_are_used():
    t, gyr, acc, R_true = synthetic_imu(n=1500)
    keep = np.ones(len(t), bool)
    keep[np.random.default_rng(0).choice(np.arange(1, len(t)), 300, replace=False)] = False
    R = attitude_from_imu(t[keep], gyr[keep], acc[keep])
    assert np.degrees(inclination_error_rad(R, R_true[keep])).max() < 1.0


# --- inclination error and yaw --------------------------------------------------
@settings(max_examples=50, deadline=None)
@given(yaw=st.floats(-np.pi, np.pi), seed=st.integers(0, 2**31 - 1))
def test_inclination_error_ignores_heading(yaw, seed):
    R = Rotation.random(random_state=seed).as_matrix()
    assert inclination_error_rad(Rz(yaw) @ R, R) < 1e-7


@settings(max_examples=50, deadline=None)
@given(tilt=st.floats(0.0, 3.0), seed=st.integers(0, 2**31 - 1))
def test_inclination_error_equals_tilt_about_horizontal_axis(tilt, seed):
    R = Rotation.random(random_state=seed).as_matrix()
    R_tilted = Rotation.from_rotvec([tilt, 0.0, 0.0]).as_matrix() @ R
    np.testing.assert_allclose(inclination_error_rad(R_tilted, R), tilt, atol=1e-7)


def ground_camera(rng):
    K = np.array([[800.0, 0.0, 640.0], [0.0, 790.0, 360.0], [0.0, 0.0, 1.0]])
    c = np.array([rng.uniform(-5, 5), rng.uniform(-5, 5), rng.uniform(2, 6)])
    T = T_world_cam_look_at(c, [rng.uniform(-2, 2), rng.uniform(-2, 2), 0.0])
    return PinholeCamera(CameraIntrinsics(K, 1280, 720), T)


def test_yaw_from_ground_points_recovers_heading(rng):
    for _ in range(20):
        cam = ground_camera(rng)
        yaw0 = rng.uniform(-np.pi, np.pi)
        R_gravity_cam = Rz(-yaw0) @ cam.R_world_cam  # filter frame rotated by -yaw0 about gravity
        uv = rng.uniform([0, 0], [1280, 720], size=(6, 2))
        xy = cam.backproject_to_height(uv, 0.0)[:, :2]
        ok = np.isfinite(xy).all(axis=1)
        if ok.sum() < 2:
            continue
        yaw = yaw_from_ground_points(cam.K, R_gravity_cam, cam.center_world, uv[ok], xy[ok])
        assert abs(np.angle(np.exp(1j * (yaw - yaw0)))) < 1e-9
        np.testing.assert_allclose(R_world_cam_from_attitude(R_gravity_cam, yaw), cam.R_world_cam, atol=1e-9)


def test_yaw_from_noisy_ground_points_is_least_squares(rng):
    cam = ground_camera(np.random.default_rng(3))
    R_gravity_cam = Rz(-0.7) @ cam.R_world_cam
    uv = np.array([[200.0, 600.0], [1000.0, 650.0], [640.0, 500.0], [300.0, 450.0], [900.0, 420.0]])
    xy = cam.backproject_to_height(uv, 0.0)[:, :2] + rng.normal(0, 0.02, (5, 2))  # 2 cm survey noise
    yaw = yaw_from_ground_points(cam.K, R_gravity_cam, cam.center_world, uv, xy)
    assert abs(yaw - 0.7) < np.radians(1.0)


def test_R_world_cam_from_attitude_batches():
    R = Rotation.random(4, random_state=2).as_matrix()
    yaw = np.array([0.1, -0.2, 3.0, 0.0])
    out = R_world_cam_from_attitude(R, yaw)
    for k in range(4):
        np.testing.assert_allclose(out[k], Rz(yaw[k]) @ R[k], atol=1e-15)


# --- bad input ---------------------------------------------------------------------
def test_attitude_bad_inputs_raise():
    t, gyr, acc, _ = synthetic_imu(n=20)
    t_back = t.copy()
    t_back[5] = t_back[4]
    with pytest.raises(ValueError, match="strictly increasing"):
        attitude_from_imu(t_back, gyr, acc)
    with pytest.raises(ValueError, match="gyro_rad_s must have shape"):
        attitude_from_imu(t, gyr[:-1], acc)
    with pytest.raises(ValueError, match=r"accel_m_s2 must have shape \(\.\.\., N, 3\)"):
        attitude_from_imu(t, gyr, acc[:, :2])
    acc_nan = acc.copy()
    acc_nan[3, 1] = np.nan
    with pytest.raises(ValueError, match="accel_m_s2 has 1 non-finite"):
        attitude_from_imu(t, gyr, acc_nan)
    with pytest.raises(ValueError, match="time_s has 1 non-finite"):
        attitude_from_imu(np.r_[t[:-1], np.nan], gyr, acc)
    with pytest.raises(ValueError, match="all-zero"):
        attitude_from_imu(t, gyr, np.zeros_like(acc))
    with pytest.raises(ValueError, match="method must be one of"):
        attitude_from_imu(t, gyr, acc, method="kalman")
    with pytest.raises(ValueError, match=r"params \['beta'\] unknown for method 'madgwick'"):
        attitude_from_imu(t, gyr, acc, method="madgwick", params={"beta": 0.1})
    with pytest.raises(ValueError, match="R_imu_cam"):
        attitude_from_imu(t, gyr, acc, R_imu_cam=2 * np.eye(3))


def test_yaw_bad_inputs_raise(rng):
    cam = ground_camera(rng)
    uv = np.array([[640.0, 700.0], [300.0, 650.0]])
    xy = cam.backproject_to_height(uv, 0.0)[:, :2]
    with pytest.raises(ValueError, match=">= 2 ground points"):
        yaw_from_ground_points(cam.K, cam.R_world_cam, cam.center_world, uv[:1], xy[:1])
    with pytest.raises(ValueError, match="same|shape"):
        yaw_from_ground_points(cam.K, cam.R_world_cam, cam.center_world, uv, xy[:1])
    with pytest.raises(ValueError, match="do not reach the ground"):
        R_up = cam.R_world_cam @ Rotation.from_rotvec([np.pi, 0, 0]).as_matrix()  # optical axis upwards
        yaw_from_ground_points(cam.K, R_up, cam.center_world, uv, xy)
    with pytest.raises(ValueError, match="above pi_ref"):
        yaw_from_ground_points(cam.K, cam.R_world_cam, [0.0, 0.0, -1.0], uv, xy)


# --- real data: BROAD (optical ground truth) ----------------------------------------
@pytest.mark.realdata
@pytest.mark.parametrize("trial", ["02", "07"])
def test_broad_inclination_rmse(trial, record_property):
    path = shared_data("imu_broad") / BROAD_TRIALS[trial]
    if not path.exists():
        pytest.skip(f"BROAD trial {trial} ({path.name}) is not in ../shared/data/imu_broad")
    t, gyr, acc, R_true, movement, nan_rows = read_broad(path)
    n_nan_total = int(nan_rows.sum())
    # The filter sees every IMU sample up to the end of the movement phase (the rest is never scored);
    # only the scoring needs the optical reference.
    stop = int(np.flatnonzero(movement)[-1]) + 1
    R = attitude_from_imu(t[:stop], gyr[:stop], acc[:stop])
    movement, nan_rows, R_true = movement[:stop], nan_rows[:stop], R_true[:stop]
    scored = movement & ~nan_rows
    err_deg = np.degrees(inclination_error_rad(R[scored], R_true[scored]))
    rmse_deg = float(np.sqrt(np.mean(err_deg**2)))
    print(
        f"\nBROAD trial {trial}: inclination RMSE {rmse_deg:.3f} deg, max {err_deg.max():.2f} deg over "
        f"{scored.sum()} movement samples; {n_nan_total} of {len(t)} ground-truth rows are NaN "
        f"({(movement & nan_rows).sum()} inside the movement phase, not scored)"
    )
    record_property(f"broad_{trial}_inclination_rmse_deg", rmse_deg)
    record_property(f"broad_{trial}_nan_gt_rows", n_nan_total)
    assert scored.sum() > 0.9 * movement.sum()
    if trial == "02":  # the goal for the default filter (chosen on simulated seeds and this trial's first half)
        assert rmse_deg <= 1.0


# --- real data: x-io Fusion example (no ground truth: agreement with imufusion) -----
@pytest.mark.realdata
def test_xio_inclination_agrees_with_imufusion(record_property):
    import imufusion

    data = np.genfromtxt(shared_data("imu_xio_fusion") / "sensor_data.csv", delimiter=",", skip_header=1)
    t, gyr_deg_s, acc_g = data[:, 0], data[:, 1:4], data[:, 4:7]
    n_nan = int((~np.isfinite(data[:, :7])).any(axis=1).sum())
    assert n_nan == 0, f"{n_nan} rows with NaN in the x-io log"
    R = attitude_from_imu(t, np.radians(gyr_deg_s), acc_g * G)
    # Independent reference: imufusion's AHRS with its default settings, driven as its own example does.
    ahrs = imufusion.Ahrs()
    dt = np.diff(t, prepend=t[0] - np.median(np.diff(t)))
    q_ref = np.empty((len(t), 4))
    for k in range(len(t)):
        ahrs.set_sample_period(float(dt[k]))
        ahrs.update_no_magnetometer(gyr_deg_s[k], acc_g[k])
        q_ref[k] = ahrs.get_quaternion()
    R_ref = Rotation.from_quat(q_ref[:, [1, 2, 3, 0]]).as_matrix()
    settled = t > 5.0  # both filters start from the first sample; compare after 5 s of convergence
    diff_deg = np.degrees(inclination_error_rad(R[settled], R_ref[settled]))
    rms_deg = float(np.sqrt(np.mean(diff_deg**2)))
    tilt_deg = np.degrees(np.arccos(np.clip(R_ref[settled][:, 2, 2], -1, 1)))
    # Where the device is still (|gyro| < 2 deg/s, |acc| within 2 % of 1 g) the accelerometer itself is gravity.
    still = settled & (np.linalg.norm(gyr_deg_s, axis=1) < 2.0) & (np.abs(np.linalg.norm(acc_g, axis=1) - 1) < 0.02)
    up_body = acc_g[still] / np.linalg.norm(acc_g[still], axis=1, keepdims=True)
    rest_deg = np.degrees(np.arccos(np.clip(np.einsum("nj,nj->n", R[still][:, 2, :], up_body), -1, 1)))
    print(
        f"\nx-io Fusion log: default filter vs imufusion.Ahrs inclination difference RMS {rms_deg:.3f} deg, "
        f"95th pct {np.percentile(diff_deg, 95):.3f} deg, max {diff_deg.max():.3f} deg "
        f"(tilt range of the recording {tilt_deg.min():.0f}-{tilt_deg.max():.0f} deg, {settled.sum()} samples); "
        f"at rest ({still.sum()} samples) vs the accelerometer: RMS {np.sqrt(np.mean(rest_deg**2)):.3f} deg"
    )
    record_property("xio_default_vs_imufusion_inclination_rms_deg", rms_deg)
    assert tilt_deg.max() > 20.0  # the recording really moves, so agreement is not trivial
    assert still.sum() > 1000
    assert rms_deg < 1.5
    assert np.sqrt(np.mean(rest_deg**2)) < 1.5
