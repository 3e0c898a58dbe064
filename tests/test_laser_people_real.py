"""People from the laser (simulated legs, real labelled leg clusters), the Intel map, camera + laser."""

from __future__ import annotations

import warnings

import cv2
import numpy as np
import pytest
import scipy.io
from scipy.spatial.distance import cdist

from conftest import shared_data
from planefuse.geometry import apply_transform, transform_from_rotation_translation
from planefuse.eval import detection_scores
from planefuse.grid import GroundDetections
from planefuse.laser import (
    LaserScannerSpec,
    T_world_laser_from_pose_2d,
    background_ranges_m,
    detect_people,
    evaluate_leg_detection,
    map_entropy_bits,
    map_from_carmen_log,
    points_world_from_scan,
    read_carmen_log,
    read_rosbag,
    read_transform_yaml,
    read_xyz,
    simulate_scan,
    wall_spread_m,
)


def test_simulated_people_found_from_their_legs(rng):
    """Two legs (r = 6 cm cylinders, 25 cm apart) per person, a 2-D scanner at knee height."""
    centres = np.array([[3.0, 1.0], [4.0, -1.5], [2.0, -0.5]])
    heading = rng.uniform(0, np.pi, len(centres))
    off = 0.125 * np.column_stack([np.cos(heading), np.sin(heading)])
    legs = np.concatenate([centres + off, centres - off])
    cylinders = np.column_stack([legs, np.full(len(legs), 0.06), np.zeros(len(legs)), np.full(len(legs), 0.8)])
    T = transform_from_rotation_translation(np.eye(3), [0.0, 0.0, 0.3])
    room = (-1.0, 8.0, -5.0, 5.0)
    scan = simulate_scan(LaserScannerSpec.hokuyo_utm30lx(0.01), T, 0.0, cylinders, None, room, 2.0, rng)
    det = detect_people(scan)
    assert isinstance(det, GroundDetections) and det.source == "laser"
    scores = detection_scores([(centres, det.xy_m)], 0.1)
    assert (scores.tp, scores.fn) == (3, 0)
    assert np.all(np.isnan(det.height_m))
    # the known limit of a geometric detector: the only false detections are leg-sized
    # stretches of wall between leg shadows
    far = cdist(det.xy_m, centres).min(axis=1) > 0.1
    assert far.sum() == scores.fp
    x0, x1, y0, y1 = room
    xy = det.xy_m[far]
    to_wall = np.min(np.abs(np.stack([xy[:, 0] - x0, xy[:, 0] - x1, xy[:, 1] - y0, xy[:, 1] - y1])), axis=0)
    assert np.all(to_wall < 0.05)


@pytest.mark.realdata
def test_leg_detection_on_labelled_real_scans_f1_at_0p3m():
    """positive_1_extracted.bag: labels are leg-cluster centroids within +-15 deg and 5 m (SOURCE.md);
    detections are evaluated in that same window."""
    bag = shared_data("lrf2d_people_leg_tracker") / "positive_1_extracted.bag"
    _, scans = read_rosbag(bag, "/training_scan")
    _, labels = read_rosbag(bag, "/leg_cluster_positions")
    assert len(scans) == len(labels) == 197  # paired by order: the PoseArrays have stamp 0
    scores = evaluate_leg_detection(scans, labels, max_distance_m=0.3)
    f1 = 2 * scores.precision * scores.recall / (scores.precision + scores.recall)
    assert f1 >= 0.8, scores.as_dict()
    assert scores.n_gt == sum(len(t) for t in labels)


@pytest.mark.realdata
def test_intel_map_walls_are_sharp_and_pose_errors_blur_them():
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        log = read_carmen_log(shared_data("lrf2d_carmen") / "intel-corrected.log.gz")
    m, pts = map_from_carmen_log(log, cell_size_m=0.1)
    assert m.n_scans == 910 and m.n_valid + m.n_no_return + m.n_invalid == 910 * 180
    spread = np.median(wall_spread_m(pts))
    assert spread < 0.015  # about the range resolution of the logged ranges (1 cm)
    assert map_entropy_bits(m.log_odds) < 0.25
    # the same scans with poses off by 5 cm / 1 deg give visibly thicker walls
    rng = np.random.default_rng(0)
    pose = log.pose_xy_theta + rng.normal(0, [0.05, 0.05, np.deg2rad(1.0)], log.pose_xy_theta.shape)
    assert np.median(wall_spread_m(log.returns_world_xy(pose))) > 1.5 * spread
    # the closed form of returns_world_xy equals the general registration of the scans
    scan = log.scans()[100]
    np.testing.assert_allclose(
        points_world_from_scan(scan.angles_rad[scan.valid], scan.ranges_m[scan.valid], 0.0, scan.T_world_laser)[:, :2],
        log.returns_world_xy()[np.repeat(np.arange(len(log)), ((log.ranges_m > 0) & (log.ranges_m < 80)).sum(1)) == 100],
        atol=1e-9)


@pytest.mark.realdata
@pytest.mark.parametrize("i", [1, 2, 3, 4])
def test_camera_laser_points_lie_on_the_checkerboard(i):
    d = shared_data("lrf3d_camera_lcct")
    T_camera_laser = read_transform_yaml(d / "T_camera_laser_stageII.yaml")
    calib = scipy.io.loadmat(d / "Calib_Results.mat")
    K, kc = calib["KK"], calib["kc"].ravel()
    R_cam_board, t_cam_board = calib[f"Rc_{i}"], calib[f"Tc_{i}"].ravel() / 1000.0  # mm -> m
    corners_uv = calib[f"x_{i}"].T.astype(np.float32)
    hull = cv2.convexHull(corners_uv)
    p_cam = apply_transform(T_camera_laser, read_xyz(d / f"laser_target{i}.xyz"))
    p_cam = p_cam[p_cam[:, 2] > 0]
    uv = cv2.projectPoints(p_cam, np.zeros(3), np.zeros(3), K, kc)[0].reshape(-1, 2)
    inside = np.array([cv2.pointPolygonTest(hull, (float(u), float(v)), False) >= 0 for u, v in uv])
    # 1) laser points seen inside the board's corner hull lie on the board plane (within a few mm)
    dist = np.abs((p_cam[inside] - t_cam_board) @ R_cam_board[:, 2])
    assert inside.sum() > 2000
    assert np.median(dist) < 0.003 and np.percentile(dist, 90) < 0.005
    # 2) conversely, laser points on the board plane within the corner grid project inside the hull
    p_board = (p_cam - t_cam_board) @ R_cam_board
    X = calib[f"X_{i}"] / 1000.0
    on = (np.abs(p_board[:, 2]) < 0.01) & (p_board[:, 0] >= X[0].min()) & (p_board[:, 0] <= X[0].max()) \
        & (p_board[:, 1] >= X[1].min()) & (p_board[:, 1] <= X[1].max())
    margin = np.array([cv2.pointPolygonTest(hull, (float(u), float(v)), True) for u, v in uv[on]])
    assert on.sum() > 2000
    assert np.mean(margin >= -1.0) > 0.98 and margin.min() > -5.0


def test_people_from_a_static_laser_in_the_simulated_scene(rng):
    """End to end with the simulator's scene (6 walking people, legs as cylinders): a 2-D scanner at 0.3 m
    on the west wall; with the per-beam median background, person F1 at 0.3 m is high and no wall
    fragment is reported."""
    from planefuse.sim import Scene, default_scene_config

    scene = Scene(default_scene_config(duration_s=10))
    T = T_world_laser_from_pose_2d(0.15, 5.0, 0.0, z_m=0.3)
    spec = LaserScannerSpec.hokuyo_utm30lx(0.01)
    scans = []
    for t in np.arange(0.0, 10.0, 0.25):
        cylinders, _, spheres, _ = scene.bodies_at(t)
        scans.append(simulate_scan(spec, T, 0.0, cylinders, spheres, scene.room_xy_m, scene.wall_height_m, rng,
                                   time_s=t))
    background = background_ranges_m(scans)
    frames = [(scene.people_at([s.time_s]).xy_m[0], detect_people(s, background_ranges_m=background).xy_m)
              for s in scans]
    scores = detection_scores(frames, 0.3)
    assert scores.precision >= 0.95 and scores.recall >= 0.9, scores.as_dict()
    without = detection_scores([(g, detect_people(s).xy_m) for (g, _), s in zip(frames, scans)], 0.3)
    assert without.tp >= scores.tp and without.fp > scores.fp  # the background removes clutter, not people
    with pytest.raises(ValueError, match="background_ranges_m has 3 beams"):
        detect_people(scans[0], background_ranges_m=np.ones(3))
