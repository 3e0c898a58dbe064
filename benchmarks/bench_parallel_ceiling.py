"""What this machine gives two processes at once: the same work in one process, then in two at the same time.

Two kinds of work, each timed (wall time, fastest of 3) alone and as two copies in parallel: a cache-resident
Python loop and a numpy loop streaming 200 MB arrays (memory-bound). The speed-up ``2 x alone / together`` is the
ceiling of any two-worker batch on the machine (docs/benchmarks.md, "Batch runs").

Run: ``python benchmarks/bench_parallel_ceiling.py``.
"""

from __future__ import annotations

import multiprocessing as mp
import time

import numpy as np


def python_loop(n: int = 12_000_000) -> int:
    """Integer arithmetic in the interpreter: no memory traffic to speak of."""
    s = 0
    for i in range(n):
        s += i * i
    return s


def numpy_streaming(n_passes: int = 10) -> float:
    """Two 200 MB float64 arrays read and written ``2 n_passes`` times: memory-bound."""
    a = np.ones(25_000_000)
    b = np.empty_like(a)
    for _ in range(n_passes):
        np.multiply(a, 1.0001, out=b)
        np.add(b, 1.0, out=a)
    return float(a[0])


def _timed(work) -> float:
    t0 = time.perf_counter()
    work()
    return time.perf_counter() - t0


def main() -> None:
    ctx = mp.get_context("spawn")
    print("| work | one process [s] | two at once [s] | speed-up |")
    print("|---|---|---|---|")
    for name, work in (("Python loop (cache-resident)", python_loop),
                       ("numpy streaming 200 MB arrays (memory-bound)", numpy_streaming)):
        with ctx.Pool(2) as pool:
            pool.map(_timed, [work, work])  # warm-up
            alone = min(pool.apply(_timed, (work,)) for _ in range(3))
            together = []
            for _ in range(3):
                t0 = time.perf_counter()
                pool.map(_timed, [work, work])
                together.append(time.perf_counter() - t0)
        print(f"| {name} | {alone:.2f} | {min(together):.2f} | {2 * alone / min(together):.2f}x |", flush=True)


if __name__ == "__main__":
    main()
