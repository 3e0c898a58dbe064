"""Benchmark: the cost of following the cameras' attitude (the ``imu`` route) against the static pipeline.

Scene: the default simulated scene (4 cameras of 360 x 288 px at 25 Hz, 6 people), 4 s, seed 4, in two
versions rendered once up front (rendering is not timed): every camera still, and every camera swaying
+-1.5 deg about its horizontal axis with a 3 s period (a mast in the wind, phases spread over the period).
Timed, interleaved, best of ``--rounds``, on the same pre-rendered frames:

* ``static, calibration``: the camera pipeline (background subtraction, registration on every plane, fusion,
  people) with fixed lookups: the baseline;
* ``static, imu``: the same still scene through the IMU route (no map is ever rebuilt: the cost of asking);
* ``sway, imu``: the swaying scene through the IMU route: each camera's stabilising map is rebuilt whenever
  its attitude moved a pixel by more than the tolerance (1 px), and every frame of a turned camera is
  remapped (``cv2.remap``);
* ``sway, calibration``: the swaying scene with fixed lookups (what it costs to ignore the motion).

Reported: ms per instant (4 frames), the ratio to the baseline, map rebuilds per second of scene and per
camera, and, once, the time to filter the 4 IMU streams (``CameraRegistration.from_recording``).

Run: ``PYTHONPATH=src python3 benchmarks/bench_attitude.py [--duration-s 4] [--rounds 3]``
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import cv2
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "scripts"))
from moving_cameras import scene_recording  # noqa: E402

from planefuse.pipeline import SystemParams, stack_for_recording  # noqa: E402
from planefuse.registration import CameraRegistration, RegistrationParams  # noqa: E402
from planefuse.vision import camera_detections, camera_instants, recording_frames  # noqa: E402


def run_once(rec, frames, stack, params, source: str) -> tuple[float, CameraRegistration]:
    reg = CameraRegistration.from_recording(rec, stack, RegistrationParams(attitude_source=source))
    t0 = time.perf_counter()
    lookups = reg.lookups_at(float(camera_instants(rec)[0]))
    for _ in camera_detections(frames, lookups, stack, params.camera_params, registration=reg):
        pass
    return time.perf_counter() - t0, reg


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--duration-s", type=float, default=4.0)
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--seed", type=int, default=4)
    args = ap.parse_args(argv)
    cv2.setNumThreads(1)
    params = SystemParams(laser=False, sound=False)
    recs = {s: scene_recording(s, args.seed, args.duration_s) for s in ("static", "sway")}
    stack = stack_for_recording(recs["static"], params)
    frames = {s: list(recording_frames(r)) for s, r in recs.items()}
    n_inst = len(frames["static"])
    t0 = time.perf_counter()
    CameraRegistration.from_recording(recs["sway"], stack, RegistrationParams(attitude_source="imu"))
    filter_s = time.perf_counter() - t0
    cases = [("static", "calibration"), ("static", "imu"), ("sway", "imu"), ("sway", "calibration")]
    best = {c: np.inf for c in cases}
    regs = {}
    for _ in range(args.rounds):
        for scene, source in cases:
            el, regs[scene, source] = run_once(recs[scene], frames[scene], stack, params, source)
            best[scene, source] = min(best[scene, source], el)
    base = best["static", "calibration"]
    print(f"{n_inst} instants x 4 cameras, {args.duration_s:g} s, seed {args.seed}; best of {args.rounds} "
          f"interleaved rounds; filtering the 4 IMU streams once: {filter_s:.2f} s")
    print("| scene | attitude from | ms / instant | ratio to static, calibration | map rebuilds / s (all cameras) |"
          " rebuilds / s per camera |")
    print("|---|---|---|---|---|---|")
    for scene, source in cases:
        reg = regs[scene, source]
        n = sum(reg.n_rebuilds)
        per = ", ".join(f"{k / args.duration_s:.1f}" for k in reg.n_rebuilds)
        print(f"| {scene} | {source} | {best[scene, source] / n_inst * 1e3:.1f} | {best[scene, source] / base:.2f} | "
              f"{n / args.duration_s:.1f} | {per} |")


if __name__ == "__main__":
    main()
