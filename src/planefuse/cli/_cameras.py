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


#: Largest ground grid ``planefuse cameras epfl`` builds (a wrong ground unit gives millions of cells).
MAX_EPFL_CELLS = 4_000_000


def epfl_stack(gt: dict, cell_m: float, margin_m: float = 1.0) -> PlaneStack:
    """The ground plane over the ground truth's extent + ``margin_m`` [m]; ``ValueError`` when the ground truth
    spans less than 2 m or more than 2 km, or the grid would exceed :data:`MAX_EPFL_CELLS` cells (a ground unit or
    cell size off by orders of magnitude)."""
    xy = np.concatenate([np.concatenate([g, i]) for g, i in gt.values()])
    if not len(xy):
        raise ValueError("the sequence's ground truth places nobody on the ground: no extent for the grid")
    span = float(np.max(xy.max(axis=0) - xy.min(axis=0)))
    if not 2.0 <= span <= 2000.0:
        raise ValueError(f"the ground truth spans {span:.3g} m: implausible for people walking in a scene "
                         "(expected 2..2000 m); the ground unit (--ground-unit-m) looks wrong")
    lo, hi = xy.min(axis=0) - margin_m, xy.max(axis=0) + margin_m
    n = np.prod(np.ceil((hi - lo) / cell_m))
    if n > MAX_EPFL_CELLS:
        raise ValueError(f"a ground grid of {(hi - lo)[0]:.4g} m x {(hi - lo)[1]:.4g} m in {cell_m:g} m cells has "
                         f"{n:.3g} cells (> {MAX_EPFL_CELLS:.0e}): check --ground-unit-m and --cell-m")
    return PlaneStack.from_extent([0.0], (lo[0], hi[0]), (lo[1], hi[1]), cell_m)


@cameras_app.command("epfl")
def epfl(
    root: Path = typer.Argument(..., help="EPFL folder holding <sequence>-c*/Homography.txt and gt/gt.txt."),
    sequence: str = typer.Option("terrace1", help="Sequence name prefix (the folder lists the ones it holds)."),
    ground_unit_m: float = typer.Option(None, help="Metres per Homography.txt ground unit [m]. Default for terrace "
                                        "sequences: the fitted map to the Tsai world (~0.0219); required for any "
                                        "other sequence (laboratory: 0.02)."),
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
    """Detect people on an EPFL POM sequence from per-view boxes (ground homographies only) and score them."""
    try:
        seq = load_epfl_sequence(root, sequence, ground_unit_m=ground_unit_m)
        gt = epfl_ground_truth(seq)
        stack = epfl_stack(gt, cell_m)
    except ValueError as exc:
        exit_with_error(str(exc))
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
    method: str = typer.Option("knn", help="Background subtraction: knn, mog2, cnt, mean (ForegroundParams.method), "
                                          "or 'masks' (exact masks)."),
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


@cameras_app.command("epfl-tsai")
def epfl_tsai(
    out_dir: Path = typer.Argument(..., help="Folder to write <camera>.xml into (created)."),
) -> None:
    """Write EPFL terrace's Tsai calibration (c0..c3, 720x576 px, world in mm) as EPFL's XML files, for
    planefuse import --calib-format tsai --units mm."""
    from ..calib import EPFL_TERRACE_TSAI, write_tsai_xml

    out_dir.mkdir(parents=True, exist_ok=True)
    for name, cam in EPFL_TERRACE_TSAI.items():
        write_tsai_xml(out_dir / f"{name}.xml", cam)
    console.print(f"wrote {', '.join(f'{n}.xml' for n in EPFL_TERRACE_TSAI)} in {out_dir}", highlight=False)
