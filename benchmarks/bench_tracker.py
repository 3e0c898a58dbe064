"""Cost per output step of the tracking stage (clustering + tracker) behind the BOF: the Kalman tracker against
the previous nearest-neighbour tracker, in the same run, on the same filtered grids and clusters.

Run: ``PYTHONPATH=src python benchmarks/bench_tracker.py [--people 6,16]``

Scene: people walking straight lines at 0.5-1.2 m/s, synthetic cylinder evidence (+2 / -1 log-odds, N(0, 0.5)
noise) at 5 Hz (the demo's output rate), on the demo grid (planes 0.1/0.5/1.0/1.5 m, 96 x 96 cells of 0.1 m,
7 x 7 velocities) and on 10 planes x 200 x 200 cells. Per output step it times, after the BOF update:

* clustering: ``cluster_occupancy`` as before (moments only) and as now (plus each cluster's velocity
  variance from the BOF's velocity hypotheses in its disc, which the Kalman tracker's measurement
  covariance needs);
* tracker: ``MultiPersonTracker.step`` of the Kalman tracker and of the previous tracker (read from git,
  ``benchmarks/_previous_tracker.py``) on the same clusters.

One thread (``_single_thread``); each clustering is timed 3 times per step, alternating, and the table gives
the fastest step after a warm-up, in process CPU time (the least disturbed on a shared machine);
ratios are what to read on a shared machine.
"""

from __future__ import annotations

import _single_thread  # noqa: F401  (first: one thread per library)

import argparse
import time

import numpy as np
from _previous_tracker import load_previous_tracker

from planefuse.grid import PlaneStack
from planefuse.tracking import (
    BayesianOccupancyFilter,
    BOFParams,
    ClusterParams,
    MultiPersonTracker,
    cluster_occupancy,
    evidence_from_people,
    velocity_correlation_time_s,
    velocity_prior_variance_m2_s2,
)

GRIDS = {
    "demo grid 4 x 96 x 96": PlaneStack.from_extent([0.1, 0.5, 1.0, 1.5], (0.2, 9.8), (0.2, 9.8), 0.1),
    "10 x 200 x 200": PlaneStack.from_extent(list(np.linspace(0.1, 1.9, 10)), (0.0, 20.0), (0.0, 20.0), 0.1),
}
DT_S = 0.2


def walkers(stack: PlaneStack, n: int, rng: np.random.Generator):
    x0, x1, y0, y1 = stack.extent_m
    start = rng.uniform([x0 + 1, y0 + 1], [x1 - 1, y1 - 1], (n, 2))
    heading = rng.uniform(0, 2 * np.pi, n)
    speed = rng.uniform(0.5, 1.2, n)
    v = speed[:, None] * np.column_stack([np.cos(heading), np.sin(heading)])
    lo, hi = np.array([x0 + 0.3, y0 + 0.3]), np.array([x1 - 0.3, y1 - 0.3])

    def at(t):  # reflect at the walls
        p = start + v * t - lo
        span = hi - lo
        p = np.abs((p + span) % (2 * span) - span)
        return lo + p

    return at


def bench(stack: PlaneStack, n_people: int, n_steps: int, warm: int = 3) -> dict:
    rng = np.random.default_rng(0)
    at = walkers(stack, n_people, rng)
    bof_params, cp = BOFParams(), ClusterParams(threshold=1.5)
    bof = BayesianOccupancyFilter(stack, bof_params)
    prev = load_previous_tracker()
    kalman = MultiPersonTracker(None, stack.extent_m, velocity_prior_variance_m2_s2(bof_params),
                                velocity_correlation_time_s(bof_params))
    previous = prev.MultiPersonTracker(prev.TrackerParams(), stack.extent_m)
    t_cl_prev, t_cl_new, t_kf, t_nn = [], [], [], []
    heights = np.full(n_people, 1.7)
    for i in range(n_steps):
        t = i * DT_S
        ev = evidence_from_people(stack, t, at(t), heights, "cam", noise_std=0.5, rng=rng)
        bof.predict_to(t)
        bof.update(ev.log_odds)
        state = bof.state
        cl_prev, cl_new = np.inf, np.inf
        for _ in range(3):  # alternate the two clusterings: both see the same load
            t0 = time.process_time()
            occ, vel = state.moments()
            cluster_occupancy(t, occ, vel, stack, bof_params.prior_occupancy, cp)
            t1 = time.process_time()
            occ, vel = state.moments()
            clusters = cluster_occupancy(t, occ, vel, stack, bof_params.prior_occupancy, cp,
                                         (state.occ_v, state.velocities_m_s))
            t2 = time.process_time()
            cl_prev, cl_new = min(cl_prev, t1 - t0), min(cl_new, t2 - t1)
        t2 = time.process_time()
        kalman.step(clusters)
        t3 = time.process_time()
        previous.step(clusters)
        t4 = time.process_time()
        if i >= warm:
            t_cl_prev.append(cl_prev)
            t_cl_new.append(cl_new)
            t_kf.append(t3 - t2)
            t_nn.append(t4 - t3)
    med = {k: 1e3 * float(np.min(v)) for k, v in
           (("cluster_prev", t_cl_prev), ("cluster_new", t_cl_new), ("kalman", t_kf), ("previous", t_nn))}
    med["n_tracks"] = len(kalman.tracks)
    return med


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--people", default="6,16")
    ap.add_argument("--steps", type=int, default=25)
    args = ap.parse_args()
    print("| grid | people | clustering before [ms] | clustering + velocity variance [ms] | ratio | "
          "previous tracker [ms] | Kalman tracker [ms] | ratio | tracks |")
    print("|---|---:|---:|---:|---:|---:|---:|---:|---:|")
    for name, stack in GRIDS.items():
        for n in (int(s) for s in args.people.split(",")):
            steps = args.steps if stack.shape[1] < 150 else max(args.steps // 2, 8)
            m = bench(stack, n, steps)
            print(f"| {name} | {n} | {m['cluster_prev']:.1f} | {m['cluster_new']:.1f} | "
                  f"{m['cluster_new'] / m['cluster_prev']:.2f} | {m['previous']:.2f} | {m['kalman']:.2f} | "
                  f"{m['kalman'] / m['previous']:.2f} | {m['n_tracks']} |", flush=True)


if __name__ == "__main__":
    main()
