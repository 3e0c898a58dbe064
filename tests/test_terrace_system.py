"""The EPFL terrace on real video through the same system as everything else: ``planefuse import`` of terrace1
c0 + c1 (Tsai cameras, watermark ignored, four cameras' box ground truth), then ``planefuse run`` of the shipped
configuration ``scripts/terrace.yaml`` (tuned on frames 0-1499), on a few held-out frames.

``scripts/terrace.py`` reproduces the full held-out range (frames 1500-2999 every 5th; docs/results.md).
"""

from __future__ import annotations

import json
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
import yaml
from conftest import shared_data
from typer.testing import CliRunner

from planefuse.cli._app import app
from planefuse.config import config_from_dict, load_config
from planefuse.io import read_recording
from planefuse.pipeline import run_plan
from planefuse.vision import detection_evidence_prior

SCRIPTS = Path(__file__).resolve().parents[1] / "scripts"
sys.path.insert(0, str(SCRIPTS))
import terrace  # noqa: E402

#: 2 s of held-out video at 5 Hz (the background model starts cold at frame 2000).
FRAMES = np.arange(2000, 2050, 5)


def _cli(*args) -> str:
    res = CliRunner().invoke(app, [str(a) for a in args], terminal_width=200)
    assert res.exit_code == 0, res.output
    return res.output


def test_shipped_configuration_is_honoured():
    """Every value of scripts/terrace.yaml reaches the library parameters the run uses."""
    data = terrace.load_base_config()
    params = config_from_dict(terrace.merged(data, {"recording": "."})).system_params()
    cams, fg, gen = data["sensors"]["cameras"], params.camera_params.foreground, params.camera_params.generative
    assert params.camera_params.sensor_model == cams["sensor_model"] == "generative"
    assert (fg.gain_compensation, fg.shadow_likelihood, fg.threshold, fg.close_px) == \
        (cams["gain_compensation"], cams["shadow_likelihood"], cams["var_threshold"], cams["close_px"])
    assert fg.gain_blocks == tuple(cams["gain_blocks"])
    assert (gen.sigma, gen.people_per_m2, gen.detection_mass) == \
        (cams["generative_sigma"], cams["generative_people_per_m2"], cams["generative_detection_mass"])
    assert params.tracking.cluster.threshold == data["models"]["detection"]["column_threshold"]
    # "detection": the evidence prior at which one frame of a just-detected person is a just-threshold cluster
    assert cams["generative_evidence_prior"] == "detection"
    assert gen.evidence_prior == pytest.approx(
        detection_evidence_prior(gen.detection_mass, params.tracking.cluster.threshold))
    assert gen.evidence_prior == pytest.approx(1 / (1 + np.exp(-(np.log(np.expm1(gen.detection_mass))
                                                                   - params.tracking.cluster.threshold))))
    assert params.heights_m == tuple(data["planes"]["heights_m"])
    assert params.tracking.tracker.support_threshold is None  # chosen on frames 0-1499
    assert not params.laser and not params.sound


@pytest.mark.realdata
def test_import_then_run_on_terrace_frames(tmp_path):
    """planefuse import + planefuse run of the shipped configuration on 10 held-out instants: the recording
    holds the Tsai cameras with the watermark ignored and every frame; the run decodes every frame, writes its
    metrics, equals the in-memory run of the same plan, and finds people where the ground truth has them."""
    data = shared_data("epfl_video").parent
    shared_data("epfl_pom")
    times = tmp_path / "times.csv"
    times.write_text("time_s,frame_index\n" + "".join(f"{f / 25.0!r},{f}\n" for f in FRAMES.tolist()))
    _cli("cameras", "epfl-tsai", tmp_path / "tsai")
    _cli(*terrace.import_command(tmp_path / "terrace", data, tmp_path / "tsai", times))
    rec = read_recording(tmp_path / "terrace")
    assert [c.name for c in rec.cameras] == ["c0", "c1"]
    assert tuple(rec.planes_heights_m) == terrace.PLANES_M
    for stream in rec.camera_streams.values():
        ignore = stream.ignore_mask
        u0, v0, u1, v1 = terrace.WATERMARK_PX
        assert ignore[v0:v1, u0:u1].all() and ignore.sum() == (u1 - u0) * (v1 - v0)
    cfg = terrace.merged(terrace.load_base_config(),
                         {"recording": str(tmp_path / "terrace"), "outputs": {"out_dir": str(tmp_path / "out"),
                                                                              "figures": False, "report": False}})
    (tmp_path / "terrace.yaml").write_text(yaml.safe_dump(cfg))
    _cli("run", tmp_path / "terrace.yaml", "--quiet")
    metrics = json.loads((tmp_path / "out" / "metrics.json").read_text())
    assert metrics["n_camera_frames"] == len(FRAMES) and metrics["n_missing_camera_frames"] == 0
    plan = replace(load_config(tmp_path / "terrace.yaml").plan(), out_dir=None)
    _, in_memory = run_plan(rec, plan, progress_mode="quiet")
    for k in ("moda", "precision", "recall", "mota", "idf1"):
        assert in_memory[k] == pytest.approx(metrics[k], nan_ok=True), k
    # per frame, the camera detector (cold background model) already finds people: measured 2026-12-02
    assert metrics["camera_only_moda"] > 0.0


def test_system_metrics_leave_out_absent_people():
    """Imported box ground truth marks a person absent (out of every view) with NaN: not a miss, not an error."""
    from types import SimpleNamespace

    from planefuse.eval import system_metrics
    from planefuse.io import GroundTruth, PeopleTruth
    from planefuse.pipeline import ModalityReport

    times = np.arange(0.0, 3.0, 0.2)
    xy = np.zeros((len(times), 2, 2))
    xy[:, 0] = [1.0, 2.0]
    xy[:, 1] = np.nan  # person 8 never in view
    nan = np.full((len(times), 2), np.nan)
    people = PeopleTruth(times, np.array([7, 8]), xy, nan, nan, np.full(2, np.nan))
    rec = SimpleNamespace(groundtruth=GroundTruth(people=people), cameras=[], lasers={})
    dets = [np.array([[1.1, 2.0]]) for _ in times]
    tracks = [(t, np.array([1]), d) for t, d in zip(times, dets)]
    m = system_metrics(rec, times, dets, tracks, ModalityReport(), 1.0)
    assert m["moda"] == pytest.approx(1.0) and m["recall"] == pytest.approx(1.0)
    assert m["mota"] == pytest.approx(1.0)


@pytest.mark.realdata
def test_replay_reproduces_the_run_and_refuses_front_end_changes(tmp_path):
    """scripts/terrace_replay.py: the kept foregrounds solved again and run through the filter, clustering and
    tracker give exactly the outputs of the run itself (the same configuration), also with another evidence prior
    and with the tracked people as the generative model's prior; a variant of the front end cannot be replayed."""
    import terrace_replay as R

    data = shared_data("epfl_video").parent
    shared_data("epfl_pom")
    frames = FRAMES[:6]
    rec = read_recording(terrace.import_terrace(tmp_path, data, frames))
    base = terrace.load_base_config()
    times, fgs, sensor, params, stack, images = R.capture(rec, base)
    assert len(times) == len(fgs) == len(images) == len(frames)
    occupancy = []
    for sets in ([], ["sensors.cameras.generative_evidence_prior=0.5"],
                 ["sensors.cameras.generative_track_prior_ratio=3", "sensors.cameras.generative_track_prior_radius_m=1"],
                 ["models.detection.appearance_weight=16", "models.detection.reid_max_s=5", "models.detection.stitch=true"]):
        cfg = terrace.with_sets(base, sets)
        plan = replace(config_from_dict(terrace.merged(cfg, {"recording": str(rec.root)})).plan(), out_dir=None)
        res, _ = run_plan(rec, plan, progress_mode="quiet")
        outs, dets = R.replay(rec, stack, times, fgs, sensor, plan.params, images)
        assert len(outs) == len(res.outputs)
        for a, b in zip(outs, res.outputs):
            np.testing.assert_array_equal(a.occupancy, b.occupancy)
            np.testing.assert_array_equal(a.detections.xy_m, b.detections.xy_m)
            np.testing.assert_array_equal(a.tracks.ids, b.tracks.ids)
        for a, b in zip(dets, res.report.camera_detections):
            np.testing.assert_array_equal(a.xy_m, b.xy_m)
        occupancy.append(np.stack([o.occupancy for o in outs]))
    assert not np.array_equal(occupancy[0], occupancy[2])  # people were tracked: the prior was used
    assert R.replayable("sensors.cameras.generative_sigma") and R.replayable("models.detection.column_threshold")
    assert not any(R.replayable(f"sensors.cameras.{f}") for f in ("close_px", "var_threshold", "sensor_model"))


def test_warm_runs_score_exactly_the_frames_asked_for():
    """--warmup-from F: the run starts at F, the scored frames --first..--last are its last ones, same step."""
    run = terrace.warm_frames(0, 1500, 3000, 5)
    np.testing.assert_array_equal(run[-300:], np.arange(1500, 3000, 5))
    assert run[0] == 0 and len(run) == 600 and np.all(np.diff(run) == 5)
    np.testing.assert_array_equal(terrace.warm_frames(None, 1500, 3000, 5), np.arange(1500, 3000, 5))
    for bad in (1501, 1600, -5):
        with pytest.raises(SystemExit, match="--warmup-from"):
            terrace.warm_frames(bad, 1500, 3000, 5)
