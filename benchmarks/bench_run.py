"""Real-time factor of ``planefuse run``: CPU seconds per second of recording, before and after, in one run.

The default scene (``planefuse demo``'s: 4 cameras at 25 Hz, nodding laser at 40 Hz, binaural head, 6 people) is
simulated and written to disk as ``planefuse simulate`` writes it (PNG frames by default), then run as
``planefuse run`` runs it (:func:`planefuse.pipeline.run_plan`: reading the recording, decoding every frame,
background subtraction, registration, filter, tracker, tables and metrics; figures, animation and report off)
by two source trees in turn, each in its own process pinned to one core with one thread per library (numba,
OpenMP, BLAS, OpenCV):

* ``before``: the tree of ``--before`` (a commit, exported with ``git archive`` into a temporary folder);
* ``after``: this checkout's ``src``.

Each process first runs a 1 s simulated scene (numba compilation, caches), then times the run. CPU time is the
process's user + system time (``resource.getrusage``), the honest measure on a shared machine; repeats are
interleaved (before, after, before, after...) and the minimum is reported. The two trees' tables
(detections.csv, tracks.csv), occupancy and metrics (run time aside) are compared.

Usage: ``PYTHONPATH=src python benchmarks/bench_run.py [--duration-s 10] [--before 1dc1878] [--repeats 2]
[--image-format png] [--profile]``; ``--terrace`` times the EPFL terrace video instead (cameras c0 and c1,
360x288 H.264 decoded by OpenCV, frames 1500-1999 at 25 Hz: 20 s of the held-out half, written as a recording by
``scripts/terrace.py``'s ``write_recording``, without its ground truth; default configuration, cameras only);
``--recording DIR`` times
any recording folder. ``--streams`` also times, in this process (all cores), the run in one process against the
run with each camera's front end on a LocalCluster of 2 workers (``planefuse run --workers 2``): wall-clock time
(the cluster started beforehand), and the two results compared.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

#: main before issue 19's speed work (2026-12-02)
BEFORE = "1dc1878"
ROOT = Path(__file__).resolve().parents[1]
SINGLE = {n: "1" for n in ("NUMBA_NUM_THREADS", "OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS")}


def child(rec_dir: str, out_dir: str, profile: bool) -> None:
    """One timed run in this process (pinned to one core); prints a JSON line."""
    import resource

    os.sched_setaffinity(0, {min(os.sched_getaffinity(0))})
    import cv2

    cv2.setNumThreads(1)
    from planefuse.io import read_recording
    from planefuse.outputs import OutputSettings
    from planefuse.pipeline import RunPlan, SystemParams, run_plan
    from planefuse.sim import default_scene_config, simulate

    settings = OutputSettings(figures=False, animation="none", report=False)
    warm = simulate(default_scene_config(duration_s=1.5, seed=1))
    run_plan(warm, RunPlan(SystemParams()), progress_mode="quiet")

    def cpu() -> float:
        r = resource.getrusage(resource.RUSAGE_SELF)
        return r.ru_utime + r.ru_stime

    prof = None
    if profile:
        import cProfile

        prof = cProfile.Profile()
        prof.enable()
    c0 = cpu()
    rec = read_recording(rec_dir)
    _, metrics = run_plan(rec, RunPlan(SystemParams(), Path(out_dir), settings), progress_mode="quiet")
    used = cpu() - c0
    if prof is not None:
        import pstats

        prof.disable()
        pstats.Stats(prof, stream=sys.stderr).sort_stats("tottime").print_stats(25)
    print(json.dumps({"cpu_s": used, "duration_s": rec.duration_s,
                      "peak_rss_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024,
                      "digest": digest(Path(out_dir))}))


def digest(out: Path) -> str:
    """A hash of everything a run's results are: tables, occupancy and metrics (run time aside)."""
    import numpy as np
    import zarr

    h = hashlib.sha256()
    for name in ("detections.csv", "tracks.csv"):
        h.update((out / name).read_bytes())
    g = zarr.open_group(out / "occupancy.zarr", mode="r")
    for key in sorted(g.array_keys()):
        h.update(np.ascontiguousarray(g[key][:]).tobytes())
    metrics = json.loads((out / "metrics.json").read_text()) if (out / "metrics.json").exists() else {}
    h.update(json.dumps({k: v for k, v in metrics.items() if k != "elapsed_s"}, sort_keys=True).encode())
    return h.hexdigest()[:16]


def terrace_recording(folder: Path, first: int = 1500, last: int = 2000) -> Path:
    """The EPFL terrace's c0 and c1 over frames ``first..last-1`` as a recording folder (scripts/terrace.py)."""
    import numpy as np

    sys.path.insert(0, str(ROOT / "scripts"))
    from terrace import terrace_truth, write_recording

    data = ROOT.parent / "shared" / "data"
    if not (data / "epfl_video" / "terrace1-c0.mp4").is_file():
        raise SystemExit(f"{data / 'epfl_video'}: the EPFL terrace videos are absent")
    import yaml

    frames = np.arange(first, last)
    truth = terrace_truth(data / "epfl_pom" / "EPFL-Terrace", frames)
    write_recording(folder, data / "epfl_video", truth, frames, 1)
    # timing only: without its ground truth (some of its positions are NaN, which the evaluation refuses)
    manifest = yaml.safe_load((folder / "scene.yaml").read_text())
    manifest.pop("groundtruth")
    (folder / "scene.yaml").write_text(yaml.safe_dump(manifest, sort_keys=False))
    return folder


def run_tree(src: Path, rec: Path, out: Path, profile: bool) -> dict:
    env = {**os.environ, **SINGLE, "PYTHONPATH": str(src)}
    p = subprocess.run([sys.executable, __file__, "--child", str(rec), str(out)] + (["--profile"] if profile else []),
                       env=env, capture_output=True, text=True)
    if p.returncode:
        raise RuntimeError(f"{src}: run failed\n{p.stderr[-3000:]}")
    if profile:
        print(p.stderr, file=sys.stderr)
    return json.loads(p.stdout.strip().splitlines()[-1])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--duration-s", type=float, default=10.0)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--image-format", default="png", choices=("png", "jpg"))
    ap.add_argument("--recording", type=Path, help="time this recording instead of a simulated one")
    ap.add_argument("--terrace", action="store_true", help="time the EPFL terrace video (frames 1500-1999)")
    ap.add_argument("--before", default=BEFORE, help="commit of the 'before' tree ('' to skip it)")
    ap.add_argument("--repeats", type=int, default=2)
    ap.add_argument("--profile", action="store_true", help="print the 'after' run's profile (slower)")
    ap.add_argument("--streams", action="store_true", help="also: serial vs per-camera streams on 2 workers")
    ap.add_argument("--child", nargs=2, help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.child:
        child(*args.child, args.profile)
        return
    tmp = Path(tempfile.mkdtemp(prefix="bench-run-"))
    rec = args.recording
    if args.terrace:
        rec = terrace_recording(tmp / "terrace")
    elif rec is None:
        from planefuse.sim import default_scene_config, simulate

        rec = tmp / "rec"
        simulate(default_scene_config(duration_s=args.duration_s, seed=args.seed)).write(
            rec, image_format=args.image_format)
    trees = {"after": ROOT / "src"}
    if args.before:
        (tmp / "before").mkdir()
        archive = subprocess.run(["git", "-C", str(ROOT), "archive", args.before, "src"], check=True,
                                 capture_output=True).stdout
        subprocess.run(["tar", "-x", "-C", str(tmp / "before")], input=archive, check=True)
        trees = {"before": tmp / "before" / "src", **trees}
    runs: dict[str, list[dict]] = {k: [] for k in trees}
    for r in range(args.repeats):
        for name, src in trees.items():
            runs[name].append(run_tree(src, rec, tmp / f"out-{name}-{r}", args.profile and name == "after"
                                       and r == args.repeats - 1))
    print(f"recording: {rec} ({runs['after'][0]['duration_s']:g} s); one core, one thread per library; "
          f"min of {args.repeats} interleaved runs")
    print("| code | CPU s | real-time factor (CPU s per s) | peak RSS [MB] | results digest |")
    print("|---|---|---|---|---|")
    for name, rs in runs.items():
        best = min(rs, key=lambda x: x["cpu_s"])
        label = f"before ({args.before})" if name == "before" else "after (this checkout)"
        print(f"| {label} | {best['cpu_s']:.2f} | {best['cpu_s'] / best['duration_s']:.3f} | "
              f"{best['peak_rss_mb']:.0f} | {best['digest']} |")
    digests = {r["digest"] for rs in runs.values() for r in rs}
    if "before" in runs:
        b, a = (min(x["cpu_s"] for x in runs[k]) for k in ("before", "after"))
        print(f"speed-up {b / a:.2f}x; identical results: {len(digests) == 1}")
    if args.streams:
        streams(rec, tmp)


def streams(rec_dir: Path, tmp: Path) -> None:
    """Wall-clock time of the run in one process against the run with per-camera streams on 2 workers."""
    import time

    from planefuse.batch import batch_client
    from planefuse.io import read_recording
    from planefuse.outputs import OutputSettings
    from planefuse.pipeline import RunPlan, SystemParams, run_plan

    settings = OutputSettings(figures=False, animation="none", report=False)
    rec = read_recording(rec_dir)
    wall = {}
    with batch_client(n_workers=2) as client:
        client.run(lambda: __import__("planefuse.vision"))
        for name in ("one process", "streams on 2 workers", "one process ", "streams on 2 workers "):
            t0 = time.perf_counter()
            run_plan(rec, RunPlan(SystemParams(), tmp / f"streams-{name.strip()}-{len(wall)}", settings),
                     progress_mode="quiet", client=client if name.startswith("streams") else None)
            wall.setdefault(name.strip(), []).append(time.perf_counter() - t0)
    same = digest(tmp / "streams-one process-0") == digest(tmp / "streams-streams on 2 workers-1")
    a, b = min(wall["one process"]), min(wall["streams on 2 workers"])
    print(f"\nwall-clock, all cores (min of 2): one process {a:.1f} s, per-camera streams on 2 workers {b:.1f} s, "
          f"speed-up {a / b:.2f}x; identical results: {same}; load average {os.getloadavg()[0]:.1f}")


if __name__ == "__main__":
    main()
