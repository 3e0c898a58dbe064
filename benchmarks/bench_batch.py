"""Batch speed-up: a 12-run sweep (6 seeds x 2 configurations of the default scene) on dask clusters of 1 and 2
single-threaded workers, in the same run, and the same sweep on a ``dask scheduler`` with two ``dask worker``
processes started as separate processes (as on several machines); checks that every cluster gives the serial
metrics (run time aside).

Each cluster's start-up (processes, importing planefuse, numba's cached kernels) is timed apart from the sweep,
which runs on the started cluster: a cluster is started once and then serves many sweeps. The runs are
submitted longest first (the filter runs), so that no long run is left alone at the end.

Usage: ``PYTHONPATH=src python benchmarks/bench_batch.py [--duration-s 10] [--seeds 1-6] [--no-scheduler]``
"""

from __future__ import annotations

import argparse
import os
import socket
import subprocess
import sys
import time

from planefuse.batch import BatchJob, SceneSpec, batch_client, run_batch
from planefuse.batch._cluster import SINGLE_THREAD_ENV
from planefuse.pipeline import RunPlan, SystemParams

TIMING = {"elapsed_s"}


def _warm() -> None:
    """Import what a run imports (on a worker)."""
    import planefuse.pipeline  # noqa: F401
    import planefuse.sim  # noqa: F401
    import planefuse.tracking  # noqa: F401


def _sweep(client, jobs) -> tuple[float, list]:
    """The sweep's time on a started cluster [s], and its results."""
    client.run(_warm)
    t0 = time.perf_counter()
    results = run_batch(jobs, progress_mode="quiet", client=client)
    return time.perf_counter() - t0, results


def _port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _scheduler_sweep(jobs, n_workers: int = 2) -> tuple[float, float, list]:
    """The sweep on a ``dask scheduler`` and ``dask worker`` processes started as a user starts them."""
    address = f"tcp://127.0.0.1:{_port()}"
    env = {**os.environ, **SINGLE_THREAD_ENV}
    t0 = time.perf_counter()
    procs = [subprocess.Popen([sys.executable, "-m", "distributed.cli.dask_scheduler", "--host", "127.0.0.1",
                               "--port", address.rsplit(":", 1)[1], "--no-dashboard"], env=env,
                              stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)]
    try:
        procs += [subprocess.Popen([sys.executable, "-m", "distributed.cli.dask_worker", address, "--nthreads", "1",
                                    "--no-dashboard"], env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
                  for _ in range(n_workers)]
        for _ in range(60):
            try:
                with batch_client(address) as client:
                    client.wait_for_workers(n_workers, timeout=60)
                    sweep, results = _sweep(client, jobs)
                return time.perf_counter() - t0 - sweep, sweep, results
            except OSError:
                time.sleep(0.5)
        raise RuntimeError(f"no scheduler at {address}")
    finally:
        for p in reversed(procs):
            p.terminate()
        for p in procs:
            p.wait(timeout=30)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--duration-s", type=float, default=10.0)
    ap.add_argument("--seeds", default="1-6")
    ap.add_argument("--no-scheduler", action="store_true", help="skip the separate dask scheduler")
    args = ap.parse_args()
    lo, hi = (int(x) for x in args.seeds.split("-"))
    configs = {"filter": SystemParams(sound=False), "no filter": SystemParams(sound=False, use_filter=False)}
    jobs = [BatchJob(f"seed{s} {name}", SceneSpec(seed=s, duration_s=args.duration_s), RunPlan(p))
            for name, p in configs.items() for s in range(lo, hi + 1)]  # the filter runs (longest) first
    rows = {}
    for n in (1, 2):
        t0 = time.perf_counter()
        with batch_client(n_workers=n) as client:
            sweep, results = _sweep(client, jobs)
        rows[f"LocalCluster, {n} worker{'s' * (n > 1)}"] = (time.perf_counter() - t0 - sweep, sweep, results)
    if not args.no_scheduler:
        rows["dask scheduler + 2 dask worker processes"] = _scheduler_sweep(jobs)
    ref = rows["LocalCluster, 1 worker"]
    print(f"{len(jobs)} runs: default scene {args.duration_s:g} s, seeds {args.seeds}, filter on and off, sound off")
    print("| cluster | start-up + close [s] | sweep [s] | speed-up vs 1 worker | identical metrics |")
    print("|---|---|---|---|---|")
    for name, (start, sweep, results) in rows.items():
        same = all(a.ok and b.ok and {k: v for k, v in a.metrics.items() if k not in TIMING}
                   == {k: v for k, v in b.metrics.items() if k not in TIMING} for a, b in zip(ref[2], results))
        print(f"| {name} | {start:.1f} | {sweep:.1f} | {ref[1] / sweep:.2f} | {same} |")
    print(f"load average at the end: {os.getloadavg()[0]:.1f} (other jobs on this machine)")


if __name__ == "__main__":
    main()
