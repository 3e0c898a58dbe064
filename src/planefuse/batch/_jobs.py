"""What one task of a batch is, and how a worker runs it."""

from __future__ import annotations

import os
import traceback
import warnings
from dataclasses import dataclass, field

from ..outputs import OutputSettings
from ..pipeline import RunPlan

__all__ = ["SceneSpec", "BatchJob", "JobResult", "TABLES_ONLY", "run_job"]


@dataclass(frozen=True)
class SceneSpec:
    """A simulated recording, made on the worker that runs the job (nothing large crosses the network).

    Attributes
    ----------
    seed : int
        Scene seed (people's paths, sensor noise).
    duration_s : float
        Simulated duration [s].
    scene_path : str, optional
        Scene YAML (:func:`planefuse.sim.load_scene_config`); the default scene when None. Its ``seed`` and
        ``duration_s`` are replaced by the ones above.
    """

    seed: int = 1
    duration_s: float = 10.0
    scene_path: str | None = None

    def recording(self):
        """The simulated :class:`~planefuse.sim.SimulatedRecording`."""
        from ..sim import default_scene_config, load_scene_config, simulate

        if self.scene_path is None:
            cfg = default_scene_config(duration_s=self.duration_s, seed=self.seed)
        else:
            cfg = load_scene_config(self.scene_path).model_copy(
                update={"duration_s": self.duration_s, "seed": self.seed})
        return simulate(cfg)


#: What a batch run writes when its plan has an out_dir and is not from a configuration: the tables, occupancy
#: and metrics, without figures, animation or report.
TABLES_ONLY = OutputSettings(figures=False, animation="none", report=False)


@dataclass(frozen=True)
class BatchJob:
    """One run of the whole system.

    Attributes
    ----------
    name : str
        Label of the run in tables and progress (unique within a batch).
    recording : str or SceneSpec
        A recording folder (read on the worker, so it must be reachable there under that path) or a
        simulated scene.
    plan : RunPlan
        What to run and what to write (:meth:`planefuse.config.RunConfig.plan` gives what ``planefuse run``
        runs); with no ``out_dir`` only the metrics are computed.
    tags : dict
        Free labels carried into the result (scenario, seed, configuration name, ...).
    """

    name: str
    recording: str | SceneSpec
    plan: RunPlan = field(default_factory=RunPlan)
    tags: dict = field(default_factory=dict)


@dataclass(frozen=True)
class JobResult:
    """What a worker gives back for one :class:`BatchJob`.

    Attributes
    ----------
    name : str
    tags : dict
    metrics : dict
        :func:`planefuse.pipeline.run_plan`'s metrics (the scores with ground truth, the run's counts without;
        empty on error).
    error : str or None
        One line naming what failed, when the run failed (the other jobs go on).
    detail : str or None
        The failure's traceback, for a log file.
    warnings : list of str
        The warnings the run raised on its worker (repairs, limits), each once, to be shown where the batch was
        started (a remote worker's own output is not).
    """

    name: str
    tags: dict
    metrics: dict
    error: str | None = None
    detail: str | None = None
    warnings: list[str] = field(default_factory=list)

    @property
    def ok(self) -> bool:
        return self.error is None


def threads_from_environment() -> None:
    """Give OpenCV the environment's thread count, and numba's configuration the environment's, before any kernel.

    A worker whose environment arrives after it imported numba (a nanny's ``env``: the spawned process imports
    the client's main module first) has a numba pool sized from the environment it started with: numba reads
    ``NUMBA_NUM_THREADS`` for that once, at import, which is why :func:`planefuse.batch.batch_client` gives its
    LocalCluster's workers their environment before they start. What re-reading the configuration here still
    does: numba re-reads it at each compilation and raised "Cannot set NUMBA_NUM_THREADS to a different value
    once the threads have been launched" (seen once in an 18-run sweep) when a kernel started the pool before
    that; re-reading before any kernel makes the configured and launched values agree. OpenCV's pool has one
    thread per core unless ``OPENCV_FOR_THREADS_NUM`` says otherwise, which it reads once: each of two
    single-threaded workers on two cores otherwise ran OpenCV (background subtraction, morphology, warps) on two
    threads.
    """
    import numba

    numba.config.reload_config()
    n = os.environ.get("OPENCV_FOR_THREADS_NUM")
    if n:
        import cv2

        cv2.setNumThreads(int(n))


def run_job(job: BatchJob) -> JobResult:
    """Run one job in this process (what a dask worker calls); failures are returned, not raised."""
    from ..io import read_recording
    from ..pipeline import run_plan

    threads_from_environment()
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("default")  # each warning once per place, as a process shows them
        try:
            rec = job.recording.recording() if isinstance(job.recording, SceneSpec) else \
                read_recording(job.recording)
            _, metrics = run_plan(rec, job.plan, progress_mode="quiet")
        except Exception as exc:  # noqa: BLE001 - one failed run must not stop a batch; reported per job
            return JobResult(job.name, dict(job.tags), {}, f"{job.name}: {type(exc).__name__}: {exc}",
                             traceback.format_exc(), _messages(caught))
    return JobResult(job.name, dict(job.tags), metrics, warnings=_messages(caught))


def _messages(caught: list[warnings.WarningMessage]) -> list[str]:
    """The caught warnings' messages, each once, in order."""
    return list(dict.fromkeys(" ".join(str(w.message).split()) for w in caught))
