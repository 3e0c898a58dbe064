"""``planefuse batch CONFIG...``: many run configurations as dask.distributed tasks."""

from __future__ import annotations

import json
from pathlib import Path

import typer
from rich.markup import escape
from rich.table import Table

from ._app import app, console


@app.command()
def batch(
    configs: list[Path] = typer.Argument(..., help="Run configurations (as for planefuse run); each is one task."),
    scheduler: str = typer.Option(None, "--scheduler", help="Address of a running dask scheduler, e.g. "
                                  "tcp://10.0.0.5:8786 (default: a local cluster on this machine)."),
    workers: int = typer.Option(None, "--workers", min=1, help="Worker processes of the local cluster "
                                "(default: one per core; not with --scheduler)."),
    json_out: Path = typer.Option(None, "--json-out", help="Write every run's metrics (or error) as JSON."),
    quiet: bool = typer.Option(False, "--quiet", help="No progress bar."),
) -> None:
    """Run every configuration's recording through the whole system, one dask task per configuration, and
    write each run's folder exactly as planefuse run would (figures included where the configuration asks).
    A run that fails is reported by name; the others go on. Exit code 1 when any run failed."""
    from ..batch import BatchJob, run_batch
    from ..config import ConfigError, load_config

    jobs = []
    for path in configs:
        try:
            cfg = load_config(path)
        except ConfigError as exc:
            console.print(escape(str(exc)), style="red")
            raise typer.Exit(2) from None
        jobs.append(BatchJob(path.stem if path.stem not in {j.name for j in jobs} else str(path),
                             str(cfg.recording), cfg.plan(), tags={"config": str(path)}))
    try:
        results = run_batch(jobs, scheduler=scheduler, n_workers=workers,
                            progress_mode="quiet" if quiet else "rich")
    except (OSError, ValueError) as exc:
        console.print(f"error: {escape(str(exc))}", style="red")
        raise typer.Exit(2) from None
    for r in results:  # what each run warned of on its worker
        for w in r.warnings:
            console.print(f"warning: {escape(r.name)}: {escape(w)}", soft_wrap=True, highlight=False)
    table = Table(title="planefuse batch")
    for col in ("run", "MODA", "MOTA", "IDF1", "tracks", "missing camera frames", "run time [s]", "error"):
        table.add_column(escape(col), overflow="fold")
    for r in results:
        m = r.metrics
        cells = [f"{m[k]:.3f}" if k in m else "-" for k in ("moda", "mota", "idf1")]
        counts = [str(m[k]) if k in m else "-" for k in ("n_tracks", "n_missing_camera_frames")]
        table.add_row(escape(r.name), *cells, *counts, f"{m['elapsed_s']:.3f}" if "elapsed_s" in m else "-",
                      escape(r.error or ""))
    console.print(table)
    if json_out is not None:
        json_out.write_text(json.dumps([{"name": r.name, "tags": r.tags, "metrics": r.metrics, "error": r.error,
                                         "warnings": r.warnings} for r in results], indent=1, default=float))
    if not all(r.ok for r in results):
        raise typer.Exit(1)
