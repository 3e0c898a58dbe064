"""``planefuse check CONFIG.yaml``: validate a configuration and its recording without running."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import typer
from rich.markup import escape
from rich.table import Table

from ..config import CheckReport, ConfigError, check_run_config, load_config
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
) -> None:
    """Validate CONFIG and its recording (calibrations, streams, time stamps, camera coverage) without running."""
    try:
        cfg = load_config(config) if not config.is_dir() else recording_check_config(config)
    except ConfigError as err:
        if log_json:
            print(json.dumps({"ok": False, "file": str(err.file), "issues": [
                {"level": "error", "subject": i.field_path, "message": i.message, "expected": i.expected,
                 "line": i.line} for i in err.issues]}))
            raise typer.Exit(2) from None
        exit_on_config_error(err)
    report, _ = check_run_config(cfg)
    if log_json:
        print(_report_json(report))
    else:
        table = Table(title=escape(f"planefuse check {config}"))
        for col in ("level", "subject", "finding"):
            table.add_column(col)
        style = {"error": "bold red", "warning": "yellow", "info": "green"}
        for it in report.issues:
            table.add_row(f"[{style[it.level]}]{it.level}[/]", escape(it.subject), escape(it.message))
        console.print(table)
        console.print("[bold green]OK[/]: ready to run" if report.ok
                      else f"[bold red]{len(report.errors)} error(s)[/]")
    raise typer.Exit(0 if report.ok else 1)


