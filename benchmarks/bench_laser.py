"""Laser registration speed: 1081-beam scans of a tilting scanner onto 10 planes of 200 x 200 cells.

Compares ``planefuse.laser.register_scan`` (numba Amanatides-Woo traversal, band clipping) with a
straightforward numpy inverse sensor model (every beam sampled every half cell, cells set by fancy
indexing) on the same scans, single-threaded, and reports how often the two agree per cell.
``LaserRegistrar`` reuses one scratch grid for a stream of scans; ``register_scan`` allocates a new
grid per call (page faults on 1.6 MB per scan cost about as much as the traversal).

Run: ``PYTHONPATH=src python benchmarks/bench_laser.py``
"""

from __future__ import annotations

import os

import _single_thread  # noqa: F401  (before numpy)

import time

import numpy as np

from planefuse.grid import PlaneStack
from planefuse.laser import (
    CELL_FREE,
    CELL_OCCUPIED,
    LaserRegistrar,
    LaserSensorModel,
    LaserScannerSpec,
    T_world_laser_from_pose_2d,
    TiltingUnit,
    points_laser_from_scan,
    register_scan,
    simulate_scan,
)


def numpy_baseline(scan, stack: PlaneStack, unit: TiltingUnit, model: LaserSensorModel) -> np.ndarray:
    """Straightforward numpy inverse sensor model: sample each beam every half cell."""
    T = scan.T_world_laser
    valid = scan.valid
    r = np.where(valid, scan.ranges_m, scan.range_max_m)
    o = points_laser_from_scan(scan.angles_rad, 0 * r, scan.tilt_rad, unit) @ T[:3, :3].T + T[:3, 3]
    e = points_laser_from_scan(scan.angles_rad, r, scan.tilt_rad, unit) @ T[:3, :3].T + T[:3, 3]
    hit = valid & (e[:, 2] >= model.ground_clearance_m)
    step = 0.5 * stack.cell_size_m
    length = np.linalg.norm(e - o, axis=1)
    diag = np.hypot(stack.nx, stack.ny) * stack.cell_size_m
    n_s = int(np.ceil(min(length.max(), diag + np.abs(o[:, :2]).max()) / step))
    s = np.arange(n_s) * step
    frac = s[None, :] / length[:, None]
    inside = frac < 1.0
    pts = o[:, None, :] + frac[..., None] * (e - o)[:, None, :]
    lo = np.zeros(stack.shape, np.float32)
    table = model.log_odds_table
    plane = stack.plane_index_from_z(pts[..., 2])
    iy, ix = stack.index_from_xy(pts[..., :2])
    ok = inside & (plane >= 0) & (iy >= 0)
    lo[plane[ok], iy[ok], ix[ok]] = table[CELL_FREE]
    pe = stack.plane_index_from_z(e[:, 2])
    ey, ex = stack.index_from_xy(e[:, :2])
    okh = hit & (pe >= 0) & (ey >= 0)
    lo[pe[okh], ey[okh], ex[okh]] = table[CELL_OCCUPIED]
    return lo


def main(n_scans: int = 40, repeats: int = 5) -> None:
    rng = np.random.default_rng(0)
    unit = TiltingUnit(LaserScannerSpec.hokuyo_utm30lx(0.01), offset_tilt_scanner_m=(0.03, 0.0, 0.05),
                       tilt_min_rad=-0.2, tilt_max_rad=0.6)
    T = T_world_laser_from_pose_2d(1.0, 1.0, np.pi / 4, z_m=1.3)  # looking diagonally into the room
    people = rng.uniform(2.5, 9.0, (6, 2))
    cylinders = np.column_stack([people, np.full(6, 0.22), np.zeros(6), rng.uniform(1.5, 1.9, 6)])
    stack = PlaneStack.from_extent(np.linspace(0.1, 1.9, 10), (0, 10), (0, 10), 0.05)
    assert stack.shape == (10, 200, 200)
    scans = [simulate_scan(unit, T, tilt, cylinders, None, (0, 10, 0, 10), 2.5, rng)
             for tilt in np.linspace(unit.tilt_min_rad, unit.tilt_max_rad, n_scans)]
    model = LaserSensorModel()
    register_scan(scans[0], stack, unit=unit, model=model)  # compile / load the numba cache
    load_before = os.getloadavg()[0]

    def timed(fn) -> tuple[float, float]:
        """Scans per wall-clock second and per CPU second of this process (best of the repeats);
        the CPU-time rate is the one-core speed when other jobs share the machine."""
        best_wall = best_cpu = np.inf
        for _ in range(repeats):
            t0, c0 = time.perf_counter(), time.process_time()
            for sc in scans:
                fn(sc)
            best_wall = min(best_wall, time.perf_counter() - t0)
            best_cpu = min(best_cpu, time.process_time() - c0)
        return n_scans / best_wall, n_scans / best_cpu

    registrar = LaserRegistrar(stack, unit, model)
    ours, ours_cpu = timed(registrar.register)
    plain, plain_cpu = timed(lambda sc: register_scan(sc, stack, unit=unit, model=model))
    base, base_cpu = timed(lambda sc: numpy_baseline(sc, stack, unit, model))
    agree = np.mean([np.mean(np.sign(register_scan(sc, stack, unit=unit, model=model).evidence.log_odds)
                             == np.sign(numpy_baseline(sc, stack, unit, model))) for sc in scans])
    print(f"laser registration with free space: {n_scans} scans x 1081 beams -> 10 planes x 200 x 200 cells, "
          f"1 thread, best of {repeats}")
    print(f"1-min load average before the run: {load_before:.2f} (machine cores: {os.cpu_count()})")
    print(f"{'method':<40}{'scans/s (wall)':>16}{'scans/CPU-s':>14}{'CPU ms/scan':>13}")
    print(f"{'numpy baseline (half-cell sampling)':<40}{base:>16.1f}{base_cpu:>14.1f}{1e3 / base_cpu:>13.2f}")
    print(f"{'LaserRegistrar.register (numba A-W)':<40}{ours:>16.1f}{ours_cpu:>14.1f}{1e3 / ours_cpu:>13.2f}")
    print(f"{'register_scan (new grid per call)':<40}{plain:>16.1f}{plain_cpu:>14.1f}{1e3 / plain_cpu:>13.2f}")
    print(f"ratio of LaserRegistrar to the baseline (wall): {ours / base:.1f}x, (CPU): {ours_cpu / base_cpu:.1f}x; "
          f"cells with the same state (free/occ/unknown): {100 * agree:.2f} %")


if __name__ == "__main__":
    main()
