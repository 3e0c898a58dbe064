"""Property-based fuzzing of bad inputs (issue 16): one thing corrupted at a time, never a traceback.

Each example corrupts one thing of a short simulated recording (a frame file, a time stamp, a laser chunk, a
manifest entry) or of a configuration (one field set to a hostile value) and asserts that what a user runs
answers with a clear error (``ValueError``/``ConfigError`` in the library, exit code 1 or 2 on the command
line) or a repair that is counted and reported (a check finding or a warning) -- never another exception.
"""

from __future__ import annotations

import json
import shutil
import warnings
from pathlib import Path

import numpy as np
import pytest
import yaml
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from typer.testing import CliRunner
from conftest import edit_laser_npz

from planefuse.cli import app
from planefuse.config import ConfigError, example_yaml, load_config
from planefuse.io import read_recording
from planefuse.pipeline import stack_for_recording
from planefuse.sim import default_scene_config, simulate

FUZZ = settings(max_examples=10, deadline=None, derandomize=True,
                suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow])


@pytest.fixture(scope="module")
def recording_dir(tmp_path_factory):
    d = tmp_path_factory.mktemp("fuzzrec") / "scene"
    simulate(default_scene_config(duration_s=1.0, seed=3)).write(d, image_format="jpg")
    return d


def _frame_file(rec: Path, cam: int, i: int) -> Path:
    return rec / "cameras" / f"cam{cam}" / "frames" / f"{i:06d}.jpg"


def _times_rows(rec: Path, cam: int) -> tuple[Path, list[str]]:
    p = rec / "cameras" / f"cam{cam}" / "times.csv"
    return p, p.read_text().splitlines()


def _set_time(rec: Path, cam: int, row: int, value: str) -> None:
    p, lines = _times_rows(rec, cam)
    parts = lines[row + 1].split(",")
    parts[0] = value
    lines[row + 1] = ",".join(parts)
    p.write_text("\n".join(lines) + "\n")


def _drop_frames(rec: Path, cam: int, row: int, n: int) -> None:
    p, lines = _times_rows(rec, cam)
    kept = lines[: row + 1] + lines[row + 1 + n:]
    p.write_text("\n".join(kept) + "\n")
    m = yaml.safe_load((rec / "scene.yaml").read_text())
    entry = [s for s in m["sensors"] if s["type"] == "camera"][cam]
    entry["n_frames"] = len(kept) - 1
    (rec / "scene.yaml").write_text(yaml.safe_dump(m))


def _manifest_value(rec: Path, cam: int, key: str, value) -> None:
    m = yaml.safe_load((rec / "scene.yaml").read_text())
    [s for s in m["sensors"] if s["type"] == "camera"][cam][key] = value
    (rec / "scene.yaml").write_text(yaml.safe_dump(m))


HOSTILE = st.sampled_from([float("nan"), float("inf"), -1.0, 0.0, 1e12, "abc", [], None, {"a": 1}, True])

# corruption -> (what to do, whether a reported repair is acceptable instead of an error)
CORRUPTIONS = {
    "frame deleted": (lambda r, c, i, v: _frame_file(r, c, i).unlink(), False),
    "frame truncated": (lambda r, c, i, v: _frame_file(r, c, i).write_bytes(
        _frame_file(r, c, i).read_bytes()[: 1 + (i * 97) % 400]), False),
    "frame garbage": (lambda r, c, i, v: _frame_file(r, c, i).write_bytes(bytes(range(i, i + 64)) * 8), False),
    "time stamp hostile": (lambda r, c, i, v: _set_time(r, c, i, str(v)), False),
    "time stamp repeated": (lambda r, c, i, v: _set_time(r, c, i, _times_rows(r, c)[1][i].split(",")[0]), False),
    "frames dropped": (lambda r, c, i, v: _drop_frames(r, c, i, 5), True),
    "laser times hostile": (lambda r, c, i, v: edit_laser_npz(r, lambda a: a["time_s"].__setitem__(
        i % len(a["time_s"]), v if isinstance(v, float) else np.nan)), False),
    "laser chunk emptied": (lambda r, c, i, v: edit_laser_npz(
        r, lambda a: a.update({k: x[:0] for k, x in a.items() if k != "angles_rad"})), False),
    "laser ranges reshaped": (lambda r, c, i, v: edit_laser_npz(r, lambda a: a.update(ranges_m=a["ranges_m"][:, :-1])),
                              False),
    "camera field hostile": (lambda r, c, i, v: _manifest_value(
        r, c, ["K", "T_world_cam", "rate_hz", "width_px", "dist", "n_frames"][i % 6], v), False),
}


@FUZZ
@given(kind=st.sampled_from(sorted(CORRUPTIONS)), cam=st.integers(0, 3), frame=st.integers(1, 23), value=HOSTILE)
def test_check_answers_a_corrupted_recording_with_an_error_or_a_reported_repair(recording_dir, tmp_path_factory,
                                                                              kind, cam, frame, value):
    rec = tmp_path_factory.mktemp("case") / "rec"
    shutil.copytree(recording_dir, rec)
    corrupt, repair_ok = CORRUPTIONS[kind]
    corrupt(rec, cam, frame, value)
    cfg = yaml.safe_load(example_yaml(str(rec)))
    cfg["outputs"]["out_dir"] = str(rec.parent / "out")
    cfg["planes"]["cell_size_m"] = 0.4  # a coarse grid: the corruption is what is tested
    (rec.parent / "run.yaml").write_text(yaml.safe_dump(cfg))
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        result = CliRunner().invoke(app, ["check", str(rec.parent / "run.yaml"), "--log-json"])
    assert result.exception is None or isinstance(result.exception, SystemExit), \
        f"{kind}: {type(result.exception).__name__}: {result.exception}"
    report = json.loads(result.output.strip().splitlines()[-1])
    levels = {i["level"] for i in report["issues"]}
    if result.exit_code == 0:
        assert repair_ok, f"{kind} ({value!r}) accepted silently"
        assert "warning" in levels or caught, f"{kind}: repaired without a report"
    else:
        assert result.exit_code in (1, 2) and "error" in levels


CONFIG_FIELDS = ["planes.heights_m", "planes.cell_size_m", "planes.x_range_m", "planes.wall_margin_m",
                 "sensors.cameras.history_frames", "sensors.cameras.p_foreground_given_occupied",
                 "sensors.laser.p_occupied_hit", "sensors.sound.block_length_s",
                 "models.filter.n_velocities_per_axis", "models.filter.velocity_max_m_s",
                 "models.filter.output_period_s", "models.filter.prior_occupancy",
                 "models.detection.gate_m", "models.detection.confirm_hits", "outputs.chunk_steps",
                 "outputs.figure_dpi", "outputs.animation", "recording"]


@settings(max_examples=60, deadline=None, derandomize=True,
          suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(field=st.sampled_from(CONFIG_FIELDS), value=HOSTILE | st.floats(allow_nan=True) | st.integers(-10**9, 10**9))
def test_a_hostile_configuration_field_is_a_config_error_or_a_valid_plan(recording_dir, tmp_path, field, value):
    cfg = yaml.safe_load(example_yaml(str(recording_dir)))
    *path, last = field.split(".")
    d = cfg
    for k in path:
        d = d[k]
    d[last] = value
    p = tmp_path / "run.yaml"
    p.write_text(yaml.safe_dump(cfg))
    try:
        loaded = load_config(p)
    except ConfigError as err:
        assert field.split(".")[-1] in str(err)  # the error names the field
        return
    try:
        plan = loaded.plan()
        stack_for_recording(read_recording(loaded.recording), plan.params)
    except ValueError as err:  # a rule of the library, or the recording's geometry / memory
        assert "\n" not in str(err).strip()
