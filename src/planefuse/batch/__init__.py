"""Many runs of the whole system at once on dask.distributed: recordings, seeds, scenarios, configurations.

Quick start::

    from planefuse.batch import BatchJob, SceneSpec, run_batch
    from planefuse.pipeline import RunPlan, SystemParams

    jobs = [BatchJob(f"seed{s}", SceneSpec(seed=s, duration_s=10), RunPlan(SystemParams())) for s in range(1, 7)]
    for r in run_batch(jobs, n_workers=2):          # or scheduler="tcp://host:8786"
        print(r.name, r.metrics["moda"] if r.ok else r.error)

See ``docs/batch.md``.
"""

from ._cluster import batch_client, run_batch
from ._jobs import TABLES_ONLY, BatchJob, JobResult, SceneSpec, run_job
from ._streams import CameraStream, remote_foregrounds

__all__ = ["TABLES_ONLY", "BatchJob", "CameraStream", "JobResult", "SceneSpec", "batch_client", "remote_foregrounds",
           "run_batch", "run_job"]
