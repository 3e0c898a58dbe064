"""``planefuse laser-map``, ``planefuse laser legs|camera-check``: real 2-D and 3-D laser data."""

from __future__ import annotations

import re
import warnings
from pathlib import Path

import numpy as np
import typer
from rich.markup import escape

from ._app import app, console, exit_with_error, units_table, write_json

laser_app = typer.Typer(help="Real laser data: people from a 2-D scanner, laser-camera checks.",
                        no_args_is_help=True)
app.add_typer(laser_app, name="laser")


@app.command("laser-map")
def laser_map(
    log_path: Path = typer.Argument(..., help="CARMEN log (.log or .log.gz) with corrected poses."),
    out: Path = typer.Option(..., "--out", help="PNG to write."),
    cell_size_m: float = typer.Option(0.05, help="Cell side [m]."),
    reference: Path = typer.Option(None, help="Reference map image to show beside ours."),
) -> None:
    """Register every scan of LOG_PATH with its pose into an occupancy map; print sharpness measures."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from ..grid import probability_from_log_odds
    from ..laser import NonMonotonicTimeWarning, map_entropy_bits, map_from_carmen_log, read_carmen_log, wall_spread_m

    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", NonMonotonicTimeWarning)
        log = read_carmen_log(log_path)
    for w in caught:
        console.print(f"[yellow]warning:[/] {escape(str(w.message))}")
    m, pts = map_from_carmen_log(log, cell_size_m=cell_size_m)
    lo = m.log_odds[0]
    entropy = map_entropy_bits(lo)
    spread = float(np.median(wall_spread_m(pts)))
    rows = []
    for k, v in [("scans", m.n_scans), ("time stamps going backwards", log.n_time_backwards),
                 ("real returns", m.n_valid), ("max-range readings", m.n_no_return),
                 ("invalid returns", m.n_invalid), ("grid (ny x nx)", f"{lo.shape[0]} x {lo.shape[1]}"),
                 ("cell size [m]", cell_size_m), ("map entropy of observed cells [bit]", f"{entropy:.3f}"),
                 ("median wall spread, RMS to local line [mm]", f"{1e3 * spread:.1f}")]:
        rows.append((k, v))
    console.print(units_table(f"laser map of {log_path.name}", ("quantity", "value"), rows))
    n_ax = 2 if reference is not None else 1
    fig, axes = plt.subplots(1, n_ax, figsize=(8 * n_ax, 8), squeeze=False)
    ax = axes[0, 0]
    ax.imshow(1.0 - probability_from_log_odds(lo), cmap="gray", origin="lower", extent=m.stack.extent_m,
              vmin=0, vmax=1, interpolation="antialiased")
    ax.set_title(f"{log_path.name}: {m.n_scans} scans, {cell_size_m * 100:.0f} cm cells\n"
                 f"entropy {entropy:.3f} bit, wall spread {1e3 * spread:.1f} mm")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    if reference is not None:
        import imageio.v3 as iio

        axes[0, 1].imshow(iio.imread(reference))
        axes[0, 1].set_title(f"reference: {reference.name}")
        axes[0, 1].axis("off")
    fig.tight_layout(rect=(0, 0, 1, 0.97))
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=150)
    plt.close(fig)
    console.print(f"wrote {out}")


def _median_range(n: np.ndarray) -> str:
    return f"{np.median(n):.0f} ({n.min()}-{n.max()})" if n.size else "-"


@laser_app.command("legs")
def legs(
    path: Path = typer.Argument(..., help="ROS 1 .bag file, ROS 2 bag folder, or CARMEN .log/.log.gz."),
    topic: str = typer.Option(None, help="LaserScan topic of the bag (default: its only one)."),
    labels_topic: str = typer.Option(None, help="PoseArray topic of labelled leg centroids, laser frame [m], "
                                     "one message per scan in order (default: the bag's only PoseArray topic, "
                                     "if any). 'none': do not score."),
    background: str = typer.Option("auto", help="Background model of a fixed scanner: 'none', 'median' "
                                   "(per-beam median range over the recording), 'both', or 'auto' (both for a "
                                   "bag, none for a CARMEN log whose robot moves)."),
    max_distance_m: float = typer.Option(0.3, help="Match distance of leg detections to labels [m]."),
    window_deg: float = typer.Option(15.0, help="Scored window: labels cover +-window_deg around the "
                                     "scanner's x axis [deg]."),
    max_range_m: float = typer.Option(5.0, help="Scored window: labels cover ranges up to this [m]."),
    json_out: Path = typer.Option(None, help="Write the summary and every scan's people (x_m, y_m, "
                                  "confidence) as JSON here."),
) -> None:
    """Legs and people in every scan of a 2-D laser recording; leg detection scored against labels if given.

    People positions are in the laser frame [m] (bags) or the map frame [m] (CARMEN logs, corrected poses).
    """
    from ..laser import background_ranges_m, detect_people, evaluate_leg_detection, read_laser_scans, read_rosbag
    from ..laser._readers import read_rosbag_topics

    if background not in ("auto", "none", "median", "both"):
        exit_with_error(f"--background must be auto, none, median or both, got {background!r}")
    try:
        scans, source = read_laser_scans(path, topic)
        is_log = source == "FLASER"
        if background == "auto":
            background = "none" if is_log else "both"
        labels = None
        if not is_log and labels_topic != "none":
            poses = sorted(t for t, (kind, _) in read_rosbag_topics(path).items()
                           if kind == "geometry_msgs/msg/PoseArray")
            if labels_topic is None and len(poses) == 1:
                labels_topic = poses[0]
            if labels_topic is not None:
                labels = read_rosbag(path, labels_topic)[1]
                if len(labels) != len(scans):
                    raise ValueError(f"{path}: {len(scans)} scans on {source} but {len(labels)} label messages "
                                     f"on {labels_topic}; they are paired by order")
        elif is_log and labels_topic not in (None, "none"):
            raise ValueError(f"--labels-topic given but {path} is a CARMEN log, not a bag")
        if not scans:
            raise ValueError(f"{path}: no scans on {source}")
        models = {"none": None}
        if background in ("median", "both"):
            if len({s.ranges_m.size for s in scans}) != 1:
                raise ValueError(f"{path}: scans of different beam counts; no per-beam background")
            models["per-beam median"] = background_ranges_m(scans)
            if background == "median":
                del models["none"]
        people = {name: [detect_people(s, background_ranges_m=bg) for s in scans] for name, bg in models.items()}
        scores = None if labels is None else evaluate_leg_detection(
            scans, labels, max_distance_m=max_distance_m, window_deg=window_deg, max_range_m=max_range_m)
    except ValueError as err:
        exit_with_error(str(err))
    frame = "map frame (corrected poses)" if is_log else "laser frame"
    rows, summary = [], {}
    for name, dets in people.items():
        n = np.array([len(d) for d in dets])
        rows.append((name, len(dets), _median_range(n), int(n.sum())))
        summary[name] = {"people_per_scan_median": float(np.median(n)), "min": int(n.min()), "max": int(n.max()),
                         "total": int(n.sum())}
    console.print(units_table(f"people in {path.name} ({source}, {len(scans)} scans, {frame})",
                              ("background model", "scans", "people per scan: median (range)", "people total"),
                              rows))
    result = {"input": str(path), "source": source, "n_scans": len(scans), "frame": frame, "people": summary,
              "leg_scores": None}
    if scores is not None:
        p, r = scores.precision, scores.recall
        f1 = 2 * p * r / (p + r) if p + r > 0 else float("nan")
        console.print(units_table(
            f"leg detection vs {labels_topic}: +-{window_deg:g} deg, <= {max_range_m:g} m, match {max_distance_m:g} m",
            ("TP", "FP", "FN", "precision", "recall", "F1"),
            [(scores.tp, scores.fp, scores.fn, f"{p:.3f}", f"{r:.3f}", f"{f1:.3f}")], right=False))
        result["leg_scores"] = {**scores.as_dict(), "f1": f1, "labels_topic": labels_topic,
                                "window_deg": window_deg, "max_range_m": max_range_m}
    if json_out:
        name = list(people)[-1]
        result["scans_background_model"] = name
        result["scans"] = [{"time_s": d.time_s, "xy_m": np.round(d.xy_m, 4).tolist(),
                            "confidence": d.confidence.tolist()} for d in people[name]]
        write_json(json_out, result)


def _pairs(text: str | None, available: list[int]) -> list[int]:
    if text is None:
        return available
    try:
        want = [int(v) for v in text.split(",")]
    except ValueError:
        raise ValueError(f"--pairs must be comma-separated image numbers, got {text!r}") from None
    missing = sorted(set(want) - set(available))
    if missing:
        raise ValueError(f"pairs {missing} have no scan and board view; available: {available}")
    return want


def _one_file(folder: Path, pattern: str, what: str) -> Path:
    found = sorted(folder.glob(pattern))
    if len(found) != 1:
        have = sorted(p.name for p in folder.iterdir())[:12]
        raise ValueError(f"{folder} has {len(found)} {what} files ({pattern}): {[p.name for p in found]}; "
                         f"name one explicitly (folder holds {have})")
    return found[0]


@laser_app.command("camera-check")
def camera_check(
    folder: Path = typer.Argument(..., help="Folder of scan/image pairs: <prefix><i>.xyz laser points [m], "
                                  "one per board image i of the calibration."),
    transform: Path = typer.Option(None, help="YAML with R, t of T_camera_laser [m] (p_cam = R p_laser + t); "
                                   "default: the folder's only T_camera_laser*.yaml."),
    calib: Path = typer.Option(None, help="Bouguet toolbox Calib_Results.mat (intrinsics, board poses, "
                               "corners); default: the folder's only .mat file."),
    scan_prefix: str = typer.Option("laser_target", help="Scan file name before the image number."),
    pairs: str = typer.Option(None, help="Comma-separated image numbers to check (default: every number with "
                              "both a scan and a board view)."),
    board_unit_m: float = typer.Option(0.001, help="Length unit of the calibration's board poses [m] "
                                       "(0.001: millimetres)."),
    plane_tolerance_m: float = typer.Option(0.01, help="On-board test: distance to the board plane [m]."),
    hull_tolerance_px: float = typer.Option(1.0, help="Hull test margin [px]."),
    json_out: Path = typer.Option(None, help="Write the per-pair results as JSON here."),
) -> None:
    """Check T_camera_laser on a checkerboard seen by a 3-D laser and a camera (e.g. CMU LCCT samples).

    Per pair: laser points projecting inside the board's corner hull and their distance to the board plane
    [mm]; points on the board plane projecting inside the hull.
    """
    from ..calib import load_bouguet_calibration
    from ..laser import board_check, read_transform_yaml, read_xyz

    try:
        if not folder.is_dir():
            raise ValueError(f"{folder} is not a folder")
        transform = transform or _one_file(folder, "T_camera_laser*.yaml", "transform")
        calib = calib or _one_file(folder, "*.mat", "calibration")
        T_camera_laser = read_transform_yaml(transform)
        cal = load_bouguet_calibration(calib, metres_per_unit=board_unit_m)
        scans = {int(m.group(1)): p for p in folder.iterdir()
                 if (m := re.fullmatch(re.escape(scan_prefix) + r"(\d+)\.xyz", p.name))}
        available = sorted(set(scans) & set(cal.views))
        if not available:
            raise ValueError(f"no pair: scans {sorted(scans)} ({scan_prefix}<i>.xyz in {folder}), "
                             f"board views {sorted(cal.views)} in {calib.name}")
        results = {}
        for i in _pairs(pairs, available):
            v = cal.views[i]
            results[i] = board_check(read_xyz(scans[i]), T_camera_laser, cal.K, cal.dist, v.T_camera_board,
                                     v.corners_px, v.corners_board_m, plane_tolerance_m, hull_tolerance_px)
    except ValueError as err:
        exit_with_error(str(err))
    rows = [(i, r.n_in_hull, f"{1e3 * r.plane_distance_median_m:.2f} / {1e3 * r.plane_distance_p90_m:.2f}",
             f"{100 * r.on_board_in_hull_fraction:.1f} % of {r.n_on_board}") for i, r in results.items()]
    console.print(units_table(
        f"{transform.name} on {calib.name}",
        ("pair", "points in corner hull", "their distance to board, median / 90 % [mm]",
         f"on-board points (< {100 * plane_tolerance_m:g} cm) in hull (+-{hull_tolerance_px:g} px)"), rows))
    if json_out:
        write_json(json_out, {"transform": str(transform), "calibration": str(calib),
                              "pairs": {str(i): r.as_dict() for i, r in results.items()}})
