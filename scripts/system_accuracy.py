"""The whole system with each modality alone and all together on short simulated scenes: the measurements
behind the bounds of ``tests/test_system_accuracy.py``. Prints a Markdown table.

Usage: ``PYTHONPATH=src python3 scripts/system_accuracy.py [--seeds 7,8,9,10,11] [--duration-s 3]``

Scores as in :func:`planefuse.pipeline.evaluate_system` (first second skipped, 0.5 m match distance);
``max det`` is the most detections at one scored step. The simulated hold-out is seeds >= 4.
"""

from __future__ import annotations

import argparse

from planefuse.pipeline import SystemParams, evaluate_system, run_system
from planefuse.sim import default_scene_config, simulate

MODALITIES = {
    "all": dict(),
    "cameras": dict(laser=False, sound=False),
    "laser": dict(cameras=False, sound=False),
    "sound": dict(cameras=False, laser=False),
}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seeds", default="7,8,9,10,11", help="comma-separated scene seeds")
    ap.add_argument("--duration-s", type=float, default=3.0, help="scene duration [s]")
    args = ap.parse_args()
    print("| seed | modalities | MODA | precision | recall | MOTA | IDF1 | max det | people | sound MAE [deg] |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    for seed in (int(s) for s in args.seeds.split(",")):
        rec = simulate(default_scene_config(duration_s=args.duration_s, seed=seed))
        warm = rec.groundtruth.people.times_s[0] + 1.0
        for name, kw in MODALITIES.items():
            res = run_system(rec, SystemParams(**kw))
            m = evaluate_system(rec, res)
            max_det = max((len(o.detections.xy_m) for o in res.outputs if o.time_s >= warm), default=0)
            az = m.get("azimuth_mae_deg", float("nan"))
            print(f"| {seed} | {name} | {m['moda']:.3f} | {m['precision']:.3f} | {m['recall']:.3f} | "
                  f"{m['mota']:.3f} | {m['idf1']:.3f} | {max_det} | {m['n_people']} | {az:.1f} |", flush=True)


if __name__ == "__main__":
    main()
