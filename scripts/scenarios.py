"""Scenario evaluation: scenario x seed x configuration (temporal filter on/off, modalities, tracker), one row
of scores per run, means and worst cases per scenario, written as a CSV, a Markdown table and a figure.

Usage::

    PYTHONPATH=src python scripts/scenarios.py --seeds 4,5,6 --duration-s 6 --out docs/scenarios
    PYTHONPATH=src python scripts/scenarios.py --seeds 1,2,3 --sweep      # tuning: tracker variants
    PYTHONPATH=src python scripts/scenarios.py --scheduler tcp://host:8786 ...   # on a dask cluster
    PYTHONPATH=src python scripts/scenarios.py --seeds 1,2,3 --set camera_params.max_rate_hz=null  # every instant

Each (scenario, seed, filter, modalities) is one system run (``planefuse.pipeline.run_system``, what
``planefuse run`` runs) on a dask worker (:func:`planefuse.batch.batch_client`: a LocalCluster of
``--n-workers`` processes, or a running scheduler). The trackers are then run on that run's clusters
(the clusters do not depend on the tracker, so every tracker sees the same input): the Kalman tracker
(:class:`planefuse.tracking.MultiPersonTracker`) and, with ``--previous-tracker``, the nearest-neighbour
tracker it replaced (read from git, ``benchmarks/_previous_tracker.py``). A scene's static occluders are
declared to the system (``SystemParams.occluder_boxes_m``), as an installation declares its floor plan. Scores as in
:func:`planefuse.eval.system_metrics` (first second skipped, 0.5 m match distance).

Hold-out: parameters are tuned on seeds 1-3 only (rows marked ``tuning``); every other seed is held out,
on every scenario.
"""

from __future__ import annotations

import argparse
import csv
import sys
import time
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
import yaml

from planefuse.config._models import _with_values
from planefuse.pipeline import SystemParams
from planefuse.sim import SCENARIOS

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
from _previous_tracker import load_previous_tracker, previous_tracker_source  # noqa: E402

TUNING_SEEDS = (1, 2, 3)
KEYS = ("moda", "precision", "recall", "mota", "idf1", "id_switches", "idf1_max_tracklets", "idf1_max_detections")
#: modality sets: name -> SystemParams fields
MODALITIES = {
    "all": {},
    "cameras": {"laser": False, "sound": False},
    "laser+sound": {"cameras": False},
}


@dataclass(frozen=True)
class Case:
    """One system run: a scenario, a seed, the filter on or off, a modality set."""

    scenario: str
    seed: int
    duration_s: float
    use_filter: bool
    modalities: str
    #: ``SystemParams`` attributes changed for this run: (dotted path, value) pairs (``--set``)
    sets: tuple = ()


def with_sets(params: SystemParams, sets: tuple) -> SystemParams:
    """``params`` with the attributes at the dotted paths of ``sets`` replaced, ``(("camera_params.max_rate_hz",
    5.0),)``: the configuration's own nested replace, each object rebuilt once so that rules between its fields see
    the final values together."""
    for path, _ in sets:
        obj = params
        for name in path.split("."):
            if not hasattr(obj, name):
                raise SystemExit(f"--set {path}: {type(obj).__name__} has no attribute {name!r}")
            obj = getattr(obj, name)
    return _with_values(params, {tuple(path.split(".")): value for path, value in sets})


#: The tracks' appearance as docs/identities.md recommends it (chosen on seeds 1-3 and terrace frames 0-1499).
APPEARANCE = {"appearance_weight": 16.0, "reid_max_s": 5.0}


def _tracker_variants(sweep: str | None) -> dict:
    """Tracker name -> TrackerParams of the Kalman tracker (``--sweep``: a tuning grid, ``noise``, ``births`` or
    ``appearance``; ``--appearance``: the Kalman tracker with the tracks' appearance, ``APPEARANCE``)."""
    base = SystemParams().tracking.tracker
    out = {"kalman": base}
    if sweep == "appearance":  # appearance in association (weight) and re-identification
        for w in (8.0, 16.0):
            out[f"kalman+app w{w:g}"] = replace(base, appearance_weight=w)
            for d in (0.2, 0.3):
                out[f"kalman+app w{w:g} reid{d:g}"] = replace(base, appearance_weight=w, reid_max_s=5.0,
                                                             reid_max_appearance_distance=d)
        return out
    if sweep == "with-appearance":
        out["kalman+appearance"] = replace(base, **APPEARANCE)
        return out
    if sweep == "births":  # track management: births near confirmed tracks, coasting tracks reported
        for excl in (0.5, 1.0, 1.5):
            for coast in (1, 2):
                if (excl, coast) != (base.birth_exclusion_m, base.max_coast_report):
                    out[f"kalman b{excl} c{coast}"] = replace(base, birth_exclusion_m=excl, max_coast_report=coast)
        return out
    if sweep is None:
        return out
    for pos in (0.1, 0.15, 0.2):
        for acc in (0.5, 1.0, 2.0):
            for gate in (0.75, 1.0):
                out[f"kalman p{pos} a{acc} g{gate}"] = replace(base, position_std_m=pos, acceleration_std_m_s2=acc,
                                                               gate_m=gate)
    return out


def score_case(case: Case, trackers: dict, previous_source: str | None, stitch: bool = False) -> list[dict]:
    """Run the system once for ``case`` and score every tracker on its clusters (runs on a dask worker); with
    ``stitch``, every tracker with appearance also after the offline stitching (``planefuse.tracking.StitchParams``'s
    defaults, as ``models.detection.stitch`` runs it), as a row ``<tracker>+stitching``."""
    from planefuse.eval import system_metrics
    from planefuse.pipeline import run_system
    from planefuse.sim import scenario_config, simulate
    from planefuse.tracking import (MultiPersonTracker, StitchParams, TrackViews, fill_gaps, smooth_positions,
                                    stitch_tracks, velocity_correlation_time_s, velocity_prior_variance_m2_s2)

    scene = scenario_config(case.scenario, seed=case.seed, duration_s=case.duration_s)
    rec = simulate(scene)
    # the installation's static occluders are declared, as a user declares a floor plan
    params = SystemParams(use_filter=case.use_filter, occluder_boxes_m=tuple(o.box_m() for o in scene.occluders),
                          **MODALITIES[case.modalities])
    params = with_sets(params, case.sets)
    t0 = time.process_time()
    result = run_system(rec, params)
    run_cpu_s = time.process_time() - t0
    outs = result.outputs
    times = np.array([o.time_s for o in outs])
    dets = [o.detections.xy_m for o in outs]
    extent = result.stack.extent_m
    # the "no filter" run's BOF still holds the uniform velocity law: its prior is the same
    bof = params.tracking.bof
    prior_var, tau_v = velocity_prior_variance_m2_s2(bof), velocity_correlation_time_s(bof)
    makers = {name: (lambda tp=tp: MultiPersonTracker(tp, extent, prior_var, tau_v)) for name, tp in trackers.items()}
    if previous_source is not None:
        prev = load_previous_tracker(previous_source)
        makers["previous"] = lambda: prev.MultiPersonTracker(prev.TrackerParams(), extent)
    rows = []
    frames = None
    if any(tp.uses_appearance for tp in trackers.values()):  # the camera frames the tracks' appearance is read from
        from planefuse.vision import recording_frames

        cp = params.camera_params
        from planefuse.pipeline._streams import _tapped

        frames = []  # as the run's camera source hands them (a black or frozen frame: None)
        for _ in _tapped(recording_frames(rec, stride=cp.frame_stride, max_rate_hz=cp.max_rate_hz),
                         lambda t, imgs: frames.append((t, imgs))):
            pass
    for name, make in makers.items():
        tracker = make()
        observer = None
        if frames is not None and name in trackers and trackers[name].uses_appearance:
            from planefuse.tracking import AppearanceObserver

            observer = AppearanceObserver(rec.cameras, params.appearance,
                                          [rec.camera(c.name).ignore_mask for c in rec.cameras],
                                          occluder_boxes_m=params.occluder_boxes_m)
            tracker.observer = observer
            if stitch and StitchParams().split_window_s is not None:
                tracker.view_log = TrackViews()  # what the offline splitting reads
        t0 = time.perf_counter()
        tracks, k = [], 0
        for o in outs:
            while observer is not None and k < len(frames) and frames[k][0] <= o.time_s + 1e-9:
                observer.add_frames(*frames[k])
                k += 1
            tracks.append(tracker.step(o.clusters))
        tracker_ms = 1e3 * (time.perf_counter() - t0) / max(len(outs), 1)
        variants = [(name, [(t.time_s, t.ids, t.xy_m) for t in tracks])]
        if stitch and observer is not None:
            sp = StitchParams(enabled=True)
            _, stitched = stitch_tracks(tracks, tracker.appearance_by_id, tracker.view_log, sp)
            if sp.max_fill_gap_s is not None:
                stitched = fill_gaps(stitched, sp.max_fill_gap_s)
            if sp.smooth_sigma_s is not None:
                stitched = smooth_positions(stitched, sp.smooth_sigma_s)
            variants.append((f"{name}+stitching", stitched))
        for label, frames_ in variants:
            m = system_metrics(rec, times, dets, frames_, result.report, result.elapsed_s, params.match_distance_m)
            rows.append({"scenario": case.scenario, "seed": case.seed,
                         "split": "tuning" if case.seed in TUNING_SEEDS else "held-out",
                         "filter": "BOF" if case.use_filter else "none", "modalities": case.modalities,
                         "tracker": label, **{k: m[k] for k in KEYS}, "run_cpu_s": run_cpu_s,
                         "tracker_ms_per_step": tracker_ms, "duration_s": case.duration_s})
    return rows


def _config(r: dict) -> str:
    return f"{r['filter']} / {r['modalities']} / {r['tracker']}"


def summarise(rows: list[dict], split: str) -> list[dict]:
    """Per scenario (and over all scenarios) and configuration: means, worst cases and switches of ``split``."""
    out = []
    rows = [r for r in rows if r["split"] == split]
    for scen in [*SCENARIOS, "all scenarios"]:
        sub = [r for r in rows if scen == "all scenarios" or r["scenario"] == scen]
        for cfg in dict.fromkeys(_config(r) for r in sub):
            c = [r for r in sub if _config(r) == cfg]
            col = {k: np.array([r[k] for r in c], dtype=float) for k in KEYS}
            out.append({"scenario": scen, "configuration": cfg, "runs": len(c),
                        "moda": col["moda"].mean(), "mota": col["mota"].mean(), "idf1": col["idf1"].mean(),
                        "worst_mota": col["mota"].min(), "worst_idf1": col["idf1"].min(),
                        "id_switches": int(col["id_switches"].sum()),
                        "idf1_max_tracklets": col["idf1_max_tracklets"].mean(),
                        "idf1_max_detections": col["idf1_max_detections"].mean()})
    return out


def markdown(summary: list[dict], title: str) -> str:
    lines = [f"{title}\n", "| scenario | filter / modalities / tracker | runs | MODA | MOTA | IDF1 | worst MOTA | "
             "worst IDF1 | ID switches | IDF1 bound: whole tracks / positions |",
             "|---|---|---:|---:|---:|---:|---:|---:|---:|---:|"]
    for s in summary:
        lines.append(f"| {s['scenario']} | {s['configuration']} | {s['runs']} | {s['moda']:.3f} | {s['mota']:.3f} | "
                     f"{s['idf1']:.3f} | {s['worst_mota']:.3f} | {s['worst_idf1']:.3f} | {s['id_switches']} | "
                     f"{s['idf1_max_tracklets']:.3f} / {s['idf1_max_detections']:.3f} |")
    return "\n".join(lines) + "\n"


def figure(summary: list[dict], path: Path, title: str) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    scens = list(dict.fromkeys(s["scenario"] for s in summary))
    cfgs = list(dict.fromkeys(s["configuration"] for s in summary))
    fig, axes = plt.subplots(1, 3, figsize=(15, 4.2), sharey=True)
    width = 0.8 / len(cfgs)
    for ax, key in zip(axes, ("moda", "mota", "idf1")):
        for j, cfg in enumerate(cfgs):
            xs, mean, worst = [], [], []
            for i, scen in enumerate(scens):
                s = next((s for s in summary if s["scenario"] == scen and s["configuration"] == cfg), None)
                if s is not None:
                    xs.append(i + (j - (len(cfgs) - 1) / 2) * width)
                    mean.append(s[key])
                    worst.append(s.get(f"worst_{key}", np.nan))
            ax.bar(xs, mean, width, label=cfg)
            if key != "moda":
                ax.plot(xs, worst, "k_", markersize=8)
        ax.set_xticks(range(len(scens)), scens, rotation=30, ha="right")
        ax.set_title(f"{key.upper()} (bars: mean; ticks: worst seed)")
        ax.set_ylim(min(0.0, min(s[key] for s in summary)) - 0.05, 1)
        ax.grid(axis="y", alpha=0.3)
    axes[0].legend(fontsize=7, loc="lower left")
    fig.suptitle(title)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scenarios", default=",".join(SCENARIOS))
    ap.add_argument("--seeds", default="4,5,6", help="comma-separated; 1-3 are the tuning seeds")
    ap.add_argument("--duration-s", type=float, default=6.0)
    ap.add_argument("--filters", default="on,off", help="temporal filter on, off or both")
    ap.add_argument("--modalities", default="all", help=f"comma-separated of {', '.join(MODALITIES)}")
    ap.add_argument("--previous-tracker", action="store_true", help="also the tracker before the Kalman tracker")
    ap.add_argument("--sweep", nargs="?", const="noise", default=None,
                    choices=("noise", "births", "appearance", "with-appearance"),
                    help="a grid of Kalman tracker variants, scored on the same runs (choose on seeds 1-3 only): "
                         "noise (default: position and acceleration noise, gate) or births (birth exclusion, "
                         "coasting tracks reported), appearance (the tracks' appearance: weight, re-identification) "
                         "or with-appearance (the Kalman tracker without and with the recommended appearance)")
    ap.add_argument("--stitch", action="store_true",
                    help="also score every tracker with appearance after the offline stitching (a row "
                         "<tracker>+stitching; docs/identities.md)")
    ap.add_argument("--from-csv", type=Path, default=None, help="re-summarise the rows of an earlier run")
    ap.add_argument("--trackers", default=None, help="comma-separated tracker names to keep in the summary")
    ap.add_argument("--n-workers", type=int, default=2)
    ap.add_argument("--scheduler", default=None, help="address of a running dask scheduler")
    ap.add_argument("--set", action="append", default=[], metavar="PATH=YAML",
                    help="a SystemParams attribute for every run, by its dotted path (repeatable), e.g. "
                         "camera_params.max_rate_hz=null or camera_correlation_s=0.8 (choose on seeds 1-3 only)")
    ap.add_argument("--out", type=Path, default=Path("scenario-results"))
    args = ap.parse_args()
    sets = []
    for item in args.set:
        path, eq, value = item.partition("=")
        if not eq:
            raise SystemExit(f"--set {item!r}: expected PATH=VALUE")
        sets.append((path.strip(), yaml.safe_load(value)))
    with_sets(SystemParams(), tuple(sets))  # a wrong path or value fails here, before any run
    seeds = [int(s) for s in args.seeds.split(",")]
    for name in args.modalities.split(","):
        if name not in MODALITIES:
            raise SystemExit(f"--modalities: unknown {name!r}; expected {', '.join(MODALITIES)}")
    if args.from_csv is not None:
        rows = _read_rows(args.from_csv)
        write(rows, args, len({(r["scenario"], r["seed"], r["filter"], r["modalities"]) for r in rows}), wall_s=None)
        return
    cases = [Case(s, seed, args.duration_s, f == "on", mod, tuple(sets)) for s in args.scenarios.split(",")
             for seed in seeds for f in args.filters.split(",") for mod in args.modalities.split(",")]
    trackers = _tracker_variants(args.sweep)
    prev = previous_tracker_source() if args.previous_tracker else None

    from planefuse.batch import batch_client

    from distributed import as_completed

    t0 = time.time()
    args.out.mkdir(parents=True, exist_ok=True)
    rows: list[dict] = []
    with batch_client(args.scheduler, None if args.scheduler else args.n_workers) as client, \
            open(args.out / f"{_stem(args)}.csv", "w", newline="") as f:
        futures = client.map(score_case, cases, trackers=trackers, previous_source=prev, stitch=args.stitch,
                             pure=False)
        writer = None
        for done, (future, case_rows) in enumerate(as_completed(futures, with_results=True), 1):
            if writer is None:  # rows are written as runs finish: an interrupted evaluation keeps them
                writer = csv.DictWriter(f, fieldnames=list(case_rows[0]))
                writer.writeheader()
            writer.writerows(case_rows)
            f.flush()
            rows += case_rows
            print(f"{done}/{len(cases)} runs ({time.time() - t0:.0f} s)", flush=True)
    write(rows, args, len(cases), time.time() - t0)


def _stem(args) -> str:
    return {None: "scenarios", "noise": "sweep"}.get(args.sweep, f"sweep-{args.sweep}")


def _read_rows(path: Path) -> list[dict]:
    with open(path, newline="") as f:
        rows = list(csv.DictReader(f))
    for r in rows:
        for k in (*KEYS, "run_cpu_s", "tracker_ms_per_step", "duration_s"):
            r[k] = float(r[k])
        r["seed"] = int(r["seed"])
    return rows


def write(rows: list[dict], args, n_runs: int, wall_s: float | None) -> None:
    """The Markdown summary (means, worst cases) and the figures of ``rows`` into ``args.out``."""
    if args.trackers:
        keep = args.trackers.split(",")
        rows = [r for r in rows if r["tracker"] in keep]
    stem = _stem(args)
    args.out.mkdir(parents=True, exist_ok=True)
    if args.from_csv is not None and args.trackers:  # the rows of the summary, for the figure and tables
        with open(args.out / f"{stem}.csv", "w", newline="") as f:
            w = csv.DictWriter(f, fieldnames=list(rows[0]))
            w.writeheader()
            w.writerows(rows)
    text = []
    for split in ("tuning", "held-out"):
        summary = summarise(rows, split)
        if summary:
            title = (f"{split} seeds {sorted({r['seed'] for r in rows if r['split'] == split})}, "
                     f"{args.duration_s:g} s scenes")
            text.append(markdown(summary, title))
            if args.trackers or not args.sweep:
                figure([s for s in summary if s["scenario"] != "all scenarios"],
                       args.out / f"{stem}_{split}.png", title)
    cmd = "PYTHONPATH=src python scripts/scenarios.py " + " ".join(sys.argv[1:])
    took = f", {wall_s:.0f} s wall" if wall_s is not None else ""
    (args.out / f"{stem}.md").write_text(f"`{cmd}` ({n_runs} system runs{took})\n\n" + "\n".join(text))
    print("\n".join(text))
    print(f"{n_runs} system runs; wrote {args.out}/{stem}.md and figures")


if __name__ == "__main__":
    main()
