"""Ablation of the whole system on the default simulated scene: prints a Markdown table.

Usage: ``PYTHONPATH=src python scripts/ablation.py [--duration-s 10] [--seed 1]``

Rows: cameras only; cameras + laser; cameras + laser + sound (the demo); laser only; laser + sound;
a single plane (1.0 m) instead of the stack; no temporal filter (``use_filter=False``). Scores are those
of :func:`planefuse.eval.system_metrics` (first second skipped, 0.5 m match distance).
"""

from __future__ import annotations

import argparse
import time

from planefuse.pipeline import RunPlan, SystemParams, run_plan
from planefuse.sim import default_scene_config, simulate

ROWS = [
    ("cameras only", SystemParams(laser=False, sound=False)),
    ("cameras + laser", SystemParams(sound=False)),
    ("cameras + laser + sound (demo)", SystemParams()),
    ("laser only", SystemParams(cameras=False, sound=False)),
    ("laser + sound", SystemParams(cameras=False)),
    ("all, single plane (1.0 m)", SystemParams(heights_m=(1.0,))),
    ("all, no filter", SystemParams(use_filter=False)),
]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--duration-s", type=float, default=10.0)
    ap.add_argument("--seed", type=int, default=1)
    args = ap.parse_args()
    rec = simulate(default_scene_config(duration_s=args.duration_s, seed=args.seed))
    print(f"default scene, duration {args.duration_s:g} s, seed {args.seed}\n")
    print("| configuration | MODA | MOTA | IDF1 | precision | recall | ID switches | CPU [s] |")
    print("|---|---|---|---|---|---|---|---|")
    for name, params in ROWS:
        t0 = time.process_time()
        _, m = run_plan(rec, RunPlan(params))  # what `planefuse run` runs, in memory
        cpu = time.process_time() - t0
        print(f"| {name} | {m['moda']:.3f} | {m['mota']:.3f} | {m['idf1']:.3f} | {m['precision']:.3f} | "
              f"{m['recall']:.3f} | {m['id_switches']} | {cpu:.1f} |", flush=True)


if __name__ == "__main__":
    main()
