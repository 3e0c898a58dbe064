"""Run configuration: example round trip, every error path names file, field and unit; pre-run checks."""

from __future__ import annotations

import json
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
import yaml
from typer.testing import CliRunner

from planefuse.cli import app
from planefuse.config import (
    ConfigError,
    RunConfig,
    check_recording,
    config_hash,
    example_yaml,
    load_config,
)
from planefuse.geometry import CameraIntrinsics, PinholeCamera, T_world_cam_look_at, default_camera_ring
from planefuse.grid import PlaneStack
from planefuse.outputs import OutputSettings
from planefuse.pipeline import SystemParams


def _write(tmp_path: Path, text: str, name: str = "run.yaml") -> Path:
    p = tmp_path / name
    p.write_text(text)
    return p


def _edited(tmp_path: Path, old: str, new: str) -> Path:
    text = example_yaml()
    assert old in text, f"example no longer contains {old!r}"
    return _write(tmp_path, text.replace(old, new))


def _error(path: Path) -> ConfigError:
    with pytest.raises(ConfigError) as info:
        load_config(path)
    return info.value


def test_example_loads_back_with_defaults_and_comments(tmp_path):
    text = example_yaml("rec/scene1")
    cfg = load_config(_write(tmp_path, text))
    assert cfg.recording == (tmp_path / "rec/scene1").resolve()
    assert cfg.outputs.out_dir == (tmp_path / "planefuse-out").resolve()
    # every field is present and equal to the model default
    ref = RunConfig(recording=Path("rec/scene1")).model_dump(mode="json")
    got = load_config(_write(tmp_path, text), resolve_paths=False).model_dump(mode="json")
    assert got == ref
    # each key line is preceded by a comment giving the unit where there is one
    lines = text.splitlines()
    i = next(k for k, l in enumerate(lines) if l.strip().startswith("cell_size_m:"))
    assert lines[i - 1].strip().startswith("#") and "[m]" in lines[i - 1] and "(0, 5]" in lines[i - 1]
    assert cfg.system_params() == SystemParams() and cfg.output_settings() == OutputSettings()


def test_height_out_of_range_names_field_unit_and_line(tmp_path):
    p = _edited(tmp_path, "heights_m: [0.1, 0.5, 1.0, 1.5]", "heights_m: [0.1, 0.5, -1.0, 1.5]")
    err = _error(p)
    (it,) = err.issues
    assert it.field_path == "planes.heights_m"
    assert "[m]" in it.expected and "[0, 10]" in it.expected
    assert it.line == next(k + 1 for k, l in enumerate(p.read_text().splitlines()) if "heights_m:" in l)
    msg = str(err)
    assert str(p) in msg and "planes.heights_m" in msg and "-1.0" in msg


def test_heights_out_of_order_are_refused(tmp_path):
    err = _error(_edited(tmp_path, "heights_m: [0.1, 0.5, 1.0, 1.5]", "heights_m: [0.1, 0.5, 0.4]"))
    (it,) = err.issues
    assert it.field_path == "planes.heights_m"
    assert "strictly increasing" in it.message and "0.4" in it.message


def test_even_velocity_count_is_rejected(tmp_path):
    err = _error(_edited(tmp_path, "n_velocities_per_axis: 7", "n_velocities_per_axis: 6"))
    (it,) = err.issues
    assert it.field_path == "models.filter.n_velocities_per_axis"
    assert "odd" in it.message


@pytest.mark.parametrize(
    "old, new, path, expected",
    [
        ("cell_size_m: 0.1", "cell_size_m: 0", "planes.cell_size_m", "(0, 5]"),
        ("cell_size_m: 0.1", "cell_size_m: fine", "planes.cell_size_m", "[m]"),
        ("velocity_max_m_s: 1.5", "velocity_max_m_s: 34.3", "models.filter.velocity_max_m_s", "[m/s]"),
        ("history_frames: 500", "history_frames: 0", "sensors.cameras.history_frames", "[frames]"),
        ("foreground_method: knn", "foreground_method: GMG", "sensors.cameras.foreground_method", "knn, mog2, cnt, mean or none"),
        ("prior_occupancy: 0.05", "prior_occupancy: 1.0", "models.filter.prior_occupancy", "(0, 1)"),
        ("animation: gif", "animation: avi", "outputs.animation", "gif"),
        ("chunk_steps: 50", "chunk_steps: 0", "outputs.chunk_steps", "[steps]"),
        ("x_range_m: null", "x_range_m: [10.0, 0.0]", "planes.x_range_m", "min < max"),
        ("x_range_m: null", "x_range_m: [0.0]", "planes.x_range_m[1]", "[m]"),
        ("zarr: true", "zarr: maybe", "outputs.zarr", "true or false"),
        ("frame_stride: 1", "frame_stride: 0", "sensors.cameras.frame_stride", "integer >= 1"),
    ],
)
def test_field_errors_name_path_and_expected_range(tmp_path, old, new, path, expected):
    p = _edited(tmp_path, old, new)
    err = _error(p)
    assert [it.field_path for it in err.issues] == [path]
    assert expected in err.issues[0].expected
    assert err.issues[0].line == next(k + 1 for k, l in enumerate(p.read_text().splitlines())
                                      if l.strip().startswith(new.split(":")[0] + ":"))
    assert str(p) in str(err) and path in str(err)


def test_unknown_field_is_reported_at_its_line(tmp_path):
    p = _edited(tmp_path, "  laser:", "  lasr:")
    err = _error(p)
    assert [it.field_path for it in err.issues] == ["sensors.lasr"]
    assert "unknown field" in err.issues[0].message
    assert err.issues[0].line == next(k + 1 for k, l in enumerate(p.read_text().splitlines()) if "lasr:" in l)


def test_section_of_wrong_type_lists_its_fields(tmp_path):
    err = _error(_write(tmp_path, "recording: r\nplanes: 5\n"))
    (it,) = err.issues
    assert it.field_path == "planes" and it.line == 2
    assert "heights_m" in it.expected and "cell_size_m" in it.expected


def test_several_errors_are_all_reported(tmp_path):
    text = example_yaml().replace("cell_size_m: 0.1", "cell_size_m: -1").replace("prior_occupancy: 0.05", "prior_occupancy: 2")
    err = _error(_write(tmp_path, text))
    assert {it.field_path for it in err.issues} == {"planes.cell_size_m", "models.filter.prior_occupancy"}


def test_model_level_rules(tmp_path):
    text = example_yaml().replace("enabled: true", "enabled: false")
    err = _error(_write(tmp_path, text))
    assert err.issues[0].field_path == "sensors.cameras.enabled" and "at least one" in err.issues[0].message
    text = example_yaml().replace("x_range_m: null", "x_range_m: [0.0, 10.0]").replace(
        "y_range_m: null", "y_range_m: [0.0, 10.0]").replace("cell_size_m: 0.1", "cell_size_m: 0.0001")
    err = _error(_write(tmp_path, text))
    assert err.issues[0].field_path == "planes.cell_size_m" and "cells" in err.issues[0].message


def test_missing_required_file_level_and_yaml_errors(tmp_path):
    err = _error(_write(tmp_path, "planes:\n  cell_size_m: 0.1\n"))
    assert err.issues[0].field_path == "recording" and "missing" in err.issues[0].message
    err = _error(_write(tmp_path, "recording: a\nplanes: [unclosed\n"))
    assert err.issues[0].field_path == "" and "invalid YAML" in err.issues[0].message and err.issues[0].line
    err = _error(_write(tmp_path, "- just\n- a list\n"))
    assert "mapping" in err.issues[0].message
    err = _error(tmp_path / "absent.yaml")
    assert "cannot read" in err.issues[0].message and "absent.yaml" in str(err)


def test_config_hash_ignores_presentation_only():
    base = RunConfig(recording=Path("r"))
    h = config_hash(base)
    pres = base.model_copy(update={"outputs": base.outputs.model_copy(update={"figures": False, "rerun": True,
                                                                              "out_dir": Path("elsewhere")})})
    assert config_hash(pres) == h
    changed = base.model_copy(update={"planes": base.planes.model_copy(update={"cell_size_m": 0.2})})
    assert config_hash(changed) != h


# -- CLI ---------------------------------------------------------------------------------------------------------------
runner = CliRunner()


def test_cli_config_init_writes_the_recording_relative_to_the_configuration(tmp_path, monkeypatch):
    """``--recording`` is relative to the working directory, the configuration's paths to its own folder."""
    monkeypatch.chdir(tmp_path)
    (tmp_path / "cfg").mkdir()
    assert runner.invoke(app, ["config", "init", "cfg/run.yaml", "--recording", "data/rec"]).exit_code == 0
    assert load_config(tmp_path / "cfg" / "run.yaml").recording == tmp_path / "data" / "rec"
    assert runner.invoke(app, ["config", "init", "run.yaml", "--recording", "data/rec"]).exit_code == 0
    assert load_config(tmp_path / "run.yaml").recording == tmp_path / "data" / "rec"


def test_cli_config_init_writes_valid_file_and_refuses_overwrite(tmp_path):
    p = tmp_path / "pf.yaml"
    r = runner.invoke(app, ["config", "init", str(p)])
    assert r.exit_code == 0, r.output
    load_config(p)
    assert runner.invoke(app, ["config", "init", str(p)]).exit_code == 1
    assert runner.invoke(app, ["config", "init", str(p), "--force"]).exit_code == 0
    r = runner.invoke(app, ["config", "show", str(p)])
    assert r.exit_code == 0 and yaml.safe_load(r.output)["planes"]["cell_size_m"] == 0.1


def test_cli_check_reports_config_errors_with_exit_2(tmp_path):
    p = _edited(tmp_path, "heights_m: [0.1, 0.5, 1.0, 1.5]", "heights_m: [0.1, 0.5, -1.0, 1.5]")
    r = runner.invoke(app, ["check", str(p)], terminal_width=200)
    assert r.exit_code == 2
    flat = r.output.replace("\n", "")  # rich may wrap long temporary paths
    assert "planes.heights_m" in flat and "[m]" in flat and p.name in flat


def test_cli_check_missing_recording_and_connected_reader(tmp_path, monkeypatch):
    # cameras and sound enabled, the laser not (its device entry is read from the recording)
    p = _write(tmp_path, example_yaml("scene").replace("laser:\n    # Use the laser range finders -- true or false\n"
                                                       "    enabled: true", "laser:\n    enabled: false"))
    r = runner.invoke(app, ["check", str(p), "--log-json"])
    assert r.exit_code == 1 and '"ok": false' in r.output and "does not exist" in r.output
    (tmp_path / "scene").mkdir()
    (tmp_path / "scene" / "scene.yaml").write_text("{}\n")
    cams = default_camera_ring()
    times = {c.name: np.arange(50) * 0.04 for c in cams} | {"laser": np.arange(20) * 0.1}
    from planefuse.config import _preflight

    # the configuration enables sound (the default); the recording has cameras and a laser only
    streams = {c.name: SimpleNamespace(frame_files=[], rate_hz=25.0) for c in cams}
    rec = SimpleNamespace(cameras=cams, lasers={}, audio={}, room_xy_m=(-0.2, 10.2, -0.2, 10.2),
                          planes_heights_m=(0.1, 1.0), camera_streams=streams, root=tmp_path / "scene", source="fake",
                          duration_s=2.0, provenance=None)
    monkeypatch.setattr(_preflight, "read_recording_for_check", lambda cfg: (rec, times))
    r = runner.invoke(app, ["check", str(p), "--log-json"])
    (err,) = [i for i in json.loads(r.output)["issues"] if i["level"] == "error"]
    # the words `planefuse run` refuses it with (planefuse.pipeline.check_modalities_present)
    assert r.exit_code == 1 and err["subject"] == "sensors", r.output
    assert err["message"].startswith("recording ") and "no stream for sensors.sound.enabled" in err["message"]
    rec.audio, times["binaural"] = {"binaural": None}, np.arange(100) * 0.02
    r = runner.invoke(app, ["check", str(p)], terminal_width=200)
    assert r.exit_code == 0, r.output
    assert "ready to run" in r.output


# -- check_recording ---------------------------------------------------------------------------------------------------
@pytest.fixture
def small_stack():
    return PlaneStack.from_extent([0.0, 1.0], (0, 10), (0, 10), 0.25)


def test_check_recording_stream_problems(small_stack):
    t = np.arange(100) * 0.1
    bad = t.copy()
    bad[10] = np.nan
    back = t.copy()
    back[[30, 60]] = back[[29, 59]]
    gappy = np.r_[t[:50], t[50:] + 30.0]
    rep = check_recording([], small_stack, {"a": bad, "b": back, "c": gappy, "e": np.zeros(0)}, ["a", "d"])
    errs = {(i.subject, i.message.split(" ")[0]) for i in rep.errors}
    assert ("d", "stream") in errs  # missing
    assert any(i.subject == "a" and "NaN" in i.message for i in rep.errors)
    assert any(i.subject == "b" and i.message.startswith("2 time stamps do not increase") for i in rep.errors)
    assert any(i.subject == "e" and "no samples" in i.message for i in rep.errors)
    assert any(i.subject == "c" and "1 gap" in i.message for i in rep.warnings)
    assert not rep.ok


def test_check_recording_streams_must_overlap(small_stack):
    rep = check_recording([], small_stack, {"a": np.arange(10.0), "b": 100 + np.arange(10.0)})
    assert any(i.subject == "streams" and "do not overlap" in i.message for i in rep.errors)
    rep = check_recording([], small_stack, {"a": np.arange(10.0), "b": 5 + np.arange(10.0)})
    assert rep.ok


def test_check_recording_cameras_must_see_the_grid(small_stack):
    ring = default_camera_ring()
    rep = check_recording(ring, small_stack, {})
    assert rep.ok
    assert rep.coverage_fraction[0] > 0.5
    for cam in ring:  # independent count: project the ground cell centres and keep those inside the image
        uv = cam.project(small_stack.cell_centers_world()[0].reshape(-1, 3))
        inside = cam.intrinsics.contains(uv)
        assert rep.camera_visible_fraction[cam.name][0] == pytest.approx(inside.mean(), abs=0.01)
    K = ring[0].intrinsics
    away = PinholeCamera(K, T_world_cam_look_at([5, 5, 3], [5, 5, 10], up_world=(0, 1, 0)), "sky")  # looks straight up
    rep = check_recording([away], small_stack, {})
    assert [i.subject for i in rep.errors] == ["sky"] and "sees no cell" in rep.errors[0].message
    corner = PinholeCamera(CameraIntrinsics(K.K, K.width_px, K.height_px),
                           T_world_cam_look_at([-20, -20, 2.5], [-30, -30, 0.0]), "corner")
    rep = check_recording([corner], small_stack, {})
    assert not rep.camera_visible_fraction["corner"].any()


def test_generative_evidence_prior_detection_is_derived_from_mass_and_threshold(tmp_path):
    """``generative_evidence_prior: detection`` sets the evidence prior from the detection mass and the column
    threshold (:func:`planefuse.vision.detection_evidence_prior`), following both; other words are refused."""
    from planefuse.vision import detection_evidence_prior

    for mass, thr in ((0.4, 1.5), (0.5, 2.0)):
        text = (example_yaml().replace("generative_evidence_prior: null", "generative_evidence_prior: detection")
                .replace("generative_detection_mass: 0.4", f"generative_detection_mass: {mass}")
                .replace("column_threshold: 1.5", f"column_threshold: {thr}"))
        cfg = load_config(_write(tmp_path, text))
        assert cfg.system_params().camera_params.generative.evidence_prior == pytest.approx(
            detection_evidence_prior(mass, thr))
    assert detection_evidence_prior(0.5, 2.0) == pytest.approx(0.0807, abs=1e-4)
    err = _error(_edited(tmp_path, "generative_evidence_prior: null", "generative_evidence_prior: detector"))
    assert err.issues and all(it.field_path.startswith("sensors.cameras.generative_evidence_prior")
                              for it in err.issues)
