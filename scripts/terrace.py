"""The seed's experiment on real video: EPFL terrace1, cameras c0 + c1, end to end, scored against the ground truth.

What it does, for frames ``--first`` to ``--last`` (every ``--step``-th):

1. writes a planefuse recording (format 2) in a temporary folder: the two videos as ``video_file`` streams with a
   ``times_file`` listing the chosen frames, the Tsai cameras converted to ``PinholeCamera``
   (:func:`planefuse.calib.pinhole_from_tsai`, so that planes above the ground are registered), the burned-in
   watermark as an ignore rectangle, and the ground truth: every person placed at the median of the feet of their
   boxes in all four cameras back-projected to the ground through the Tsai models; a person seen by neither c0
   nor c1 is "ignore" (kept aside, neither a miss nor a false alarm);
2. runs :func:`planefuse.pipeline.run_system` on it -- what ``planefuse run`` runs -- with background
   subtraction learnt from the video itself (no empty plate exists), the plane stack, the BOF and the tracker,
   for each configuration of the table (front end, planes, filter, sensor model);
3. runs the generative sensor model (:mod:`planefuse.occupancy`, mean-field marginals over ground locations with
   silhouettes projected from the same cameras) on the same foreground masks, frame by frame;
4. optionally (``--pom``) POM, the reference program, on the same masks and silhouettes
   (``benchmarks/bench_terrace_pom.py``);
5. scores every row with the same scorer: MODA, MODP, precision, recall at 0.5 m and 1.0 m
   (:func:`planefuse.eval.detection_scores`), MOTA, IDF1 and identity switches of the tracks
   (:func:`planefuse.eval.tracking_metrics`), and writes ``terrace.json`` and a Markdown table.

Hold-out: every parameter was chosen on frames 0-1499; report on 1500-2999. Example::

    PYTHONPATH=src python3 scripts/terrace.py --data ../shared/data --first 1500 --last 3000 --step 5 --out /tmp/terrace

Outside ``planefuse run``: the recording is written by this script (``planefuse import`` does it for users), the
ignore people of the ground truth are the script's (the recording format has no "ignore" people), and the
generative rows run the library's solver directly until the run configuration selects it.
"""

from __future__ import annotations

import argparse
import json
import shutil
import sys
import tempfile
import time
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
import yaml

from planefuse.calib import EPFL_TERRACE_TSAI, pinhole_from_tsai
from planefuse.eval import detection_scores, match_detections, tracking_metrics
from planefuse.grid import PlaneStack
from planefuse.io import read_recording
from planefuse.occupancy import GenerativeParams
from planefuse.pipeline import SystemParams, run_system
from planefuse.vision import (BackgroundSubtractor, CameraParams, ForegroundParams, GenerativeSensorParams,
                              epfl_ground_truth_from_cameras, load_epfl_sequence, recording_frames)

FPS = 25.0
#: The converter's watermark, (u_min, v_min, u_max, v_max) px, max exclusive (../shared/data/epfl_video/SOURCE.md).
WATERMARK_PX = (130, 230, 356, 285)
#: The monitored area [m, Tsai world]: POM's terrace grid, 7.5 m x 11 m from (-0.5, -1.5).
AREA_X_M, AREA_Y_M = (-0.5, 7.0), (-1.5, 9.5)
PLANES_M = (0.1, 0.5, 1.0, 1.5)
CELL_M = 0.1
ROWS = ("knn", "gain", "ground", "nofilter", "gen", "gen-ground", "gen-nofilter", "generative")

#: Front ends compared (parameters chosen on frames 0-1499, docs/results.md).
FRONT_ENDS = {
    "KNN defaults": ForegroundParams(),
    "KNN + gain compensation": ForegroundParams(gain_compensation=True, shadow_likelihood=0.5),
}


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


def write_recording(folder: Path, video_root: Path, truth: TerraceTruth, frames: np.ndarray, step: int) -> Path:
    """A format-2 recording of c0 + c1 over ``frames`` (video files copied in: paths must stay inside it)."""
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "cameras").mkdir(exist_ok=True)
    (folder / "groundtruth").mkdir(exist_ok=True)
    sensors = []
    for cam in terrace_cameras((0, 1)):
        video = f"cameras/terrace1-{cam.name}.mp4"
        shutil.copyfile(video_root / f"terrace1-{cam.name}.mp4", folder / video)
        times = f"cameras/{cam.name}_times.csv"
        (folder / times).write_text("time_s,frame_index\n" + "".join(f"{float(f) / FPS!r},{int(f)}\n" for f in frames))
        sensors.append(dict(type="camera", name=cam.name, width_px=cam.intrinsics.width_px,
                            height_px=cam.intrinsics.height_px, K=cam.K.tolist(), dist=cam.intrinsics.dist.tolist(),
                            T_world_cam=cam.T_world_cam.tolist(), rate_hz=FPS / step, n_frames=len(frames),
                            times_file=times, video_file=video, ignore_rects_px=[list(WATERMARK_PX)]))
    lines = ["time_s,person_id,x_m,y_m,heading_rad,speed_m_s,height_m"]
    for f in frames:
        for pid, (x, y) in zip(truth.ids[int(f)], truth.xy_m[int(f)]):
            lines.append(f"{float(f) / FPS!r},{pid},{float(x)!r},{float(y)!r},nan,nan,nan")
    (folder / "groundtruth" / "people.csv").write_text("\n".join(lines) + "\n")
    m = 0.2  # stack_for_recording's wall margin
    manifest = dict(format="planefuse-recording", format_version=2, duration_s=float((frames[-1] - frames[0]) / FPS),
                    planes_heights_m=list(PLANES_M),
                    room_xy_m=[AREA_X_M[0] - m, AREA_X_M[1] + m, AREA_Y_M[0] - m, AREA_Y_M[1] + m],
                    sensors=sensors, groundtruth=dict(people_file="groundtruth/people.csv"),
                    source="EPFL terrace1 c0+c1 (scripts/terrace.py)")
    (folder / "scene.yaml").write_text(yaml.safe_dump(manifest, sort_keys=False))
    return folder


def _frame_of(time_s: float) -> int:
    return int(round(time_s * FPS))


def score(truth: TerraceTruth, frames, detections, tracks=None) -> dict:
    """MODA/MODP/precision/recall at 0.5 and 1.0 m (ignored people neither missed nor false), and, with
    ``tracks`` ((ids, xy) per frame), MOTA, IDF1 and ID switches at 0.5 m (hypotheses on ignored people dropped)."""
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
        mot = tracking_metrics(gt_frames, hyp_frames, match_distance_m=0.5)
        out.update(mota=mot["mota"], idf1=mot["idf1"], id_switches=int(mot["num_switches"]))
    return out


def run_row(rec, params: SystemParams, truth: TerraceTruth, frames) -> tuple[dict, dict]:
    """One ``run_system`` run: scores of the filtered detections and tracks, and of the per-frame camera detector."""
    t0 = time.process_time()
    res = run_system(rec, params)
    cpu_s = time.process_time() - t0
    by_frame = {_frame_of(o.time_s): o for o in res.outputs}
    fr = [f for f in frames if f in by_frame]
    filt = score(truth, fr, [by_frame[f].detections.xy_m for f in fr],
                 [(np.asarray(by_frame[f].tracks.ids), by_frame[f].tracks.xy_m) for f in fr])
    cams = {_frame_of(d.time_s): d for d in res.report.camera_detections}
    frc = [f for f in frames if f in cams]
    raw = score(truth, frc, [cams[f].xy_m for f in frc])
    filt.update(cpu_s=cpu_s, frames_per_cpu_s=2 * len(frames) / cpu_s, unscored_steps=len(frames) - len(fr))
    return filt, raw


def foreground_masks(rec, fg: ForegroundParams) -> tuple[list[np.ndarray], float]:
    """The front end's foreground likelihoods of every recorded frame, per camera ((F, H, W) uint8 0..255), as the
    camera pipeline computes them, and the CPU seconds it took (decode included)."""
    t0 = time.process_time()
    subs = [BackgroundSubtractor(c.intrinsics.width_px, c.intrinsics.height_px, fg, c.name) for c in rec.cameras]
    out: list[list[np.ndarray]] = [[] for _ in subs]
    for _, imgs in recording_frames(rec):
        for c, (sub, img) in enumerate(zip(subs, imgs)):
            out[c].append(np.round(sub.apply(img) * 255).astype(np.uint8))
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


#: The mean-field solver on 25 cm ground locations (chosen on frames 0-1499: sigma 0.005, prior 0.003).
GENERATIVE = GenerativeParams(sigma=0.005, prior=0.003)
#: The generative sensor of the run (planefuse.vision): same sigma; its prior density, 0.05 people/m^2, is
#: 0.003 per 25 cm location, the prior chosen on frames 0-1499.
GENERATIVE_SENSOR = GenerativeSensorParams(sigma=0.005, people_per_m2=0.05,
                                           evidence_prior=0.5)
#: BOF column log-odds of a person, per sensor model (generative: chosen on frames 0-1499 every 10th, 3 vs 1.5;
#: per cell: the system's default).
COLUMN_THRESHOLDS = {"cell": 1.5, "generative": 3.0}


def markdown(rows: list[dict]) -> str:
    head = ("| front end | planes (m) | filter | sensor model | MODA 0.5 m | MODP 0.5 m | precision | recall "
            "| MODA 1.0 m | MOTA | IDF1 | ID switches | detections/frame |\n|---|---|---|---|---|---|---|---|---|---|---|---|---|")
    lines = [head]
    for r in rows:
        s = r["scores"]
        mot = (f"{s['mota']:.3f} | {s['idf1']:.3f} | {s['id_switches']}" if "mota" in s else "- | - | -")
        lines.append(f"| {r['front_end']} | {r['planes']} | {r['filter']} | {r['sensor_model']} | {s['moda@0.5']:.3f} "
                     f"| {s['modp@0.5']:.3f} | {s['precision@0.5']:.2f} | {s['recall@0.5']:.2f} | {s['moda@1.0']:.3f} "
                     f"| {mot} | {s['detections_per_frame']:.1f} |")
    return "\n".join(lines)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--data", type=Path, default=Path(__file__).resolve().parents[2] / "shared" / "data",
                    help="folder holding epfl_video/ and epfl_pom/")
    ap.add_argument("--first", type=int, default=1500, help="first frame (0-based)")
    ap.add_argument("--last", type=int, default=3000, help="end frame (exclusive)")
    ap.add_argument("--step", type=int, default=5, help="use every step-th frame")
    ap.add_argument("--out", type=Path, default=None, help="folder for terrace.json, table.md and masks")
    ap.add_argument("--rows", default="all", help="comma-separated subset of " + ",".join(ROWS))
    ap.add_argument("--cell", type=float, default=CELL_M, help="grid cell side of the plane stack [m]")
    ap.add_argument("--column-threshold", type=float, default=None,
                    help="BOF column log-odds of a person (models.detection.column_threshold); default per sensor "
                         "model: " + str(COLUMN_THRESHOLDS))
    ap.add_argument("--pom", action="store_true", help="also run POM on the same masks (needs g++, make, libpng)")
    args = ap.parse_args(argv)
    video_root, pom_root = args.data / "epfl_video", args.data / "epfl_pom" / "EPFL-Terrace"
    for p in (video_root / "terrace1-c0.mp4", pom_root / "terrace1-c0" / "gt" / "gt.txt"):
        if not p.is_file():
            print(f"skipped: {p} is absent", file=sys.stderr)
            return 0
    frames = np.arange(args.first, args.last, args.step)
    out = args.out or Path(tempfile.mkdtemp(prefix="terrace-"))
    out.mkdir(parents=True, exist_ok=True)
    truth = terrace_truth(pom_root, frames)
    tmp = Path(tempfile.mkdtemp(prefix="terrace-rec-"))
    try:
        rec = read_recording(write_recording(tmp / "rec", video_root, truth, frames, args.step))
        rows = _rows(args.rows)
        results = []
        tuned = FRONT_ENDS["KNN + gain compensation"]
        gain = "KNN + gain compensation"
        for key, front, heights, use_filter, model in [
                ("knn", "KNN defaults", PLANES_M, True, "cell"), ("gain", gain, PLANES_M, True, "cell"),
                ("ground", gain, (0.0,), True, "cell"), ("nofilter", gain, PLANES_M, False, "cell"),
                ("gen", gain, PLANES_M, True, "generative"), ("gen-ground", gain, (0.0,), True, "generative"),
                ("gen-nofilter", gain, PLANES_M, False, "generative")]:
            if key not in rows:
                continue
            cp = CameraParams(foreground=FRONT_ENDS[front], sensor_model=model, generative=GENERATIVE_SENSOR)
            params = SystemParams(heights_m=heights, cell_size_m=args.cell, laser=False, sound=False,
                                  use_filter=use_filter, camera_params=cp)
            threshold = args.column_threshold or COLUMN_THRESHOLDS[model]
            params = replace(params, tracking=replace(params.tracking, cluster=replace(
                params.tracking.cluster, threshold=threshold)))
            filt, raw = run_row(rec, params, truth, frames)
            planes = "/".join(f"{h:g}" for h in heights)
            name = "per cell" if model == "cell" else "generative"
            results.append(dict(front_end=front, planes=planes, filter="BOF" if use_filter else "off",
                                sensor_model=name, scores=filt))
            if use_filter:
                results.append(dict(front_end=front, planes=planes, filter="none (per frame)",
                                    sensor_model=name, scores=raw))
            print(markdown(results[-2:] if use_filter else results[-1:]).split("\n", 2)[-1], flush=True)
        if "generative" in rows or args.pom:
            masks, mask_cpu_s = foreground_masks(rec, tuned)
            np.savez_compressed(out / "masks.npz", frames=frames, c0=masks[0], c1=masks[1])
            gen, q = generative_row(rec, masks, truth, frames)
            gen["mask_cpu_s"] = mask_cpu_s
            results.append(dict(front_end="KNN + gain compensation", planes="ground locations (25 cm)",
                                filter="none (per frame)", sensor_model="generative (mean field)", scores=gen))
            print(markdown(results[-1:]).split("\n", 2)[-1], flush=True)
            if args.pom:
                sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
                from bench_terrace_pom import pom_row

                pom = pom_row(rec, masks, frames, lambda d: score(truth, frames, d), out)
                if pom is not None:
                    results.append(dict(front_end="KNN + gain compensation", planes="ground locations (25 cm)",
                                        filter="none (per frame)", sensor_model="POM (reference program)",
                                        scores=pom))
                    print(markdown(results[-1:]).split("\n", 2)[-1], flush=True)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    meta = dict(first=args.first, last=args.last, step=args.step, n_frames=len(frames), planes_m=PLANES_M,
                cell_m=CELL_M, front_ends={k: repr(v) for k, v in FRONT_ENDS.items()}, generative=repr(GENERATIVE))
    (out / "terrace.json").write_text(json.dumps(dict(meta=meta, rows=results), indent=1, default=float))
    (out / "table.md").write_text(markdown(results) + "\n")
    print(markdown(results))
    print(f"written {out / 'terrace.json'}")
    return 0


def _rows(spec: str) -> set[str]:
    allowed = set(ROWS)
    rows = allowed if spec == "all" else set(spec.split(","))
    if rows - allowed:
        raise SystemExit(f"--rows: unknown {sorted(rows - allowed)}; choose from {sorted(allowed)}")
    return rows


if __name__ == "__main__":
    raise SystemExit(main())
