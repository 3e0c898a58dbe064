"""BOF throughput: cell x velocity updates per second per core, numba kernels vs plain numpy.

Run: ``python benchmarks/bench_bof.py`` (10 planes of 200x200 cells, 7x7 velocity hypotheses).
One "cell x velocity update" is one (plane, cell, hypothesis) carried through predict + update.
"""

from __future__ import annotations

import argparse
import time

import os
import numpy as np

from planefuse.grid import PlaneStack
from planefuse.tracking import (
    BOFParams,
    bof_initial_state,
    bof_predict,
    bof_predict_numpy,
    bof_update,
    bof_update_numpy,
)


def _time_steps(predict, update, state, params, log_odds, n_steps: int) -> tuple[float, float]:
    """(wall, CPU) seconds per predict + update step; CPU time is this process's, i.e. core time for
    single-threaded code, and stays meaningful when other jobs share the cores."""
    t0, c0 = time.perf_counter(), time.process_time()
    for i in range(n_steps):
        predict(state, 0.1, params)
        update(state, log_odds[i % len(log_odds)])
    return (time.perf_counter() - t0) / n_steps, (time.process_time() - c0) / n_steps


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--planes", type=int, default=10)
    ap.add_argument("--cells", type=int, default=200, help="cells per side")
    ap.add_argument("--velocities", type=int, default=7, help="velocity hypotheses per axis")
    ap.add_argument("--steps", type=int, default=10)
    args = ap.parse_args()

    stack = PlaneStack.from_extent(np.linspace(0.1, 1.9, args.planes), (0, args.cells * 0.05),
                                   (0, args.cells * 0.05), 0.05)
    rng = np.random.default_rng(0)
    log_odds = [rng.normal(0, 1.5, stack.shape).astype(np.float32) for _ in range(4)]
    n_updates = stack.n_planes * stack.ny * stack.nx * args.velocities**2
    print(f"{stack.n_planes} planes x {stack.ny}x{stack.nx} cells x {args.velocities}x{args.velocities} velocities"
          f" = {n_updates / 1e6:.1f} M cell-velocity updates per step; "
          f"single-threaded kernels; load average {os.getloadavg()[0]:.1f} on {os.cpu_count()} cores")
    print(f"{'implementation':<24}{'wall ms/step':>13}{'CPU ms/step':>12}{'M updates/s/core':>18}{'ratio':>7}")
    rows = []
    for subcell in ("bilinear", "accumulate"):
        params = BOFParams(n_velocities_per_axis=args.velocities, subcell=subcell)
        state = bof_initial_state(stack, params)
        _time_steps(bof_predict, bof_update, state, params, log_odds, 1)  # compile / warm up
        t_nb = _time_steps(bof_predict, bof_update, state, params, log_odds, args.steps)
        state = bof_initial_state(stack, params)
        t_np = _time_steps(bof_predict_numpy, bof_update_numpy, state, params, log_odds, max(2, args.steps // 4))
        rows.append((f"numpy ({subcell})", t_np, 1.0))
        rows.append((f"numba ({subcell})", t_nb, t_np[1] / t_nb[1]))
    for name, (wall, cpu), ratio in rows:
        print(f"{name:<24}{wall * 1e3:>13.1f}{cpu * 1e3:>12.1f}{n_updates / cpu / 1e6:>18.1f}{ratio:>7.1f}")


if __name__ == "__main__":
    main()
