"""Accuracy of the generative camera model (docs/results.md, "Generative multi-view occupancy").

A. POM agreement on POM's own test data (``../shared/data/epfl_pom_test``: 2 real cameras, 1332 locations), POM
   built from ``../shared/reference/pom`` in a temporary folder and run in the same invocation. The solver's damping
   was chosen on frames 160-174 (shown as "tune"); frames 175-189 are the held-out report.
B. The simulator's default scene seen by only 2 of its 4 cameras (cam0 and cam1, adjacent corners), seeds given
   (report: 4 and 5; 1-3 are the tuning seeds): per-cell model vs generative model vs POM on the same foreground
   images (KNN background subtraction on the rendered frames; exact masks as a labelled upper bound) at the same
   instants (every ``--every``-th camera instant after a 2 s warm-up), MODA/MODP/precision/recall at 0.5 m.
   The per-cell model runs on its default 5 cm multi-plane stack; the generative model and POM on the same ground
   locations (cells of ``--cell-size-m``) with the same silhouettes (``.pom`` written by ``write_pom``).

Run: ``python scripts/generative_results.py [--seeds 4 5] [--duration-s 12] [--every 10] [--no-pom] [--skip-a]
[--skip-b]``.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
from pathlib import Path

import cv2
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
from _pom_reference import agreement, build_pom, demo_pom_file, run_pom_program  # noqa: E402

from planefuse.eval import detection_scores  # noqa: E402
from planefuse.grid import PlaneStack  # noqa: E402
from planefuse.occupancy import read_pom, run_pom, write_pom  # noqa: E402
from planefuse.vision import (  # noqa: E402
    BackgroundSubtractor,
    CameraFusion,
    ForegroundParams,
    GenerativeCameraSensor,
    GenerativeSensorParams,
    PersonParams,
    ground_detections_from_log_odds,
    lookups_from_cameras,
    max_log_ratio,
    recording_frames,
)


def part_a(exe: Path | None, work: Path) -> None:
    print("\n## A. POM's test data: agreement with POM (2 cameras, 1332 locations)\n")
    if exe is None:
        print("POM could not be built: skipped")
        return
    pom_file = demo_pom_file(work)
    frames = list(range(160, 190))
    pom, _ = run_pom_program(exe, pom_file, 1332, frames, work / "out")
    ours = np.array([r.marginals for _, r in run_pom(read_pom(pom_file), frames, write=False)])
    # the same marginals summed over each location's 3 x 3 neighbourhood: insensitive to one-location shifts
    k3 = np.ones((3, 3))

    def smooth(a):
        return np.array([cv2.filter2D(x.reshape(37, 36), -1, k3, borderType=cv2.BORDER_CONSTANT).ravel() for x in a])

    print("| frames | POM detections (> 0.5) | found within 1 location | extra | Pearson | Pearson, 3x3 sums |")
    print("|---|---|---|---|---|---|")
    for name, sl in (("160-174 (tune)", slice(0, 15)), ("175-189 (held out)", slice(15, 30))):
        a = agreement(ours[sl], pom[sl], (37, 36))
        r3 = float(np.corrcoef(smooth(ours[sl]).ravel(), smooth(pom[sl]).ravel())[0, 1])
        print(f"| {name} | {a['pom_detections']} | {a['found']} ({100 * a['found_fraction']:.0f} %) | {a['extra']} | "
              f"{a['pearson']:.3f} | {r3:.3f} |")


def part_b(exe: Path | None, work: Path, seeds, duration_s: float, every: int, cell_size_m: float,
           camera_idx=(0, 1), warmup_s: float = 2.0) -> None:
    from planefuse.sim import default_scene_config, simulate

    print(f"\n## B. Simulated default scene, cameras {list(camera_idx)} of 4, {duration_s:g} s, every {every}-th "
          f"instant after {warmup_s:g} s\n")
    print("| seed | foreground | model | frames | MODA | MODP | precision | recall | detections / frame |")
    print("|---|---|---|---|---|---|---|---|---|")
    for seed in seeds:
        rec = simulate(default_scene_config(duration_s=duration_s, seed=seed))
        cams = [rec.cameras[i] for i in camera_idx]
        x0, x1, y0, y1 = rec.scene.room_xy_m
        cell_stack = PlaneStack.from_extent([0.1, 0.5, 1.0, 1.5], (x0, x1), (y0, y1), 0.05)
        gen_stack = PlaneStack.from_extent([0.1, 0.5, 1.0, 1.5], (x0, x1), (y0, y1), cell_size_m)
        fusion = CameraFusion(lookups_from_cameras(cams, cell_stack), cell_stack)
        sensor = GenerativeCameraSensor(cams, gen_stack, GenerativeSensorParams())
        person = PersonParams()
        # the same foreground images for every model: KNN on every rendered frame, exact masks
        subs = [BackgroundSubtractor(c.intrinsics.width_px, c.intrinsics.height_px, ForegroundParams(), c.name)
                for c in cams]
        inputs = {"KNN": [], "exact masks (upper bound)": []}
        times = []
        for i, ((t, imgs), (_, masks)) in enumerate(zip(recording_frames(rec), recording_frames(rec, masks=True))):
            imgs = [imgs[j] for j in camera_idx]
            masks = [masks[j] for j in camera_idx]
            fg = [s.apply(im) for s, im in zip(subs, imgs)]
            if t >= warmup_s and i % every == 0:
                times.append(t)
                inputs["KNN"].append(fg)
                inputs["exact masks (upper bound)"].append([m.astype(np.float32) / 255.0 for m in masks])
        gt = [rec.groundtruth.people.detections_at(t).xy_m for t in times]
        for fg_name, fgs in inputs.items():
            results = {}
            dets = []
            for t, fg in zip(times, fgs):
                ev = fusion.evidence(fg, t)
                dets.append(ground_detections_from_log_odds(ev.log_odds, fusion.cameras_seeing(fusion.active),
                                                            cell_stack, t, max_log_ratio(fusion.params), person).xy_m)
            results["per-cell (5 cm, 4 planes)"] = dets
            dets = [sensor.detections(sensor.marginals(fg), t, person.nms_radius_m).xy_m for t, fg in zip(times, fgs)]
            results[f"generative ({100 * cell_size_m:g} cm locations)"] = dets
            if exe is not None:
                d = work / f"seed{seed}-{'knn' if fg_name == 'KNN' else 'masks'}"
                (d / "masks").mkdir(parents=True)
                (d / "out").mkdir()
                # POM gets the binary masks the generative model solves on (foreground_threshold)
                thr = sensor.params.foreground_threshold
                for f, fg in enumerate(fgs):
                    for c, img in enumerate(fg):
                        cv2.imwrite(str(d / "masks" / f"f{f}-c{c}.png"),
                                    np.where(np.asarray(img, float) >= thr, 255, 0).astype(np.uint8))
                write_pom(d / "sim.pom", sensor.silhouettes, sensor.solver_params,
                          input_view_format="masks/f%f-c%c.png", result_format="out/proba-f%f.dat",
                          process=(0, len(fgs)))
                q_pom, _ = run_pom_program(exe, d / "sim.pom", sensor.silhouettes.n_locations,
                                              list(range(len(fgs))), d / "out")
                dets = [sensor.detections(q.reshape(gen_stack.ny, gen_stack.nx), t, person.nms_radius_m).xy_m
                        for t, q in zip(times, q_pom)]
                results["POM (same locations and masks)"] = dets
            for model, dets in results.items():
                s = detection_scores(list(zip(gt, dets)), 0.5)
                n_det = np.mean([len(x) for x in dets])
                print(f"| {seed} | {fg_name} | {model} | {len(times)} | {s.moda:.3f} | {s.modp:.3f} | "
                      f"{s.precision:.3f} | {s.recall:.3f} | {n_det:.1f} |")
        print(f"| {seed} | | people per frame (ground truth) | | | | | | {np.mean([len(g) for g in gt]):.1f} |")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, nargs="+", default=[4, 5])
    ap.add_argument("--duration-s", type=float, default=12.0)
    ap.add_argument("--every", type=int, default=10)
    ap.add_argument("--cell-size-m", type=float, default=0.1)
    ap.add_argument("--no-pom", action="store_true")
    ap.add_argument("--skip-a", action="store_true")
    ap.add_argument("--skip-b", action="store_true")
    args = ap.parse_args()
    with tempfile.TemporaryDirectory(prefix="generative-results-") as tmp:
        tmp = Path(tmp)
        exe = None
        if not args.no_pom:
            try:
                exe = build_pom(tmp)
            except RuntimeError as exc:
                print(f"POM not built ({exc}): POM columns skipped")
        if not args.skip_a:
            (tmp / "a").mkdir()
            part_a(exe, tmp / "a")
        if not args.skip_b:
            (tmp / "b").mkdir()
            part_b(exe, tmp / "b", args.seeds, args.duration_s, args.every, args.cell_size_m)


if __name__ == "__main__":
    main()
