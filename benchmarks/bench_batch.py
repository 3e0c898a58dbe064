"""Batch speed-up: a 12-run sweep (6 seeds x 2 configurations of the default scene) on a dask LocalCluster of 1
worker and of 2 workers, in the same run; checks that both give identical metrics (run time aside).

Usage: ``PYTHONPATH=src python benchmarks/bench_batch.py [--duration-s 4] [--seeds 1-6]``
"""

from __future__ import annotations

import argparse
import time

from planefuse.batch import BatchJob, SceneSpec, run_batch
from planefuse.pipeline import RunPlan, SystemParams

TIMING = {"elapsed_s"}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--duration-s", type=float, default=4.0)
    ap.add_argument("--seeds", default="1-6")
    args = ap.parse_args()
    lo, hi = (int(x) for x in args.seeds.split("-"))
    configs = {"filter": SystemParams(sound=False), "no filter": SystemParams(sound=False, use_filter=False)}
    jobs = [BatchJob(f"seed{s} {name}", SceneSpec(seed=s, duration_s=args.duration_s), RunPlan(p))
            for s in range(lo, hi + 1) for name, p in configs.items()]
    wall, results = {}, {}
    for n in (1, 2):
        t0 = time.perf_counter()
        results[n] = run_batch(jobs, n_workers=n, progress_mode="quiet")
        wall[n] = time.perf_counter() - t0
    same = all(a.ok and b.ok and {k: v for k, v in a.metrics.items() if k not in TIMING}
               == {k: v for k, v in b.metrics.items() if k not in TIMING} for a, b in zip(results[1], results[2]))
    print(f"| runs | 1 worker [s] | 2 workers [s] | speed-up | identical metrics |")
    print("|---|---|---|---|---|")
    print(f"| {len(jobs)} | {wall[1]:.1f} | {wall[2]:.1f} | {wall[1] / wall[2]:.2f} | {same} |")


if __name__ == "__main__":
    main()
