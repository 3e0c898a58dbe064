"""Resuming an interrupted run: time of the re-run against an uninterrupted run, in the same process.

Run: ``python benchmarks/bench_resume.py [--duration-s 10] [--chunk-steps 10]``

The default scene is simulated and written to disk (JPEG frames, laser NPZ, WAV), then read back the way
``planefuse run`` reads a recording. Baseline: one uninterrupted ``run_to_folder`` (figures, report and
animation off). Then, for each fraction ``f``, a run is interrupted (KeyboardInterrupt) at output step
``f * steps`` and re-run into the same folder; the re-run's time is compared with the baseline's and with
``1 - f`` (the ideal: nothing finished is recomputed). Before checkpoints, a re-run replayed the whole
filter and every sensor (ratio ~1.0). The outputs of every resumed run are checked identical to the
baseline's. Times are medians of ``--repeats`` runs (this machine's timings vary by 20 % from run to run).
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import numpy as np
import zarr

from planefuse.io import read_recording
from planefuse.outputs import OutputSettings, OutputWriter
from planefuse.pipeline import RunPlan, SystemParams, run_to_folder
from planefuse.sim import default_scene_config, simulate


def run(rec, out: Path, chunk_steps: int, stop_at: int | None = None) -> float:
    original = OutputWriter.write_occupancy

    def write(self, k, *a, **kw):
        if stop_at is not None and k == stop_at:
            raise KeyboardInterrupt
        return original(self, k, *a, **kw)

    OutputWriter.write_occupancy = write
    t0 = time.perf_counter()
    try:
        run_to_folder(rec, RunPlan(SystemParams(), out, OutputSettings(animation="none", figures=False, report=False,
                                                              chunk_steps=chunk_steps)), progress_mode="quiet")
    except KeyboardInterrupt:
        pass
    finally:
        OutputWriter.write_occupancy = original
    return time.perf_counter() - t0


def same(a: Path, b: Path) -> bool:
    occ = [zarr.open_group(d / "occupancy.zarr", mode="r")["occupancy"][:] for d in (a, b)]
    return bool(np.array_equal(*occ)) and all((a / n).read_bytes() == (b / n).read_bytes()
                                              for n in ("detections.csv", "tracks.csv"))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--duration-s", type=float, default=10.0)
    ap.add_argument("--chunk-steps", type=int, default=10)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--repeats", type=int, default=3)
    args = ap.parse_args()
    tmp = Path(tempfile.mkdtemp(prefix="bench-resume-"))
    simulate(default_scene_config(duration_s=args.duration_s, seed=args.seed)).write(tmp / "rec", image_format="jpg")
    rec = read_recording(tmp / "rec")
    run(rec, tmp / "warm", args.chunk_steps)  # numba compilation, file caches
    base = float(np.median([run(rec, tmp / f"base-{r}", args.chunk_steps) for r in range(args.repeats)]))
    n_steps = zarr.open_group(tmp / "base-0" / "occupancy.zarr", mode="r")["time_s"].shape[0]
    ck = tmp / "base-0" / "checkpoint.npz"
    print(f"{args.duration_s:g} s scene, {n_steps} output steps, chunks of {args.chunk_steps}; "
          f"checkpoint.npz {ck.stat().st_size / 1e6:.1f} MB")
    print(f"uninterrupted run: {base:.2f} s")
    print("| interrupted at | resumed at step | re-run time [s] | ratio to uninterrupted | ideal (1 - f) "
          "| identical outputs |")
    print("|---|---|---|---|---|---|")
    for f in (0.5, 0.8):
        stop = int(f * n_steps)
        times = []
        for r in range(args.repeats):
            out = tmp / f"resume-{f}-{r}"
            run(rec, out, args.chunk_steps, stop_at=stop)
            times.append(run(rec, out, args.chunk_steps))
        t = float(np.median(times))
        resumed = (stop // args.chunk_steps) * args.chunk_steps
        print(f"| step {stop} ({f:.0%}) | {resumed} | {t:.2f} | {t / base:.2f} | {1 - resumed / n_steps:.2f} "
              f"| {same(tmp / 'base-0', out)} |")


if __name__ == "__main__":
    main()
