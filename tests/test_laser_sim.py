"""Laser scanner model, ray casting and scan simulation: analytic cases and simulator ground truth."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from planefuse.geometry import apply_transform, transform_from_rotation_translation
from planefuse.laser import (
    HIT_CYLINDER,
    HIT_FLOOR,
    HIT_NONE,
    HIT_SPHERE,
    HIT_WALL,
    LaserScan,
    LaserScannerSpec,
    T_world_laser_from_pose_2d,
    TiltingUnit,
    points_laser_from_scan,
    points_world_from_scan,
    raycast,
    simulate_scan,
)

ROOM = (0.0, 10.0, 0.0, 8.0)
WALL_H = 2.5


def _people_scene():
    cylinders = np.array([[4.0, 3.0, 0.2, 0.0, 1.75], [6.5, 5.0, 0.25, 0.0, 1.6], [3.0, 6.0, 0.18, 0.0, 1.8]])
    spheres = np.array([[4.0, 3.0, 1.85, 0.12], [6.5, 5.0, 1.72, 0.12], [3.0, 6.0, 1.9, 0.11]])
    return cylinders, spheres


def _unit_pose():
    unit = TiltingUnit(LaserScannerSpec.hokuyo_utm30lx(0.01), offset_tilt_scanner_m=(0.03, 0.0, 0.05),
                       tilt_min_rad=-0.2, tilt_max_rad=0.6)
    T_world_laser = T_world_laser_from_pose_2d(1.0, 1.5, np.pi / 4, z_m=1.2)  # looking diagonally into the room
    return unit, T_world_laser


def test_hokuyo_spec_matches_datasheet():
    spec = LaserScannerSpec.hokuyo_utm30lx()
    assert spec.n_beams == 1081
    assert np.rad2deg(spec.fov_rad) == pytest.approx(270.0)
    assert np.rad2deg(spec.angles_rad[[0, 540, -1]]) == pytest.approx([-135.0, 0.0, 135.0])


def test_tilting_unit_points_match_transform_composition(rng):
    unit, _ = _unit_pose()
    a = rng.uniform(-2, 2, 50)
    r = rng.uniform(0.1, 20, 50)
    tilt = rng.uniform(-0.5, 0.5, 50)
    p_L = points_laser_from_scan(a, r, tilt, unit)
    # independent route: homogeneous T_laser_scanner @ p_S, one beam at a time
    p_S = np.stack([r * np.cos(a), r * np.sin(a), 0 * r], axis=1)
    ref = np.array([unit.T_laser_scanner(t) @ np.r_[p, 1.0] for t, p in zip(tilt, p_S)])[:, :3]
    np.testing.assert_allclose(p_L, ref, atol=1e-12)
    # range 0 is the optical centre: the offset rotated about the tilt axis, whose distance to
    # the y axis does not depend on the tilt
    o = points_laser_from_scan(a, 0 * r, tilt, unit)
    np.testing.assert_allclose(np.hypot(o[:, 0], o[:, 2]), np.hypot(0.03, 0.05), atol=1e-12)


def test_positive_tilt_looks_down():
    p = points_laser_from_scan([0.0], [1.0], [0.3])
    assert p[0, 2] == pytest.approx(-np.sin(0.3))


@settings(max_examples=60, deadline=None)
@given(
    cx=st.floats(-3, 3), cy=st.floats(-3, 3), r=st.floats(0.05, 1.0),
    az=st.floats(-np.pi, np.pi), el=st.floats(-0.3, 0.3),
)
def test_raycast_equals_analytic_ray_cylinder_distance(cx, cy, r, az, el):
    origin = np.array([[cx + 5 * np.cos(az), cy + 5 * np.sin(az), 10.0]])  # floor far below
    # aim at the cylinder axis at the origin's height, tilted by el
    d = np.array([[-np.cos(az) * np.cos(el), -np.sin(az) * np.cos(el), np.sin(el)]])
    cyl = np.array([[cx, cy, r, -100.0, 100.0]])
    t = raycast(origin, d, cyl, None, (-50, 50, -50, 50), 0.0, 1e3)
    # the ray meets the axis line; in the horizontal plane it hits at distance 5 - r, scaled by 1/cos(el)
    assert t[0] == pytest.approx((5.0 - r) / np.cos(el), rel=1e-9)


def test_raycast_kinds_caps_spheres_floor_walls():
    o = np.array([[0.0, 0.0, 3.0], [0.0, 0.0, 1.0], [5.0, 4.0, 1.0], [5.0, 4.0, 1.0], [5.0, 4.0, 1.0], [5, 4, 3.0]])
    d = np.array([[0.0, 0.0, -1.0], [1.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0, -1.0, 0], [1.0, 0, 0]])
    cyl = np.array([[0.0, 0.0, 0.5, 0.0, 1.8]])       # cap from above at z = 1.8
    sph = np.array([[8.0, 4.0, 1.0, 0.5]])
    t, kind, idx = raycast(o, d, cyl, sph, ROOM, WALL_H, 100.0, return_hits=True)
    np.testing.assert_allclose(t[:5], [1.2, 0.5, 2.5, 1.0, 4.0])
    assert list(kind) == [HIT_CYLINDER, HIT_CYLINDER, HIT_SPHERE, HIT_FLOOR, HIT_WALL, HIT_NONE]
    assert np.isinf(t[5])  # above the walls, no ceiling
    assert list(idx[:3]) == [0, 0, 0]
    # max range cuts
    assert np.isinf(raycast(o[2:3], d[2:3], cyl, sph, ROOM, WALL_H, 2.0)[0])


def test_raycast_bad_inputs():
    o = np.zeros((2, 3))
    with pytest.raises(ValueError, match="origins and directions"):
        raycast(o, np.ones((3, 3)), None, None, ROOM, WALL_H, 10)
    with pytest.raises(ValueError, match="zero-length"):
        raycast(o, np.zeros((2, 3)), None, None, ROOM, WALL_H, 10)
    with pytest.raises(ValueError, match="cylinders"):
        raycast(o, np.ones((2, 3)), np.ones((2, 4)), None, ROOM, WALL_H, 10)
    with pytest.raises(ValueError, match="room_xy_m"):
        raycast(o, np.ones((2, 3)), None, None, (1, 0, 0, 1), WALL_H, 10)


def _distance_to_surface(p, kind, idx, cylinders, spheres):
    """Unsigned distance of world points to the surface that was hit."""
    dist = np.full(len(p), np.nan)
    m = kind == HIT_FLOOR
    dist[m] = np.abs(p[m, 2])
    m = kind == HIT_WALL
    x0, x1, y0, y1 = ROOM
    dist[m] = np.min(np.abs(np.stack([p[m, 0] - x0, p[m, 0] - x1, p[m, 1] - y0, p[m, 1] - y1])), axis=0)
    m = kind == HIT_SPHERE
    s = spheres[idx[m]]
    dist[m] = np.abs(np.linalg.norm(p[m] - s[:, :3], axis=1) - s[:, 3])
    m = kind == HIT_CYLINDER
    c = cylinders[idx[m]]
    side = np.abs(np.hypot(p[m, 0] - c[:, 0], p[m, 1] - c[:, 1]) - c[:, 2])
    cap = np.minimum(np.abs(p[m, 2] - c[:, 3]), np.abs(p[m, 2] - c[:, 4]))
    dist[m] = np.minimum(side, cap)
    return dist


def test_simulated_tilting_scan_points_lie_on_true_surfaces(rng):
    unit, T_world_laser = _unit_pose()
    cylinders, spheres = _people_scene()
    sigma = unit.scanner.range_noise_sigma_m
    kinds_seen = set()
    for tilt in np.linspace(-0.2, 0.6, 5):
        scan, truth = simulate_scan(unit, T_world_laser, tilt, cylinders, spheres, ROOM, WALL_H, rng,
                                    return_truth=True)
        assert isinstance(scan, LaserScan) and len(scan) == 1081
        ok = scan.valid
        p_W = points_world_from_scan(scan.angles_rad[ok], scan.ranges_m[ok], scan.tilt_rad[ok], T_world_laser, unit)
        dist = _distance_to_surface(p_W, truth.hit_kind[ok], truth.hit_index[ok], cylinders, spheres)
        # a point displaced by range noise e along the beam is at most |e| from the surface
        assert np.all(dist <= 5 * sigma), dist.max()
        assert np.sqrt(np.mean((scan.ranges_m[ok] - truth.range_m[ok]) ** 2)) == pytest.approx(sigma, rel=0.15)
        # the noise-free ranges put points exactly on the surfaces
        p_true = points_world_from_scan(scan.angles_rad[ok], truth.range_m[ok], scan.tilt_rad[ok], T_world_laser, unit)
        assert np.all(_distance_to_surface(p_true, truth.hit_kind[ok], truth.hit_index[ok], cylinders, spheres) < 1e-9)
        kinds_seen |= set(np.unique(truth.hit_kind[ok]).tolist())
        # beams escaping the room over the walls are max-range readings, marked inf
        assert np.all(np.isinf(scan.ranges_m[truth.hit_kind == HIT_NONE]))
        assert np.all(scan.no_return[truth.hit_kind == HIT_NONE])
    assert {HIT_CYLINDER, HIT_FLOOR, HIT_WALL} <= kinds_seen


def test_laser_scan_rejects_mismatched_counts():
    with pytest.raises(ValueError, match="angles_rad has 3 beams but ranges_m has 2"):
        LaserScan(0.0, np.zeros(3), np.ones(2), 0.0, 0.1, 10.0)
    with pytest.raises(ValueError, match="same shape"):
        points_laser_from_scan(np.zeros(3), np.ones(2))


def test_laser_scan_classifies_invalid_returns():
    scan = LaserScan(0.0, np.zeros(6), [1.0, np.nan, 0.0, -1.0, np.inf, 30.0], 0.0, 0.05, 30.0)
    assert scan.valid.tolist() == [True, False, False, False, False, False]
    assert scan.no_return.tolist() == [False, False, False, False, True, True]
    assert scan.invalid.tolist() == [False, True, True, True, False, False]


def test_fixed_scanner_world_points_round_trip(rng):
    spec = LaserScannerSpec.sick_lms200(0.0)
    T = transform_from_rotation_translation(np.eye(3), [5.0, 4.0, 0.4])
    scan = simulate_scan(spec, T, 0.0, np.array([[7.0, 4.0, 0.3, 0.0, 1.7]]), None, ROOM, WALL_H, rng)
    p = points_world_from_scan(scan.angles_rad, scan.ranges_m, 0.0, T)
    np.testing.assert_allclose(p[scan.valid, 2], 0.4)
    # beam straight ahead hits the cylinder at x = 7 - 0.3
    assert p[90, 0] == pytest.approx(6.7)
    np.testing.assert_allclose(apply_transform(T, np.zeros(3)), [5, 4, 0.4])


def test_beam_origins_directions_fused_equals_per_beam_pose_and_points(rng):
    from scipy.spatial.transform import Rotation

    from planefuse.laser import origins_world_from_scan

    unit = TiltingUnit(LaserScannerSpec.hokuyo_utm30lx(), (0.03, 0.01, 0.05), Rotation.random(random_state=2).as_matrix())
    T = transform_from_rotation_translation(Rotation.random(random_state=3).as_matrix(), [1.0, 2.0, 3.0])
    a, t = rng.uniform(-2, 2, 50), rng.uniform(-1, 1, 50)
    o, d = origins_world_from_scan(a, t, T, unit)  # fused numba path
    o2, d2 = origins_world_from_scan(a, t, np.broadcast_to(T, (50, 4, 4)), unit)  # per-beam numpy path
    np.testing.assert_allclose(o, o2, atol=1e-12)
    np.testing.assert_allclose(d, d2, atol=1e-12)
    np.testing.assert_allclose(np.linalg.norm(d, axis=1), 1.0)
    np.testing.assert_allclose(o + 2.0 * d, points_world_from_scan(a, np.full(50, 2.0), t, T, unit), atol=1e-12)


def test_scans_from_recording_arrays_round_trip(rng):
    """The recording format stores NaN for no return; scans_from_arrays turns it into max-range readings."""
    from planefuse.io import LaserScans
    from planefuse.laser import scans_from_arrays

    unit, T = _unit_pose()
    cylinders, spheres = _people_scene()
    sims = [simulate_scan(unit, T, tilt, cylinders, spheres, ROOM, WALL_H, rng, time_s=0.025 * k)
            for k, tilt in enumerate([0.0, 0.2, 0.4])]
    rec = LaserScans(np.array([s.time_s for s in sims]), sims[0].angles_rad,
                     np.array([np.where(np.isinf(s.ranges_m), np.nan, s.ranges_m) for s in sims]),
                     np.array([s.tilt_rad[0] for s in sims]))
    back = scans_from_arrays(rec.times_s, rec.angles_rad, rec.ranges_m, rec.tilt_rad, T, 0.1, 30.0)
    for a, b in zip(sims, back):
        np.testing.assert_array_equal(a.no_return, b.no_return)
        np.testing.assert_array_equal(a.valid, b.valid)
        np.testing.assert_allclose(points_world_from_scan(b.angles_rad[b.valid], b.ranges_m[b.valid], b.tilt_rad[b.valid],
                                                          b.T_world_laser, unit),
                                   points_world_from_scan(a.angles_rad[a.valid], a.ranges_m[a.valid], a.tilt_rad[a.valid],
                                                          T, unit))
    with pytest.raises(ValueError, match="ranges_m must have shape"):
        scans_from_arrays(rec.times_s, rec.angles_rad, rec.ranges_m[:, :5], rec.tilt_rad, T, 0.1, 30.0)
