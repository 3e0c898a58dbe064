"""Fast tuning on the EPFL terrace: run the cameras once, then replay their evidence through variants of the
filter, clustering and tracker (and of the generative evidence mapping).

The camera front end and the mean-field solver are most of a run's time, and none of the filter's, the
clustering's or the tracker's parameters changes them. This script runs ``scripts/terrace.yaml`` (with
``--set`` changes) once on frames ``--first``..``--last`` (``planefuse import`` + the run's own camera source),
keeps every instant's generative marginals and the per-frame detections, and then, for each ``--try``, rebuilds
the camera evidence from the kept marginals with that variant's generative sensor (so
``sensors.cameras.generative_evidence_prior`` and ``generative_max_log_odds`` may change) and runs it through
:class:`planefuse.tracking.EvidenceTracker` exactly as :class:`planefuse.pipeline.SystemRun` does, scored by
``scripts/terrace.py``'s scorer. The first variant is the configuration itself; a variant that changes the front
end or the solver is refused (it needs a new capture). Tuning only: frames 0-1499. Example::

    PYTHONPATH=src python3 scripts/terrace_replay.py --first 1000 --last 1500 \\
        --try "sensors.cameras.generative_evidence_prior=0.5" --try "models.filter.enabled=false"
"""

from __future__ import annotations

import argparse
import pickle
import shutil
import sys
import tempfile
from dataclasses import replace
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import terrace as T  # noqa: E402

from planefuse.config import config_from_dict  # noqa: E402
from planefuse.grid import Evidence  # noqa: E402
from planefuse.io import read_recording  # noqa: E402
from planefuse.pipeline import SystemRun  # noqa: E402
from planefuse.tracking import EvidenceTracker  # noqa: E402
from planefuse.vision import GenerativeCameraSensor  # noqa: E402

#: Generative fields a replay may change (they map the kept marginals to evidence; the rest made the marginals).
REPLAYABLE = {"generative_evidence_prior", "generative_max_log_odds", "generative_detection_mass",
              "generative_hidden_unknown"}


def capture(rec, config: dict):
    """Run the cameras of ``config`` on ``rec``: (their evidence messages, the marginals of every instant, the
    generative sensor, the per-frame detections, the system parameters)."""
    params = config_from_dict(T.merged(config, {"recording": str(rec.root)})).system_params()
    if params.camera_params.sensor_model != "generative":
        raise ValueError("terrace_replay.py replays the generative sensor model only")
    kept: dict = {"q": [], "sensor": None}
    solve = GenerativeCameraSensor.marginals

    def marginals(self, foregrounds):
        q = solve(self, foregrounds)
        kept["q"].append(q.copy())
        kept["sensor"] = self
        return q

    GenerativeCameraSensor.marginals = marginals
    try:
        run = SystemRun(rec, params)
        messages = list(run.evidence)
    finally:
        GenerativeCameraSensor.marginals = solve
    return messages, kept["q"], kept["sensor"], run.report.camera_detections, params, run.stack


def replay(stack, messages, qs, sensor, params) -> list:
    """The outputs of the filter, clustering and tracker of ``params`` on the camera evidence rebuilt from the
    marginals ``qs`` with ``params``' generative sensor (as :class:`SystemRun` sets the tracker up)."""
    gen = params.camera_params.generative
    if gen != sensor.params:
        sensor = GenerativeCameraSensor(sensor.cameras, stack, gen, names=sensor.names,
                                        ignore_masks=[~o for o in sensor._observed])
    evidence = [Evidence(m.time_s, m.sensor, sensor.log_odds_from_marginals(q)) for m, q in zip(messages, qs)]
    tp = replace(params.tracking, output_period_s=params.output_period_s,
                 evidence_correlation_s={"cameras": params.camera_correlation_s, **params.tracking.evidence_correlation_s})
    if not params.use_filter:
        tp = replace(tp, bof=replace(tp.bof, decay_rate_hz=1e6), evidence_correlation_s={})
    tracker = EvidenceTracker(stack, tp)
    outs = []
    for ev in evidence:
        outs.extend(tracker.push(ev))
    outs.extend(tracker.flush())
    return outs


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
        messages, qs, sensor, cams, _, stack = kept
        by_cam = {T._frame_of(d.time_s): d.xy_m for d in cams}
        fr = [f for f in scored if f in by_cam]
        s = T.score(truth, fr, [by_cam[f] for f in fr])
        print(f"per frame: MODA {s['moda@0.5']:.3f} / {s['moda@1.0']:.3f}, recall {s['recall@0.5']:.2f}")
        for spec in ["", *args.tries]:
            sets = [x for x in spec.split(";") if x]
            cams_changed = {x.partition("=")[0].split(".")[-1] for x in sets if x.startswith("sensors.")}
            if cams_changed - REPLAYABLE:
                print(f"{spec}: refused, {sorted(cams_changed - REPLAYABLE)} change the marginals (new capture)")
                continue
            cfg = T.with_sets(base, sets)
            params = config_from_dict(T.merged(cfg, {"recording": str(rec.root)})).system_params()
            outs = replay(stack, messages, qs, sensor, params)
            by = {T._frame_of(o.time_s): o for o in outs}
            fr = [f for f in scored if f in by]
            s = T.score(truth, fr, [by[f].detections.xy_m for f in fr],
                        [(np.asarray(by[f].tracks.ids), by[f].tracks.xy_m) for f in fr])
            print(f"{spec or 'configuration'}: MODA {s['moda@0.5']:.3f} / {s['moda@1.0']:.3f}, precision "
                  f"{s['precision@0.5']:.2f}, recall {s['recall@0.5']:.2f}, MOTA {s['mota']:.3f}, IDF1 "
                  f"{s['idf1']:.3f}, ID switches {s['id_switches']}, track FP {s['track_false_positives']}, misses "
                  f"{s['track_misses']}", flush=True)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
