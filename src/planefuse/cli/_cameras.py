"""``planefuse cameras``: the camera pipeline on EPFL, WILDTRACK and simulated data."""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np
import typer

from ..eval import detection_scores
from ..grid import PlaneStack
from ..vision import (
    CameraParams,
    CameraReport,
    ForegroundParams,
    PersonParams,
    camera_detections,
    epfl_box_frames,
    epfl_ground_truth,
    epfl_lookups,
    load_epfl_sequence,
    lookups_from_cameras,
    read_epfl_detections,
    recording_frames,
    wildtrack_frames,
)
from ._app import app, console, exit_with_error, units_table, write_json

cameras_app = typer.Typer(help="Camera pipeline: foreground -> plane stack -> people on the ground.",
                          no_args_is_help=True)
app.add_typer(cameras_app, name="cameras")


def _heights(text: str) -> list[float]:
    try:
        return [float(h) for h in text.split(",")]
    except ValueError:
        raise typer.BadParameter(f"heights must be comma-separated numbers, got {text!r}") from None


def _print_scores(title: str, rows: list[tuple[str | None, dict]]) -> None:
    """Detection scores, one row per (run name, scores); the run column is left out when no row names one."""
    named = any(name for name, _ in rows)
    console.print(units_table(
        title, ("run",) * named + ("thr [m]", "frames", "GT", "TP", "FP", "FN", "MODA", "MODP", "prec.", "recall"),
        [(name,) * named + (f"{s['match_distance_m']:.2f}", s["frames"], s["gt"], s["tp"], s["fp"], s["fn"],
                            f"{s['moda']:.3f}", f"{s['modp']:.3f}", f"{s['precision']:.3f}", f"{s['recall']:.3f}")
         for name, s in rows],
        caption="thr: match distance [m]; GT: ground-truth people; MODA = 1 - (FN + FP) / GT; MODP: mean "
                "localisation precision of the matches (1 - distance / thr)"))


#: Ground area of the EPFL terrace scored by ``cameras epfl`` [m]: x range, y range of the metric map.
TERRACE_EXTENT_M = ((-1.0, 7.5), (-1.5, 9.5))


@cameras_app.command("epfl")
def epfl(
    root: Path = typer.Argument(..., help="EPFL folder holding <sequence>-c*/Homography.txt and gt/gt.txt."),
    sequence: str = typer.Option("terrace1", help="Sequence name prefix (the folder lists the ones it holds)."),
    metres_per_unit: float = typer.Option(None, help="Top-view unit of the homographies [m] for sequences other "
                                          "than terrace (terrace: planefuse's metric map, ~0.0219 m)."),
    detections: str = typer.Option("", help="Per-camera MOTChallenge file inside each camera folder "
                                   "(e.g. det/det.txt); default: the ground-truth boxes."),
    foot_fraction: float = typer.Option(0.1, help="Bottom fraction of each box used as ground-plane foreground."),
    cell_m: float = typer.Option(0.05, help="Cell size [m]."),
    step: int = typer.Option(1, help="Use every step-th frame."),
    thresholds_m: str = typer.Option("0.5,1.0", help="Match distances [m] to score at."),
    min_cameras: int = typer.Option(3, help="Cameras that must see a ground cell."),
    nms_radius_m: float = typer.Option(0.8, help="Minimum distance between detections [m]."),
    json_out: Path = typer.Option(None, help="Write the scores as JSON here."),
) -> None:
    """Detect people on an EPFL POM sequence from per-view boxes (ground homographies only) and score them.

    Ground truth: the multi-view median of the boxes' foot points; people seen by one camera are ignored.
    """
    terrace = sequence.startswith("terrace") and metres_per_unit is None
    if not terrace and metres_per_unit is None:
        exit_with_error(f"sequence {sequence!r}: planefuse knows the metric ground map of the terrace sequences only; "
                        "give --metres-per-unit (the length of one top-view unit [m])")
    try:
        seq = load_epfl_sequence(root, sequence, metres_per_unit=metres_per_unit)
        gt = epfl_ground_truth(seq)
        if terrace:
            (x0, x1), (y0, y1) = TERRACE_EXTENT_M
        else:  # the annotated ground area, 1 m around it
            xy = np.concatenate([np.concatenate(v) for v in gt.values()])
            (x0, y0), (x1, y1) = xy.min(axis=0) - 1.0, xy.max(axis=0) + 1.0
        stack = PlaneStack.from_extent([0.0], (x0, x1), (y0, y1), cell_m)
        lookups = epfl_lookups(seq, stack)
        boxes = read_epfl_detections(root, seq.names, detections) if detections else None
        frames = seq.frames[::step]
        params = CameraParams(foreground=None,
                              person=PersonParams(min_cameras=min_cameras, nms_radius_m=nms_radius_m))
        pairs = []
        for _, det in camera_detections(epfl_box_frames(seq, frames, boxes=boxes, foot_fraction=foot_fraction),
                                        lookups, stack, params, names=seq.names):
            g, ign = gt[int(round(det.time_s * 25))]
            pairs.append((g, det.xy_m, ign))
        rows = [(None, detection_scores(pairs, float(t)).as_dict()) for t in _heights(thresholds_m)]
    except ValueError as err:
        exit_with_error(str(err))
    _print_scores(f"EPFL {sequence}: {len(frames)} frames, {len(seq.names)} cameras", rows)
    if json_out:
        write_json(json_out, [r for _, r in rows])


@cameras_app.command("wildtrack")
def wildtrack(
    root: Path = typer.Argument(..., help="WILDTRACK folder: intrinsic/, extrinsic/, Image_subsets/C1..C7/."),
    heights: str = typer.Option("0.1,0.5,1.0,1.5", help="Plane heights [m]."),
    cell_m: float = typer.Option(0.1, help="Cell size [m]."),
    out: Path = typer.Option(Path("wildtrack_detections.csv"), help="CSV of detections (time_s, x_m, y_m, "
                             "confidence, height_m)."),
) -> None:
    """Detect people in WILDTRACK frames (background subtraction, full camera model with distortion)."""
    report = CameraReport()
    try:
        cameras, frames = wildtrack_frames(root)
        stack = PlaneStack.from_extent(_heights(heights), (-3.0, 9.0), (-9.0, 27.0), cell_m)
        lookups = lookups_from_cameras(cameras, stack)
        with out.open("w", newline="") as fh:
            w = csv.writer(fh)
            w.writerow(["time_s", "x_m", "y_m", "confidence", "height_m"])
            for _, det in camera_detections(frames, lookups, stack, CameraParams(),
                                            names=[c.name for c in cameras], report=report):
                for (x, y), c, h in zip(det.xy_m, det.confidence, det.height_m):
                    w.writerow([f"{det.time_s:.3f}", f"{x:.3f}", f"{y:.3f}", f"{c:.3f}", f"{h:.2f}"])
    except ValueError as err:
        exit_with_error(str(err))
    console.print(f"{report.instants} instants, {report.n_missing} missing frames, blind cameras: "
                  f"{report.blind_cameras or 'none'}; detections in {out}")


@cameras_app.command("simulated")
def simulated(
    duration_s: float = typer.Option(20.0, help="Simulated duration [s]."),
    seed: int = typer.Option(1, help="Scene seed."),
    heights: str = typer.Option("0.1,0.5,1.0,1.5", help="Plane heights [m] of the multi-plane run."),
    method: str = typer.Option("knn", help="Background subtraction: knn, mog2, or 'masks' (exact masks)."),
    warmup_s: float = typer.Option(2.0, help="Seconds left out of the scores while the background is learnt [s]."),
    match_distance_m: float = typer.Option(0.5, "--match-distance-m", help="Match distance [m]."),
) -> None:
    """Score the camera pipeline on the simulator's default scene, multi-plane vs ground plane alone."""
    from ..sim import default_scene_config, simulate

    rec = simulate(default_scene_config(duration_s=duration_s, seed=seed))
    people = rec.groundtruth.people
    fg = None if method == "masks" else ForegroundParams(method=method)
    rows = []
    for name, hs in ((f"planes {heights} m", _heights(heights)), ("ground only, 0.1 m", [0.1])):
        stack = PlaneStack.from_extent(hs, rec.scene.room_xy_m[:2], rec.scene.room_xy_m[2:], 0.05)
        lookups = lookups_from_cameras(rec.cameras, stack)
        pairs = [(people.detections_at(det.time_s).xy_m, det.xy_m)
                 for _, det in camera_detections(recording_frames(rec, masks=fg is None), lookups, stack,
                                                 CameraParams(foreground=fg), names=[c.name for c in rec.cameras])
                 if det.time_s >= warmup_s]
        rows.append((name, detection_scores(pairs, match_distance_m).as_dict()))
    _print_scores(f"simulated default scene, seed {seed}, {duration_s:g} s, foreground: {method}", rows)
