"""Cameras registered through their IMU (registration.CameraRegistration): the ``imu`` route against the
``calibration`` route on simulated scenes whose cameras stay still, are bumped, sway; the simulator's moving
cameras (frames and IMU from one attitude); the registration error measure."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from planefuse.geometry import attitude_from_imu, inclination_error_rad
from planefuse.pipeline import SystemParams, run_system, stack_for_recording
from planefuse.registration import CameraRegistration, RegistrationParams, ground_reprojection_error_m
from planefuse.sim import (CameraMotionSpec, ImuSpec, R_world_cam_at, default_scene_config, omega_cam_rad_s_at,
                           simulate, simulate_rotating_imu)

BUMP = CameraMotionSpec(kind="bump", amplitude_deg=3.0, start_s=5.0)


def scene(duration_s: float, seed: int, motions=None, **kw):
    """Default scene without laser and head; camera 0 moves as ``motions`` says."""
    cfg = default_scene_config(duration_s=duration_s, seed=seed, laser=None, head=None, **kw)
    if motions:
        cams = list(cfg.cameras)
        cams[0] = cams[0].model_copy(update={"motion": list(motions)})
        cfg = cfg.model_copy(update={"cameras": cams})
    return cfg, simulate(cfg)


def with_source(params: SystemParams, source: str) -> SystemParams:
    cp = params.camera_params
    return replace(params, camera_params=replace(cp, registration=replace(cp.registration, attitude_source=source)))


@pytest.fixture(scope="module")
def bumped():
    """8 s, camera 0 tilted by 3 deg at t = 5 s (0.1 s rise) and left there; its registration followed
    through every frame with the default IMU filter."""
    cfg, rec = scene(8.0, seed=11, motions=[BUMP])
    stack = stack_for_recording(rec, SystemParams())
    reg = CameraRegistration.from_recording(rec, stack, RegistrationParams(attitude_source="imu"))
    times = rec.camera(rec.cameras[0].name).times_s
    reg.lookups_at(float(times[0]))
    used = []
    for t in times:
        reg.advance([float(t)])
        used.append(reg.lookup_attitudes[0])
    return cfg, rec, stack, reg, times, np.array(used)


def test_bump_breaks_the_calibration_route_not_the_imu_route(bumped):
    """Registration error = where each route puts the true feet the camera sees (projected with the true
    attitude, taken back to the ground with the route's), in cells: it jumps at the bump and stays for the
    fixed calibration; it stays below half a cell through the IMU."""
    cfg, rec, stack, _, times, used = bumped
    cam, gt = rec.cameras[0], rec.groundtruth.people
    R_true = R_world_cam_at(cam.R_world_cam, cfg.cameras[0].motion, times)
    err = {"calibration": [], "imu": []}
    for k, t in enumerate(times):
        xy = gt.xy_m[gt.index_at(t)]
        for route, R in (("calibration", cam.R_world_cam), ("imu", used[k])):
            e = ground_reprojection_error_m(cam.center_world, R_true[k], R, xy)
            err[route].append(np.nanmedian(e) / stack.cell_size_m)
    calib, imu = np.array(err["calibration"]), np.array(err["imu"])
    before, after = times < 5.0, times > 5.0 + BUMP.duration_s + 0.05
    assert calib[before].max() < 1e-9  # the calibration is the truth until the bump
    assert calib[after].min() > 3.0  # jumps by several cells and stays there
    assert imu[before].max() < 0.5 and imu[after].max() < 0.5
    assert np.median(imu[after]) < 0.1 * np.median(calib[after])


def test_lookups_rebuilt_only_after_real_motion(bumped):
    _, rec, _, reg, _, _ = bumped
    # the still cameras are never rebuilt over 8 s (IMU noise, bias and vibration stay below the tolerance)
    assert reg.n_rebuilds[1:] == [0, 0, 0]
    # the bumped one only while it turns (a 3 deg tilt moves pixels by ~10 px: a few rebuilds of 1 px each
    # would show; the rise lasts 0.1 s = 2-3 frames at 25 Hz)
    times = np.array(reg.rebuild_times_s[0])
    assert 1 <= len(times) <= 4
    assert np.all((times >= BUMP.start_s) & (times <= BUMP.start_s + BUMP.duration_s + 0.1))


def test_swaying_camera_rebuilds_scale_with_the_tolerance():
    """A 1 deg sway: a tighter tolerance costs more rebuilds, and the attitude each lookup uses stays within
    the tolerance of the IMU attitude at every frame (the error it allows is bounded by it)."""
    sway = CameraMotionSpec(kind="sway", amplitude_deg=1.0, period_s=2.0, start_s=1.0)
    _, rec = scene(4.0, seed=12, motions=[sway])
    stack = stack_for_recording(rec, SystemParams())
    times = rec.camera(rec.cameras[0].name).times_s
    counts = {}
    for tol in (0.5, 2.0):
        reg = CameraRegistration.from_recording(rec, stack, RegistrationParams(attitude_source="imu",
                                                                                tolerance_px=tol))
        reg.lookups_at(float(times[0]))
        from planefuse.registration import pixel_shift_px
        cam = rec.cameras[0]
        for t in times[1:]:
            reg.advance([float(t)])
            shift = pixel_shift_px(cam.K, reg.lookup_attitudes[0], reg.attitude_at(0, float(t)),
                                   cam.intrinsics.width_px, cam.intrinsics.height_px)
            assert shift <= tol + 1e-9
        counts[tol] = reg.n_rebuilds
    assert counts[0.5][0] > counts[2.0][0] > 0
    assert counts[2.0][1:] == [0, 0, 0]


def test_imu_route_reproduces_calibration_detections_on_a_still_scene():
    """Still cameras: the IMU route registers exactly as the calibration (the mount is refined at the
    calibration's moment and no lookup is rebuilt), so the cameras find the same people at every step."""
    _, rec = scene(2.5, seed=13)
    base = SystemParams(laser=False, sound=False)
    base = replace(base, camera_params=replace(base.camera_params, max_rate_hz=None))  # every frame
    res = {src: run_system(rec, with_source(base, src)) for src in ("calibration", "imu")}
    assert res["imu"].report.camera_registration.n_rebuilds == [0, 0, 0, 0]
    cal, imu = res["calibration"].report.camera_detections, res["imu"].report.camera_detections
    assert len(cal) == len(imu) > 50
    assert sum(len(d.xy_m) for d in cal) > 0
    for a, b in zip(cal, imu):
        np.testing.assert_allclose(b.xy_m, a.xy_m, atol=1e-9)
    for a, b in zip(res["calibration"].outputs, res["imu"].outputs):
        np.testing.assert_allclose(b.detections.xy_m, a.detections.xy_m, atol=1e-9)


def test_ground_reprojection_error_analytic():
    """A camera 3 m up: a point at ground distance d is seen under depression atan(3/d); a registration
    that believes the camera pitched further down by delta puts it at 3 / tan(atan(3/d) + delta)."""
    h, d, delta = 3.0, 6.0, np.radians(2.0)
    # camera x = world +x, optical axis along world +y pitched 30 deg down
    R0 = Rotation.from_euler("x", -90 - 30, degrees=True).as_matrix()
    R_used = Rotation.from_rotvec(R0[:, 0] * -delta).as_matrix() @ R0  # pitched down by delta more
    c = np.array([0.0, 0.0, h])
    e = ground_reprojection_error_m(c, R0, R_used, [[0.0, d]])
    dep = np.arctan2(h, d)
    assert e[0] == pytest.approx(d - h / np.tan(dep + delta), rel=1e-9)
    assert ground_reprojection_error_m(c, R0, R0, [[0.0, d], [1.0, 4.0]]) == pytest.approx([0.0, 0.0], abs=1e-12)
    assert np.isnan(ground_reprojection_error_m(c, R0, R0, [[0.0, -d]])[0])  # behind the camera


def test_moving_camera_imu_matches_its_attitude():
    """The simulated IMU of a panning, bumped camera (noise-free) integrates to the attitude that renders its
    frames, and its accelerometer is gravity in that attitude."""
    motions = [CameraMotionSpec(kind="pan", amplitude_deg=20.0, period_s=3.0, start_s=0.5), BUMP]
    quiet = ImuSpec(gyro_noise_rad_s=0, accel_noise_m_s2=0, gyro_bias_rad_s=0, accel_bias_m_s2=0, vibration_m_s2=0)
    cfg, rec = scene(6.0, seed=14, motions=motions, imu=quiet)
    cam = rec.cameras[0]
    imu = rec.imu_for(cam.name)
    d = imu.read()
    R_cam_imu = np.asarray(imu.T_cam_imu)[:3, :3]
    R_true = R_world_cam_at(cam.R_world_cam, motions, d.times_s) @ R_cam_imu  # R_world_imu
    R = R_true[0].copy()
    for k in range(1, len(d)):  # midpoint integration of the body rate
        w = 0.5 * (d.gyro_rad_s[k - 1] + d.gyro_rad_s[k])
        R = R @ Rotation.from_rotvec(w * (d.times_s[k] - d.times_s[k - 1])).as_matrix()
    assert np.degrees(Rotation.from_matrix(R.T @ R_true[-1]).magnitude()) < 0.05
    np.testing.assert_allclose(d.accel_m_s2, np.einsum("nji,j->ni", R_true, [0, 0, 9.81]), atol=1e-9)
    w_cam = omega_cam_rad_s_at(cam.R_world_cam, motions, d.times_s)
    np.testing.assert_allclose(d.gyro_rad_s, w_cam @ R_cam_imu, atol=1e-6)


def test_simulated_fast_rotation_is_consistent():
    """simulate_rotating_imu without noise: gyro integrates to the returned attitude, the accelerometer is
    gravity plus the lever arm's centripetal and tangential terms, and at rest gravity alone."""
    quiet = ImuSpec(gyro_noise_rad_s=0, accel_noise_m_s2=0, gyro_bias_rad_s=0, accel_bias_m_s2=0, vibration_m_s2=0)
    t = np.arange(0.0, 10.0, 1 / 200)
    d, R = simulate_rotating_imu(t, quiet, np.random.default_rng(0), max_rate_rad_s=10.0, lever_arm_m=(0.05, 0, 0))
    assert np.linalg.norm(d.gyro_rad_s, axis=1).max() > 3.0  # it does move fast
    Ri = R[0].copy()
    for k in range(1, len(t)):
        Ri = Ri @ Rotation.from_rotvec(0.5 * (d.gyro_rad_s[k - 1] + d.gyro_rad_s[k]) / 200).as_matrix()
    assert np.degrees(Rotation.from_matrix(Ri.T @ R[-1]).magnitude()) < 0.5
    still = np.linalg.norm(d.gyro_rad_s, axis=1) == 0
    assert still.sum() > 100
    # (atol: at the first sample of a move the rate is still 0 but the angular acceleration not quite)
    np.testing.assert_allclose(d.accel_m_s2[still], np.einsum("nji,j->ni", R[still], [0, 0, 9.81]), atol=1e-4)
    # the default filter follows it (the accuracy table is docs/results.md, scripts/imu_filter_selection.py)
    est = attitude_from_imu(t, d.gyro_rad_s, d.accel_m_s2)
    assert np.degrees(inclination_error_rad(est[t > 2], R[t > 2])).max() < 5.0


# --- IMU streams validated like every other stream ----------------------------------------------------------
def _imu_route(rec):
    stack = stack_for_recording(rec, SystemParams())
    return CameraRegistration.from_recording(rec, stack, RegistrationParams(attitude_source="imu"))


def _edit_imu(rec, edit):
    """Replace camera 0's IMU samples by ``edit(times_s, gyro, accel)`` (in memory)."""
    from planefuse.io import ImuData

    imu = rec.imu_for(rec.cameras[0].name)
    d = imu.data
    imu.data = ImuData(*edit(d.times_s.copy(), d.gyro_rad_s.copy(), d.accel_m_s2.copy()))
    imu.n_samples = len(imu.data)
    return imu


def test_imu_time_order_and_nan_are_clear_errors_in_memory():
    _, rec = scene(2.0, seed=15)

    def swap(t, g, a):
        t[[100, 101]] = t[[101, 100]]
        return t, g, a

    imu = _edit_imu(rec, swap)
    with pytest.raises(ValueError, match=rf"imu '{imu.name}': time_s\[101\]: .* goes backwards"):
        _imu_route(rec)
    _, rec = scene(2.0, seed=15)

    def nan_accel(t, g, a):
        a[250, 2] = np.nan
        return t, g, a

    imu = _edit_imu(rec, nan_accel)
    with pytest.raises(ValueError, match=rf"imu '{imu.name}': sample 250: accel_m_s2 is not finite"):
        _imu_route(rec)
    # the calibration route does not read the IMU; `planefuse check` and the imu route do
    stack = stack_for_recording(rec, SystemParams())
    CameraRegistration.from_recording(rec, stack, RegistrationParams(attitude_source="calibration"))


def test_imu_errors_name_the_file_and_line(tmp_path):
    from planefuse.io import read_recording, write_recording

    _, rec = scene(1.0, seed=16)
    write_recording(rec, tmp_path / "rec")
    name = rec.imu_for(rec.cameras[0].name).name
    path = tmp_path / "rec" / "imu" / f"{name}.csv"
    lines = path.read_text().splitlines(keepends=True)
    good = list(lines)
    lines[11], lines[12] = lines[12], lines[11]  # file lines 12 and 13 swapped
    path.write_text("".join(lines))
    with pytest.raises(ValueError, match=rf"{name}\.csv: line 13: time_s .* goes backwards"):
        _imu_route(read_recording(tmp_path / "rec"))
    fields = good[20].rstrip("\n").split(",")
    fields[5] = "nan"  # accel_y of file line 21
    good[20] = ",".join(fields) + "\n"
    path.write_text("".join(good))
    with pytest.raises(ValueError, match=rf"{name}\.csv: line 21: accel_m_s2 is not finite"):
        _imu_route(read_recording(tmp_path / "rec"))
    # the whole system stops with the same one-line error, before any frame is processed
    with pytest.raises(ValueError, match=rf"{name}\.csv: line 21"):
        run_system(read_recording(tmp_path / "rec"), with_source(SystemParams(laser=False, sound=False), "imu"))


def test_imu_gaps_are_counted_and_reported():
    _, rec = scene(3.0, seed=17)

    def drop(t, g, a):
        keep = np.ones(len(t), bool)
        keep[200:240] = False  # 0.2 s at 200 Hz
        keep[400:405] = False
        return t[keep], g[keep], a[keep]

    imu = _edit_imu(rec, drop)
    with pytest.warns(UserWarning, match=rf"{imu.name}: 2 gaps in the IMU stream \(45 samples missing, longest 0.2"):
        reg = _imu_route(rec)
    assert [g.missing for g in reg.imu_gaps[rec.cameras[0].name]] == [40, 5]
    assert all(not v for k, v in reg.imu_gaps.items() if k != rec.cameras[0].name)


def test_stabilising_map_points_to_where_the_turned_camera_sees_each_point():
    """OpenCV projection as the reference: a ground point's pixel in the calibrated view maps to its pixel
    in the image of the turned camera (lens distortion included)."""
    import cv2

    _, rec = scene(1.0, seed=18)
    stack = stack_for_recording(rec, SystemParams())
    reg = CameraRegistration.from_recording(rec, stack, RegistrationParams(attitude_source="imu"))
    reg.lookups_at(0.0)
    cam = rec.cameras[1]
    R = Rotation.from_rotvec([0.01, -0.03, 0.02]).as_matrix() @ cam.R_world_cam
    map_u, map_v, _ = reg._stabilising_map(1, R)
    rng = np.random.default_rng(0)
    p = np.c_[rng.uniform(1, 9, (200, 2)), np.zeros(200)]
    dist = cam.intrinsics.dist
    u0 = cv2.projectPoints(p, cv2.Rodrigues(cam.R_world_cam.T)[0], -cam.R_world_cam.T @ cam.center_world,
                           cam.K, dist)[0][:, 0]
    u1 = cv2.projectPoints(p, cv2.Rodrigues(R.T)[0], -R.T @ cam.center_world, cam.K, dist)[0][:, 0]
    inside = (u0[:, 0] > 1) & (u0[:, 0] < 358) & (u0[:, 1] > 1) & (u0[:, 1] < 286)
    assert inside.sum() > 50
    got = np.c_[cv2.remap(map_u, u0[inside, :1].astype(np.float32), u0[inside, 1:].astype(np.float32),
                          cv2.INTER_LINEAR).ravel(),
                cv2.remap(map_v, u0[inside, :1].astype(np.float32), u0[inside, 1:].astype(np.float32),
                          cv2.INTER_LINEAR).ravel()]
    np.testing.assert_allclose(got, u1[inside], atol=0.02)
    assert reg._stabilising_map(1, cam.R_world_cam) is None  # at the calibrated attitude: nothing to do


def test_unseen_strip_of_a_turned_camera_gives_no_evidence():
    """A camera panned by 3 deg: the calibrated pixels whose ray leaves its current image (a strip along one
    side, from OpenCV's projection of those rays) are :meth:`unseen`, and the front end gives them the
    neutral foreground likelihood, whose fused log-odds is ~0 (no evidence either way)."""
    import cv2

    from planefuse.vision import CameraFrontEnd, FusionParams, ForegroundParams, camera_foregrounds
    from planefuse.vision._fusion import NEUTRAL_FOREGROUND, log_odds_table, quantise_foreground

    _, rec = scene(1.0, seed=18)
    stack = stack_for_recording(rec, SystemParams())
    reg = CameraRegistration.from_recording(rec, stack, RegistrationParams(attitude_source="imu"))
    reg.lookups_at(0.0)
    cam = rec.cameras[1]
    R = Rotation.from_rotvec([0.0, 0.0, np.radians(3.0)]).as_matrix() @ cam.R_world_cam  # about the vertical
    reg._maps[1] = reg._stabilising_map(1, R)
    unseen = reg.unseen(1)
    W, H = cam.intrinsics.width_px, cam.intrinsics.height_px
    assert unseen is not None and 0.01 < unseen.mean() < 0.2
    # reference: each calibrated pixel's ray, seen by the turned camera through OpenCV's full model
    v, u = np.mgrid[0:H:7, 0:W:7]
    xy = cam.intrinsics.normalized_from_pixels(np.c_[u.ravel(), v.ravel()].astype(float))
    rays_world = (cam.R_world_cam @ np.c_[xy, np.ones(len(xy))].T).T
    uv = cv2.projectPoints(rays_world, cv2.Rodrigues(R.T)[0], np.zeros(3), cam.K, cam.intrinsics.dist)[0][:, 0]
    outside = (uv[:, 0] < -0.5) | (uv[:, 0] > W - 0.5) | (uv[:, 1] < -0.5) | (uv[:, 1] > H - 0.5)
    got = unseen[v.ravel(), u.ravel()]
    assert np.mean(got == outside) > 0.995  # disagreements only at the strip's edge
    # the front end: unseen pixels are neutral, the others are the subtractor's foreground
    frame = np.full((H, W), 200, np.uint8)
    fe = [CameraFrontEnd(W, H, ForegroundParams(), c.name) for c in rec.cameras]
    images = [frame.copy() for _ in rec.cameras]
    reg._moved = lambda time_s: []  # keep the map set above
    (_, fgs, status, _), = camera_foregrounds([(0.5, images)], fe, registration=reg)
    assert status[1] == "ok"
    assert np.all(fgs[1][unseen] == NEUTRAL_FOREGROUND)
    assert not np.any(fgs[1][~unseen] == NEUTRAL_FOREGROUND)
    assert all(reg.unseen(c) is None and not np.any(fgs[c] == NEUTRAL_FOREGROUND) for c in (0, 2, 3))
    table = log_odds_table(FusionParams())
    assert abs(table[quantise_foreground(np.float32([NEUTRAL_FOREGROUND]))[0]]) < 0.01 * table[255]


def test_imu_route_follows_a_pan():
    """A +-10 deg pan about the vertical from t = 1 s: only the gyroscope sees it (the heading); the IMU
    attitude stays within 1.5 px of the truth throughout, against ~60 px off without the fix (imufusion's start-up, which pins the heading
    without a magnetometer, is skipped)."""
    pan = CameraMotionSpec(kind="pan", amplitude_deg=10.0, period_s=3.0, start_s=1.0)
    _, rec = scene(4.0, seed=19, motions=[pan])
    stack = stack_for_recording(rec, SystemParams())
    reg = CameraRegistration.from_recording(rec, stack, RegistrationParams(attitude_source="imu"))
    cam = rec.cameras[0]
    from planefuse.registration import pixel_shift_px
    ts = np.arange(0.0, 4.0, 0.1)
    R_true = R_world_cam_at(cam.R_world_cam, [pan], ts)
    err = [pixel_shift_px(cam.K, reg.attitude_at(0, t), R, 360, 288) for t, R in zip(ts, R_true)]
    assert max(err) < 1.5
