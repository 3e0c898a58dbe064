"""``planefuse live LIVE.yaml``: the whole system on cameras as they stream, people on a live page."""

from __future__ import annotations

from pathlib import Path

import typer
from rich.console import Console
from rich.markup import escape

from ._app import app, exit_with_error


@app.command()
def live(
    config: Path = typer.Argument(..., help="Live configuration: the run configuration and each camera's stream "
                                  "(docs/live.md)."),
    host: str = typer.Option(None, "--host", help="Serve the live page on this interface instead of the "
                             "configuration's (127.0.0.1 by default: this machine only); e.g. 0.0.0.0 for every "
                             "interface, explicitly."),
    port: int = typer.Option(None, "--port", min=0, help="The live page's port (0: any free one)."),
    no_page: bool = typer.Option(False, "--no-page", help="Do not serve the live page."),
    tracks_jsonl: str = typer.Option(None, "--tracks-jsonl", help="Tracks as JSON lines: '-' on standard output, "
                                     "or a file (overrides the configuration's tracks_jsonl)."),
    duration_s: float = typer.Option(None, "--duration-s", min=0.0, help="Stop after this time [s] (default: "
                                     "until Ctrl-C or every source has ended)."),
    threads: int = typer.Option(None, "--threads", min=1, help="Threads of OpenCV and numba (--threads 1: one "
                                "core)."),
    fresh: bool = typer.Option(False, "--fresh", help="Start afresh in an output folder holding a live run of this "
                               "configuration (default: resume it) or another run's results."),
    force: bool = typer.Option(False, "--force", help="Write into an output folder holding another run's results "
                               "(replaced) or files planefuse did not write (kept)."),
) -> None:
    """Read the configured cameras as they stream (RTSP, HTTP MJPEG, local devices, video files played at their
    rate), feed their frames to the whole system as they arrive, write the tracks as they come (tracks.csv in
    the output folder, JSON lines) and show them on a live page. Frames the system cannot keep up with are
    dropped, the oldest first, and counted per camera; a stream that stalls or closes is retried with back-off
    and unobserved meanwhile. Ctrl-C ends the run with every output flushed (live_report.json: per camera
    frames used, skipped, dropped, reconnects; latency). Run again on the same output folder, it resumes: track
    identities and output steps go on, tracks.csv and tracks_mot.txt are appended to; a folder holding another
    run's results is refused unless --fresh/--force says so."""
    from dataclasses import replace

    from ..config import ConfigError, config_hash, load_config
    from ..io import read_recording
    from ..live import LiveRun, load_live_config
    from ._run import set_threads

    err = Console(stderr=True)
    try:
        lcfg = load_live_config(config)
        cfg = load_config(lcfg.run)
    except (ValueError, ConfigError) as exc:
        exit_with_error(str(exc), 2)
    settings = lcfg.settings()
    if host is not None:
        settings = replace(settings, host=host)
    if port is not None:
        settings = replace(settings, port=port)
    if no_page:
        settings = replace(settings, serve=False)
    try:
        rec = read_recording(cfg.recording)
    except (ValueError, OSError) as exc:
        exit_with_error(f"recording {cfg.recording}: {exc}", 1)
    if threads is not None:
        set_threads(threads)
    # beside (not over) a recording run's results in the same folder
    out_dir = lcfg.out_dir if lcfg.out_dir is not None else (
        None if cfg.outputs.out_dir is None else cfg.outputs.out_dir / "live")
    jsonl = tracks_jsonl if tracks_jsonl is not None else lcfg.tracks_jsonl
    try:
        run = LiveRun(rec, cfg.system_params(), settings, out_dir=out_dir, jsonl=jsonl,
                      on_event=lambda m: err.print(f"[dim]live:[/dim] {escape(m)}", highlight=False),
                      resume=not fresh, force=force, config_key=config_hash(cfg))
    except (ValueError, ImportError, OSError) as exc:
        exit_with_error(str(exc), 1)
    try:
        summary = run.run(duration_s)
    except (ValueError, ImportError, OSError) as exc:
        exit_with_error(str(exc), 1)
    finally:
        run.close()
    p50, p95 = summary.latency_ms(50), summary.latency_ms(95)
    err.print(f"{summary.outputs} output steps; latency p50 "
              f"{'-' if p50 is None else f'{p50:.0f}'} ms, p95 {'-' if p95 is None else f'{p95:.0f}'} ms"
              + (f"; outputs in {escape(str(out_dir))}" if out_dir is not None else ""), highlight=False)
    if summary.interrupted:
        raise typer.Exit(130)
