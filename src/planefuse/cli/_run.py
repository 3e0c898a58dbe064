"""``planefuse run CONFIG.yaml``: the whole system on a recording folder."""

from __future__ import annotations

from pathlib import Path

import typer
from rich.markup import escape

from ._app import app, console


@app.command()
def run(
    config: Path = typer.Argument(..., help="Run configuration (planefuse config init writes an example)."),
    quiet: bool = typer.Option(False, "--quiet", help="No progress output."),
    log_json: bool = typer.Option(False, "--log-json", help="Progress as JSON lines on stderr (for scripts)."),
    rerun: bool = typer.Option(False, "--rerun", help="Also write planefuse.rrd (overrides outputs.rerun)."),
    fresh: bool = typer.Option(False, "--fresh", help="Start afresh: do not resume the finished chunks of an "
                               "interrupted run of the same configuration in outputs.out_dir."),
) -> None:
    """Register every modality of the configured recording on the planes, filter, track, evaluate (when the
    recording has ground truth) and write occupancy, detections, tracks, metrics, figures and report.html.

    An interrupted run (Ctrl-C, kill) re-run with the same configuration resumes after its last finished
    chunk and ends with the same files as an uninterrupted run; --fresh starts afresh."""
    from dataclasses import replace

    from ..config import ConfigError, load_config
    from ..io import read_recording
    from ..outputs import progress_mode
    from ..pipeline import run_plan
    from ._demo import print_summary

    try:
        cfg = load_config(config)
    except ConfigError as exc:
        console.print(f"[red]{escape(str(exc))}[/red]")
        raise typer.Exit(2) from None
    try:
        rec = read_recording(cfg.recording)
    except (ValueError, OSError) as exc:
        console.print(f"[red]recording {escape(str(cfg.recording))}: {escape(str(exc))}[/red]")
        raise typer.Exit(1) from None
    plan = cfg.plan(resume=not fresh)
    if rerun:
        plan = replace(plan, outputs=replace(plan.outputs, rerun=True))
    try:
        _, metrics = run_plan(rec, plan, progress_mode=progress_mode(quiet, log_json))
    except KeyboardInterrupt:
        console.print(f"interrupted: outputs so far are in {escape(str(plan.out_dir))}; re-run to resume")
        raise typer.Exit(130) from None
    except ValueError as exc:
        console.print(f"[red]{escape(str(exc))}[/red]")
        raise typer.Exit(1) from None
    if metrics and not quiet:
        print_summary(metrics, plan.out_dir, f"planefuse run {config}")
