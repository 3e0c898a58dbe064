"""A person detector in a whole run: each camera's boxes written per output step (``camera_boxes.csv`` and one
MOTChallenge 2-D file per camera), identical after an interrupted run resumes, and its boxes registered on the
planes. The detector is a tiny ONNX model built here that finds one known box in every frame."""

from __future__ import annotations

import json
import math
from dataclasses import replace

import numpy as np
import pytest

from planefuse.io import read_recording
from planefuse.outputs import OutputSettings, OutputWriter, read_table
from planefuse.pipeline import RunPlan, SystemParams, run_to_folder
from planefuse.sim import default_scene_config, simulate
from planefuse.vision import resolve_engine

from test_vision_yolox import SIDE, constant_model, pooled_model, raw_rows, set_row

pytest.importorskip("onnx", reason="the onnx package (dev extra) builds the test model")


@pytest.fixture(scope="module")
def recording_dir(tmp_path_factory):
    d = tmp_path_factory.mktemp("rec") / "scene"
    simulate(default_scene_config(duration_s=2.0, seed=2)).write(d, image_format="jpg")
    return d


@pytest.fixture(scope="module")
def model(tmp_path_factory):
    rows = raw_rows()
    # one box: centre (28, 28), 16 x 32 px on the 64 x 64 canvas, score 0.9
    set_row(rows, 8, 3, 3, (0.5, 0.5, math.log(2.0), math.log(4.0)), 0.9, 1.0)
    return constant_model(tmp_path_factory.mktemp("model") / "one_box.onnx", rows)


def _params(model: str, box_log_odds: float = 2.0) -> SystemParams:
    base = SystemParams(laser=False, sound=False)
    cams = base.camera_params
    fg = replace(cams.foreground, person_detector="yolox", person_model=model, person_input_px=(SIDE, SIDE),
                 person_likelihood=None)
    boxes = replace(cams.boxes, log_odds=box_log_odds, free_log_odds=0.0)
    return replace(base, camera_params=replace(cams, foreground=fg, boxes=boxes))


def _run(rec, out, params, resume=True):
    settings = OutputSettings(animation="none", figures=False, report=False, chunk_steps=3)
    return run_to_folder(rec, RunPlan(params, out, settings, resume=resume), progress_mode="quiet")


def test_each_cameras_boxes_are_written_per_step_and_survive_a_resume(recording_dir, model, tmp_path, monkeypatch):
    rec = read_recording(recording_dir)
    params = _params(model)
    ref = tmp_path / "ref"
    _run(rec, ref, params)
    boxes = read_table(ref / "camera_boxes.csv")
    names = [c.name for c in rec.cameras]
    w, h = rec.cameras[0].intrinsics.width_px, rec.cameras[0].intrinsics.height_px
    r = min(SIDE / w, SIDE / h)
    n_steps = len(read_table(ref / "tracks.csv")["step"]) and int(read_table(ref / "detections.csv")["step"].max()) + 1
    # one box per camera and camera instant (5 Hz, the output rate): its canvas box (20, 12, 36, 44) / r
    assert sorted(set(boxes["camera"])) == sorted(names)
    for name in names:
        mine = boxes["camera"] == name
        np.testing.assert_allclose(np.c_[boxes["left_px"], boxes["top_px"], boxes["width_px"], boxes["height_px"]][mine],
                                   np.tile(np.array([20.0, 12.0, 16.0, 32.0]) / r, (mine.sum(), 1)), atol=0.01)
        np.testing.assert_allclose(boxes["score"][mine], 0.9, rtol=1e-5)
        assert np.array_equal(boxes["step"][mine], np.unique(boxes["step"][mine]))  # one instant per step
        mot = np.loadtxt(ref / f"boxes_{name}_mot.txt", delimiter=",", ndmin=2)
        assert mot.shape == (mine.sum(), 10)
        np.testing.assert_array_equal(mot[:, 0], boxes["step"][mine] + 1)  # MOTChallenge frames count from 1
        assert (mot[:, 1] == -1).all()
    assert boxes["step"].max() <= n_steps
    # interrupted at step 4 (in its second chunk) and resumed: the same files
    original = OutputWriter.write_occupancy

    def write(self, k, *a, **kw):
        if k == 4:
            raise KeyboardInterrupt
        return original(self, k, *a, **kw)

    out = tmp_path / "out"
    with monkeypatch.context() as m:
        m.setattr(OutputWriter, "write_occupancy", write)
        with pytest.raises(KeyboardInterrupt):
            _run(rec, out, params)
    _run(rec, out, params)
    for name in ["camera_boxes.csv", "tracks.csv", *(f"boxes_{n}_mot.txt" for n in names)]:
        assert (out / name).read_bytes() == (ref / name).read_bytes(), name
    # metrics.json says which engine ran the model ("auto" resolved)
    from planefuse.vision import resolve_engine
    assert json.loads((out / "metrics.json").read_text())["person_engine"] == resolve_engine("auto")


@pytest.mark.parametrize("engine", ["opencv", "onnxruntime"])
def test_the_run_records_the_engine_that_ran_the_model(recording_dir, model, tmp_path, engine):
    if engine == "onnxruntime":
        pytest.importorskip("onnxruntime", reason="onnxruntime (the dev extra) is not installed")
    rec = read_recording(recording_dir)
    params = _params(model)
    cams = params.camera_params
    params = replace(params, camera_params=replace(cams, foreground=replace(cams.foreground, person_engine=engine)))
    _run(rec, tmp_path / "out", params)
    assert json.loads((tmp_path / "out" / "metrics.json").read_text())["person_engine"] == engine


def test_registered_boxes_change_the_occupancy_only_through_their_bumps(recording_dir, model, tmp_path):
    rec = read_recording(recording_dir)
    with_boxes, _ = _run(rec, tmp_path / "on", _params(model, 3.0))
    without, _ = _run(rec, tmp_path / "off", _params(model, 0.0))
    a, b = (read_table(tmp_path / d / "camera_boxes.csv") for d in ("on", "off"))
    assert len(a["step"]) == len(b["step"]) > 0  # the detector runs either way
    import zarr
    za, zb = (zarr.open_group(tmp_path / d / "occupancy.zarr", mode="r")["occupancy"][:] for d in ("on", "off"))
    assert not np.array_equal(za, zb)
    assert (za >= zb - 1e-6).mean() > 0.99  # the bumps only add evidence for a person


@pytest.mark.parametrize("engine", ["opencv", "onnxruntime"])
def test_check_prints_the_models_checksum_engine_and_cost(recording_dir, model, tmp_path, engine):
    """`planefuse check` with a person model: its SHA-256 (hashlib's, of the file), the engine that runs it and its
    measured cost per frame, in the info lines."""
    import hashlib

    import yaml
    from typer.testing import CliRunner

    from planefuse.cli._app import app
    from planefuse.config import example_yaml

    if engine == "onnxruntime":
        pytest.importorskip("onnxruntime", reason="onnxruntime (the dev extra) is not installed")
    cfg = yaml.safe_load(example_yaml(str(recording_dir)))
    cfg.setdefault("sensors", {}).setdefault("cameras", {}).update(
        person_detector="yolox", person_model=model, person_engine=engine, person_input_px=[SIDE, SIDE])
    path = tmp_path / "run.yaml"
    path.write_text(yaml.safe_dump(cfg))
    res = CliRunner().invoke(app, ["check", str(path), "--log-json"])
    assert res.exit_code == 0, res.output
    found = [i["message"] for i in json.loads(res.output)["issues"] if i["subject"] == "sensors.cameras.person_model"]
    digest = hashlib.sha256(open(model, "rb").read()).hexdigest()
    assert len(found) == 1 and found[0].startswith(f"{model}: sha256 {digest}, 1 classes, run by {engine}, ")
    w, h = (read_recording(recording_dir).cameras[0].intrinsics.width_px,
            read_recording(recording_dir).cameras[0].intrinsics.height_px)
    assert found[0].endswith(f" ms per {w} x {h} frame at a {SIDE} x {SIDE} px canvas")
    # the table folds the long path and checksum over lines instead of cutting them
    res = CliRunner().invoke(app, ["check", str(path)])
    assert res.exit_code == 0 and "…" not in res.output
    assert digest in "".join(ch for ch in res.output if ch.isalnum())


def test_check_measures_the_cost_at_the_canvas_fitted_to_the_cameras(recording_dir, tmp_path):
    """person_input_px null: check times the model at the canvas the run will fit to the recording's frames."""
    import yaml
    from typer.testing import CliRunner

    from planefuse.cli._app import app
    from planefuse.config import example_yaml
    from planefuse.vision import fitted_input_size

    cfg = yaml.safe_load(example_yaml(str(recording_dir)))
    cfg.setdefault("sensors", {}).setdefault("cameras", {}).update(
        person_detector="yolox", person_model=pooled_model(tmp_path / "any_size.onnx"), person_engine="opencv")
    path = tmp_path / "run.yaml"
    path.write_text(yaml.safe_dump(cfg))
    res = CliRunner().invoke(app, ["check", str(path), "--log-json"])
    assert res.exit_code == 0, res.output
    found = [i["message"] for i in json.loads(res.output)["issues"] if i["subject"] == "sensors.cameras.person_model"]
    cam = read_recording(recording_dir).cameras[0].intrinsics
    cw, ch = fitted_input_size((cam.width_px, cam.height_px))
    assert found[0].endswith(f" ms per {cam.width_px} x {cam.height_px} frame at a {cw} x {ch} px canvas")


def test_a_replaced_model_or_another_engine_is_another_run_not_resumed(recording_dir, model, tmp_path):
    """The resume key holds the model file's checksum and the engine that runs it: a folder written with one model
    is refused (one line) for a run with a model replaced at the same path, or run by another engine."""
    import shutil

    rec = read_recording(recording_dir)
    path = tmp_path / "model.onnx"
    shutil.copy(model, path)
    params = _params(str(path))
    out = tmp_path / "out"
    _run(rec, out, params)
    _run(rec, out, params)  # the same run again: resumed from its finished state, not refused
    cams = params.camera_params
    other_engine = replace(params, camera_params=replace(cams, foreground=replace(
        cams.foreground, person_engine="opencv" if resolve_engine("auto") == "onnxruntime" else "auto")))
    if resolve_engine(other_engine.camera_params.foreground.person_engine) != resolve_engine("auto"):
        with pytest.raises(ValueError, match="holds the results of another run"):
            _run(rec, out, other_engine)
    rows = raw_rows()
    set_row(rows, 8, 3, 3, (0.5, 0.5, math.log(2.0), math.log(4.0)), 0.8, 1.0)  # another model, same path
    constant_model(path, rows)
    with pytest.raises(ValueError, match=r"^out_dir .* holds the results of another run \(a different configuration, "
                                         r"recording or person model"):
        _run(rec, out, params)
