"""``planefuse check CONFIG.yaml``: validate a configuration and its recording without running."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import typer
from rich.markup import escape
from rich.table import Table

from ..config import CheckReport, ConfigError, RunConfig, check_run_config, load_config
from ._app import app, console
from ._config import exit_on_config_error
from ._import import recording_check_config



def _report_json(report: CheckReport) -> str:
    return json.dumps({
        "ok": report.ok,
        "issues": [{"level": i.level, "subject": i.subject, "message": i.message} for i in report.issues],
        "camera_visible_fraction": {k: np.asarray(v).tolist() for k, v in report.camera_visible_fraction.items()},
    })


@app.command()
def check(
    config: Path = typer.Argument(..., help="Run configuration (YAML), or a recording folder (checked with its "
                                  "own plane stack and monitored area, 10 cm cells)."),
    log_json: bool = typer.Option(False, "--log-json", help="Print the findings as one JSON object."),
    figures: Path = typer.Option(None, "--figures", help="Also write pictures to this folder: each camera's image "
                                 "with the monitored area, a 1 m ground grid and each plane's border drawn "
                                 "(camera_NAME.png), and a top view of how many cameras see each cell "
                                 "(coverage.png)."),
    frame: int = typer.Option(0, "--frame", help="With --figures: the recording's frame to draw on (negative: from "
                              "the end)."),
) -> None:
    """Validate CONFIG and its recording (calibrations, streams, time stamps, camera coverage) without running;
    with --figures, draw the ground, the monitored area and the planes on every camera."""
    try:
        cfg, chosen = (load_config(config), ()) if not config.is_dir() else recording_check_config(config)
    except ConfigError as err:
        if log_json:
            print(json.dumps({"ok": False, "file": str(err.file), "issues": [
                {"level": "error", "subject": i.field_path, "message": i.message, "expected": i.expected,
                 "line": i.line} for i in err.issues]}))
            raise typer.Exit(2) from None
        exit_on_config_error(err)
    report, rec = check_run_config(cfg)
    for message in chosen:
        report.add("info", "configuration", message)
    _check_person_model(cfg, report, rec)
    if figures is not None and rec is not None and cfg.sensors.cameras.enabled and rec.camera_streams:
        from ..pipeline import stack_for_recording

        try:
            stack = stack_for_recording(rec, cfg.system_params(), check_cameras=False)
        except ValueError:
            pass  # reported by check_run_config as a planes error
        else:
            _write_figures(rec, stack, figures, frame, report)
    elif figures is None and rec is not None and cfg.sensors.cameras.enabled and rec.camera_streams:
        report.add("info", "figures", "see where the monitored area, the ground and the planes lie on each "
                   "camera's image: planefuse check ... --figures DIR")
    if log_json:
        print(_report_json(report))
    else:
        table = Table(title=escape(f"planefuse check {config}"))
        table.add_column("level")
        table.add_column("subject")
        table.add_column("finding", overflow="fold")  # a long path or checksum wraps, never cut
        style = {"error": "bold red", "warning": "yellow", "info": "green"}
        for it in report.issues:
            table.add_row(f"[{style[it.level]}]{it.level}[/]", escape(it.subject), escape(it.message))
        console.print(table)
        console.print("[bold green]OK[/]: ready to run" if report.ok
                      else f"[bold red]{len(report.errors)} error(s)[/]")
    raise typer.Exit(0 if report.ok else 1)


def _check_person_model(cfg: RunConfig, report: CheckReport, rec=None) -> None:
    """The person detector's model (loaded and checked by :func:`load_config` already): its checksum, its engine and
    its cost per frame on one core, measured here at the canvas each of ``rec``'s cameras will use (the configured
    one, or the one fitted to its frames; 416 x 416 without a recording)."""
    cams = cfg.sensors.cameras
    if not cams.enabled or cams.person_detector != "yolox":
        return
    import cv2

    from ..vision import YoloxDetector, fitted_input_size

    frame_sizes = sorted({(c.intrinsics.width_px, c.intrinsics.height_px) for c in rec.cameras}) if rec else []
    canvases = {}  # canvas -> a frame size that uses it
    for wh in frame_sizes or [(416, 416)]:
        canvases.setdefault(tuple(cams.person_input_px or fitted_input_size(wh)), wh)
    threads = cv2.getNumThreads()
    cv2.setNumThreads(1)
    try:
        costs = []
        for canvas, frame_wh in canvases.items():
            det = YoloxDetector(cams.person_model, canvas, engine=cams.person_engine, threads=1)
            costs.append(f"{det.cost_ms(frame_wh):.1f} ms per {frame_wh[0]} x {frame_wh[1]} frame at a {canvas[0]} x "
                         f"{canvas[1]} px canvas")
    finally:
        cv2.setNumThreads(threads)
    info = det.info
    report.add("info", "sensors.cameras.person_model",
               f"{info.path}: sha256 {info.sha256}, {info.n_classes} classes, run by {info.engine}, on one core "
               f"(measured now): {'; '.join(costs)}")


def _write_figures(rec, stack, folder: Path, frame: int, report: CheckReport) -> None:
    """The pictures of :func:`planefuse.viz.installation_preview` written into ``folder``."""
    from ..outputs import atomic_write_bytes
    from ..viz import installation_preview

    try:
        pictures = installation_preview(rec, stack, frame_index=frame)
        folder.mkdir(parents=True, exist_ok=True)
        for stem, png in pictures.items():
            atomic_write_bytes(folder / f"{stem}.png", png)
    except (ValueError, OSError) as err:
        report.add("error", "figures", f"cannot draw the pictures into {folder}: {err}")
        return
    report.add("info", "figures", f"wrote {', '.join(f'{s}.png' for s in pictures)} to {folder}")
