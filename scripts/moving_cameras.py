"""The whole system on simulated scenes whose cameras move (a swaying mast, a bump, a pan sweep), with each
camera's attitude from its calibration (fixed) or from its IMU (followed): docs/results.md, "Cameras that
move". Prints a Markdown table.

Scenes: the default scene (4 cameras in the corners, 6 people), with

* ``static``: no camera moves (the reference);
* ``sway``: every camera sways about its horizontal axis (a mast in the wind): 1.5 deg, 3 s period, from
  t = 1 s on, the cameras' phases spread over the period;
* ``bump``: cameras 0 and 2 are knocked down by 3 deg at t = 2 s (0.1 s) and stay there;
* ``pan``: cameras 0 and 2 sweep +-10 deg about the vertical, 6 s period, from t = 1 s on.

Every camera is still for the first second: the IMU route takes the gyroscope bias from the still start of
the stream (``RegistrationParams.gyro_bias_rest_s``); without one, the heading, which only the gyroscope
sees, drifts at the bias rate (0.17 deg/s for the simulated IMU, ~0.5 px/s).

Scores as :func:`planefuse.pipeline.evaluate_system` (first second skipped, 0.5 m match distance). The
simulated hold-out is seeds >= 4 (seeds 1-3 tune); nothing here is tuned.

Usage: ``PYTHONPATH=src python3 scripts/moving_cameras.py [--seeds 4,5] [--duration-s 6] [--modalities all]``
"""

from __future__ import annotations

import argparse
import time
from dataclasses import replace

from planefuse.pipeline import SystemParams, evaluate_system, run_system
from planefuse.sim import CameraMotionSpec, default_scene_config, simulate


def motions(scene: str, n_cameras: int) -> list[list[CameraMotionSpec]]:
    """Per camera, its motion in ``scene``."""
    none: list[list[CameraMotionSpec]] = [[] for _ in range(n_cameras)]
    if scene == "static":
        return none
    if scene == "sway":
        return [[CameraMotionSpec(kind="sway", amplitude_deg=1.5, period_s=3.0, start_s=1.0 + 3.0 * c / n_cameras)]
                for c in range(n_cameras)]
    kind = {"bump": CameraMotionSpec(kind="bump", amplitude_deg=3.0, start_s=2.0),
            "pan": CameraMotionSpec(kind="pan", amplitude_deg=10.0, period_s=6.0, start_s=1.0)}[scene]
    return [[kind] if c in (0, 2) else [] for c in range(n_cameras)]


SCENES = ("static", "sway", "bump", "pan")
MODALITIES = {"all": {}, "cameras": dict(laser=False, sound=False)}


def scene_recording(scene: str, seed: int, duration_s: float):
    cfg = default_scene_config(duration_s=duration_s, seed=seed)
    cams = [c.model_copy(update={"motion": m}) for c, m in zip(cfg.cameras, motions(scene, len(cfg.cameras)))]
    return simulate(cfg.model_copy(update={"cameras": cams}))


def with_source(params: SystemParams, source: str) -> SystemParams:
    cp = params.camera_params
    return replace(params, camera_params=replace(cp, registration=replace(cp.registration, attitude_source=source)))


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seeds", default="4,5", help="comma-separated scene seeds (hold-out: >= 4)")
    ap.add_argument("--duration-s", type=float, default=6.0, help="scene duration [s]")
    ap.add_argument("--modalities", default="all", choices=sorted(MODALITIES))
    ap.add_argument("--scenes", default=",".join(SCENES))
    ap.add_argument("--sources", default="calibration,imu", help="attitude sources to run")
    args = ap.parse_args(argv)
    base = SystemParams(**MODALITIES[args.modalities])
    print("| scene | seed | attitude from | MODA | MOTA | IDF1 | camera-only MODA | map rebuilds | run time [s] |")
    print("|---|---|---|---|---|---|---|---|---|")
    for scene in args.scenes.split(","):
        for seed in (int(s) for s in args.seeds.split(",")):
            rec = scene_recording(scene, seed, args.duration_s)
            for source in args.sources.split(","):
                t0 = time.perf_counter()
                res = run_system(rec, with_source(base, source))
                el = time.perf_counter() - t0
                m = evaluate_system(rec, res)
                reg = res.report.camera_registration
                print(f"| {scene} | {seed} | {source} | {m['moda']:.3f} | {m['mota']:.3f} | {m['idf1']:.3f} | "
                      f"{m.get('camera_only_moda', float('nan')):.3f} | {sum(reg.n_rebuilds)} | {el:.0f} |",
                      flush=True)


if __name__ == "__main__":
    main()
