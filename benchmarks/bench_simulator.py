"""Time the simulator on the default scene: every modality, in memory and written to disk.

    python benchmarks/bench_simulator.py [--duration-s 20] [--write jpg|png|none]

Prints wall and CPU (this process) seconds per stage. Baseline, measured in the same run: a naive per-frame
render of the same number of frames (copy the background, draw nothing, add fresh numpy Gaussian noise
with ``rng.normal`` and convert to uint8), i.e. the least per-pixel work a noisy renderer must do; the
ratio says how the full renderer (people, shading, shadows, masks, gain, noise) compares with it.
"""

from __future__ import annotations

import argparse
import shutil
import tempfile
import time
from pathlib import Path

import numpy as np

from planefuse.sim import default_scene_config, simulate


class Timer:
    def __enter__(self):
        self.w, self.c = time.perf_counter(), time.process_time()
        return self

    def __exit__(self, *a):
        self.wall, self.cpu = time.perf_counter() - self.w, time.process_time() - self.c


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--duration-s", type=float, default=20.0)
    ap.add_argument("--write", choices=["jpg", "png", "none"], default="jpg")
    args = ap.parse_args()
    cfg = default_scene_config(duration_s=args.duration_s)
    rows = []
    with Timer() as t:
        rec = simulate(cfg)
    rows.append(("scene + IMUs + ground truth + binaural audio", t))
    with Timer() as t:
        rec.laser().read()
    rows.append((f"laser: {rec.laser().n_scans} scans x 1081 beams", t))
    n_frames = sum(len(cs) for cs in rec.camera_streams.values())
    with Timer() as t:
        for cs in rec.camera_streams.values():
            for _ in cs:
                pass
    rows.append((f"cameras: render {n_frames} frames + masks", t))
    render = t
    cs0 = next(iter(rec.camera_streams.values()))
    bg = cs0.frame(0).astype(np.float32)
    rng = np.random.default_rng(0)
    with Timer() as t:
        for _ in range(n_frames):
            np.clip(bg + rng.normal(0, 3, bg.shape), 0, 255).astype(np.uint8)
    rows.append((f"baseline: naive noise-only render x {n_frames}", t))
    base = t
    total_w = sum(r[1].wall for r in rows[:3])
    total_c = sum(r[1].cpu for r in rows[:3])
    if args.write != "none":
        out = Path(tempfile.mkdtemp()) / "rec"
        with Timer() as t:
            simulate(cfg).write(out, image_format=args.write)
        rows.append((f"simulate + write everything ({args.write} frames, png masks)", t))
        size = sum(p.stat().st_size for p in out.rglob("*") if p.is_file()) / 1e6
        shutil.rmtree(out.parent)
    print(f"default scene, {args.duration_s:g} s, {cfg.n_people} people, {len(cfg.cameras)} cameras")
    print(f"{'stage':62s} {'wall [s]':>9s} {'cpu [s]':>8s}")
    for name, t in rows:
        print(f"{name:62s} {t.wall:9.2f} {t.cpu:8.2f}")
    print(f"{'all modalities in memory (first three rows)':62s} {total_w:9.2f} {total_c:8.2f}")
    print(f"render / baseline (cpu): {render.cpu / base.cpu:.2f}   per frame: {1e3 * render.cpu / n_frames:.2f} ms cpu")
    if args.write != "none":
        print(f"recording size: {size:.0f} MB")


if __name__ == "__main__":
    main()
