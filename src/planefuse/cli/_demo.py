"""``planefuse demo``: the whole system on the embedded default scene (no downloads), run as ``planefuse run``."""

from __future__ import annotations

import time
from pathlib import Path

import typer
from rich.markup import escape
from rich.table import Table

from ._app import app, console, exit_with_error


@app.command()
def demo(
    out: Path = typer.Option(None, "--out", help="Output folder (default: a new planefuse-demo-<time> folder)."),
    duration_s: float = typer.Option(10.0, "--duration-s", help="Simulated duration [s]."),
    seed: int = typer.Option(1, help="Scene seed."),
    quiet: bool = typer.Option(False, "--quiet", help="No progress bars."),
    rerun: bool = typer.Option(False, "--rerun", help="Also write planefuse.rrd for the rerun viewer."),
    fresh: bool = typer.Option(False, "--fresh", help="Start afresh in an --out folder holding an interrupted "
                               "demo of the same scene (default: resume it), replacing another run's results."),
) -> None:
    """Simulate the default scene (cameras+IMU, nodding laser, binaural head) and run it exactly as
    planefuse run runs a recording with the default configuration: register every modality on the plane
    stack, filter with one BOF per plane, track people, evaluate against ground truth and write metrics.json,
    tracks, figures and report.html to OUT (its config.yaml is that default configuration)."""
    from ..pipeline import run_plan
    from ..sim import default_scene_config, simulate

    out = out if out is not None else Path(f"planefuse-demo-{time.strftime('%Y%m%d-%H%M%S')}")
    t0 = time.perf_counter()
    plan = demo_config(out, seed=seed, duration_s=duration_s, rerun=rerun).plan(resume=not fresh)
    rec = simulate(default_scene_config(duration_s=duration_s, seed=seed))
    try:
        _, metrics = run_plan(rec, plan, progress_mode="quiet" if quiet else "rich")
    except (ValueError, ImportError, OSError) as exc:  # a refused --out folder, a missing rerun-sdk, ...
        exit_with_error(str(exc), 1)
    metrics["wall_time_s"] = time.perf_counter() - t0
    print_summary(metrics, out, f"planefuse demo: default simulated scene (seed {seed}, {duration_s:g} s)")


def demo_config(out: Path, *, seed: int = 1, duration_s: float = 10.0, rerun: bool = False):
    """The demo's :class:`~planefuse.config.RunConfig`: every field at its default, ``out`` as output folder.

    Its ``recording`` names the simulated recording, which ``planefuse simulate --out REC --seed SEED
    --duration-s DURATION`` writes to disk: ``planefuse run`` of REC with this configuration writes the
    demo's tracks, detections and metrics.
    """
    from ..config import OutputsConfig, RunConfig

    return RunConfig(recording=Path(f"simulated-default-scene-seed{seed}-{duration_s:g}s"),
                     outputs=OutputsConfig(out_dir=out, rerun=rerun))


def print_summary(metrics: dict, out: Path, title: str) -> None:
    """The run's main metrics as a table, and where its outputs are."""
    table = Table(title=escape(title))
    table.add_column("metric")
    table.add_column("value", justify="right")
    for k in ("moda", "modp", "precision", "recall", "mota", "idf1", "id_switches", "camera_only_moda",
              "azimuth_mae_deg", "n_steps", "n_tracks", "mean_tracks_per_step", "n_camera_frames",
              "n_missing_camera_frames", "n_laser_scans", "n_sound_blocks", "wall_time_s"):
        if k in metrics:
            v = metrics[k]
            table.add_row(k, f"{v:.3f}" if isinstance(v, float) else str(v))
    for k in ("mota", "idf1", "id_switches"):  # the offline pass's tracks (tracks_stitched.csv)
        if k in metrics.get("stitched", {}):
            v = metrics["stitched"][k]
            table.add_row(f"{k} (stitched)", f"{v:.3f}" if isinstance(v, float) else str(v))
    console.print(table)
    tracks = "tracks.csv, tracks_stitched.csv" if "stitched_identities" in metrics else "tracks.csv"
    console.print(f"outputs in {escape(str(out))}/ (metrics.json, {tracks}, figures/, report.html)")
