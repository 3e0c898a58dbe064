"""``planefuse demo``: the whole system on the embedded default scene (no downloads)."""

from __future__ import annotations

import time
from pathlib import Path

import typer
from rich.table import Table

from ._app import app, console


@app.command()
def demo(
    out: Path = typer.Option(None, "--out", help="Output folder (default: a new planefuse-demo-<time> folder)."),
    duration_s: float = typer.Option(10.0, "--duration-s", help="Simulated duration [s]."),
    seed: int = typer.Option(1, help="Scene seed."),
    quiet: bool = typer.Option(False, "--quiet", help="No progress bars."),
    rerun: bool = typer.Option(False, "--rerun", help="Also write planefuse.rrd for the rerun viewer."),
    fresh: bool = typer.Option(False, "--fresh", help="Start afresh in an --out folder holding an interrupted "
                               "demo of the same scene (default: resume it)."),
) -> None:
    """Simulate the default scene (cameras+IMU, nodding laser, binaural head), register every modality on
    the plane stack, filter with one BOF per plane, track people, evaluate against ground truth and write
    metrics.json, tracks and figures to OUT."""
    from ..pipeline import SystemParams, run_to_folder
    from ..sim import default_scene_config, simulate

    out = out if out is not None else Path(f"planefuse-demo-{time.strftime('%Y%m%d-%H%M%S')}")
    t0 = time.perf_counter()
    rec = simulate(default_scene_config(duration_s=duration_s, seed=seed))
    _, metrics = run_to_folder(rec, SystemParams(), out, progress_mode="quiet" if quiet else "rich",
                               rerun=rerun, resume=not fresh)
    metrics["wall_time_s"] = time.perf_counter() - t0
    _print_summary(metrics, out)


def _print_summary(metrics: dict, out: Path) -> None:
    table = Table(title="planefuse demo: default simulated scene")
    table.add_column("metric")
    table.add_column("value", justify="right")
    for k in ("moda", "modp", "precision", "recall", "mota", "idf1", "id_switches", "camera_only_moda",
              "azimuth_mae_deg", "n_camera_frames", "n_laser_scans", "n_sound_blocks", "wall_time_s"):
        if k in metrics:
            v = metrics[k]
            table.add_row(k, f"{v:.3f}" if isinstance(v, float) else str(v))
    console.print(table)
    console.print(f"outputs in {out}/ (metrics.json, tracks.csv, figures/, report.html)")
