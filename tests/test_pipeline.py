"""The whole system end to end on a short simulated recording: check, run, outputs, metrics."""

from __future__ import annotations

import json

import numpy as np
import pytest
import yaml
from hypothesis import given, settings
from hypothesis import strategies as st
from typer.testing import CliRunner

from planefuse.cli import app
from planefuse.config import example_yaml, load_config
from planefuse.io import read_recording
from planefuse.pipeline import (
    SystemParams,
    evaluate_system,
    run_system,
)
from planefuse.sim import default_scene_config, simulate
from planefuse.vision import camera_instants


@pytest.fixture(scope="module")
def recording_dir(tmp_path_factory):
    d = tmp_path_factory.mktemp("rec") / "scene"
    simulate(default_scene_config(duration_s=2.5, seed=2)).write(d, image_format="jpg")
    return d


def test_config_maps_every_model_field():
    cfg = load_config_text("recording: r\nmodels:\n  filter:\n    n_velocities_per_axis: 5\n    decay_rate_hz: 0.3\n"
                           "  detection:\n    gate_m: 0.6\nsensors:\n  laser:\n    p_occupied_hit: 0.8\n")
    p = cfg.system_params()
    assert p.tracking.bof.n_velocities_per_axis == 5 and p.tracking.bof.decay_rate_hz == 0.3
    assert p.tracking.tracker.gate_m == 0.6 and p.laser_model.p_occupied_hit == 0.8
    assert p.heights_m == tuple(cfg.planes.heights_m) and p.cell_size_m == cfg.planes.cell_size_m


def load_config_text(text: str, tmp=None):
    import tempfile
    from pathlib import Path

    d = Path(tempfile.mkdtemp())
    (d / "run.yaml").write_text(text)
    return load_config(d / "run.yaml")


def test_run_system_fuses_every_modality(recording_dir):
    rec = read_recording(recording_dir)
    res = run_system(rec, SystemParams())
    # every camera instant at the default rate cap (5 Hz), none missing
    assert res.report.n_camera_frames == len(camera_instants(rec, max_rate_hz=5.0))
    assert len(camera_instants(rec, max_rate_hz=5.0)) == len(rec.camera(rec.cameras[0].name).times_s[::5]) > 5
    assert res.report.n_laser_scans > 0 and res.report.n_sound_blocks > 0
    fused = set().union(*(o.sensors for o in res.outputs))
    assert {"cameras", *rec.lasers, *rec.audio} <= fused
    for o in res.outputs:
        assert o.occupancy.shape == res.stack.shape
        assert np.all((o.occupancy >= 0) & (o.occupancy <= 1))
    m = evaluate_system(rec, res)
    for k in ("moda", "modp", "precision", "recall", "mota", "idf1", "azimuth_mae_deg"):
        assert k in m


def test_cli_check_and_run_on_a_recording(recording_dir, tmp_path):
    cfg_path = tmp_path / "run.yaml"
    text = example_yaml(str(recording_dir)).replace("animation: gif", "animation: none")
    cfg_path.write_text(text.replace("out_dir: planefuse-out", f"out_dir: {tmp_path / 'out'}"))
    runner = CliRunner()
    r = runner.invoke(app, ["check", str(cfg_path)])
    assert r.exit_code == 0, r.output
    r = runner.invoke(app, ["run", str(cfg_path), "--quiet"])
    assert r.exit_code == 0, r.output
    out = load_config(cfg_path).outputs.out_dir
    metrics = json.loads((out / "metrics.json").read_text())
    assert {"moda", "mota", "idf1", "azimuth_mae_deg"} <= set(metrics)
    assert (out / "report.html").exists() and (out / "tracks.csv").exists()
    assert yaml.safe_load((out / "config.yaml").read_text().split("\n#")[0])["recording"] == str(recording_dir)


def test_laser_alone_finds_people_the_cameras_do_not_see():
    """Cameras off (every person invisible to them): the nodding laser alone still finds most people,
    and it needs the system's laser model (the laser's own default frees the cells around thin legs)."""
    from planefuse.laser import LaserSensorModel
    from planefuse.pipeline import system_laser_model

    rec = simulate(default_scene_config(duration_s=4.0, seed=1))
    scores = {}
    for name, model in (("system", system_laser_model()), ("laser default", LaserSensorModel())):
        res = run_system(rec, SystemParams(cameras=False, sound=False, laser_model=model))
        assert not any("cameras" in o.sensors for o in res.outputs)
        scores[name] = evaluate_system(rec, res)
    m = scores["system"]
    assert m["recall"] >= 0.65 and m["precision"] >= 0.9, m  # 0.73 / 1.0 measured
    assert m["recall"] > scores["laser default"]["recall"] + 0.3, scores


def test_rerun_recording_holds_every_modality(recording_dir, tmp_path):
    pytest.importorskip("rerun")
    from planefuse.outputs import OutputSettings
    from planefuse.pipeline import RunPlan, run_to_folder
    from planefuse.viz import rrd_entity_paths

    rec = read_recording(recording_dir)
    settings = OutputSettings(animation="none", figures=False, report=False, rerun=True)
    run_to_folder(rec, RunPlan(SystemParams(), tmp_path / "out", settings), progress_mode="quiet")
    paths = rrd_entity_paths(tmp_path / "out" / "planefuse.rrd")
    for expected in ("/world/tracks", "/world/laser/laser", "/world/sound/front"):
        assert expected in paths, sorted(paths)
    assert any(p.startswith("/world/cameras/") and p.endswith("/image") for p in paths)
    assert any(p.startswith("/planes/") for p in paths)


def test_a_run_without_figures_does_not_import_matplotlib_or_rerun(recording_dir, tmp_path):
    """matplotlib and rerun (about a second of start-up) are imported by a run only where figures, the report,
    the animation or a rerun recording are asked for; the run's files are written all the same."""
    import os
    import subprocess
    import sys
    from pathlib import Path

    import planefuse

    code = (
        "import sys\n"
        "from pathlib import Path\n"
        "from planefuse.io import read_recording\n"
        "from planefuse.outputs import OutputSettings\n"
        "from planefuse.pipeline import RunPlan, SystemParams, run_plan\n"
        "settings = OutputSettings(figures=False, animation='none', report=False)\n"
        f"run_plan(read_recording({str(recording_dir)!r}), RunPlan(SystemParams(sound=False), "
        f"Path({str(tmp_path / 'out')!r}), settings), progress_mode='quiet')\n"
        "print(sorted(m for m in ('matplotlib', 'rerun', 'planefuse.viz') if m in sys.modules))\n"
    )
    src = str(Path(planefuse.__file__).resolve().parents[1])
    p = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                       env={**os.environ, "PYTHONPATH": src})
    assert p.returncode == 0, p.stderr[-2000:]
    assert p.stdout.strip().splitlines()[-1] == "[]"
    assert (tmp_path / "out" / "tracks.csv").is_file() and (tmp_path / "out" / "metrics.json").is_file()
    assert not (tmp_path / "out" / "figures").exists() and not (tmp_path / "out" / "report.html").exists()


def test_frame_stride_is_the_run_on_a_recording_of_every_other_frame(recording_dir, tmp_path):
    """``CameraParams.frame_stride`` 2 on a 25 Hz recording gives exactly the run (evidence, detections, tracks,
    camera report) of the default stride on a copy of it whose cameras kept every other frame (12.5 Hz)."""
    import shutil
    from dataclasses import replace

    half = tmp_path / "half"
    shutil.copytree(recording_dir, half)
    manifest = yaml.safe_load((half / "scene.yaml").read_text())
    for entry in (s for s in manifest["sensors"] if s["type"] == "camera"):
        times = half / entry["times_file"]
        header, *rows = times.read_text().splitlines()
        times.write_text("\n".join([header, *rows[::2]]) + "\n")
        entry.update(n_frames=len(rows[::2]), rate_hz=entry["rate_hz"] / 2)
    (half / "scene.yaml").write_text(yaml.safe_dump(manifest, sort_keys=False))
    full, kept = read_recording(recording_dir), read_recording(half)
    np.testing.assert_array_equal(camera_instants(full, 2), camera_instants(kept))
    base = SystemParams()
    base = replace(base, camera_params=replace(base.camera_params, max_rate_hz=None))  # every instant
    strided = replace(base, camera_params=replace(base.camera_params, frame_stride=2))
    a, b = run_system(full, strided), run_system(kept, base)
    assert a.report.n_camera_frames == b.report.n_camera_frames == len(camera_instants(full)[::2]) > 20
    assert len(a.outputs) == len(b.outputs) > 5
    for oa, ob in zip(a.outputs, b.outputs, strict=True):
        assert oa.time_s == ob.time_s
        np.testing.assert_array_equal(oa.detections.xy_m, ob.detections.xy_m)
        np.testing.assert_array_equal(oa.tracks.ids, ob.tracks.ids)
        np.testing.assert_array_equal(oa.tracks.xy_m, ob.tracks.xy_m)
    det_a, det_b = list(a.report.camera_detections), list(b.report.camera_detections)
    assert [d.time_s for d in det_a] == [d.time_s for d in det_b]
    for da, db in zip(det_a, det_b):
        np.testing.assert_array_equal(da.xy_m, db.xy_m)
    with pytest.raises(ValueError, match="frame_stride"):
        replace(base.camera_params, frame_stride=0)
    with pytest.raises(ValueError, match="stride must be an integer >= 1"):
        camera_instants(full, 0)
    # the same run asked for in time: at most 12.5 instants per second of the 25 Hz cameras
    capped = run_system(full, replace(base, camera_params=replace(base.camera_params, max_rate_hz=12.5)))
    for oa, oc in zip(a.outputs, capped.outputs, strict=True):
        np.testing.assert_array_equal(oa.tracks.xy_m, oc.tracks.xy_m)
        np.testing.assert_array_equal(oa.detections.xy_m, oc.detections.xy_m)


class _Cameras:
    """A recording's camera side only, as :func:`camera_instants` reads it: streams of given frame times."""

    def __init__(self, *times_s, rate_hz=25.0):
        from types import SimpleNamespace

        self._s = {f"c{i}": SimpleNamespace(times_s=np.asarray(t, float), rate_hz=rate_hz) for i, t in enumerate(times_s)}
        self.cameras = [SimpleNamespace(name=n) for n in self._s]

    def camera(self, name):
        return self._s[name]


@pytest.mark.parametrize("rate_hz, cap_hz, every", [(25.0, 5.0, 5), (25.0, 12.5, 2), (30.0, 10.0, 3), (5.0, 5.0, 1),
                                                    (5.0, 12.5, 1)])
def test_max_rate_keeps_every_kth_instant_where_the_rate_is_a_multiple(rate_hz, cap_hz, every):
    from planefuse.vision import camera_instants

    t = np.arange(300) / rate_hz
    got = camera_instants(_Cameras(t, t, rate_hz=rate_hz), max_rate_hz=cap_hz)
    np.testing.assert_array_equal(got, t[::every])


@settings(max_examples=40, deadline=None)
@given(rate_hz=st.sampled_from([15.0, 25.0, 30.0]), cap_hz=st.floats(0.5, 40.0), jitter=st.floats(0.0, 0.2),
       seed=st.integers(0, 1000))
def test_max_rate_is_never_exceeded_and_keeps_up_with_the_cap(rate_hz, cap_hz, jitter, seed):
    """With time stamps that jitter (up to a fifth of a frame) and a camera that drops frames, the kept instants are
    a subset of the instants, the first kept, at most one per period of the cap (its grid from the first instant),
    and, where the cameras are more than twice as fast as the cap, nearly one per period."""
    from planefuse.vision import camera_instants

    rng = np.random.default_rng(seed)
    t = np.arange(400) / rate_hz + rng.uniform(-jitter, jitter, 400) / rate_hz
    t = np.sort(t[rng.random(400) > 0.1])  # 10 % of the frames dropped
    all_inst = camera_instants(_Cameras(t, rate_hz=rate_hz))
    got = camera_instants(_Cameras(t, rate_hz=rate_hz), max_rate_hz=cap_hz)
    assert got[0] == all_inst[0] and np.isin(got, all_inst).all()
    span = all_inst[-1] - all_inst[0]
    assert len(got) <= np.floor((span + 0.25 / rate_hz) * cap_hz) + 1  # at most one per grid slot
    if cap_hz < 0.5 * rate_hz:
        assert len(got) >= 0.8 * span * cap_hz


def test_max_rate_is_checked():
    from dataclasses import replace

    from planefuse.vision import CameraParams, camera_instants

    with pytest.raises(ValueError, match="max_rate_hz"):
        replace(CameraParams(), max_rate_hz=0.0)
    with pytest.raises(ValueError, match="max_rate_hz must be finite and > 0"):
        camera_instants(_Cameras(np.arange(10) / 25.0), max_rate_hz=float("nan"))
