"""``planefuse pom CONFIG.pom`` and ``planefuse pom-export``: POM's configuration files, both ways.

``pom`` runs planefuse's generative model (planefuse.occupancy) on a POM configuration and its masks and writes
``proba-f<frame>.dat`` where its RESULT_FORMAT line says, as POM does; ``pom-export`` writes a ``.pom`` file
(silhouettes projected from a recording's calibrated cameras) and, optionally, the recording's foreground masks,
so that POM and planefuse can be run side by side on any recording.
"""

from __future__ import annotations

import time
from dataclasses import replace
from pathlib import Path

import numpy as np
import typer

from ._app import app, console, exit_with_error, units_table


@app.command("pom")
def pom(
    config: Path = typer.Argument(..., help="POM configuration file (.pom); relative names are taken relative to "
                                  "its folder."),
    first_frame: int = typer.Option(None, help="First frame (default: the PROCESS lines)."),
    n_frames: int = typer.Option(None, help="Number of frames from --first-frame."),
    threshold: float = typer.Option(0.5, help="Marginal above which a location is listed as occupied."),
    threads: int = typer.Option(1, min=1, help="Threads for the cameras (the same probabilities on any number; "
                                              "pays on large grids with free cores)."),
    quiet: bool = typer.Option(False, "--quiet", help="Only the summary."),
) -> None:
    """Run the generative occupancy model (Fleuret et al. 2008) on a POM configuration's masks; write
    proba-f<frame>.dat (one 'location probability' line per location) where RESULT_FORMAT says, as POM does."""
    from ..occupancy import read_pom, run_pom

    try:
        cfg = read_pom(config)
    except (ValueError, OSError) as exc:
        exit_with_error(str(exc))
    if (first_frame is None) != (n_frames is None):
        exit_with_error("--first-frame and --n-frames go together")
    frames = cfg.frames if first_frame is None else list(range(first_frame, first_frame + n_frames))
    if not frames:
        exit_with_error(f"{config}: no frame to process (no PROCESS line; use --first-frame and --n-frames)")
    if "RESULT_FORMAT" not in cfg.formats:
        console.print(f"note: {config} has no RESULT_FORMAT line: no proba-f<frame>.dat is written", highlight=False)
    rows, t0 = [], time.perf_counter()
    try:
        for frame, res in run_pom(cfg, frames, threads=threads):
            occupied = np.nonzero(res.marginals > threshold)[0]
            rows.append((frame, res.n_iterations, "yes" if res.converged else "no", len(occupied),
                         " ".join(str(k) for k in occupied[:12]) + (" ..." if len(occupied) > 12 else "")))
            if not quiet:
                console.print(f"frame {frame}: {res.n_iterations} iterations, {len(occupied)} locations above "
                              f"{threshold}", highlight=False)
    except (ValueError, OSError) as exc:
        exit_with_error(str(exc))
    seconds = time.perf_counter() - t0
    console.print(units_table(f"{config.name}: {cfg.silhouettes.n_cameras} cameras, {cfg.silhouettes.n_locations} "
                              f"locations, {len(frames)} frames, {1e3 * seconds / len(frames):.1f} ms per frame",
                              ("frame", "iterations", "converged", f"locations > {threshold}", "locations"), rows))


@app.command("pom-export")
def pom_export(
    config: Path = typer.Argument(..., help="Run configuration (its recording, cameras and planes)."),
    out: Path = typer.Argument(..., help=".pom file to write."),
    masks: bool = typer.Option(False, "--masks", help="Also write the recording's foreground masks (background "
                               "subtraction as configured, binary at the generative model's foreground threshold) "
                               "as masks/f<instant>-c<camera>.png beside OUT."),
    n_frames: int = typer.Option(None, help="Instants to write masks of (default: all)."),
    radius_m: float = typer.Option(None, help="Radius of the person's cylinder [m] (default: the generative "
                                   "sensor model's, GenerativeSensorParams.radius_m)."),
) -> None:
    """Write a POM configuration from a recording's calibrated cameras: one rectangle per camera and cell of the
    configured grid (cylinder across the planes' height bands, clipped at the image border); ground location k
    is cell (iy, ix) = divmod(k, nx)."""
    import cv2

    from ..config import ConfigError, load_config
    from ..io import read_recording
    from ..occupancy import silhouettes_from_cameras, write_pom
    from ..pipeline import stack_for_recording
    from ..vision import BackgroundSubtractor, recording_frames

    try:
        cfg = load_config(config)
    except ConfigError as exc:
        exit_with_error(str(exc))
    try:
        rec = read_recording(cfg.recording)
    except (ValueError, OSError) as exc:
        exit_with_error(f"recording {cfg.recording}: {exc}")
    system = cfg.system_params()
    try:
        stack = stack_for_recording(rec, system)
    except ValueError as exc:
        exit_with_error(f"{config}: {exc}")
    params = system.camera_params
    generative = params.generative if radius_m is None else replace(params.generative, radius_m=radius_m)
    sil = silhouettes_from_cameras(rec.cameras, stack, generative.person(stack))
    solver = generative.solver_params(stack)
    n_written = 0
    thr = generative.foreground_threshold
    if masks:
        folder = out.parent / "masks"
        folder.mkdir(parents=True, exist_ok=True)
        subs = [None if params.foreground is None else
                BackgroundSubtractor(c.intrinsics.width_px, c.intrinsics.height_px, params.foreground, c.name)
                for c in rec.cameras]
        for i, (_, images) in enumerate(recording_frames(rec, masks=params.foreground is None)):
            if n_frames is not None and i >= n_frames:
                break
            for c, img in enumerate(images):
                fg = np.zeros(sil.image_sizes[c]) if img is None else (
                    img / 255.0 if subs[c] is None else subs[c].apply(img))
                # what the generative model solves on: binary at foreground_threshold (as POM's masks), else grey
                fg = np.asarray(fg, float)
                img8 = np.round(255 * fg) if thr is None else np.where(fg >= thr, 255, 0)
                cv2.imwrite(str(folder / f"f{i}-c{c}.png"), img8.astype(np.uint8))
            n_written = i + 1
    comment = (f"written by planefuse pom-export from {config}\n"
               f"locations: cells of a {stack.ny} x {stack.nx} grid, x_min {stack.x_min_m} m, y_min {stack.y_min_m} m, "
               f"cell {stack.cell_size_m} m; location k = cell (iy, ix) = divmod(k, {stack.nx})\n"
               f"cameras: " + ", ".join(f"{i} = {c.name}" for i, c in enumerate(rec.cameras)))
    write_pom(out, sil, solver, input_view_format="masks/f%f-c%c.png", result_format="proba-f%f.dat",
              process=(0, n_written) if n_written else None, comment=comment)
    console.print(f"wrote {out} ({sil.n_cameras} cameras, {sil.n_locations} locations"
                  + (f", masks of {n_written} instants in {out.parent / 'masks'})" if n_written else ")"),
                  highlight=False)
