"""Hostile inputs (issue 16): paths from data stay inside their folder, names that become file names are checked;
bad frames, geometry, grid sizes and output folders are clear errors; the run state is written last."""

import json
import re
import sys
import tracemalloc
import warnings
from pathlib import Path

import numpy as np
import pytest
import yaml
from hypothesis import given, settings
from hypothesis import strategies as st
from typer.testing import CliRunner
from conftest import edit_laser_npz

from planefuse.cli import app
from planefuse.config import example_yaml
from planefuse.geometry import apply_homography
from planefuse.io import image_file_problem, read_recording
from planefuse.io._paths import check_name, resolve_all_inside, resolve_inside
from planefuse.outputs import FIGURES_WRITTEN, OutputSettings, OutputWriter, out_dir_problem
from planefuse.pipeline import RunPlan, SystemParams, _system, filter_memory_bytes, run_to_folder, stack_for_recording


@pytest.mark.parametrize("rel", ["../../../../etc/passwd", "/etc/passwd", "a/../../x", "C:\\x", ""])
def test_resolve_inside_refuses_paths_outside_the_recording(tmp_path, rel):
    with pytest.raises(ValueError, match="times_file"):
        resolve_inside(tmp_path, rel, "times_file")


def test_resolve_inside_refuses_a_symlink_pointing_out(tmp_path):
    (tmp_path / "rec").mkdir()
    (tmp_path / "rec" / "link").symlink_to(tmp_path)
    with pytest.raises(ValueError, match="outside"):
        resolve_inside(tmp_path / "rec", "link/x.csv", "file")


def test_resolve_inside_accepts_a_nested_path(tmp_path):
    assert resolve_inside(tmp_path, "cameras/cam0/times.csv", "f") == (tmp_path / "cameras/cam0/times.csv").resolve()


@pytest.mark.parametrize("name", ["x/../../somewhere", "a/b", "..", "", ".hidden", "a" * 65])
def test_camera_name_that_would_escape_the_output_folder_is_refused(name):
    with pytest.raises(ValueError, match="sensor name"):
        check_name(name, "sensor name")


# -- recordings, configurations and output folders ---------------------------------------------------
def _config(tmp: Path, rec: Path, **planes) -> Path:
    cfg = yaml.safe_load(example_yaml(str(rec)))
    cfg["planes"].update(planes)
    cfg["outputs"].update(out_dir=str(tmp / "out"), figures=False, report=False, animation="none")
    p = tmp / "run.yaml"
    p.write_text(yaml.safe_dump(cfg))
    return p


def _check(cfg: Path):
    r = CliRunner().invoke(app, ["check", str(cfg), "--log-json"])
    assert r.exception is None or isinstance(r.exception, SystemExit), r.exception
    return r.exit_code, json.loads(r.output.strip().splitlines()[-1])


def _errors(report: dict) -> str:
    return "\n".join(f"{i['subject']}: {i['message']}" for i in report["issues"] if i["level"] == "error")


def _frame(rec: Path, i: int = 10) -> Path:
    return rec / "cameras" / "cam1" / "frames" / f"{i:06d}.jpg"


@pytest.mark.parametrize("damage, why", [
    (lambda p: p.unlink(), "not found"),
    (lambda p: p.write_bytes(b""), "empty"),
    (lambda p: p.write_bytes(b"\x00garbage" * 50), "not a JPEG"),
    (lambda p: p.write_bytes(p.read_bytes()[:500]), "truncated"),
])
def test_a_bad_frame_file_is_an_error_in_check_and_in_run(rec_copy, tmp_path, damage, why):
    assert image_file_problem(_frame(rec_copy)) is None
    damage(_frame(rec_copy))
    assert why in image_file_problem(_frame(rec_copy))
    code, report = _check(_config(tmp_path, rec_copy))
    assert code == 1 and "000010.jpg" in _errors(report) and why in _errors(report)
    with pytest.raises(ValueError, match="000010.jpg"):  # what run meets when it reads the frame
        read_recording(rec_copy).camera("cam1").frame(10)


def test_a_truncated_png_is_found_without_decoding(tmp_path):
    import cv2

    p = tmp_path / "a.png"
    cv2.imwrite(str(p), np.zeros((8, 8, 3), np.uint8))
    assert image_file_problem(p) is None
    p.write_bytes(p.read_bytes()[:-12])
    assert "truncated" in image_file_problem(p)


def _edit_cameras(rec: Path, edit) -> None:
    m = yaml.safe_load((rec / "scene.yaml").read_text())
    for s in m["sensors"]:
        if s["type"] == "camera":
            edit(s)
    (rec / "scene.yaml").write_text(yaml.safe_dump(m))


def test_camera_translations_in_millimetres_are_refused_naming_the_camera(rec_copy, tmp_path):
    def mm(s):
        for r in range(3):
            s["T_world_cam"][r][3] *= 1000.0

    _edit_cameras(rec_copy, mm)
    with pytest.raises(ValueError, match=r"'cam0'.*millimetres"):
        stack_for_recording(read_recording(rec_copy), SystemParams())
    code, report = _check(_config(tmp_path, rec_copy))
    assert code == 1 and "millimetres" in _errors(report) and "sees 100%" not in json.dumps(report)


@pytest.mark.parametrize("heights, match, check_match", [
    ([0.1, 1.0, 5.0], "above every camera", "at or above the camera centre"),  # check: per camera
    ([0.1, 1.0, 3.0], "at the height of camera 'cam0'", "at the height of camera 'cam0'")])
def test_planes_above_or_level_with_the_cameras_are_refused_without_warnings(recording_dir, tmp_path, heights,
                                                                              match, check_match):
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        with pytest.raises(ValueError, match=match):
            stack_for_recording(read_recording(recording_dir), SystemParams(heights_m=tuple(heights)))
        code, report = _check(_config(tmp_path, recording_dir, heights_m=heights))
    assert code == 1 and check_match in _errors(report)


def test_a_grid_too_large_for_memory_is_refused_before_allocating(recording_dir, tmp_path, monkeypatch):
    params = SystemParams(x_range_m=(0.0, 350.0), y_range_m=(0.0, 350.0))
    rec = read_recording(recording_dir)
    monkeypatch.setattr(_system, "available_memory_bytes", lambda: 4 * 2**30)
    tracemalloc.start()
    try:
        with pytest.raises(ValueError, match=r"4 planes x 3500 x 3500 cells x 49 velocities needs about .* GiB"):
            stack_for_recording(rec, params)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert peak < 50e6  # nothing of the size of the grid was allocated
    stack = _system.PlaneStack.from_extent((0.1, 0.5, 1.0, 1.5), (0.0, 350.0), (0.0, 350.0), 0.1)
    assert filter_memory_bytes(stack, params) >= 4 * 3500 * 3500 * 50 * 4  # the filter state alone
    code, report = _check(_config(tmp_path, recording_dir, x_range_m=[0.0, 350.0], y_range_m=[0.0, 350.0]))
    assert code == 1 and "GiB" in _errors(report)


def test_out_dir_in_the_recording_a_file_or_below_a_file_is_refused(recording_dir, tmp_path):
    (tmp_path / "f").write_text("x")
    for out, match in ((recording_dir, "is the recording folder"), (recording_dir / "out", "inside the recording"),
                       (tmp_path / "f", "is a file"), (tmp_path / "f" / "out", "is a file")):
        assert match in out_dir_problem(out, config_hash="k", protected=recording_dir)
    cfg = yaml.safe_load(_config(tmp_path, recording_dir).read_text())
    cfg["outputs"]["out_dir"] = str(tmp_path / "f" / "out")
    (tmp_path / "run.yaml").write_text(yaml.safe_dump(cfg))
    code, report = _check(tmp_path / "run.yaml")
    assert code == 1 and "is a file" in _errors(report)


def _stack():
    return _system.PlaneStack.from_extent((0.1, 1.0), (0.0, 1.0), (0.0, 1.0), 0.1)


def test_out_dir_of_another_run_or_with_foreign_files_is_refused_unless_fresh_or_force(tmp_path):
    out = tmp_path / "out"
    w = OutputWriter(out, _stack(), config_hash="a")
    w.finish()
    with pytest.raises(ValueError, match="results of another run"):
        OutputWriter(out, _stack(), config_hash="b")
    assert OutputWriter(out, _stack(), config_hash="b", resume=False).config_hash == "b"  # --fresh replaces them
    (out / "notes.txt").write_text("mine")
    with pytest.raises(ValueError, match="notes.txt"):
        OutputWriter(out, _stack(), config_hash="b")
    OutputWriter(out, _stack(), config_hash="c", force=True)
    assert (out / "notes.txt").read_text() == "mine"  # --force writes beside the user's files, keeps them


def test_the_users_own_figures_are_never_deleted(tmp_path):
    out = tmp_path / "out"
    OutputWriter(out, _stack(), config_hash="a").finish()
    (out / "figures").mkdir()
    (out / "figures" / "stack.png").write_bytes(b"ours")
    (out / "figures" / FIGURES_WRITTEN).write_text("stack.png\n")
    (out / "figures" / "mine.png").write_bytes(b"mine")
    with pytest.raises(ValueError, match="figures/mine.png"):
        OutputWriter(out, _stack(), config_hash="a", resume=False)
    OutputWriter(out, _stack(), config_hash="a", resume=False, force=True)
    assert not (out / "figures" / "stack.png").exists() and (out / "figures" / "mine.png").read_bytes() == b"mine"


def test_finished_is_written_last_and_a_failed_report_says_failed(recording_dir, tmp_path, monkeypatch):
    from planefuse.pipeline import _outputs

    settings = OutputSettings(animation="none", figures=False, report=True, chunk_steps=4)
    rec = read_recording(recording_dir)
    seen = {}
    original = OutputWriter.mark_finished

    def mark(self):
        seen["report"] = (self.out_dir / "report.html").exists()
        seen["status"] = json.loads((self.out_dir / "run_state.json").read_text())["status"]
        original(self)

    monkeypatch.setattr(OutputWriter, "mark_finished", mark)
    run_to_folder(rec, RunPlan(SystemParams(sound=False), tmp_path / "ok", settings), progress_mode="quiet")
    assert seen == {"report": True, "status": "presenting"}
    assert json.loads((tmp_path / "ok" / "run_state.json").read_text())["status"] == "finished"

    def broken(*a, **kw):
        raise RuntimeError("matplotlib fell over")

    monkeypatch.setattr(_outputs, "write_presentation", broken)
    with pytest.raises(ValueError, match="figures, animation or report failed .*matplotlib fell over"):
        run_to_folder(rec, RunPlan(SystemParams(sound=False), tmp_path / "bad", settings), progress_mode="quiet")
    assert json.loads((tmp_path / "bad" / "run_state.json").read_text())["status"] == "failed"


def test_rerun_without_rerun_sdk_is_a_one_line_error(recording_dir, tmp_path, monkeypatch):
    monkeypatch.setitem(sys.modules, "rerun", None)  # import rerun -> ImportError
    r = CliRunner().invoke(app, ["run", str(_config(tmp_path, recording_dir)), "--quiet", "--rerun"])
    assert r.exit_code == 2 and isinstance(r.exception, SystemExit)
    assert "rerun-sdk" in r.output and len(r.output.strip().splitlines()) == 1
    assert not (tmp_path / "out").exists()  # refused before anything was written


@pytest.mark.parametrize("edit, match", [
    (lambda a: a.update({k: v[:0] for k, v in a.items() if k != "angles_rad"}), "n_scans|no scans|empty"),
    (lambda a: a["time_s"].__setitem__(slice(3, 5), np.nan), "NaN|finite"),
])
def test_bad_laser_chunks_are_one_line_errors(rec_copy, edit, match):
    p = edit_laser_npz(rec_copy, edit)
    with pytest.raises(ValueError, match=match) as exc:
        rec = read_recording(rec_copy)
        for name in rec.lasers:
            list(rec.lasers[name].chunks())
    assert "\n" not in str(exc.value) and ("laser0" in str(exc.value) or p.name in str(exc.value))


def test_a_point_mapped_to_infinity_is_nan_not_inf():
    H = np.array([[0.0, 0, 1], [0, 1.0, 0], [1.0, 0, 0]])  # w = x: the line x = 0 goes to infinity
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        out = apply_homography(H, [[0.0, 2.0], [1.0, 2.0]])
    assert np.isnan(out[0]).all() and np.allclose(out[1], [1.0, 2.0])


def test_a_point_mapped_beyond_the_float_range_is_nan_not_inf():
    """Overflow is "mapped to infinity" too (issue 39): x = 1e10 * 1e300 is not a float64; the row is NaN, never
    inf, and without a NumPy warning; the rows that fit are exact."""
    H = np.diag([1e10, 1.0, 1.0])
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        out = apply_homography(H, [[1e300, 2.0], [3.0, 2.0], [-1e300, 1e300]])
    assert np.isnan(out[[0, 2]]).all() and np.array_equal(out[1], [3e10, 2.0])


@given(st.lists(st.floats(-1e300, 1e300), min_size=9, max_size=9), st.lists(st.floats(-1e300, 1e300), min_size=2,
                                                                          max_size=2))
@settings(max_examples=200, deadline=None, derandomize=True)
def test_apply_homography_never_returns_inf(h, p):
    H = np.array(h).reshape(3, 3)
    try:
        out = apply_homography(H, [p])
    except ValueError as err:  # a singular or non-finite H: refused by check_homography, named
        assert "H " in str(err) or "H has" in str(err)
        return
    assert not np.isinf(out).any()


def test_resolve_all_inside_is_resolve_inside(tmp_path):
    """The bulk resolution of frame files gives resolve_inside's paths and errors: plain names, links inside and
    out (folder and file), absent files and folders, '..' and absolute paths."""
    rec = tmp_path / "rec"
    (rec / "cam" / "frames").mkdir(parents=True)
    (rec / "cam" / "frames" / "0.png").write_bytes(b"x")
    (rec / "cam" / "frames" / "in.png").symlink_to(rec / "cam" / "frames" / "0.png")
    (rec / "cam" / "frames" / "out.png").symlink_to(tmp_path / "elsewhere.png")
    (rec / "cam" / "linked").symlink_to(rec / "cam" / "frames")
    (rec / "cam" / "away").symlink_to(tmp_path)
    rels = ["cam/frames/0.png", "cam/frames/in.png", "cam/frames/absent.png", "cam/linked/0.png", "cam/nowhere/0.png",
            "cam/frames/../frames/0.png", "cam/frames/out.png", "cam/away/x.png", "../x.png", "/etc/passwd", "C:\\x"]
    for rel in rels:
        try:
            expected = resolve_inside(rec, rel, f"file {rel}")
        except ValueError as exc:
            with pytest.raises(ValueError, match=re.escape(str(exc))):
                resolve_all_inside(rec, ["cam/frames/0.png", rel], lambda k: f"file {rel}")
        else:
            assert resolve_all_inside(rec, ["cam/frames/0.png", rel], lambda k: f"file {rel}")[1] == str(expected)


def test_scans_missing_from_a_laser_are_counted_per_laser_in_the_metrics(rec_copy):
    """A gap in a laser's time stamps (scans 10-14 dropped) is a repair, warned of and counted per laser in the
    run's metrics (here a 1 s recording: its counts, not scored)."""
    from planefuse.pipeline import RunPlan, SystemParams, run_plan

    def drop(a):
        keep = np.r_[0:10, 15:len(a["time_s"])]
        for k, v in a.items():
            if k != "angles_rad":
                a[k] = v[keep]

    edit_laser_npz(rec_copy, drop)
    m = yaml.safe_load((rec_copy / "scene.yaml").read_text())
    (laser,) = [s for s in m["sensors"] if s["type"] == "laser"]
    laser["n_scans"] -= 5
    (rec_copy / "scene.yaml").write_text(yaml.safe_dump(m, sort_keys=False))
    with pytest.warns(UserWarning, match="gap"):
        _, metrics = run_plan(read_recording(rec_copy), RunPlan(SystemParams()), progress_mode="quiet")
    assert metrics["missing_laser_scans"] == {laser["name"]: 5}
    assert metrics["n_laser_scans"] == laser["n_scans"]  # a 1 s recording: the counts, not scored
