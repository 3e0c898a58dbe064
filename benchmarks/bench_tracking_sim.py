"""Filter + tracker on the default simulated scene: exact camera masks vs background subtraction.

Run: ``python benchmarks/bench_tracking_sim.py [--duration-s 8]``

Separates the filter/tracker from the camera foreground: the same BOF, clustering and tracker
(`planefuse.tracking` defaults, outputs every 0.08 s) on the same stack as `planefuse demo`
(`stack_for_recording`), fed with the laser plus either the simulator's exact person masks as camera
foreground or the camera pipeline's background subtraction (what the demo uses).
"""

from __future__ import annotations

import argparse
import time
import warnings

import numpy as np

from planefuse.eval import detection_scores, tracking_metrics
from planefuse.laser import LaserSensorModel
from planefuse.pipeline import (
    ModalityReport,
    SystemParams,
    camera_evidence,
    laser_evidence,
    merged_evidence,
    stack_for_recording,
)
from planefuse.sim import default_scene_config, simulate
from planefuse.tracking import TrackingParams, track_evidence
from planefuse.vision import CameraParams, camera_detections, foreground_from_mask, lookups_from_cameras


def mask_camera_evidence(rec, stack, every: int = 2):
    """Camera evidence with the simulator's exact masks as foreground likelihoods."""
    streams = [rec.camera(c.name) for c in rec.cameras]
    n = min(len(s) for s in streams)
    frames = ((float(streams[0].times_s[i]), [foreground_from_mask(s.mask(i) > 0) for s in streams])
              for i in range(0, n, every))
    for ev, _ in camera_detections(frames, lookups_from_cameras(rec.cameras, stack), stack,
                                   CameraParams(foreground=None)):
        yield ev


def scores(rec, outputs, warm_s: float = 1.0) -> dict:
    """MODA (clusters) and MOTA, IDF1 (tracks) after the first ``warm_s`` seconds, 0.5 m threshold."""
    gt = rec.groundtruth.people
    outs = [o for o in outputs if o.time_s >= gt.times_s[0] + warm_s]
    frames = []
    for o in outs:
        k = int(np.argmin(np.abs(gt.times_s - o.time_s)))
        ok = np.isfinite(gt.xy_m[k]).all(axis=1)
        frames.append((o.time_s, gt.person_ids[ok], gt.xy_m[k][ok]))
    det = detection_scores([(f[2], o.detections.xy_m) for f, o in zip(frames, outs)], 0.5)
    mot = tracking_metrics(frames, [o.tracks for o in outs], match_distance_m=0.5)
    return {"moda": det.moda, "recall": det.recall, "mota": mot["mota"], "idf1": mot["idf1"]}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--duration-s", type=float, default=8.0)
    args = ap.parse_args()
    warnings.simplefilter("ignore")
    rec = simulate(default_scene_config(duration_s=args.duration_s, seed=1))
    stack = stack_for_recording(rec, SystemParams())
    params = TrackingParams(output_period_s=0.08 - 1e-6, merge_tolerance_s=0.02)
    print(f"{args.duration_s:.0f} s of the default scene, planes {stack.heights_m}, grid {stack.shape}")
    print(f"{'camera foreground':<34}{'MODA':>7}{'MOTA':>7}{'IDF1':>7}{'recall':>8}{'CPU s':>7}")
    for name, cams in [("exact masks", lambda: mask_camera_evidence(rec, stack)),
                       ("background subtraction", lambda: camera_evidence(rec, stack, CameraParams(),
                                                                          ModalityReport()))]:
        c0 = time.process_time()
        evidence = merged_evidence(cams(), laser_evidence(rec, stack, LaserSensorModel(), ModalityReport()))
        outs = list(track_evidence(stack, evidence, params))
        m = scores(rec, outs)
        print(f"{name + ' + laser':<34}{m['moda']:>7.3f}{m['mota']:>7.3f}{m['idf1']:>7.3f}{m['recall']:>8.3f}"
              f"{time.process_time() - c0:>7.1f}")


if __name__ == "__main__":
    main()
