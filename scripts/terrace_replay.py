"""Fast tuning on the EPFL terrace: run the camera front ends once, then replay what they gave through variants of
the generative sensor model, the filter, clustering and tracker.

The camera front ends (decoding, background subtraction) are most of a run's time, and no parameter of the
generative model, the filter, the clustering or the tracker changes them. This script runs ``scripts/terrace.yaml``
(with ``--set`` changes) once on frames ``--first``..``--last`` (``planefuse import`` + the run's own camera
source), keeps every instant's foreground images as the generative model receives them, and then, for each
``--try``, solves them again with that variant's generative sensor and runs the evidence through the tracker of
that variant's :class:`planefuse.pipeline.SystemRun`, as the run does (the tracked people as the model's prior at
each instant included, ``generative_track_prior_ratio``), scored by
``scripts/terrace.py``'s scorer. The first variant is the configuration itself; a variant that changes the front
end is refused (it needs a new capture). Tuning only: frames 0-1499. Example::

    PYTHONPATH=src python3 scripts/terrace_replay.py --first 1000 --last 1500 \\
        --try "sensors.cameras.generative_evidence_prior=0.5" --try "models.filter.enabled=false"
"""

from __future__ import annotations

import argparse
import pickle
import shutil
import sys
import tempfile
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import terrace as T  # noqa: E402

from planefuse.config import config_from_dict  # noqa: E402
from planefuse.grid import Evidence  # noqa: E402
from planefuse.io import read_recording  # noqa: E402
from planefuse.pipeline import SystemRun  # noqa: E402
from planefuse.vision import GenerativeCameraSensor, recording_frames  # noqa: E402


def replayable(field: str) -> bool:
    """Whether a replay may change the configuration field ``field`` (dotted): the generative sensor model's, the
    filter's, the clustering's and the tracker's; not the front end's (it made the kept foregrounds)."""
    if field.startswith("sensors.cameras."):
        return field.split(".")[-1].startswith("generative_")
    return field.startswith("models.")


def capture(rec, config: dict):
    """Run the cameras of ``config`` on ``rec``: (the instants' times [s], the foreground images the generative
    sensor received at each, that sensor, the system parameters, the stack, the colour frames of each instant (the
    tracks' appearance))."""
    params = config_from_dict(T.merged(config, {"recording": str(rec.root)})).system_params()
    if params.camera_params.sensor_model != "generative":
        raise ValueError("terrace_replay.py replays the generative sensor model only")
    kept: dict = {"fg": [], "sensor": None}
    solve = GenerativeCameraSensor.marginals

    def marginals(self, foregrounds, prior=None):
        kept["fg"].append([None if f is None else np.array(f) for f in foregrounds])
        kept["sensor"] = self
        return solve(self, foregrounds, prior)

    GenerativeCameraSensor.marginals = marginals
    try:
        run = SystemRun(rec, params)
        times = [m.time_s for m in run.evidence]
    finally:
        GenerativeCameraSensor.marginals = solve
    cp = params.camera_params
    from planefuse.pipeline._streams import _tapped

    frames = []  # as the run's camera source hands them to the tracks' appearance (a black or frozen frame: None)
    for _ in _tapped(recording_frames(rec, stride=cp.frame_stride, max_rate_hz=cp.max_rate_hz),
                     lambda t, imgs: frames.append(imgs)):
        pass
    return times, kept["fg"], kept["sensor"], params, run.stack, frames


def replay(rec, stack, times, foregrounds, sensor, params, frames=None) -> tuple[list, list]:
    """The outputs of ``params``' generative sensor, filter, clustering and tracker on the kept ``foregrounds``
    (the tracker of a :class:`SystemRun` of ``params`` on ``rec``, asked for the tracked people at each instant
    as that run asks it, and the colour ``frames`` of each instant where its tracker uses appearance), and the
    per-frame detections."""
    cp = params.camera_params
    if cp.generative != sensor.params:
        sensor = GenerativeCameraSensor(sensor.cameras, stack, cp.generative, names=sensor.names,
                                        ignore_masks=[~o for o in sensor._observed])
    run = SystemRun(rec, params, stack)  # its sources are never started: only its tracker is used
    tracker, track_prior = run.tracker, run._track_prior()
    outs, detections = [], []
    for k, (t, fgs) in enumerate(zip(times, foregrounds)):
        if run.appearance is not None:
            run.appearance.add_frames(t, frames[k])
        prior = sensor.location_prior(run._tracked_xy(t)) if track_prior else None
        q = sensor.marginals(fgs, prior)
        detections.append(sensor.detections(q, t, cp.person.nms_radius_m))
        outs.extend(tracker.push(Evidence(t, "cameras", sensor.log_odds_from_marginals(q, prior))))
    outs.extend(tracker.flush())
    if params.stitch.enabled:  # the offline pass over the run's tracks, as run_system does
        _, outs = run.stitch_outputs(outs)
    return outs, detections


def _load_capture(path: Path | None, key) -> tuple | None:
    """The capture kept in ``path`` if it was made with ``key`` (frames, configuration, background), else None."""
    if path is None or not path.is_file():
        return None
    with path.open("rb") as f:
        kept_key, kept = pickle.load(f)
    if kept_key != key:
        print(f"{path}: made with other frames or settings; capturing again", file=sys.stderr)
        return None
    return kept


def _save_capture(path: Path | None, key, kept: tuple) -> None:
    if path is not None:
        with path.open("wb") as f:
            pickle.dump((key, kept), f, protocol=pickle.HIGHEST_PROTOCOL)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--data", type=Path, default=T.REPO.parent / "shared" / "data")
    ap.add_argument("--first", type=int, default=0, help="first frame (0-based; tuning: 0-1499)")
    ap.add_argument("--last", type=int, default=1500, help="end frame (exclusive)")
    ap.add_argument("--step", type=int, default=5, help="use every step-th frame")
    ap.add_argument("--warmup-from", type=int, default=None, metavar="F",
                    help="a warm run, as scripts/terrace.py's: run from frame F, score only the frames from --first")
    ap.add_argument("--background-median-s", type=float, default=T.BACKGROUND_MEDIAN_S, metavar="S",
                    help="import with an empty-scene estimate: the median of each video's first S seconds [s]; 0 = "
                         f"none (default {T.BACKGROUND_MEDIAN_S:g}, as scripts/terrace.py)")
    ap.add_argument("--config", type=Path, default=T.CONFIG)
    ap.add_argument("--set", action="append", default=[], metavar="FIELD=YAML",
                    help="change of the captured configuration (repeatable)")
    ap.add_argument("--capture", type=Path, default=None, metavar="FILE",
                    help="keep the capture in FILE (pickle) and reuse it when FILE exists with the same frames, "
                         "configuration and --set changes")
    ap.add_argument("--try", dest="tries", action="append", default=[], metavar="FIELD=YAML[;FIELD=YAML]",
                    help="a variant replayed on the capture (filter, clustering, tracker, evidence mapping)")
    args = ap.parse_args(argv)
    pom_root = args.data / "epfl_pom" / "EPFL-Terrace"
    if not (args.data / "epfl_video" / "terrace1-c0.mp4").is_file() or not pom_root.is_dir():
        print(f"skipped: the terrace data is absent under {args.data}", file=sys.stderr)
        return 0
    scored = np.arange(args.first, args.last, args.step)
    frames = T.warm_frames(args.warmup_from, args.first, args.last, args.step)
    truth = T.terrace_truth(pom_root, scored)
    base = T.with_sets(T.load_base_config(args.config), args.set)
    tmp = Path(tempfile.mkdtemp(prefix="terrace-replay-"))
    try:
        rec = read_recording(T.import_terrace(tmp, args.data, frames, args.background_median_s or None))
        key = (list(map(int, frames)), base, args.background_median_s or None)
        kept = _load_capture(args.capture, key)
        if kept is None:
            kept = capture(rec, base)
            _save_capture(args.capture, key, kept)
        times, fgs, sensor, _, stack, frames = kept
        for spec in ["", *args.tries]:
            sets = [x for x in spec.split(";") if x]
            refused = [x.partition("=")[0] for x in sets if not replayable(x.partition("=")[0])]
            if refused:
                print(f"{spec}: refused, {refused} change the front end or what is not replayed (new capture)")
                continue
            cfg = T.with_sets(base, sets)
            params = config_from_dict(T.merged(cfg, {"recording": str(rec.root)})).system_params()
            outs, dets = replay(rec, stack, times, fgs, sensor, params, frames)
            by_cam = {T._frame_of(d.time_s): d.xy_m for d in dets}
            fr = [f for f in scored if f in by_cam]
            raw = T.score(truth, fr, [by_cam[f] for f in fr])
            by = {T._frame_of(o.time_s): o for o in outs}
            fr = [f for f in scored if f in by]
            s = T.score(truth, fr, [by[f].detections.xy_m for f in fr],
                        [(np.asarray(by[f].tracks.ids), by[f].tracks.xy_m) for f in fr])
            print(f"{spec or 'configuration'}: MODA {s['moda@0.5']:.3f} / {s['moda@1.0']:.3f}, precision "
                  f"{s['precision@0.5']:.2f}, recall {s['recall@0.5']:.2f}, MOTA {s['mota']:.3f}, IDF1 "
                  f"{s['idf1']:.3f}, ID switches {s['id_switches']}, track FP {s['track_false_positives']}, misses "
                  f"{s['track_misses']} (its per-frame detector: MODA {raw['moda@0.5']:.3f} / {raw['moda@1.0']:.3f})",
                  flush=True)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
