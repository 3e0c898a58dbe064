"""``planefuse run CONFIG.yaml``: the whole system on a recording folder."""

from __future__ import annotations

import signal
from pathlib import Path

import typer
from rich.markup import escape

from ._app import app, console, exit_with_error
from ._config import exit_on_config_error


@app.command()
def run(
    config: Path = typer.Argument(..., help="Run configuration (planefuse config init writes an example)."),
    quiet: bool = typer.Option(False, "--quiet", help="No progress output."),
    log_json: bool = typer.Option(False, "--log-json", help="Progress as JSON lines on stderr (for scripts)."),
    rerun: bool = typer.Option(False, "--rerun", help="Also write planefuse.rrd (overrides outputs.rerun)."),
    fresh: bool = typer.Option(False, "--fresh", help="Start afresh: do not resume the finished chunks of an "
                               "interrupted run of the same configuration in outputs.out_dir; replace the "
                               "results of another run there."),
    force: bool = typer.Option(False, "--force", help="Write into an outputs.out_dir holding another run's "
                               "results (replaced) or files planefuse did not write (kept)."),
    workers: int = typer.Option(None, "--workers", min=1, help="Run each camera's front end (decoding, background "
                                "subtraction) as a stream on a local dask cluster of this many worker processes; "
                                "same results as without."),
    scheduler: str = typer.Option(None, "--scheduler", help="The same on a running dask scheduler, e.g. "
                                  "tcp://10.0.0.5:8786 (its workers must read the recording under the same path)."),
    threads: int = typer.Option(None, "--threads", min=1, help="Threads of OpenCV (decoding, background "
                                "subtraction) and numba in this process (default: one per core); --threads 1 "
                                "runs on one core. Same results with any number."),
) -> None:
    """Register every modality of the configured recording on the planes, filter, track, evaluate (when the
    recording has ground truth) and write occupancy, detections, tracks, metrics, figures and report.html.

    An interrupted run (Ctrl-C, kill) re-run with the same configuration resumes after its last finished
    chunk and ends with the same files as an uninterrupted run; --fresh starts afresh. An out_dir holding
    another run's results or files planefuse did not write is refused unless --fresh/--force says so;
    run_state.json says "finished" only once everything (figures, report included) is written, "failed" or
    "interrupted" (Ctrl-C, SIGTERM) otherwise. The run first validates as `planefuse check` does and refuses any
    input check reports an error for; one run writes into an out_dir at a time (a second is refused)."""
    from dataclasses import replace

    from ..config import ConfigError, check_run_config, load_config
    from ..outputs import progress_mode
    from ..pipeline import run_plan
    from ._demo import print_summary

    try:
        cfg = load_config(config)
    except ConfigError as exc:
        exit_on_config_error(exc)
    plan = replace(cfg.plan(resume=not fresh), force=force)
    if rerun:
        plan = replace(plan, outputs=replace(plan.outputs, rerun=True))
    if plan.outputs.rerun:
        try:
            import rerun as _  # noqa: F401
        except ImportError:
            exit_with_error("--rerun / outputs.rerun needs rerun-sdk: pip install 'planefuse[viz]'", 2)
    # the validation `planefuse check` runs: the same input gets the same verdict from both
    report, rec = check_run_config(cfg, resume=not fresh, force=force)
    if report.errors:  # one line each, the first last (what a script reads)
        first, *rest = report.errors
        for it in rest:
            console.print(f"[red]error:[/red] {escape(it.subject)}: {escape(' '.join(it.message.split()))}",
                          soft_wrap=True, highlight=False)
        exit_with_error(f"{first.subject}: {first.message}" + (f" (and the {len(rest)} error(s) above)" if rest else "")
                        + "; nothing was run", 1)
    if threads is not None:
        set_threads(threads)
    if workers is not None and scheduler is not None:
        exit_with_error("--workers starts a local cluster; a --scheduler's workers are started with it", 2)
    previous = _terminate_as_interrupt()
    try:
        if workers is None and scheduler is None:
            _, metrics = run_plan(rec, plan, progress_mode=progress_mode(quiet, log_json))
        else:
            from ..batch import batch_client

            with batch_client(scheduler, workers) as client:
                _, metrics = run_plan(rec, plan, progress_mode=progress_mode(quiet, log_json), client=client)
    except KeyboardInterrupt as exc:
        console.print(f"interrupted: outputs so far are in {escape(str(plan.out_dir))} (run_state.json says "
                      "interrupted); re-run to resume")
        raise typer.Exit(143 if isinstance(exc, Terminated) else 130) from None
    except (ValueError, ImportError, OSError) as exc:
        exit_with_error(str(exc), 1)
    except MemoryError as exc:  # beyond the pre-run estimate (planefuse.pipeline.check_memory): said, not a traceback
        exit_with_error(f"out of memory during the run ({exc or 'MemoryError'}; run_state.json says failed): coarsen "
                        "planes.cell_size_m, shrink the grid or lower outputs.chunk_steps", 1)
    finally:
        if previous is not None:
            signal.signal(signal.SIGTERM, previous)
    if metrics and not quiet:
        print_summary(metrics, plan.out_dir, f"planefuse run {config}")


class Terminated(KeyboardInterrupt):
    """SIGTERM (``kill PID``, a batch system's time limit) received during a run: handled as Ctrl-C is, so that the
    run's state says "interrupted" and every file written is valid."""


def _terminate_as_interrupt():
    """Have SIGTERM raise :class:`Terminated` in the main thread; returns the previous handler (None where it cannot
    be set: not the main thread)."""
    def handler(signum, frame):
        raise Terminated()

    try:
        return signal.signal(signal.SIGTERM, handler)
    except ValueError:
        return None


def set_threads(n: int) -> None:
    """Use at most ``n`` threads in OpenCV and numba (numba: at most the threads it was started with)."""
    import cv2
    import numba

    cv2.setNumThreads(int(n))
    numba.set_num_threads(max(1, min(int(n), numba.config.NUMBA_NUM_THREADS)))
