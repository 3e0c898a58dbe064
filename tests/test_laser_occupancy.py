"""Inverse sensor model on the plane stack: exact cell traversal and simulated cross-sections."""

from __future__ import annotations

import numpy as np
import pytest

from planefuse.geometry import transform_from_rotation_translation
from planefuse.grid import Evidence, PlaneStack
from planefuse.laser import (
    CELL_FREE,
    CELL_OCCUPIED,
    LaserScan,
    LaserScannerSpec,
    T_world_laser_from_pose_2d,
    LaserSensorModel,
    TiltingUnit,
    register_points,
    register_scan,
    simulate_scan,
    traverse_beams,
    xy_ref_from_points_laser,
)

MODEL = LaserSensorModel()
L_FREE, L_OCC = MODEL.log_odds_table[CELL_FREE], MODEL.log_odds_table[CELL_OCCUPIED]


def _brute_force(o, e, hit, stack):
    """Reference: a cell of plane l is crossed iff the part of the segment inside band l meets the
    cell's square (exact segment/box test per cell and beam); the end cell is occupied for hits."""
    L, ny, nx = stack.shape
    ref = np.zeros(stack.shape, np.float32)
    xy = stack.cell_centers_xy().reshape(-1, 2)
    half = stack.cell_size_m / 2
    for i in range(len(o)):  # reference only: loops are fine in a test
        d = e[i] - o[i]
        for l in range(L):
            zl, zh = stack.band_edges_m[l], stack.band_edges_m[l + 1]
            if d[2] == 0:
                if not zl <= o[i, 2] < zh:
                    continue
                s0, s1 = 0.0, 1.0
            else:
                s0, s1 = sorted(((zl - o[i, 2]) / d[2], (zh - o[i, 2]) / d[2]))
                s0, s1 = max(s0, 0.0), min(s1, 1.0)
                if s0 > s1:
                    continue
            a, b = o[i, :2] + s0 * d[:2], o[i, :2] + s1 * d[:2]
            # Liang-Barsky of segment a->b against every cell square at once
            lo, hi = np.zeros(len(xy)), np.ones(len(xy))
            ok = np.ones(len(xy), bool)
            for k in range(2):
                dk = b[k] - a[k]
                for p, q in ((-dk, a[k] - (xy[:, k] - half)), (dk, (xy[:, k] + half) - a[k])):
                    if p == 0:
                        ok &= q >= 0
                    else:
                        r = q / p
                        if p < 0:
                            lo = np.maximum(lo, r)
                        else:
                            hi = np.minimum(hi, r)
            crossed = (ok & (lo <= hi)).reshape(ny, nx)
            plane = ref[l]
            plane[crossed & (plane == 0)] = L_FREE
            if hit[i] and s1 >= 1.0 and zl <= e[i, 2] < zh:
                iy, ix = stack.index_from_xy(e[i, :2])
                if iy >= 0:
                    plane[iy, ix] = L_OCC
    return ref


def test_traversal_equals_brute_force_cell_intersection(rng):
    stack = PlaneStack.from_extent([0.2, 0.6, 1.0], (0.0, 2.0), (-1.0, 1.0), 0.1)
    n = 40
    o = np.column_stack([rng.uniform(-0.5, 2.5, n), rng.uniform(-1.5, 1.5, n), rng.uniform(0.0, 1.4, n)])
    e = np.column_stack([rng.uniform(-0.5, 2.5, n), rng.uniform(-1.5, 1.5, n), rng.uniform(0.0, 1.4, n)])
    e[:10, 2] = o[:10, 2]  # horizontal beams (2-D scanner) lie in one band
    hit = rng.uniform(size=n) < 0.7
    any_occ = np.zeros(stack.shape, bool)
    any_seen = np.zeros(stack.shape, bool)
    for i in range(n):  # one beam at a time, against the reference
        ours = traverse_beams(o[i:i + 1], e[i:i + 1], hit[i:i + 1], stack)
        np.testing.assert_array_equal(ours, _brute_force(o[i:i + 1], e[i:i + 1], hit[i:i + 1], stack))
        any_occ |= ours == L_OCC
        any_seen |= ours != 0
    assert any_occ.sum() >= 5 and any_seen.sum() > 100
    # all beams at once: a cell is occupied if any beam ends there, free if beams only pass
    together = traverse_beams(o, e, hit, stack)
    np.testing.assert_array_equal(together == L_OCC, any_occ)
    np.testing.assert_array_equal(together == L_FREE, any_seen & ~any_occ)


def test_eq5_projection_and_band_assignment():
    T = transform_from_rotation_translation(np.eye(3), [1.0, 2.0, 0.5])
    p_L = np.array([[1.0, 0.0, 0.0], [0.0, 1.0, 1.0], [0.0, 0.0, 5.0]])
    np.testing.assert_allclose(xy_ref_from_points_laser(T, p_L), [[2.0, 2.0], [1.0, 3.0], [1.0, 2.0]])
    stack = PlaneStack.from_extent([0.2, 1.0, 1.6], (0, 4), (0, 4), 0.5)
    plane, iy, ix = register_points(p_L + T[:3, 3], stack)
    assert plane.tolist() == [0, 2, -1]
    assert (iy.tolist(), ix.tolist()) == ([4, 6, 4], [4, 2, 2])


def _sim_setup():
    unit = TiltingUnit(LaserScannerSpec.hokuyo_utm30lx(0.01), offset_tilt_scanner_m=(0.03, 0.0, 0.05),
                       tilt_min_rad=-0.15, tilt_max_rad=0.5, tilt_period_s=2.0)
    T = T_world_laser_from_pose_2d(0.5, 0.5, np.pi / 4, z_m=1.3)  # looking diagonally into the room
    cylinders = np.array([[3.0, 2.0, 0.25, 0.0, 1.75], [2.0, 4.0, 0.2, 0.0, 1.2], [5.0, 5.0, 0.3, 0.0, 1.6]])
    return unit, T, cylinders


def test_simulated_per_plane_occupancy_marks_true_cross_sections(rng):
    unit, T, cylinders = _sim_setup()
    room, wall_h = (0.0, 7.0, 0.0, 7.0), 2.2
    stack = PlaneStack.from_extent([0.1, 0.5, 0.9, 1.4, 1.7, 2.0], (0, 7), (0, 7), 0.05)
    acc = np.zeros(stack.shape, np.float32)
    for tilt in np.linspace(unit.tilt_min_rad, unit.tilt_max_rad, 40):
        scan = simulate_scan(unit, T, tilt, cylinders, None, room, wall_h, rng)
        reg = register_scan(scan, stack, unit=unit)
        assert isinstance(reg.evidence, Evidence) and reg.evidence.log_odds.shape == stack.shape
        assert reg.n_valid + reg.n_no_return + reg.n_invalid == len(scan)
        acc += reg.evidence.log_odds
    xy = stack.cell_centers_xy()
    edges = stack.band_edges_m
    occ_ok_total = 0
    for l in range(stack.n_planes):
        occ = acc[l] > 0
        free = acc[l] < 0
        # distance of every cell centre to the nearest true surface in band l
        d = np.full(xy.shape[:2], np.inf)
        inside = np.zeros(xy.shape[:2], bool)
        for cx, cy, r, zb, zt in cylinders:
            if zb < edges[l + 1] and zt >= edges[l]:
                rho = np.hypot(xy[..., 0] - cx, xy[..., 1] - cy)
                cap_in_band = edges[l] <= zt < edges[l + 1]
                d = np.minimum(d, np.maximum(rho - r, 0.0) if cap_in_band else np.abs(rho - r))
                if not cap_in_band:
                    inside |= rho < r - stack.cell_size_m
                if min(zt, edges[l + 1]) - edges[l] >= 0.15:
                    # the cross-section is seen: occupied cells within one cell of its rim
                    near = occ & (np.abs(rho - r) < 1.5 * stack.cell_size_m)
                    assert near.sum() >= 3, (l, cx, cy)
        if edges[l] < wall_h:
            x0, x1, y0, y1 = room
            dw = np.min(np.abs(np.stack([xy[..., 0] - x0, xy[..., 0] - x1, xy[..., 1] - y0, xy[..., 1] - y1])), 0)
            d = np.minimum(d, dw)
        # every occupied cell lies on a true surface (within a cell diagonal + noise)
        assert np.all(d[occ] < 0.75 * stack.cell_size_m + 0.04), (l, d[occ].max())
        # no free space inside the bodies
        assert not np.any(free & inside)
        occ_ok_total += occ.sum()
    assert occ_ok_total > 500


def test_bad_returns_free_space_and_are_counted():
    spec = LaserScannerSpec(-0.2, 0.1, 5, 0.05, 4.0)
    stack = PlaneStack.from_extent([0.5], (-5, 5), (-5, 5), 0.1)
    T = transform_from_rotation_translation(np.eye(3), [0.0, 0.0, 0.5])
    scan = LaserScan(0.0, spec.angles_rad, [2.0, np.nan, 0.0, -1.0, np.inf], 0.0, 0.05, 4.0, T)
    reg = register_scan(scan, stack)
    assert (reg.n_valid, reg.n_invalid, reg.n_no_return) == (1, 3, 1)
    lo = reg.evidence.log_odds[0]
    assert np.count_nonzero(lo > 0) == 1  # only the real return occupies
    # the max-range beam frees ~4 m of cells, the invalid ones too
    assert np.count_nonzero(lo < 0) > 4 * 4.0 / 0.1
    strict = register_scan(scan, stack, model=LaserSensorModel(invalid_frees=False))
    assert np.count_nonzero(strict.evidence.log_odds < 0) < np.count_nonzero(lo < 0)
    assert strict.n_invalid == 3
    with pytest.raises(ValueError, match="T_world_laser"):
        register_scan(LaserScan(0.0, [0.0], [1.0], 0.0, 0.0, 4.0), stack)


def test_moving_platform_per_beam_pose_equals_fixed_pose(rng):
    unit, T, cylinders = _sim_setup()
    stack = PlaneStack.from_extent([0.1, 0.9, 1.7], (0, 7), (0, 7), 0.1)
    scan = simulate_scan(unit, T, 0.2, cylinders, None, (0, 7, 0, 7), 2.2, rng)
    a = register_scan(scan, stack, unit=unit)
    b = register_scan(scan, stack, unit=unit, T_world_laser=np.broadcast_to(T, (len(scan), 4, 4)))
    np.testing.assert_array_equal(a.evidence.log_odds, b.evidence.log_odds)
