"""Evidence for the simulator: body geometry contract, walking realism, masks vs camera projection, IMU."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from planefuse.geometry import invert_transform
from planefuse.sim import (
    CameraRenderer,
    Scene,
    SceneConfig,
    default_scene_config,
    load_scene_config,
    sample_points_in_bodies,
    simulate,
)


@pytest.fixture(scope="module")
def scene() -> Scene:
    return Scene(default_scene_config(duration_s=12.0, seed=3))


def test_bodies_at_contract(scene):
    cyl, cid, sph, sid = scene.bodies_at(4.0)
    P = scene.n_people
    assert cyl.shape == (3 * P, 5) and cyl.dtype == np.float64
    assert sph.shape == (P, 4) and sph.dtype == np.float64
    np.testing.assert_array_equal(cid, np.repeat(np.arange(P), 3))
    np.testing.assert_array_equal(sid, np.arange(P))
    h = scene.height_m
    assert np.all((h >= 1.5) & (h <= 1.95))
    legs, torso = cyl.reshape(P, 3, 5)[:, :2], cyl.reshape(P, 3, 5)[:, 2]
    np.testing.assert_array_equal(legs[..., 3], 0.0)  # legs stand on the floor
    np.testing.assert_allclose(legs[:, 0, 4], torso[:, 3])  # hip: leg top = torso bottom
    np.testing.assert_allclose(torso[:, 4], sph[:, 2] - sph[:, 3])  # torso touches the head
    np.testing.assert_allclose(sph[:, 2] + sph[:, 3], h)  # head top = person's height
    # The torso is centred between the legs.
    np.testing.assert_allclose(legs[..., :2].mean(axis=1), torso[:, :2], atol=1e-12)


def test_legs_swing_while_walking_and_close_when_standing(scene):
    t = np.arange(0, 12, 0.02)
    st = scene.people_at(t)
    sep = []
    for k in range(0, len(t), 5):
        cyl = scene.bodies_at(t[k])[0].reshape(-1, 3, 5)
        sep.append(np.linalg.norm(cyl[:, 0, :2] - cyl[:, 1, :2], axis=1))
    sep = np.array(sep)
    speed = st.speed_m_s[::5]
    spacing = np.array([b.leg_spacing_m for b in scene.bodies])
    walking = speed > 1.0
    assert (sep[walking] > spacing[None].repeat(len(sep), 0)[walking] + 0.1).mean() > 0.3
    still = speed < 0.02
    if still.any():
        np.testing.assert_allclose(sep[still], np.broadcast_to(spacing, sep.shape)[still], atol=0.01)


def test_walking_is_realistic_and_seeded(scene):
    t = np.arange(0, 12, 0.04)
    st = scene.people_at(t)
    x0, x1, y0, y1 = scene.room_xy_m
    assert np.all((st.xy_m[..., 0] > x0 + 0.3) & (st.xy_m[..., 0] < x1 - 0.3))
    assert np.all((st.xy_m[..., 1] > y0 + 0.3) & (st.xy_m[..., 1] < y1 - 0.3))
    moving = st.speed_m_s[st.speed_m_s > 0.3]
    assert 0.9 < np.median(moving) < 1.6 and moving.max() <= 1.8 + 1e-9
    # Speeds from finite differences of the positions agree with the reported speed.
    v = np.linalg.norm(np.diff(st.xy_m, axis=0), axis=2) / 0.04
    np.testing.assert_allclose(v, 0.5 * (st.speed_m_s[1:] + st.speed_m_s[:-1]), atol=0.1)
    # People turn (heading changes by more than 60 degrees for most of them) and roughly avoid each other.
    turn = np.ptp(np.unwrap(st.heading_rad, axis=0), axis=0)
    assert (turn > np.radians(60)).mean() >= 0.5
    d = np.linalg.norm(st.xy_m[:, :, None] - st.xy_m[:, None], axis=-1) + 10 * np.eye(scene.n_people)
    r = np.array([b.torso_radius_m for b in scene.bodies])
    assert np.all(d > r[:, None] + r[None])  # torsos never interpenetrate
    again = Scene(default_scene_config(duration_s=12.0, seed=3)).people_at(t)
    np.testing.assert_array_equal(again.xy_m, st.xy_m)
    other = Scene(default_scene_config(duration_s=12.0, seed=4)).people_at(t)
    assert np.abs(other.xy_m - st.xy_m).max() > 1.0


@pytest.fixture(scope="module")
def rec8():
    return simulate(default_scene_config(duration_s=8.0, seed=1, laser=None, head=None))


@pytest.mark.parametrize("time_s", [1.0, 7.32])
def test_masks_agree_with_projected_volumes(time_s, rng, rec8):
    rec = rec8
    scene = rec.scene
    cyl, _, sph, _ = scene.bodies_at(time_s)
    pts, vol = sample_points_in_bodies(cyl, sph, 20000, rng)
    ids = np.where(vol < len(cyl), vol // 3, vol - len(cyl))  # person of each point
    for cs in rec.camera_streams.values():
        k = int(np.argmin(np.abs(cs.times_s - time_s)))
        assert cs.times_s[k] == pytest.approx(time_s)
        mask = cs.mask(k)
        cam = cs.camera
        uv = cam.project(pts)
        inside = cam.intrinsics.contains(uv)
        px = np.round(uv[inside]).astype(int)
        fg = mask > 0
        # Every point inside a body projects onto a foreground pixel (1-pixel tolerance for the rasteriser).
        fg_dil = cv2.dilate(fg.astype(np.uint8), np.ones((3, 3), np.uint8)) > 0
        assert fg_dil[px[:, 1], px[:, 0]].mean() > 0.999
        assert fg[px[:, 1], px[:, 0]].mean() > 0.999
        # Independent rasterisation: pixels hit by the dense volume samples, closed to fill sampling holes.
        dense = np.zeros_like(fg, dtype=np.uint8)
        dense[px[:, 1], px[:, 0]] = 1
        dense = cv2.morphologyEx(dense, cv2.MORPH_CLOSE, np.ones((3, 3), np.uint8)) > 0
        iou = (dense & fg).sum() / (dense | fg).sum()
        assert iou > 0.92, (cam.name, iou)
        # Labels: a pixel that only one person's points reach carries that person's label.
        owner = np.full(fg.shape, -1)
        clash = np.zeros(fg.shape, bool)
        pid = ids[inside]
        for p in np.unique(pid):
            hit = np.zeros(fg.shape, bool)
            q = px[pid == p]
            hit[q[:, 1], q[:, 0]] = True
            clash |= hit & (owner >= 0)
            owner[hit] = p
        sole = (owner >= 0) & ~clash & (cv2.erode(fg.astype(np.uint8), np.ones((3, 3), np.uint8)) > 0)
        assert (mask[sole] == owner[sole] + 1).mean() > 0.98


def test_rendering_is_reproducible_and_masks_are_the_drawn_pixels():
    cfg = default_scene_config(duration_s=2.0, seed=2)
    scene = Scene(cfg)
    cam = cfg.cameras[1].pinhole()
    r = CameraRenderer(cam, scene, cfg.render, cfg.seed, 1)
    img, labels = r.render(0.4, 10)
    r.render(0.12, 3)
    img2, labels2 = r.render(0.4, 10)
    np.testing.assert_array_equal(img, img2)
    np.testing.assert_array_equal(labels, labels2)
    np.testing.assert_array_equal(r.labels(0.4), labels)
    fg = labels > 0
    assert fg.mean() > 0.005
    diff = cv2.GaussianBlur(img, (0, 0), 1).astype(float) - cv2.GaussianBlur(r.background, (0, 0), 1)
    # Away from the people (and their shadows) a frame is the background up to noise and gain drift.
    far = cv2.dilate(fg.astype(np.uint8), np.ones((31, 31), np.uint8)) == 0
    assert np.abs(np.median(diff[far])) < 8
    assert np.percentile(np.abs(diff[far]), 99) < 20
    # On the people it is not.
    assert np.abs(diff[fg]).mean() > 15


def test_imu_gives_camera_attitude():
    rec = simulate(default_scene_config(duration_s=3.0, seed=0, laser=None, head=None))
    for cs in rec.camera_streams.values():
        imu = rec.imu_for(cs.name)
        d = imu.read()
        assert len(d) == 600 and np.allclose(np.diff(d.times_s), 1 / 200)
        R_world_imu = cs.camera.R_world_cam @ imu.T_cam_imu[:3, :3]
        g_imu = R_world_imu.T @ np.array([0.0, 0.0, 1.0])
        f = d.accel_m_s2.mean(axis=0)
        ang = np.degrees(np.arccos(f @ g_imu / np.linalg.norm(f)))
        assert ang < 1.0  # bias 0.03 m/s^2 ~ 0.2 deg
        assert abs(np.linalg.norm(f) - 9.81) < 0.15
        assert np.abs(d.gyro_rad_s.mean(axis=0)).max() < 0.015
        assert 0.01 < d.accel_m_s2.std(axis=0).min() < 0.05


def test_sound_groundtruth_azimuth_analytic():
    cfg = default_scene_config(duration_s=4.0, seed=0)
    scene = Scene(cfg)
    T = scene.T_world_head()
    # Default head on the y = 0 wall facing +y: its left (+y_head) is world -x.
    np.testing.assert_allclose(T[:3, 0], [0, 1, 0], atol=1e-12)
    np.testing.assert_allclose(T[:3, 1], [-1, 0, 0], atol=1e-12)
    t = np.array([0.5, 3.0])
    az, el = scene.azimuth_in_head_at(t)
    p = scene.mouth_positions_at(t) - T[:3, 3]
    np.testing.assert_allclose(az, np.arctan2(-p[..., 0], p[..., 1]))
    np.testing.assert_allclose(el, np.arctan2(p[..., 2], np.hypot(p[..., 0], p[..., 1])))
    p_head = (invert_transform(T) @ np.c_[scene.mouth_positions_at(t).reshape(-1, 3), np.ones(2 * 6)].T).T
    np.testing.assert_allclose(np.cos(az).ravel() * np.hypot(p_head[:, 0], p_head[:, 1]), p_head[:, 0])
    speaking = scene.speaking_at([0.1, 0.5, 1.9, 2.5])
    np.testing.assert_array_equal(speaking[:, :2], [[False, False], [True, False], [False, False], [False, True]])


def test_scene_file_errors_name_file_line_and_field(tmp_path):
    p = tmp_path / "scene.yaml"
    p.write_text("duration_s: 5\nn_people: 3\ncameras:\n  - name: a\n    position_m: [1, 1, 3]\n"
                 "    target_m: [5, 5, 0]\n    fov: 60\n")
    with pytest.raises(ValueError, match=r"scene\.yaml:7: field cameras\.0\.fov: Extra inputs"):
        load_scene_config(p)
    p.write_text("n_people: 2\nspeakers:\n  - {person_id: 5, intervals_s: [[0, 1]]}\n")
    with pytest.raises(ValueError, match=r"speakers\[0\]\.person_id = 5 but there are 2 people"):
        load_scene_config(p)
    p.write_text("duration_s: -1\n")
    with pytest.raises(ValueError, match=r"scene\.yaml:1: field duration_s"):
        load_scene_config(p)
    p.write_text("")
    assert load_scene_config(p) == SceneConfig()


def test_zero_people_and_custom_cameras():
    cfg = SceneConfig.model_validate({
        "duration_s": 1.0, "n_people": 0, "room_size_m": [8, 6], "laser": None, "head": None,
        "cameras": [{"name": "top", "position_m": [4, 3, 3.5], "target_m": [4, 3.01, 0], "rate_hz": 10}],
    })
    rec = simulate(cfg)
    cs = rec.camera("top")
    assert len(cs) == 10 and cs.frame(0).shape == (288, 360, 3)
    assert not cs.mask(5).any()
    assert rec.groundtruth.sound is None
