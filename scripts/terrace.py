"""The seed's experiment on real video: EPFL terrace1, cameras c0 + c1, end to end, scored against the ground truth.

What it does, for frames ``--first`` to ``--last`` (every ``--step``-th):

1. ``planefuse import`` (the command users run) of the two videos with a times file listing the chosen frames,
   the terrace's **Tsai** calibration (``planefuse cameras epfl-tsai``; planes above the ground registered, not
   only the ground), the burned-in watermark as an ignore rectangle, and the ground truth from all four cameras'
   boxes (EPFL/Vatic ``gt.txt``, feet back-projected through the Tsai models, median over the cameras);
2. for each row of the table, the run configuration ``scripts/terrace.yaml`` (chosen on frames 0-1499) with the
   row's changes (front end, planes, filter, sensor model) run by :func:`planefuse.pipeline.run_plan`, what
   ``planefuse run`` runs; with ``--run-dir`` the main row is also run into a folder exactly as ``planefuse run
   terrace.yaml`` does (``metrics.json``, tables, figures);
3. the mean-field solver on 25 cm ground locations on the same foreground masks, frame by frame, and optionally
   (``--pom``) POM, the reference program, on the same masks and silhouettes (``benchmarks/bench_terrace_pom.py``);
4. scores every row with the same scorer: MODA, MODP, precision, recall at 0.5 m and 1.0 m
   (:func:`planefuse.eval.detection_scores`), MOTA, IDF1 and identity switches of the tracks
   (:func:`planefuse.eval.tracking_metrics`); a person seen by neither c0 nor c1 is "ignore" (neither missed nor
   false), the only difference with ``planefuse run``'s own ``metrics.json`` (which also skips the first second);
   writes ``terrace.json`` and a Markdown table.

With ``--warmup-from F`` the run starts at frame F (a deployed system runs continuously: background models, filter
and tracker warm) and only the frames from ``--first`` are scored; without it the models start cold at ``--first``.

Hold-out: every parameter was chosen on frames 0-1499; report on 1500-2999. Example::

    PYTHONPATH=src python3 scripts/terrace.py --data ../shared/data --first 1500 --last 3000 --step 5 --out /tmp/terrace
"""

from __future__ import annotations

import argparse
import copy
import json
import os
import shutil
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
import yaml

from planefuse.calib import EPFL_TERRACE_TSAI, pinhole_from_tsai
from planefuse.config import config_from_dict
from planefuse.eval import detection_scores, match_detections, tracking_metrics
from planefuse.grid import PlaneStack
from planefuse.io import read_recording
from planefuse.occupancy import GenerativeParams
from planefuse.pipeline import run_plan
from planefuse.vision import (CameraFrontEnd, ForegroundParams, epfl_ground_truth_from_cameras,
                              load_epfl_sequence, recording_frames)

REPO = Path(__file__).resolve().parents[1]
#: The run configuration of the experiment (chosen on frames 0-1499).
CONFIG = Path(__file__).resolve().with_name("terrace.yaml")
FPS = 25.0
#: The converter's watermark, (u_min, v_min, u_max, v_max) px, max exclusive (../shared/data/epfl_video/SOURCE.md).
WATERMARK_PX = (130, 230, 356, 285)
#: The monitored area [m, Tsai world]: POM's terrace grid, 7.5 m x 11 m from (-0.5, -1.5).
AREA_X_M, AREA_Y_M = (-0.5, 7.0), (-1.5, 9.5)
PLANES_M = (0.1, 0.5, 1.0, 1.5)
#: The recording's empty-scene estimate: the median of each video's first 20 s (``planefuse import
#: --background-median-s``), with terrace.yaml's ``primed_rate: automatic``. Chosen on frames 0-1499: from a cold
#: start at frames 500 / 750 / 1000 (people in view) filtered MODA at 0.5 m 0.778 / 0.711 / 0.658 against 0.745 /
#: 0.629 / 0.553 without (docs/results.md).
BACKGROUND_MEDIAN_S = 20.0


def merged(base: dict, changes: dict) -> dict:
    """``base`` with the nested mapping ``changes`` written over it (a copy)."""
    out = copy.deepcopy(base)
    for k, v in changes.items():
        out[k] = merged(out.get(k) or {}, v) if isinstance(v, dict) else v
    return out


#: The rows of the table: (key, front end, configuration changes). "tuned" = terrace.yaml's front end.
_KNN_DEFAULTS = {"gain_compensation": False, "shadow_likelihood": 0.1, "var_threshold": None, "close_px": 5}
#: The front end before this tuning round: gain compensation and shadows 0.5, OpenCV's KNN threshold, 5 px closing.
_GAIN_ONLY = {"var_threshold": None, "close_px": 5}
_CELL = {"sensor_model": "cell"}
_GROUND = {"planes": {"heights_m": [0.0]}}
_NOFILTER = {"models": {"filter": {"enabled": False}}}
#: BOF column log-odds of a person with the per-cell model: the system's default (terrace.yaml's 2.0 is the
#: generative model's, chosen on frames 0-1499).
_CELL_THRESHOLD = {"models": {"detection": {"column_threshold": 1.5}}}

def with_sets(config: dict, sets) -> dict:
    """``config`` with the ``FIELD=YAML`` changes ``sets`` (``models.detection.column_threshold=2``) written over it."""
    for item in sets:
        field, _, value = item.partition("=")
        change: dict = {}
        node = change
        *heads, last = field.split(".")
        for h in heads:
            node = node.setdefault(h, {})
        node[last] = yaml.safe_load(value)
        config = merged(config, change)
    return config


def _changes(*parts: dict) -> dict:
    """The nested configuration changes ``parts`` applied one after the other."""
    out: dict = {}
    for p in parts:
        out = merged(out, p)
    return out


_CELL_ROW = _changes({"sensors": {"cameras": _CELL}}, _CELL_THRESHOLD)
#: The tracks' appearance (docs/identities.md; chosen on frames 0-1499 and simulated seeds 1-3): in association and
#: re-identification (online), then also the offline stitching of the tracklets.
_APPEARANCE = {"models": {"detection": {"appearance_weight": 16.0, "reid_max_s": 5.0}}}
#: The offline pass: the library's global tracklet association, then terrace.yaml's (the real-video profile's) gap
#: filling and smoothing (docs/identities.md).
_STITCH = {"models": {"detection": {"stitch": True}}}
#: The rows without "-app" in their key: the tracker on position and velocity alone, no offline pass (terrace.yaml, the
#: real-video profile, turns both on; its rows are "gen-app-stitch" and "det-app-stitch").
_NO_IDENTITY = {"models": {"detection": {"appearance_weight": None, "reid_max_s": None, "stitch": False}}}
#: The person detector's rows: ``--person-model`` fills the model's path (``detector_rows``). "det": the tuned system
#: with the detector at the library's settings (its boxes as evidence of free space, docs/cameras.md); "detonly": the
#: detector alone, its boxes the generative model's silhouettes (no background subtraction; the person's cylinder
#: 0.3 m wide, chosen on frames 1000-1499 against 0.2 m: filtered MODA 0.650 / 0.844 against 0.638 / 0.808).
_DET = {"sensors": {"cameras": {"person_detector": "yolox", "person_model": None}}}
_DET_ONLY = {"sensors": {"cameras": {"foreground_method": "none", "person_likelihood": 0.9,
                                     "box_free_log_odds": 0.0, "generative_radius_m": 0.3}}}
DET_NAME = "tuned + YOLOX-Nano boxes"
DET_ONLY_NAME = "YOLOX-Nano boxes alone"
ROWS = {
    "gen": ("tuned", {}),
    "gen-nofilter": ("tuned", _NOFILTER),
    "gen-ground": ("tuned", _GROUND),
    "gen-app": ("tuned", _APPEARANCE),
    "gen-app-stitch": ("tuned", _changes(_APPEARANCE, _STITCH)),
    "cell": ("tuned", _CELL_ROW),
    "cell-nofilter": ("tuned", _changes(_CELL_ROW, _NOFILTER)),
    "cell-ground": ("tuned", _changes(_CELL_ROW, _GROUND)),
    "knn": ("KNN defaults", _changes(_CELL_ROW, {"sensors": {"cameras": _KNN_DEFAULTS}})),
    "gen-gain": ("KNN + gain compensation", {"sensors": {"cameras": _GAIN_ONLY}}),
    "gen-knn": ("KNN defaults", {"sensors": {"cameras": _KNN_DEFAULTS}}),
    "det": (DET_NAME, _DET),
    "det-nofilter": (DET_NAME, _changes(_DET, _NOFILTER)),
    "det-ground": (DET_NAME, _changes(_DET, _GROUND)),
    "det-app": (DET_NAME, _changes(_DET, _APPEARANCE)),
    "det-app-stitch": (DET_NAME, _changes(_DET, _APPEARANCE, _STITCH)),
    "detonly": (DET_ONLY_NAME, _changes(_DET, _DET_ONLY)),
    "detonly-nofilter": (DET_ONLY_NAME, _changes(_DET, _DET_ONLY, _NOFILTER)),
}
TABLE_ROWS = ("generative", "pom", "pom-det")
TUNED_NAME = "tuned (terrace.yaml)"


def with_person_model(changes: dict, model: Path | None) -> dict:
    """A row's configuration changes with the person model's path filled in (None: the row needs none)."""
    cams = changes.get("sensors", {}).get("cameras", {})
    if "person_model" not in cams:
        return changes
    if model is None:
        raise SystemExit("the detector rows need --person-model (a YOLOX ONNX file)")
    return merged(changes, {"sensors": {"cameras": {"person_model": str(model.resolve())}}})


def load_base_config(path: Path = CONFIG) -> dict:
    """The run configuration as a mapping (``recording`` and ``outputs.out_dir`` to be set by the caller)."""
    return yaml.safe_load(path.read_text(encoding="utf-8"))


def tuned_front_end(config: dict | None = None) -> ForegroundParams:
    """The front end of the run configuration (``scripts/terrace.yaml`` by default)."""
    cfg = config_from_dict(merged(config or load_base_config(), {"recording": "."}))
    return cfg.system_params().camera_params.foreground


def terrace_cameras(indices=(0, 1)) -> list:
    """The EPFL terrace cameras ``c<i>`` as :class:`~planefuse.geometry.PinholeCamera` for the 360x288 videos
    (Tsai world in metres, z up)."""
    return [pinhole_from_tsai(EPFL_TERRACE_TSAI[f"c{i}"], metres_per_unit=1e-3, width_px=360, height_px=288)[0]
            for i in indices]


@dataclass
class TerraceTruth:
    """Per frame: scored people ``ids (G,)``, ``xy_m (G, 2)`` and ignored people ``ignore_xy_m (I, 2)``."""

    ids: dict[int, np.ndarray]
    xy_m: dict[int, np.ndarray]
    ignore_xy_m: dict[int, np.ndarray]


def terrace_truth(pom_root: Path, frames) -> TerraceTruth:
    """Ground truth from the four cameras' boxes: the median of the feet back-projected through the Tsai models
    (:func:`planefuse.vision.epfl_ground_truth_from_cameras`); a person seen by neither c0 nor c1 is "ignore"."""
    seq = load_epfl_sequence(pom_root, "terrace1")
    gt = epfl_ground_truth_from_cameras(seq, terrace_cameras((0, 1, 2, 3)), (0, 1), frames)
    return TerraceTruth({f: v[0] for f, v in gt.items()}, {f: v[1] for f, v in gt.items()},
                        {f: v[2] for f, v in gt.items()})


def import_command(out: Path, data: Path, tsai_dir: Path, times_file: Path,
                   background_median_s: float | None = None) -> list[str]:
    """The ``planefuse import`` arguments of terrace1 c0 + c1 (videos, Tsai cameras, watermark, ground truth;
    with ``background_median_s``, an empty-scene estimate from the first seconds of each video)."""
    video, pom = data / "epfl_video", data / "epfl_pom" / "EPFL-Terrace"
    wm = ",".join(str(v) for v in WATERMARK_PX)
    args = ["import", str(out), "--calib-format", "tsai", "--units", "mm", "--gt-format", "vatic",
            "--planes", ",".join(f"{h:g}" for h in PLANES_M),
            "--room", ",".join(f"{v:g}" for v in (*AREA_X_M, *AREA_Y_M)), "--overwrite"]
    for c in (0, 1):
        args += ["--camera", f"c{c}={video / f'terrace1-c{c}.mp4'}", "--times", f"c{c}={times_file}",
                 "--ignore-rect", f"c{c}={wm}"]
    for c in (0, 1, 2, 3):
        args += ["--calib", f"c{c}={tsai_dir / f'c{c}.xml'}", "--gt-boxes", f"c{c}={pom / f'terrace1-c{c}' / 'gt' / 'gt.txt'}"]
    if background_median_s is not None:
        args += ["--background-median-s", f"{background_median_s:g}"]
    return args + ["--image-size", "c2=360x288", "--image-size", "c3=360x288"]


def planefuse_cli(args: list[str]) -> str:
    """Run ``python -m planefuse ARGS`` with this checkout's source first; its output (raises on failure)."""
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(REPO / "src"), os.environ.get("PYTHONPATH", "")]))
    res = subprocess.run([sys.executable, "-m", "planefuse", *args], env=env, capture_output=True, text=True)
    if res.returncode not in (0,):
        raise RuntimeError(f"planefuse {args[0]} failed ({res.returncode}): {res.stdout}{res.stderr}")
    return res.stdout


def import_terrace(folder: Path, data: Path, frames: np.ndarray,
                   background_median_s: float | None = BACKGROUND_MEDIAN_S) -> Path:
    """``planefuse import`` of terrace1 c0 + c1 over video frames ``frames`` into ``folder/terrace``
    (``background_median_s``: :func:`import_command`)."""
    folder.mkdir(parents=True, exist_ok=True)
    planefuse_cli(["cameras", "epfl-tsai", str(folder / "tsai")])
    times = folder / "times.csv"
    times.write_text("time_s,frame_index\n" + "".join(f"{float(f) / FPS!r},{int(f)}\n" for f in frames))
    args = import_command(folder / "terrace", data, folder / "tsai", times, background_median_s)
    print("planefuse " + " ".join(args), flush=True)
    planefuse_cli(args)
    return folder / "terrace"


def _frame_of(time_s: float) -> int:
    return int(round(time_s * FPS))


def score(truth: TerraceTruth, frames, detections, tracks=None) -> dict:
    """MODA/MODP/precision/recall at 0.5 and 1.0 m (ignored people neither missed nor false), and, with
    ``tracks`` ((ids, xy) per frame), MOTA, IDF1 and ID switches at 0.5 m (hypotheses on ignored people dropped),
    and IDF1's labelled upper bounds (:func:`planefuse.eval.tracking_metrics`' ``identity_bounds``)."""
    frames = [int(f) for f in frames]
    out = {"n_frames": len(frames), "n_people": int(sum(len(truth.xy_m[f]) for f in frames)),
           "detections_per_frame": float(np.mean([len(d) for d in detections]))}
    for thr in (0.5, 1.0):
        s = detection_scores([(truth.xy_m[f], d, truth.ignore_xy_m[f]) for f, d in zip(frames, detections)], thr)
        out.update({f"moda@{thr}": s.moda, f"modp@{thr}": s.modp, f"precision@{thr}": s.precision,
                    f"recall@{thr}": s.recall})
    if tracks is not None:
        gt_frames, hyp_frames = [], []
        for f, (ids, xy) in zip(frames, tracks):
            ign = truth.ignore_xy_m[f]
            if len(ign) and len(xy):
                # a track on a person the videos cannot see is neither right nor wrong
                both = np.concatenate([truth.xy_m[f], ign])
                gi, di, _ = match_detections(both, xy, 0.5)
                drop = di[gi >= len(truth.xy_m[f])]
                keep = np.setdiff1d(np.arange(len(xy)), drop)
                ids, xy = ids[keep], xy[keep]
            gt_frames.append((f / FPS, truth.ids[f], truth.xy_m[f]))
            hyp_frames.append((f / FPS, ids, xy))
        mot = tracking_metrics(gt_frames, hyp_frames, match_distance_m=0.5, switch_events=True,
                               identity_bounds=True)
        out.update(mota=mot["mota"], idf1=mot["idf1"], id_switches=int(mot["num_switches"]),
                   idf1_max_tracklets=mot["idf1_max_tracklets"], idf1_max_detections=mot["idf1_max_detections"],
                   track_false_positives=int(mot["num_false_positives"]), track_misses=int(mot["num_misses"]),
                   switch_events=mot["switch_events"])
    return out


def run_row(rec, config: dict, truth: TerraceTruth, frames) -> tuple[dict, dict]:
    """One run of the configuration mapping ``config`` on ``rec`` (:func:`planefuse.pipeline.run_plan`, in
    memory): scores of the filtered detections and tracks, and of the per-frame camera detector."""
    plan = replace(config_from_dict(merged(config, {"recording": str(rec.root)})).plan(), out_dir=None)
    t0 = time.process_time()
    res, _ = run_plan(rec, plan, progress_mode="quiet")
    cpu_s = time.process_time() - t0
    by_frame = {_frame_of(o.time_s): o for o in res.outputs}
    fr = [f for f in frames if f in by_frame]
    filt = score(truth, fr, [by_frame[f].detections.xy_m for f in fr],
                 [(np.asarray(by_frame[f].tracks.ids), by_frame[f].tracks.xy_m) for f in fr])
    cams = {_frame_of(d.time_s): d for d in res.report.camera_detections}
    frc = [f for f in frames if f in cams]
    raw = score(truth, frc, [cams[f].xy_m for f in frc])
    n_instants = res.report.n_camera_frames
    filt.update(cpu_s=cpu_s, frames_per_cpu_s=n_instants * len(rec.cameras) / cpu_s, camera_instants=n_instants,
                missing_camera_frames=res.report.n_missing_camera_frames, unscored_steps=len(frames) - len(fr))
    return filt, raw


def foreground_masks(rec, fg: ForegroundParams) -> tuple[list[np.ndarray], float]:
    """The front end's foreground likelihoods of every recorded frame, per camera ((F, H, W) uint8 0..255), as the
    camera pipeline computes them, and the CPU seconds it took (decode included)."""
    t0 = time.process_time()
    fronts = []
    for c in rec.cameras:  # the run's own front end, primed with the recording's empty-scene image where it has one
        stream = rec.camera(c.name)
        fronts.append(CameraFrontEnd(c.intrinsics.width_px, c.intrinsics.height_px, fg, c.name,
                                     background=stream.background() if stream.has_background else None))
    out: list[list[np.ndarray]] = [[] for _ in fronts]
    for _, imgs in recording_frames(rec):
        for c, (front, img) in enumerate(zip(fronts, imgs)):
            out[c].append(np.round(front.foreground(img) * 255).astype(np.uint8))
    return [np.stack(o) for o in out], time.process_time() - t0


def generative_row(rec, masks, truth: TerraceTruth, frames, cell_m: float = 0.25,
                   person=None) -> tuple[dict, np.ndarray]:
    """Mean-field marginals per frame on the ground locations (silhouettes from the same cameras), detections at
    local maxima with marginal >= 0.5; returns the scores and the marginals (F, ny, nx)."""
    from planefuse.occupancy import MeanFieldSolver, silhouettes_from_cameras

    stack = PlaneStack.from_extent((0.0,), AREA_X_M, AREA_Y_M, cell_m)
    xy = stack.cell_centers_xy().reshape(-1, 2)
    solver = MeanFieldSolver(silhouettes_from_cameras(list(rec.cameras), xy, person), GENERATIVE)
    observed = [~ignore_mask(c) for c in rec.cameras]
    t0 = time.process_time()
    dets, qs = [], []
    for k in range(len(frames)):
        q = solver.solve([m[k] for m in masks], observed).marginals.reshape(stack.ny, stack.nx)
        dets.append(peaks_from_marginals(q, xy))
        qs.append(q)
    out = score(truth, frames, dets)
    out.update(cpu_s=time.process_time() - t0)
    return out, np.stack(qs)


def peaks_from_marginals(q: np.ndarray, xy: np.ndarray) -> np.ndarray:
    """Locations (M, 2) [m] of the local maxima (3 x 3) of marginals ``q`` (ny, nx) that reach 0.5; ``xy`` (ny nx, 2)
    are the locations' positions."""
    from scipy import ndimage

    peak = ndimage.maximum_filter(q, size=3, mode="constant")
    return xy[((q >= peak) & (q >= 0.5)).ravel()]


def ignore_mask(cam) -> np.ndarray:
    """The watermark as an ignore mask (height_px, width_px) bool."""
    m = np.zeros((cam.intrinsics.height_px, cam.intrinsics.width_px), bool)
    u0, v0, u1, v1 = WATERMARK_PX
    m[v0:v1, u0:u1] = True
    return m


#: The mean-field solver on 25 cm ground locations (chosen on frames 0-1499: sigma 0.005, prior 0.003 = the
#: configuration's 0.05 people/m^2 on 25 cm locations).
GENERATIVE = GenerativeParams(sigma=0.005, prior=0.003)


def markdown(rows: list[dict]) -> str:
    head = ("| front end | planes (m) | filter | sensor model | MODA 0.5 m | MODP 0.5 m | precision | recall "
            "| MODA 1.0 m | MOTA | IDF1 | ID switches | IDF1 bound: whole tracks / positions (labelled) "
            "| detections/frame |\n|---|---|---|---|---|---|---|---|---|---|---|---|---|---|")
    lines = [head]
    for r in rows:
        s = r["scores"]
        mot = (f"{s['mota']:.3f} | {s['idf1']:.3f} | {s['id_switches']} "
               f"| {s['idf1_max_tracklets']:.3f} / {s['idf1_max_detections']:.3f}" if "mota" in s else "- | - | - | -")
        lines.append(f"| {r['front_end']} | {r['planes']} | {r['filter']} | {r['sensor_model']} | {s['moda@0.5']:.3f} "
                     f"| {s['modp@0.5']:.3f} | {s['precision@0.5']:.2f} | {s['recall@0.5']:.2f} | {s['moda@1.0']:.3f} "
                     f"| {mot} | {s['detections_per_frame']:.1f} |")
    return "\n".join(lines)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--data", type=Path, default=REPO.parent / "shared" / "data",
                    help="folder holding epfl_video/ and epfl_pom/")
    ap.add_argument("--first", type=int, default=1500, help="first frame (0-based)")
    ap.add_argument("--last", type=int, default=3000, help="end frame (exclusive)")
    ap.add_argument("--step", type=int, default=5, help="use every step-th frame")
    ap.add_argument("--process-step", type=int, default=None, metavar="N",
                    help="run the system on every N-th frame (N divides --step; default --step) while scoring every "
                         "step-th: the output period stays --step frames")
    ap.add_argument("--warmup-from", type=int, default=None, metavar="F",
                    help="a warm run: import and run from frame F (every step-th, F <= first, first - F a multiple of "
                         "step) as a deployed system runs continuously, but score only the frames from --first (the "
                         "warm-up frames are not scored); default: start cold at --first")
    ap.add_argument("--config", type=Path, default=CONFIG, help="run configuration (default scripts/terrace.yaml)")
    ap.add_argument("--background-median-s", type=float, default=BACKGROUND_MEDIAN_S, metavar="S",
                    help="import with an empty-scene estimate, the median of each video's first S seconds [s]; 0 = "
                         f"none (default {BACKGROUND_MEDIAN_S:g}, chosen on frames 0-1499)")
    ap.add_argument("--out", type=Path, default=None, help="folder for terrace.json, table.md and masks")
    ap.add_argument("--rows", default="all",
                    help="comma-separated subset of " + ",".join((*ROWS, *TABLE_ROWS)) + " (or all)")
    ap.add_argument("--set", action="append", default=[], metavar="FIELD=YAML",
                    help="change a configuration field for every row, e.g. models.detection.column_threshold=2 "
                         "(tuning; repeatable)")
    ap.add_argument("--pom", action="store_true", help="also run POM on the same masks (needs g++, make, libpng)")
    ap.add_argument("--person-model", type=Path, default=_shared_person_model(),
                    help="YOLOX ONNX file of the detector rows (default ../shared/models/yolox_nano where present)")
    ap.add_argument("--run-dir", type=Path, default=None,
                    help="also run the main row into this folder exactly as `planefuse run` does")
    args = ap.parse_args(argv)
    video_root, pom_root = args.data / "epfl_video", args.data / "epfl_pom" / "EPFL-Terrace"
    for p in (video_root / "terrace1-c0.mp4", pom_root / "terrace1-c0" / "gt" / "gt.txt"):
        if not p.is_file():
            print(f"skipped: {p} is absent", file=sys.stderr)
            return 0
    frames = np.arange(args.first, args.last, args.step)
    process_step = args.process_step or args.step
    if process_step < 1 or args.step % process_step:
        raise SystemExit(f"--process-step {process_step}: must divide --step {args.step}")
    if process_step != args.step and {"generative", "pom"} & _rows(args.rows):
        raise SystemExit("--process-step: the generative and pom rows run on the scored frames only")
    run_frames = warm_frames(args.warmup_from, args.first, args.last, process_step)
    if args.warmup_from is not None and args.run_dir is not None:
        raise SystemExit("--run-dir with --warmup-from: planefuse run's metrics.json would score the warm-up "
                         "frames too; run them separately")
    out = args.out or Path(tempfile.mkdtemp(prefix="terrace-"))
    out.mkdir(parents=True, exist_ok=True)
    truth = terrace_truth(pom_root, frames)
    base = with_sets(load_base_config(args.config), args.set)
    if process_step != args.step:
        # outputs at the scored instants only; every processed frame its own update (not merged with the next)
        base = merged(base, {"models": {"filter": {"output_period_s": args.step / FPS,
                                                   "merge_tolerance_s": 0.25 * process_step / FPS}}})
    rows = _rows(args.rows)
    tmp = Path(tempfile.mkdtemp(prefix="terrace-rec-"))
    results = []
    try:
        t0 = time.perf_counter()
        rec = read_recording(import_terrace(tmp, args.data, run_frames, args.background_median_s or None))
        print(f"planefuse import: {time.perf_counter() - t0:.1f} s wall", flush=True)
        for key, (front, changes) in ROWS.items():
            if key not in rows:
                continue
            cfg = merged(merged(base, _NO_IDENTITY), with_person_model(changes, args.person_model))
            filt, raw = run_row(rec, cfg, truth, frames)
            if filt["n_frames"] != len(frames) or raw["n_frames"] != len(frames):
                raise RuntimeError(f"row {key}: scored {filt['n_frames']} / {raw['n_frames']} instants, "
                                   f"expected the {len(frames)} of --first..--last")
            cams = cfg["sensors"]["cameras"]
            heights = cfg["planes"]["heights_m"]
            planes = "/".join(f"{h:g}" for h in heights) + (" (ground alone)" if heights == [0.0] else "")
            model = "generative" if cams.get("sensor_model") == "generative" else "per cell"
            det = cfg.get("models", {}).get("detection", {})
            if det.get("appearance_weight") is not None or det.get("reid_max_s") is not None:
                model += " + appearance"
            if det.get("stitch"):
                model += " + stitching"
            use_filter = cfg.get("models", {}).get("filter", {}).get("enabled", True)
            front_name = TUNED_NAME if front == "tuned" else front
            if cams.get("person_detector"):
                filt["detector_min_score"] = config_from_dict(merged(cfg, {"recording": "."})).system_params() \
                    .camera_params.foreground.min_person_score
            results.append(dict(row=key, front_end=front_name, planes=planes,
                                filter="BOF" if use_filter else "off", sensor_model=model, scores=filt))
            # the per-frame detector's own row comes from a run that does not feed its tracks back into the
            # generative model (the filtered one, or, where that one takes the tracks as its prior, the one without
            # the filter)
            track_prior = model.startswith("generative") and float(cams.get("generative_track_prior_ratio", 1.0)) != 1.0
            if use_filter != track_prior:
                results.append(dict(row=key + "-perframe", front_end=front_name, planes=planes,
                                    filter="none (per frame)", sensor_model=model, scores=raw))
            print(markdown(results[-2:] if use_filter != track_prior else results[-1:]).split("\n", 2)[-1],
                  flush=True)
        if args.run_dir is not None:
            run_cfg = merged(base, {"recording": str(rec.root), "outputs": {"out_dir": str(args.run_dir.resolve())}})
            cfg_file = tmp / "terrace.yaml"
            cfg_file.write_text(yaml.safe_dump(run_cfg, sort_keys=False))
            t0 = time.process_time()
            planefuse_cli(["run", str(cfg_file), "--quiet", "--fresh"])
            metrics = json.loads((args.run_dir / "metrics.json").read_text())
            print(f"planefuse run into {args.run_dir}: MODA {metrics['moda']:.3f}, MOTA {metrics['mota']:.3f}, "
                  f"IDF1 {metrics['idf1']:.3f} (all people, first second skipped)", flush=True)
        if {"generative", "pom"} & rows:
            masks, mask_cpu_s = foreground_masks(rec, tuned_front_end(base))
            masks = [m[len(run_frames) - len(frames):] for m in masks]  # the scored frames (warm-up dropped)
            np.savez_compressed(out / "masks.npz", frames=frames, c0=masks[0], c1=masks[1])
            gen, q = generative_row(rec, masks, truth, frames)
            gen["mask_cpu_s"] = mask_cpu_s
            results.append(dict(row="generative", front_end=TUNED_NAME,
                                planes="ground locations (25 cm)", filter="none (per frame)",
                                sensor_model="generative (mean field)", scores=gen))
            print(markdown(results[-1:]).split("\n", 2)[-1], flush=True)
            if "pom" in rows or args.pom:
                sys.path.insert(0, str(REPO / "benchmarks"))
                from bench_terrace_pom import pom_row

                pom = pom_row(rec, masks, frames, lambda d: score(truth, frames, d), out)
                if pom is not None:
                    results.append(dict(row="pom", front_end=TUNED_NAME,
                                        planes="ground locations (25 cm)", filter="none (per frame)",
                                        sensor_model="POM (reference program)", scores=pom))
                    print(markdown(results[-1:]).split("\n", 2)[-1], flush=True)
        if "pom-det" in rows:
            # POM fed the detector's masks: its boxes filled, no background subtraction (the detector-alone front end)
            det_cfg = merged(base, with_person_model(_changes(_DET, _DET_ONLY), args.person_model))
            det_masks, _ = foreground_masks(rec, tuned_front_end(det_cfg))
            det_masks = [m[len(run_frames) - len(frames):] for m in det_masks]
            sys.path.insert(0, str(REPO / "benchmarks"))
            from bench_terrace_pom import pom_row

            (out / "pom-det").mkdir(exist_ok=True)
            pom = pom_row(rec, det_masks, frames, lambda d: score(truth, frames, d), out / "pom-det")
            if pom is not None:
                results.append(dict(row="pom-det", front_end=DET_ONLY_NAME, planes="ground locations (25 cm)",
                                    filter="none (per frame)", sensor_model="POM (reference program)", scores=pom))
                print(markdown(results[-1:]).split("\n", 2)[-1], flush=True)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    meta = dict(first=args.first, last=args.last, step=args.step, process_step=process_step,
                warmup_from=args.warmup_from,
                background_median_s=args.background_median_s or None,
                n_frames=len(frames), config=base,
                generative_25cm=repr(GENERATIVE))
    (out / "terrace.json").write_text(json.dumps(dict(meta=meta, rows=results), indent=1, default=float))
    (out / "table.md").write_text(markdown(results) + "\n")
    print(markdown(results))
    print(f"written {out / 'terrace.json'}")
    return 0


def _shared_person_model() -> Path | None:
    """The shared YOLOX-Nano test model beside the checkout, where it is."""
    p = REPO.parent / "shared" / "models" / "yolox_nano" / "yolox_nano.onnx"
    return p if p.is_file() else None


def warm_frames(warmup_from: int | None, first: int, last: int, step: int) -> np.ndarray:
    """The frames run: ``first..last`` every ``step``-th, preceded by the warm-up frames from ``warmup_from``
    (same step) when given; the scored frames ``first..last`` are then the run's last ones."""
    if warmup_from is None:
        return np.arange(first, last, step)
    if not 0 <= warmup_from <= first or (first - warmup_from) % step:
        raise SystemExit(f"--warmup-from {warmup_from}: must lie in 0..{first} (--first) with --first minus it "
                         f"a multiple of --step {step}")
    return np.arange(warmup_from, last, step)


def _rows(spec: str) -> set[str]:
    allowed = set(ROWS) | set(TABLE_ROWS)
    rows = allowed if spec == "all" else set(spec.split(","))
    if rows - allowed:
        raise SystemExit(f"--rows: unknown {sorted(rows - allowed)}; choose from {sorted(allowed)}")
    return rows


if __name__ == "__main__":
    raise SystemExit(main())
