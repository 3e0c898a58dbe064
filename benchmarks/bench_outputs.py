"""Cost of writing a run's outputs, per time step, against the bare array write it wraps.

Run: python benchmarks/bench_outputs.py
"""

from __future__ import annotations

import tempfile
import time
from pathlib import Path

import numpy as np
import zarr

from planefuse.grid import GroundDetections, PlaneStack
from planefuse.outputs import OutputWriter
from planefuse.viz import stack_frames


def _bench(fn, repeat: int = 3) -> float:
    best = np.inf
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - t0)
    return best


def main() -> None:
    stack = PlaneStack.from_extent([0.0, 0.5, 1.0, 1.5], (0, 10), (0, 10), 0.05)  # 4 x 200 x 200
    n, chunk = 100, 25
    rng = np.random.default_rng(0)
    occ = rng.random((n,) + stack.shape).astype(np.float32)

    def baseline() -> None:  # the same chunked zarr array written directly, no CSVs, state or checkpoints
        with tempfile.TemporaryDirectory() as d:
            a = zarr.create_array(Path(d) / "o.zarr", shape=occ.shape, chunks=(chunk, 1) + stack.shape[1:],
                                  dtype="float32")
            for k in range(0, n, chunk):
                a[k:k + chunk] = occ[k:k + chunk]

    def writer() -> None:
        with tempfile.TemporaryDirectory() as d:
            w = OutputWriter(d, stack, config_hash="bench", chunk_steps=chunk, figures=False, report=False,
                             animation="none")
            for k in range(n):
                w.write_occupancy(k, 0.1 * k, occ[k])
                w.write_detections(k, GroundDetections(0.1 * k, rng.random((3, 2)) * 10, np.ones(3)))
                w.write_tracks(k, 0.1 * k, [1, 2, 3], rng.random((3, 2)) * 10)
            w.finish()

    t_base, t_writer = _bench(baseline), _bench(writer)
    t_frames = _bench(lambda: stack_frames(stack, occ, cell_px=1))
    print(f"{n} steps of (L, ny, nx) = {stack.shape}, chunks of {chunk} steps")
    print(f"{'what':<44}{'ms/step':>10}{'ratio':>8}")
    print(f"{'zarr array write (baseline)':<44}{1e3 * t_base / n:>10.2f}{1.0:>8.2f}")
    print(f"{'OutputWriter (zarr + CSV + MOT + state)':<44}{1e3 * t_writer / n:>10.2f}{t_writer / t_base:>8.2f}")
    print(f"{'animation frames (stack_frames)':<44}{1e3 * t_frames / n:>10.2f}{t_frames / t_base:>8.2f}")


if __name__ == "__main__":
    main()
