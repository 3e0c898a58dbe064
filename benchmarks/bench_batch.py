"""Batch speed-up: a 12-run sweep (6 seeds x 2 configurations of the default scene) on dask clusters of 1 and 2
single-threaded workers, in the same run, and the same sweep on a ``dask scheduler`` with two ``dask worker``
processes started as separate processes (as on several machines); checks that every cluster gives the serial
metrics (run time aside).

Each cluster's start-up (processes, importing planefuse, numba's cached kernels) is timed apart from the sweep,
which runs on the started cluster: a cluster is started once and then serves many sweeps. The runs are
submitted longest first (the filter runs), so that no long run is left alone at the end. Every cluster runs the
sweep once per round, in the same order, ``--repeats`` rounds (interleaved: the machine's load moves); a row's
speed-up is against the one-worker sweep of the same round. The workers' CPU seconds over the sweep
(``time.process_time`` in each worker, summed) are printed beside the wall-clock time: on a machine that
delivers two cores they should not grow from one worker to two.

``--before-fix`` adds a LocalCluster of 2 workers made as ``batch_client`` made it before c6be4cd: the
single-thread environment given as the nanny's ``env``, which a spawned worker gets only after it imported this
script (so numba, whose thread pool is then sized to the machine's cores).

Usage: ``PYTHONPATH=src python benchmarks/bench_batch.py [--duration-s 10] [--seeds 1-6] [--repeats 2]
[--no-scheduler] [--before-fix]``
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


def _sweep(client, jobs) -> tuple[float, float, list]:
    """The sweep's time on a started cluster [s], its workers' CPU time [s], and its results."""
    client.run(_warm)
    cpu0 = client.run(time.process_time)
    t0 = time.perf_counter()
    results = run_batch(jobs, progress_mode="quiet", client=client)
    wall = time.perf_counter() - t0
    cpu1 = client.run(time.process_time)
    return wall, sum(cpu1[w] - cpu0[w] for w in cpu1), results


def _local_sweep(jobs, n_workers: int, before_fix: bool = False) -> tuple[float, float, float, list]:
    """Start-up + close [s], then :func:`_sweep`'s numbers, on a LocalCluster of ``n_workers``."""
    t0 = time.perf_counter()
    if before_fix:
        from distributed import Client, LocalCluster

        env = {**SINGLE_THREAD_ENV, "PYTHONPATH": os.environ.get("PYTHONPATH", "")}
        with LocalCluster(n_workers=n_workers, threads_per_worker=1, processes=True, dashboard_address=None,
                          env=env) as cluster, Client(cluster) as client:
            sweep, cpu, results = _sweep(client, jobs)
    else:
        with batch_client(n_workers=n_workers) as client:
            sweep, cpu, results = _sweep(client, jobs)
    return time.perf_counter() - t0 - sweep, sweep, cpu, results


def _port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _scheduler_sweep(jobs, n_workers: int = 2) -> tuple[float, float, float, list]:
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
                    sweep, cpu, results = _sweep(client, jobs)
                return time.perf_counter() - t0 - sweep, sweep, cpu, results
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
    ap.add_argument("--repeats", type=int, default=2, help="rounds, every cluster once per round")
    ap.add_argument("--no-scheduler", action="store_true", help="skip the separate dask scheduler")
    ap.add_argument("--before-fix", action="store_true", help="add the LocalCluster as made before c6be4cd")
    args = ap.parse_args()
    lo, hi = (int(x) for x in args.seeds.split("-"))
    configs = {"filter": SystemParams(sound=False), "no filter": SystemParams(sound=False, use_filter=False)}
    jobs = [BatchJob(f"seed{s} {name}", SceneSpec(seed=s, duration_s=args.duration_s), RunPlan(p))
            for name, p in configs.items() for s in range(lo, hi + 1)]  # the filter runs (longest) first
    clusters = {"LocalCluster, 1 worker": lambda: _local_sweep(jobs, 1),
                "LocalCluster, 2 workers": lambda: _local_sweep(jobs, 2)}
    if args.before_fix:
        clusters["LocalCluster, 2 workers, environment after import (before c6be4cd)"] = \
            lambda: _local_sweep(jobs, 2, before_fix=True)
    if not args.no_scheduler:
        clusters["dask scheduler + 2 dask worker processes"] = lambda: _scheduler_sweep(jobs)
    print(f"{len(jobs)} runs: default scene {args.duration_s:g} s, seeds {args.seeds}, filter on and off, sound off")
    print("| round | cluster | start-up + close [s] | sweep [s] | speed-up vs 1 worker (same round) "
          "| workers' CPU [s] | CPU vs 1 worker | identical metrics | load average (1 min) |")
    print("|---|---|---|---|---|---|---|---|---|")
    ref_results = None
    for r in range(1, args.repeats + 1):
        ref = None
        for name, sweep_on in clusters.items():
            start, sweep, cpu, results = sweep_on()
            ref = ref or (sweep, cpu)
            ref_results = ref_results or results
            same = all(a.ok and b.ok and {k: v for k, v in a.metrics.items() if k not in TIMING}
                       == {k: v for k, v in b.metrics.items() if k not in TIMING} for a, b in zip(ref_results, results))
            print(f"| {r} | {name} | {start:.1f} | {sweep:.1f} | {ref[0] / sweep:.2f} | {cpu:.1f} | {cpu / ref[1]:.2f} "
                  f"| {same} | {os.getloadavg()[0]:.1f} |", flush=True)


if __name__ == "__main__":
    main()
