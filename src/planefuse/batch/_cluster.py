"""Many runs as dask.distributed tasks: a LocalCluster by default, any scheduler by address."""

from __future__ import annotations

import os
from collections.abc import Iterator, Sequence
from contextlib import contextmanager

from ..outputs import progress_steps
from ._jobs import BatchJob, JobResult, run_job

__all__ = ["batch_client", "run_batch"]

#: Worker environment for a LocalCluster: one thread per library in each worker process, so that
#: ``n_workers`` processes use ``n_workers`` cores and a run gives the same numbers on any worker. It must be in
#: the process's environment when it starts: numba sizes its thread pool from ``NUMBA_NUM_THREADS`` when it is
#: imported, which a spawned worker does (importing the client's main module) before dask applies a nanny's
#: ``env``; set then, each worker ran numba's parallel kernels on one OpenMP thread per core, two workers four
#: spinning threads on two cores (:func:`batch_client` gives it as dask's ``pre-spawn-environ``).
SINGLE_THREAD_ENV = {name: "1" for name in ("NUMBA_NUM_THREADS", "OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS",
                                             "MKL_NUM_THREADS", "OPENCV_FOR_THREADS_NUM")}


@contextmanager
def batch_client(scheduler: str | None = None, n_workers: int | None = None) -> Iterator:
    """A ``distributed.Client``: connected to ``scheduler`` (``tcp://HOST:PORT``, a running ``dask scheduler``
    with its ``dask worker`` processes), or to a new LocalCluster of ``n_workers`` single-threaded worker
    processes (default: the machine's cores) closed on exit.

    Raises
    ------
    ValueError
        ``n_workers`` given together with ``scheduler`` (a remote cluster's size is its own), or below 1.
    OSError
        The scheduler cannot be reached (names the address).
    """
    try:
        from distributed import Client, LocalCluster
    except ImportError:  # pragma: no cover - the extra is part of the dev install
        raise ImportError("planefuse batch needs dask.distributed: pip install 'planefuse[distributed]'") from None
    if scheduler is not None:
        if n_workers is not None:
            raise ValueError("n_workers is for a local cluster; a scheduler's workers are started with it")
        try:
            client = Client(scheduler, timeout="10s")
        except (OSError, TimeoutError) as exc:
            raise OSError(f"dask scheduler {scheduler}: cannot connect ({exc})") from None
        try:
            yield client
        finally:
            client.close()
        return
    n = n_workers if n_workers is not None else (os.cpu_count() or 1)
    if n < 1:
        raise ValueError(f"n_workers must be >= 1, got {n}")
    # the parent's PYTHONPATH reaches the spawned workers (a source checkout run without installing)
    env = dict(SINGLE_THREAD_ENV)
    if os.environ.get("PYTHONPATH"):
        env["PYTHONPATH"] = os.environ["PYTHONPATH"]
    with _pre_spawn_environ(env) as restore:
        cluster = LocalCluster(n_workers=n, threads_per_worker=1, processes=True, dashboard_address=None, env=env)
        restore()
        with cluster, Client(cluster) as client:
            yield client


@contextmanager
def _pre_spawn_environ(env: dict[str, str]) -> Iterator:
    """Give ``env`` to the worker processes a LocalCluster spawns, from their first instruction, and leave this
    process's environment as it was.

    ``env`` becomes part of dask's ``distributed.nanny.pre-spawn-environ``, which each nanny reads when it is
    made (so a worker it restarts gets it too; this process's variables of the same names would win there, so
    they are set to ``env`` meanwhile). The nanny copies it into this process's ``os.environ`` before it spawns
    a worker, and leaves it there: here ``NUMBA_NUM_THREADS=1`` in a process whose numba pool may already run
    more threads, and numba re-reads its environment at every compilation and raises on a different pool size.
    So the variables this process had are put back once the cluster started (call the yielded ``restore()``)
    and again on exit (a nanny restarting a worker sets them again).
    """
    import dask

    pre_spawn = {**dask.config.get("distributed.nanny.pre-spawn-environ"), **env}
    keys = set(pre_spawn) | {"PYTHONHASHSEED"}  # the nanny also sets a hash seed
    saved = {k: os.environ.get(k) for k in keys}
    os.environ.update(env)

    def restore() -> None:
        for k, v in saved.items():
            if v is None:
                os.environ.pop(k, None)
            else:
                os.environ[k] = v

    try:
        with dask.config.set({"distributed.nanny.pre-spawn-environ": pre_spawn}):
            yield restore
    finally:
        restore()


def run_batch(jobs: Sequence[BatchJob], scheduler: str | None = None, n_workers: int | None = None,
              progress_mode: str = "rich", client=None) -> list[JobResult]:
    """Run every job as one dask task; results in the order of ``jobs``.

    Each task computes exactly what :func:`run_job` computes in this process, so a batch's metrics (and its
    run folders) are identical to the serial runs'. A job that fails gives a :class:`JobResult` with
    ``error`` set; the others go on.

    Parameters
    ----------
    jobs : sequence of BatchJob
        Names must be unique.
    scheduler : str, optional
        Address of a running dask scheduler; default: a LocalCluster (:func:`batch_client`).
    n_workers : int, optional
        Size of the LocalCluster (default: the machine's cores).
    progress_mode : {"rich", "json", "quiet"}
        One bar advancing as the cluster finishes runs (:func:`planefuse.outputs.progress_steps`).
    client : distributed.Client, optional
        Use this client instead of making one (``scheduler`` and ``n_workers`` are then ignored).
    """
    names = [j.name for j in jobs]
    if len(set(names)) != len(names):
        dup = sorted({n for n in names if names.count(n) > 1})
        raise ValueError(f"batch job names must be unique; repeated: {', '.join(dup)}")
    if not jobs:
        return []
    if client is None:
        with batch_client(scheduler, n_workers) as c:
            return _run(c, list(jobs), progress_mode)
    return _run(client, list(jobs), progress_mode)


def _run(client, jobs: list[BatchJob], progress_mode: str) -> list[JobResult]:
    from distributed import as_completed

    futures = client.map(run_job, jobs, key=[f"planefuse-run-{i}-{j.name}" for i, j in enumerate(jobs)],
                         pure=False)
    try:
        with progress_steps(progress_mode) as progress, \
                progress.step("batch", total=len(jobs), unit="runs") as advance:
            for _ in as_completed(futures):
                advance(1)
        return client.gather(futures)
    finally:
        client.cancel(futures)
