"""Real-time factor of ``planefuse run``: CPU seconds per second of recording, before and after, in one run.

The default scene (``planefuse demo``'s: 4 cameras at 25 Hz, nodding laser at 40 Hz, binaural head, 6 people) is
simulated and written to disk twice: frames as stored PNG (what ``planefuse simulate`` wrote before, ``--image-format
png``) and as uncompressed BMP (its default now; the same pixels); ``--image-format png`` writes PNG at zlib level 1
and stored instead, ``jpg`` JPEG. Then it is run
as ``planefuse run`` runs it (:func:`planefuse.pipeline.run_plan`: reading the recording, decoding every frame,
background subtraction, registration, filter, tracker, tables and metrics; figures, animation and report off), each
run in its own process pinned to one core with one thread per library (numba, OpenMP, BLAS, OpenCV):

* ``before``: the tree of ``--before`` (a commit, exported with ``git archive`` into a temporary folder), on the
  last recording (BMP: what ``planefuse simulate`` writes since the third pass);
* ``after``: this checkout's ``src`` on every recording (the first: code only), and on the last recording with the
  cameras' background subtraction at 1/``--downscale`` resolution (a different detector: its scores are printed
  beside it), and on the last recording with the subtractor ``--method`` (default ``mean``, the numba running
  average: a different detector, its scores beside it).

Each process first runs a 1.5 s simulated scene (numba compilation, caches), then times the run. CPU time is the
process's user + system time (``resource.getrusage``), the honest measure on a shared machine; repeats are
interleaved (every configuration once, then again...) and the minimum is reported. The runs' tables
(detections.csv, tracks.csv), occupancy and metrics (run time aside) are compared by a digest.

Usage: ``PYTHONPATH=src python benchmarks/bench_run.py [--duration-s 10] [--before d6630e0] [--repeats 2]
[--downscale 2] [--stride 2] [--image-format bmp|png|jpg] [--profile] [--stages] [--cli]``; ``--terrace`` times
the EPFL terrace video instead (cameras c0 and c1, 360x288 H.264 decoded by OpenCV, frames 1500-1999 at 25 Hz:
20 s of the held-out half, made a recording by ``planefuse import`` as ``scripts/terrace.py`` does, without its
ground truth; default configuration, cameras only; ``--terrace-step 5 --config scripts/terrace.yaml``: every 5th
frame with the terrace's own configuration, as ``scripts/terrace.py`` runs it); ``--config FILE`` runs a
configuration file's system (``--before-config FILE``: the before row's, the same system without the fields its
tree does not know); ``--recording DIR`` times any recording folder. ``--streams``
also times, in this process (all cores), the run in one process against the run with each camera's front end on a
LocalCluster of 2 workers (``planefuse run --workers 2``): wall-clock time (the cluster started beforehand), and the
two results compared. ``--stride N`` (default 2) adds the rows of the last recording with every N-th camera instant
only (``frame_stride``, the 5 Hz cap of the default lifted), alone, with the reduced resolution and with ``--method``
(other detectors: their scores beside them). ``--stages`` adds the CPU seconds of every stage of every row
(:data:`STAGES`: timers around the stages' functions, exclusive times).
``--cli`` also times the whole ``planefuse run`` process as a user starts it, start-up included (imports, numba's
cached kernels, the default binaural model), for every row (the options as configuration fields), interleaved:
``taskset`` to one core, ``--threads 1``, figures off, the process's CPU time from ``os.wait4``.
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

#: main before the tenth session's speed changes (plate frames, subtraction windows, clustering, BOF velocity noise;
#: 2026-12-04); the ninth session's before, every camera instant, was 898a3b1
BEFORE = "b754747"
ROOT = Path(__file__).resolve().parents[1]
SCORES = ("moda", "mota", "idf1", "camera_only_moda")
SINGLE = {n: "1" for n in ("NUMBA_NUM_THREADS", "OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS")}
#: ``--stages``: what each stage's timer wraps, ``(stage, module, attribute)``; ``Class.method`` for a method, else
#: the module's global that its callers look up (the name where it is used). Time is exclusive: a stage called
#: inside another (the KNN model inside the foreground) is not counted twice.
STAGES = (
    ("background model (priming included)", "planefuse.vision._foreground", "BackgroundSubtractor._learn"),
    ("foreground cleaning, likelihood", "planefuse.vision._foreground", "BackgroundSubtractor.apply"),
    ("frame read + decode", "planefuse.io._streams", "_read_png"),
    ("frame read + decode", "planefuse.io._video", "VideoFrames.__call__"),
    ("dead-frame check", "planefuse.vision._pipeline", "CameraFrontEnd.check"),
    ("camera fusion", "planefuse.vision._fusion", "CameraFusion.log_odds"),
    ("person extraction", "planefuse.vision._pipeline", "ground_detections_from_log_odds"),
    ("laser registration", "planefuse.laser._occupancy", "LaserRegistrar.register"),
    ("sound localisation + registration", "planefuse.audio", "localize"),
    ("sound localisation + registration", "planefuse.audio", "evidence_from_saliency"),
    ("generative model (mean field)", "planefuse.occupancy._meanfield", "MeanFieldSolver.solve"),
    ("gain compensation", "planefuse.vision._foreground", "GainCompensator.compensate"),
    ("BOF predict + update", "planefuse.tracking._bof", "bof_predict_update"),
    ("clustering", "planefuse.tracking._pipeline", "cluster_occupancy"),
    ("tracker", "planefuse.tracking._tracker", "MultiPersonTracker.step"),
    ("tables + occupancy writing", "planefuse.outputs._writer", "OutputWriter.write_occupancy"),
    ("tables + occupancy writing", "planefuse.outputs._writer", "OutputWriter.write_detections"),
    ("tables + occupancy writing", "planefuse.outputs._writer", "OutputWriter.write_tracks"),
    ("evaluation", "planefuse.pipeline._outputs", "system_metrics"),
    ("person detector (YOLOX)", "planefuse.vision._yolox", "YoloxDetector.detect"),
    ("person boxes on the planes", "planefuse.vision._pipeline", "box_evidence"),
)


def stage_timers() -> dict[str, float]:
    """Wrap :data:`STAGES` with CPU timers (exclusive time); returns the dict they fill [s]."""
    import functools
    import importlib
    import time

    spent: dict[str, float] = {}
    running: list[float] = []  # per open stage: CPU time of the stages called inside it

    def wrap(stage, fn):
        @functools.wraps(fn)
        def timed(*args, **kwargs):
            running.append(0.0)
            t0 = time.process_time()
            try:
                return fn(*args, **kwargs)
            finally:
                dt = time.process_time() - t0
                inner = running.pop()
                spent[stage] = spent.get(stage, 0.0) + dt - inner
                if running:
                    running[-1] += dt
        return timed

    for stage, module, attr in STAGES:
        try:
            owner = importlib.import_module(module)
        except ImportError:  # a stage the tree under test does not have (an older "before")
            continue
        *cls, name = attr.split(".")
        if cls:
            owner = getattr(owner, cls[0])
        if not hasattr(owner, name):
            continue
        setattr(owner, name, wrap(stage, getattr(owner, name)))
    return spent


def child(rec_dir: str, out_dir: str, profile: bool, downscale: int, stages: bool = False, stride: int = 1,
          method: str = "", config: str = "") -> None:
    """One timed run in this process (pinned to one core), background subtraction at 1/``downscale``
    resolution where above 1, by the subtractor ``method`` where given (``ForegroundParams.method``), every
    ``stride``-th camera instant (``CameraParams.frame_stride``), with per-stage
    CPU timers (:data:`STAGES`) where asked; prints a JSON line."""
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
    params = SystemParams()
    if config:  # a configuration file's system (its recording and outputs replaced by the benchmark's)
        import yaml

        from planefuse.config import config_from_dict

        cfg = yaml.safe_load(Path(config).read_text())
        cfg.pop("outputs", None)
        params = config_from_dict({**cfg, "recording": rec_dir}).system_params()
    from dataclasses import replace

    cam = params.camera_params
    if downscale > 1:
        cam = replace(cam, foreground=replace(cam.foreground, downscale=downscale))
    if method:
        cam = replace(cam, foreground=replace(cam.foreground, method=method))
    if stride > 1:  # every stride-th instant, uncapped (a tree before frame_stride has none)
        cam = replace(cam, frame_stride=stride, max_rate_hz=None)
    spent = stage_timers() if stages else {}
    c0 = cpu()
    rec = read_recording(rec_dir)
    # the modalities the recording has (the terrace video: cameras only)
    params = replace(params, camera_params=cam, laser=bool(rec.lasers), sound=bool(rec.audio))
    _, metrics = run_plan(rec, RunPlan(params, Path(out_dir), settings), progress_mode="quiet")
    used = cpu() - c0
    if prof is not None:
        import pstats

        prof.disable()
        pstats.Stats(prof, stream=sys.stderr).sort_stats("tottime").print_stats(25)
    # seconds recorded: from the first camera frame (an imported video clip starts at its first frame's time)
    print(json.dumps({"cpu_s": used, "duration_s": recorded_s(rec),
                      "peak_rss_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024,
                      "digest": digest(Path(out_dir)), "scores": {k: metrics.get(k) for k in SCORES},
                      "stages_s": spent}))


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


def terrace_recording(folder: Path, first: int = 1500, last: int = 2000, step: int = 1) -> Path:
    """The EPFL terrace's c0 and c1 over every ``step``-th frame of ``first..last-1`` as a recording folder
    (``planefuse import``, as ``scripts/terrace.py`` makes it), without its ground truth (timing only)."""
    import numpy as np
    import yaml

    sys.path.insert(0, str(ROOT / "scripts"))
    from terrace import import_terrace

    data = ROOT.parent / "shared" / "data"
    if not (data / "epfl_video" / "terrace1-c0.mp4").is_file():
        raise SystemExit(f"{data / 'epfl_video'}: the EPFL terrace videos are absent")
    rec = import_terrace(folder, data, np.arange(first, last, step))
    manifest = yaml.safe_load((rec / "scene.yaml").read_text())
    manifest.pop("groundtruth", None)
    (rec / "scene.yaml").write_text(yaml.safe_dump(manifest, sort_keys=False))
    return rec


def run_tree(src: Path, rec: Path, out: Path, profile: bool, downscale: int = 1, stages: bool = False,
             stride: int = 1, method: str = "", config: str = "") -> dict:
    env = {**os.environ, **SINGLE, "PYTHONPATH": str(src)}
    p = subprocess.run([sys.executable, __file__, "--child", str(rec), str(out), "--downscale", str(downscale)]
                       + ["--stride", str(stride), "--method", method, "--config", config]
                       + (["--profile"] if profile else []) + (["--stages"] if stages else []),
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
    ap.add_argument("--image-format", default="bmp", choices=("bmp", "png", "jpg"))
    ap.add_argument("--recording", type=Path, help="time this recording instead of a simulated one")
    ap.add_argument("--terrace", action="store_true", help="time the EPFL terrace video (frames 1500-1999)")
    ap.add_argument("--before", default=BEFORE, help="commit of the 'before' tree ('' to skip it)")
    ap.add_argument("--repeats", type=int, default=2)
    ap.add_argument("--downscale", type=int, default=2,
                    help="also time background subtraction at 1/N resolution (1: skip)")
    ap.add_argument("--stride", type=int, default=2,
                    help="also time every N-th camera instant only (frame_stride), alone and with --downscale "
                    "(1: skip)")
    ap.add_argument("--profile", action="store_true", help="print the last 'after' run's profile (slower)")
    ap.add_argument("--streams", action="store_true", help="also: serial vs per-camera streams on 2 workers")
    ap.add_argument("--stages", action="store_true", help="also: CPU seconds per stage of every run")
    ap.add_argument("--cli", action="store_true",
                    help="also: the whole `planefuse run` process (start-up included), before and after")
    ap.add_argument("--method", default="mean",
                    help="also time the last recording with this subtractor (ForegroundParams.method; '' to skip; "
                    "default: mean, the numba running average)")
    ap.add_argument("--config", default="", help="run this configuration file's system (e.g. scripts/terrace.yaml; "
                    "its recording and outputs replaced) instead of the default SystemParams")
    ap.add_argument("--person-model", default="", metavar="ONNX",
                    help="the after rows run --config's system with this YOLOX file as the cameras' person detector "
                         "(the library's settings for its boxes; the before row keeps --before-config's system)")
    ap.add_argument("--before-config", default="", metavar="FILE",
                    help="the before row's configuration file (default --config's): the same system written "
                         "without the fields the before tree does not know")
    ap.add_argument("--terrace-step", type=int, default=1,
                    help="--terrace: every N-th video frame (5: the 5 Hz of scripts/terrace.py and terrace.yaml)")
    ap.add_argument("--child", nargs=2, help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.child:
        child(*args.child, args.profile, args.downscale, args.stages, args.stride, args.method, args.config)
        return
    tmp = Path(tempfile.mkdtemp(prefix="bench-run-"))
    recs: dict[str, Path] = {}
    if args.terrace:
        recs["terrace"] = terrace_recording(tmp / "terrace", step=args.terrace_step)
    elif args.recording is not None:
        recs["recording"] = args.recording
    else:
        from planefuse.sim import default_scene_config, simulate

        rec = simulate(default_scene_config(duration_s=args.duration_s, seed=args.seed))
        if args.image_format == "bmp":  # main's default (stored PNG), then this checkout's (BMP)
            recs["PNG stored"] = tmp / "rec-png0"
            rec.write(recs["PNG stored"], image_format="png", png_compression=0)
            recs["BMP"] = tmp / "rec-bmp"
            rec.write(recs["BMP"], image_format="bmp")
        elif args.image_format == "png":
            for level, name in ((1, "PNG level 1"), (0, "PNG stored")):
                recs[name] = tmp / f"rec-png{level}"
                rec.write(recs[name], image_format="png", png_compression=level)
        else:
            recs["JPEG"] = tmp / "rec-jpg"
            rec.write(recs["JPEG"], image_format="jpg")
    last = list(recs)[-1]
    after = ROOT / "src"
    # label, source tree, recording, downscale, frame stride, subtractor ('' = the tree's default)
    runs: list[tuple[str, Path, Path, int, int, str]] = []
    if args.before:
        (tmp / "before").mkdir()
        archive = subprocess.run(["git", "-C", str(ROOT), "archive", args.before, "src"], check=True,
                                 capture_output=True).stdout
        subprocess.run(["tar", "-x", "-C", str(tmp / "before")], input=archive, check=True)
        runs.append((f"before ({args.before}), {last}", tmp / "before" / "src", recs[last], 1, 1, ""))
    runs += [(f"after (this checkout), {name}", after, path, 1, 1, "") for name, path in recs.items()]
    if args.method:
        runs.append((f"after, {last}, foreground_method {args.method}", after, recs[last], 1, 1, args.method))
    if args.downscale > 1:
        runs.append((f"after, {last}, subtraction at 1/{args.downscale} resolution", after, recs[last], args.downscale,
                     1, ""))
    if args.stride > 1:
        runs.append((f"after, {last}, frame_stride {args.stride}", after, recs[last], 1, args.stride, ""))
        if args.downscale > 1:
            runs.append((f"after, {last}, frame_stride {args.stride}, subtraction at 1/{args.downscale}", after,
                         recs[last], args.downscale, args.stride, ""))
        if args.method:
            runs.append((f"after, {last}, frame_stride {args.stride}, foreground_method {args.method}", after,
                         recs[last], 1, args.stride, args.method))
    results: dict[str, list[dict]] = {label: [] for label, *_ in runs}
    config = str(Path(args.config).resolve()) if args.config else ""
    before_config = str(Path(args.before_config).resolve()) if args.before_config else config
    if args.person_model:  # the after rows: the same system with the person detector
        import yaml

        cfg = yaml.safe_load(Path(config).read_text()) if config else {}
        cams = cfg.setdefault("sensors", {}).setdefault("cameras", {})
        cams.update(person_detector="yolox", person_model=str(Path(args.person_model).resolve()))
        config = str(tmp / "after_with_detector.yaml")
        Path(config).write_text(yaml.safe_dump(cfg, sort_keys=False))
    for r in range(args.repeats):
        for k, (label, src, rec_dir, downscale, stride, method) in enumerate(runs):
            profile = args.profile and r == args.repeats - 1 and k == len(runs) - 1
            results[label].append(run_tree(src, rec_dir, tmp / f"out-{k}-{r}", profile, downscale, args.stages,
                                           stride, method, before_config if label.startswith("before") else config))
    some = next(iter(results.values()))[0]
    print(f"recordings: {', '.join(f'{n} {p}' for n, p in recs.items())} ({some['duration_s']:g} s); one core, one "
          f"thread per library; min of {args.repeats} interleaved runs; load average {os.getloadavg()[0]:.1f}")
    print("| code, recording | CPU s | real-time factor (CPU s per s) | vs first row | peak RSS [MB] | results digest "
          "| MODA | MOTA | IDF1 | cameras-only MODA |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    base = None
    for label, rs in results.items():
        best = min(rs, key=lambda x: x["cpu_s"])
        base = base or best["cpu_s"]
        sc = best.get("scores") or {}
        cells = " | ".join("-" if sc.get(k) is None else f"{sc[k]:.3f}" for k in SCORES)
        print(f"| {label} | {best['cpu_s']:.2f} | {best['cpu_s'] / best['duration_s']:.3f} | "
              f"{base / best['cpu_s']:.2f}x | {best['peak_rss_mb']:.0f} | {best['digest']} | {cells} |")
    same = {r["digest"] for label in identical_groups(runs) for r in results[label]}
    print(f"identical results (before and after, default configuration, every recording): {len(same) == 1}")
    if args.stages:
        print_stages(results)
    if args.cli:
        cli_runs(runs, tmp, args.repeats)
    if args.streams:
        streams(recs[last], tmp)


def print_stages(results: dict[str, list[dict]]) -> None:
    """CPU seconds per stage (exclusive) of each row's fastest run; the rest is everything unwrapped."""
    best = {label: min(rs, key=lambda x: x["cpu_s"]) for label, rs in results.items()}
    names = list(dict.fromkeys(stage for stage, *_ in STAGES))
    labels = list(best)
    print("\nCPU seconds per stage (the fastest run of each row; exclusive times)")
    print("| stage | " + " | ".join(labels) + " |")
    print("|---|" + "---|" * len(labels))
    for name in names + ["rest (sources, buffers, Python glue)"]:
        cells = []
        for label in labels:
            b = best[label]
            v = b["stages_s"].get(name, 0.0) if name in names else b["cpu_s"] - sum(b["stages_s"].values())
            cells.append(f"{v:.2f} ({100 * v / b['cpu_s']:.0f} %)")
        print(f"| {name} | " + " | ".join(cells) + " |")


def cli_runs(runs: list, tmp: Path, repeats: int) -> None:
    """The whole ``planefuse run`` process on one core, start-up included (imports, numba's cached kernels, the
    default binaural model's calibration), figures off: CPU time of the process (``os.wait4``)."""
    import yaml

    rows: dict[str, list[tuple[float, str]]] = {label: [] for label, *_ in runs}
    for r in range(repeats):
        for k, (label, src, rec_dir, downscale, stride, method) in enumerate(runs):
            cfg = tmp / f"cli-{k}.yaml"
            out = tmp / f"cli-out-{k}-{r}"
            env = {**os.environ, **SINGLE, "PYTHONPATH": str(src)}
            subprocess.run([sys.executable, "-m", "planefuse", "config", "init", str(cfg), "--recording",
                            str(rec_dir), "--force"], env=env, check=True, capture_output=True)
            conf = yaml.safe_load(cfg.read_text())
            conf["outputs"].update(out_dir=str(out), figures=False, animation="none", report=False)
            if downscale > 1:
                conf["sensors"]["cameras"]["subtraction_downscale"] = downscale
            if stride > 1:
                conf["sensors"]["cameras"].update(frame_stride=stride, max_rate_hz=None)
            if method:
                conf["sensors"]["cameras"]["foreground_method"] = method
            cfg.write_text(yaml.safe_dump(conf, sort_keys=False))
            core = str(min(os.sched_getaffinity(0)))
            with open(tmp / f"cli-{k}-{r}.log", "w+") as log:
                p = subprocess.Popen(["taskset", "-c", core, sys.executable, "-m", "planefuse", "run", str(cfg),
                                      "--quiet", "--threads", "1", "--fresh"], env=env, stdout=log, stderr=log)
                _, status, usage = os.wait4(p.pid, 0)
                if os.waitstatus_to_exitcode(status):
                    log.seek(0)
                    raise RuntimeError(f"{label}: planefuse run failed\n{log.read()[-3000:]}")
            rows[label].append((usage.ru_utime + usage.ru_stime, digest(out)))
    print("\nwhole `planefuse run` process, one core (taskset), --threads 1, figures off; CPU s of the process, "
          f"min of {repeats} interleaved")
    print("| code, recording | CPU s | real-time factor | vs first row | results digest |")
    print("|---|---|---|---|---|")
    base = None
    for label, _, rec_dir, *_ in runs:
        cpu_s, dig = min(rows[label])
        base = base or cpu_s
        from planefuse.io import read_recording

        duration = recorded_s(read_recording(rec_dir))
        print(f"| {label} | {cpu_s:.2f} | {cpu_s / duration:.3f} | {base / cpu_s:.2f}x | {dig} |")
    same = {d for label in identical_groups(runs) for _, d in rows[label]}
    print(f"identical results (every process with the default configuration): {len(same) == 1}")


def identical_groups(runs: list) -> list[str]:
    """The rows that must give the same results: the 'before' tree and this checkout, both with their default
    configuration (full resolution, every frame, the default subtractor), on every recording."""
    return [r[0] for r in runs if r[0].startswith(("before", "after (this checkout)"))]


def recorded_s(rec) -> float:
    """Seconds recorded by the recording ``rec`` from its first camera frame (a clip of a video may start late)."""
    start_s = min((float(rec.camera(c.name).times_s[0]) for c in rec.cameras if len(rec.camera(c.name))), default=0.0)
    return rec.duration_s - start_s


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
