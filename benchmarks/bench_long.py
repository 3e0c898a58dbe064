"""Memory and time per step over the length of a run: the default scene run for 10 s and for 300 s.

Each duration runs in its own process (one core, one thread per library): the default scene (4 cameras at 25 Hz,
nodding laser at 40 Hz, binaural head, 6 people; frames rendered when taken, so the recording itself holds no
frames in memory) run as ``planefuse run`` runs it (:func:`planefuse.pipeline.run_to_folder`: filter, tracker,
tables, occupancy, checkpoints; figures, animation and report off). At every output step the process's CPU time
and resident memory are sampled. Reported: CPU time per output step over the first and the last fifth of the
run (medians; simulation of the frames included), the resident memory after the first fifth and at the end, and
the peak.

Usage: ``PYTHONPATH=src python benchmarks/bench_long.py [--durations 10,300] [--seed 1]``
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

SINGLE = {n: "1" for n in ("NUMBA_NUM_THREADS", "OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS")}


def _rss_mb() -> float:
    return int(Path("/proc/self/statm").read_text().split()[1]) * os.sysconf("SC_PAGE_SIZE") / 2**20


def child(duration_s: float, seed: int, out: str) -> None:
    import resource
    import time

    import cv2
    import numpy as np

    os.sched_setaffinity(0, {min(os.sched_getaffinity(0))})
    cv2.setNumThreads(1)
    from planefuse.outputs import OutputSettings, OutputWriter
    from planefuse.pipeline import RunPlan, SystemParams, run_to_folder
    from planefuse.sim import default_scene_config, simulate

    cpu, rss = [], []
    original = OutputWriter.write_occupancy

    def sample(self, *a, **kw):
        r = original(self, *a, **kw)
        cpu.append(time.process_time())
        rss.append(_rss_mb())
        return r

    OutputWriter.write_occupancy = sample
    rec = simulate(default_scene_config(duration_s=duration_s, seed=seed))
    run_to_folder(rec, RunPlan(SystemParams(), Path(out), OutputSettings(figures=False, animation="none",
                                                                          report=False)), progress_mode="quiet")
    step = np.diff(cpu)
    fifth = max(len(step) // 5, 1)
    print(json.dumps({"steps": len(cpu), "first_ms": 1e3 * float(np.median(step[:fifth])),
                      "last_ms": 1e3 * float(np.median(step[-fifth:])), "rss_early_mb": rss[fifth],
                      "rss_end_mb": rss[-1],
                      "peak_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024}))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--durations", default="10,300")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--child", nargs=3, help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.child:
        child(float(args.child[0]), int(args.child[1]), args.child[2])
        return
    tmp = Path(tempfile.mkdtemp(prefix="bench-long-"))
    print("| duration [s] | output steps | CPU ms per step, first fifth | last fifth | RSS after first fifth [MB] "
          "| RSS at end [MB] | peak RSS [MB] |")
    print("|---|---|---|---|---|---|---|")
    for d in (float(x) for x in args.durations.split(",")):
        p = subprocess.run([sys.executable, __file__, "--child", str(d), str(args.seed), str(tmp / f"out-{d:g}")],
                           env={**os.environ, **SINGLE}, capture_output=True, text=True)
        if p.returncode:
            raise RuntimeError(p.stderr[-3000:])
        r = json.loads(p.stdout.strip().splitlines()[-1])
        print(f"| {d:g} | {r['steps']} | {r['first_ms']:.0f} | {r['last_ms']:.0f} | {r['rss_early_mb']:.0f} | "
              f"{r['rss_end_mb']:.0f} | {r['peak_mb']:.0f} |", flush=True)


if __name__ == "__main__":
    main()
