"""``planefuse simulate``: writes a readable recording; bad scene files exit with the file and field named."""

from __future__ import annotations

import json
import shutil

import numpy as np
import pytest
from typer.testing import CliRunner

from planefuse.cli._app import app
from planefuse.io import read_recording


def test_simulate_scene_file_to_recording(tmp_path):
    scene = tmp_path / "scene.yaml"
    scene.write_text(
        "duration_s: 0.4\nn_people: 2\nseed: 9\nhead: null\nlaser: {resolution_deg: 3.0}\n"
        "cameras:\n  - {name: top, position_m: [5, 5, 3.4], target_m: [5, 5.1, 0], width_px: 120, height_px: 96}\n"
    )
    out = tmp_path / "rec"
    res = CliRunner().invoke(app, ["simulate", str(scene), "--out", str(out), "--image-format", "jpg", "--no-masks"])
    assert res.exit_code == 0, res.output
    rec = read_recording(out)
    assert list(rec.camera_streams) == ["top"] and len(rec.camera("top")) == 10
    assert not rec.camera("top").has_masks
    assert rec.camera("top").frame(3).shape == (96, 120, 3)
    assert rec.laser().n_scans == 16 and rec.audio == {}
    assert rec.groundtruth.people.xy_m.shape == (10, 2, 2) and rec.groundtruth.sound is None
    assert rec.provenance["seed"] == 9
    # Writing into the same folder again is refused, with a clear message and exit code 2.
    res = CliRunner().invoke(app, ["simulate", str(scene), "--out", str(out)])
    assert res.exit_code == 2 and "not empty" in res.output


@pytest.fixture(scope="module")
def default_out(tmp_path_factory):
    out = tmp_path_factory.mktemp("cli") / "scene"
    res = CliRunner().invoke(app, ["simulate", "--out", str(out), "--duration-s", "0.4", "--seed", "3",
                                   "--image-format", "jpg"])
    assert res.exit_code == 0, res.output
    return out


def test_simulate_overrides_and_default_scene(default_out):
    rec = read_recording(default_out)
    assert len(rec.camera_streams) == 4 and rec.camera("cam0").has_masks and len(rec.camera("cam0")) == 10
    assert rec.provenance["duration_s"] == 0.4 and rec.provenance["seed"] == 3
    # Default speakers follow the overridden duration.
    assert np.allclose(rec.provenance["speakers"][0]["intervals_s"], [[0.02, 0.18]])


def test_simulate_bad_scene_names_file_and_field(tmp_path):
    scene = tmp_path / "bad.yaml"
    scene.write_text("duration_s: 1\nn_peeple: 3\n")
    res = CliRunner().invoke(app, ["simulate", str(scene), "--out", str(tmp_path / "x")])
    assert res.exit_code == 2
    flat = res.output.replace("\n", "")  # rich wraps long paths at the terminal width
    assert "bad.yaml:2" in flat and "n_peeple" in flat


def test_planefuse_check_reads_a_simulated_recording(default_out, tmp_path):
    from planefuse.config import example_yaml

    runner = CliRunner()
    shutil.copytree(default_out, tmp_path / "scene")
    cfg = tmp_path / "run.yaml"
    cfg.write_text(example_yaml("scene"))
    res = runner.invoke(app, ["check", str(cfg)], terminal_width=200)
    assert res.exit_code == 0, res.output
    assert "ready to run" in res.output
    # A stream the configuration needs disappears: check names it.
    (tmp_path / "scene/imu/cam2_imu.csv").unlink()
    res = runner.invoke(app, ["check", str(cfg)], terminal_width=200)
    assert res.exit_code == 1 and "1 error(s)" in res.output
    res = runner.invoke(app, ["check", str(cfg), "--log-json"])
    issues = json.loads(res.output)["issues"]
    assert res.exit_code == 1 and any("missing stream of imu 'cam2_imu'" in i["message"] for i in issues)
