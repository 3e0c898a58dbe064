"""One system: ``demo`` is ``run`` on the simulated default recording, every configuration field reaches what
runs, the library's rules are the configuration's rules, and output options do not restart a run."""

from __future__ import annotations

import json
from dataclasses import asdict, fields, is_dataclass
from pathlib import Path

import numpy as np
import pytest
import yaml
from typer.testing import CliRunner

from planefuse.cli import app
from planefuse.config import RunConfig, config_from_dict, example_yaml, library_fields, load_config
from planefuse.outputs import OutputSettings, OutputWriter
from planefuse.pipeline import RunPlan, SystemParams, resume_key, run_plan, run_system, run_to_folder
from planefuse.sim import default_scene_config, simulate

runner = CliRunner()
TIMING = ("elapsed_s", "wall_time_s", "resumed_at_step")
TABLES = ("detections.csv", "tracks.csv", "detections_mot.txt", "tracks_mot.txt")


def _metrics(folder: Path) -> dict:
    m = json.loads((folder / "metrics.json").read_text())
    return {k: v for k, v in m.items() if k not in TIMING}


def test_demo_equals_simulate_config_init_and_run_byte_for_byte(tmp_path):
    """``planefuse demo`` = ``planefuse simulate`` + ``planefuse config init --recording`` + ``planefuse run``: the
    same tracks, detections and metrics (issue 38: config init wrote planes from 0.0 m and the whole room)."""
    demo, run = tmp_path / "demo", tmp_path / "run"
    r = runner.invoke(app, ["demo", "--out", str(demo), "--duration-s", "3", "--seed", "1", "--quiet"])
    assert r.exit_code == 0, r.output
    assert "planefuse demo: default simulated scene (seed 1, 3 s)" in " ".join(r.output.split())
    r = runner.invoke(app, ["simulate", "--out", str(tmp_path / "rec"), "--duration-s", "3", "--seed", "1",
                            "--no-masks"])
    assert r.exit_code == 0, r.output
    cfg = yaml.safe_load((demo / "config.yaml").read_text())
    assert cfg == yaml.safe_load(RunConfig(recording=Path(cfg["recording"]),
                                           outputs={"out_dir": Path(cfg["outputs"]["out_dir"])}
                                           ).plan().config_text)  # the default configuration
    # the user's way: `config init` on the simulated recording writes the simulated profile, the library's defaults
    r = runner.invoke(app, ["config", "init", str(tmp_path / "run.yaml"), "--recording", str(tmp_path / "rec")],
                      terminal_width=200)
    assert r.exit_code == 0 and "profile simulated" in r.output, r.output
    text = (tmp_path / "run.yaml").read_text()
    (tmp_path / "run.yaml").write_text(text.replace("out_dir: planefuse-out", f"out_dir: {run}"))
    r = runner.invoke(app, ["run", str(tmp_path / "run.yaml")], terminal_width=200)
    assert r.exit_code == 0, r.output
    flat = " ".join(r.output.split())
    assert "planefuse run" in flat and "planefuse demo" not in flat
    for name in TABLES:
        assert (demo / name).read_bytes() == (run / name).read_bytes(), name
    assert _metrics(demo) == _metrics(run)
    assert _metrics(demo)["n_camera_frames"] > 0


# -- every field reaches the library ---------------------------------------------------------------------------------
#: A valid value other than the default for every configuration field that sets a library value. A new field
#: must be added here (the test below fails until it is).
CHANGED = {
    "planes.heights_m": [0.2, 1.2],
    "planes.x_range_m": [1.0, 7.0],
    "planes.y_range_m": [0.5, 6.0],
    "planes.wall_margin_m": 0.4,
    "planes.cell_size_m": 0.2,
    "scene.occluder_boxes_m": [(4.0, 4.6, 4.0, 4.6, 0.0, 2.5)],
    "sensors.cameras.enabled": False,
    "sensors.cameras.foreground_method": "mog2",
    "sensors.cameras.history_frames": 20,
    "sensors.cameras.var_threshold": 30.0,
    "sensors.cameras.detect_shadows": False,
    "sensors.cameras.p_foreground_given_occupied": 0.8,
    "sensors.cameras.p_foreground_given_free": 0.3,
    "sensors.cameras.attitude_source": "imu",
    "sensors.cameras.attitude_tolerance_px": 2.0,
    "sensors.cameras.imu_filter": "mahony",
    "sensors.cameras.sensor_model": "generative",
    "sensors.cameras.ignore_rects_px": [("cam0", 0, 0, 360, 200)],
    "sensors.cameras.learning_rate": 0.01,
    "sensors.cameras.shadow_likelihood": 0.5,
    "sensors.cameras.gain_compensation": True,
    "sensors.cameras.gain_blocks": [2, 3],
    "sensors.cameras.gain_rate": 0.1,
    "sensors.cameras.relearn_fraction": 0.4,
    "sensors.cameras.relearn_frames": 3,
    "sensors.cameras.relearn_rate": 0.5,
    "sensors.cameras.selective_update": True,
    "sensors.cameras.selective_max_frames": 20,
    "sensors.cameras.open_px": 3,
    "sensors.cameras.close_px": 7,
    "sensors.cameras.blur_px": 5,
    "sensors.cameras.foreground_floor": 0.05,
    "sensors.cameras.foreground_ceiling": 0.9,
    "sensors.cameras.subtraction_downscale": 2,
    "sensors.cameras.frame_stride": 2,
    "sensors.cameras.max_rate_hz": 10.0,
    "sensors.cameras.knn_samples": 3,
    "sensors.cameras.primed_rate": "automatic",
    "sensors.cameras.plate_frames": 12,
    "sensors.cameras.cnt_min_stability": 10,
    "sensors.cameras.mean_foreground_rate": 0.5,
    "sensors.cameras.person_detector": "hog",
    "sensors.cameras.person_upscale": 1.5,
    "sensors.cameras.person_min_score": 1.0,
    "sensors.cameras.person_likelihood": 0.7,
    "sensors.cameras.person_model": "person.onnx",
    "sensors.cameras.person_engine": "opencv",
    "sensors.cameras.person_input_px": [384, 288],
    "sensors.cameras.person_nms_iou": 0.6,
    "sensors.cameras.person_outside_weight": 0.5,
    "sensors.cameras.box_log_odds": 2.0,
    "sensors.cameras.box_foot_std_frac": 0.1,
    "sensors.cameras.box_min_std_m": 0.2,
    "sensors.cameras.box_override": True,
    "sensors.cameras.box_free_log_odds": -1.0,
    "sensors.cameras.selective_source": "detector",
    "sensors.cameras.generative_people_per_m2": 0.1,
    "sensors.cameras.generative_sigma": 0.01,
    "sensors.cameras.generative_radius_m": 0.3,
    "sensors.cameras.generative_height_range_m": [0.0, 1.8],
    "sensors.cameras.generative_max_log_odds": 4.0,
    "sensors.cameras.generative_detection_mass": 0.5,
    "sensors.cameras.generative_foreground_threshold": None,
    "sensors.cameras.generative_evidence_prior": 0.5,
    "sensors.cameras.generative_hidden_unknown": True,
    "sensors.cameras.generative_max_iterations": 30,
    "sensors.cameras.generative_track_prior_ratio": 2.0,
    "sensors.cameras.generative_track_prior_radius_m": 0.5,
    "sensors.laser.enabled": False,
    "sensors.laser.p_occupied_hit": 0.7,
    "sensors.laser.p_occupied_free": 0.3,
    "sensors.laser.no_return_free_m": 4.0,
    "sensors.sound.enabled": False,
    "sensors.sound.block_length_s": 0.25,
    "sensors.sound.model_path": "model.npz",
    "models.filter.enabled": False,
    "models.filter.n_velocities_per_axis": 5,
    "models.filter.velocity_max_m_s": 2.0,
    "models.filter.prior_occupancy": 0.1,
    "models.filter.decay_rate_hz": 2.0,
    "models.filter.velocity_noise_rate_hz": 0.5,
    "models.filter.merge_tolerance_s": 0.01,
    "models.filter.window_s": 0.5,
    "models.filter.output_period_s": 0.1,
    "models.filter.camera_correlation_s": 0.0,
    "models.filter.laser_correlation_s": 0.2,
    "models.filter.sound_correlation_s": 1.0,
    "models.detection.column_threshold": 3.0,
    "models.detection.person_radius_m": 0.4,
    "models.detection.min_separation_m": 0.6,
    "models.detection.gate_m": 0.5,
    "models.detection.gate_chi2": 6.0,
    "models.detection.max_coast_report": 3,
    "models.detection.birth_exclusion_m": 0.6,
    "models.detection.position_std_m": 0.2,
    "models.detection.velocity_std_m_s": 0.5,
    "models.detection.acceleration_std_m_s2": 3.0,
    "models.detection.confirm_hits": 2,
    "models.detection.max_misses": 4,
    "models.detection.clutter_density_per_m2": 0.5,
    "models.detection.support_threshold": None,
    "models.detection.reacquire_speed_m_s": 0.5,
    "models.detection.velocity_decorrelation": False,
    "models.detection.position_from_step_evidence": False,
    "models.detection.appearance_weight": 4.0,
    "models.detection.appearance_reference_distance": 0.4,
    "models.detection.appearance_update_rate": 0.2,
    "models.detection.reid_max_s": 5.0,
    "models.detection.reid_max_distance_m": 3.0,
    "models.detection.reid_max_appearance_distance": 0.2,
    "models.detection.stitch": True,
    "models.detection.stitch_max_gap_s": 3.0,
    "models.detection.stitch_fill_gap_s": 2.0,
    "models.detection.stitch_smooth_s": 0.5,
    "models.detection.stitch_split_s": 3.0,
    "models.detection.match_distance_m": 1.0,
    "outputs.zarr": False,
    "outputs.chunk_steps": 7,
    "outputs.figures": False,
    "outputs.animation": "mp4",
    "outputs.report": False,
    "outputs.rerun": True,
    "outputs.figure_dpi": 60,
    "outputs.animation_max_frames": 40,
    "outputs.camera_videos": True,
    "outputs.mcap": True,
    "outputs.ros2_bag": True,
}


def _nested(path: str, value) -> dict:
    out: dict = {"recording": "r"}
    node = out
    *heads, last = path.split(".")
    for h in heads:
        node = node.setdefault(h, {})
    node[last] = value
    return out


def _flat(obj, prefix: str = "") -> dict:
    if is_dataclass(obj):
        return {k: v for f in fields(obj) for k, v in _flat(getattr(obj, f.name), f"{prefix}{f.name}.").items()}
    return {prefix.rstrip("."): obj}


def test_every_library_field_has_a_changed_value():
    assert set(CHANGED) == {f for f, _ in library_fields()}


@pytest.mark.parametrize("field, lib", list(library_fields()))
def test_each_field_sets_its_library_value_and_nothing_else(field, lib):
    cfg = config_from_dict(_nested(field, CHANGED[field]))
    root, _, attr = lib.partition(".")
    base = _flat(SystemParams() if root == "system" else OutputSettings())
    got = _flat(cfg.system_params() if root == "system" else cfg.output_settings())
    changed = {k for k in base if base[k] != got[k]}
    assert changed == {attr}, (field, changed)
    want = CHANGED[field]
    want = tuple(want) if isinstance(want, list) else Path(want) if field.endswith("model_path") else want
    assert got[attr] == want


@pytest.fixture(scope="module")
def short_recording():
    return simulate(default_scene_config(duration_s=1.6, seed=2))


@pytest.fixture(scope="module")
def default_outputs(short_recording):
    return _outputs(short_recording, RunConfig(recording=Path("r")))


def _outputs(rec, cfg: RunConfig):
    res = run_system(rec, cfg.system_params())
    return (np.stack([o.occupancy for o in res.outputs]), [o.detections.xy_m for o in res.outputs],
            [o.tracks.xy_m for o in res.outputs])


#: Fields whose change must change the occupancy, detections or tracks of a short run of the default scene.
#: The others are observed elsewhere: the output options below; attitude_tolerance_px and imu_filter only with
#: attitude_source imu on moving cameras (tests/test_registration*.py); x/y ranges, wall margin and cell size
#: change the grid (tests/test_pipeline.py); match_distance_m only the metrics; model_path needs a calibrated
#: model file; the tracker's gate, confirmation and misses only change tracks over longer runs
#: (tests/test_tracking_tracker.py); selective_update only over longer runs at the cameras' default 5 Hz
#: (tests/test_vision_selective.py).
RUN_FIELDS = ["planes.heights_m", "sensors.cameras.history_frames", "sensors.cameras.p_foreground_given_free",
              "sensors.cameras.sensor_model", "sensors.laser.p_occupied_hit", "sensors.sound.block_length_s",
              "models.filter.enabled",
              "models.filter.decay_rate_hz", "models.detection.column_threshold", "models.filter.output_period_s",
              "models.filter.camera_correlation_s", "scene.occluder_boxes_m", "sensors.cameras.ignore_rects_px"]


@pytest.mark.parametrize("field", RUN_FIELDS)
def test_changing_a_field_changes_what_runs(short_recording, default_outputs, field):
    base = default_outputs
    new = _outputs(short_recording, config_from_dict(_nested(field, CHANGED[field])))
    same_occ = base[0].shape == new[0].shape and np.array_equal(base[0], new[0])
    same_det = len(base[1]) == len(new[1]) and all(np.array_equal(a, b) for a, b in zip(base[1], new[1]))
    assert not (same_occ and same_det), field


def test_output_options_are_honoured(short_recording, tmp_path):
    plain = OutputSettings(zarr=False, chunk_steps=3, figures=False, animation="none", report=False)
    run_to_folder(short_recording, RunPlan(SystemParams(cameras=False), tmp_path / "a", plain), progress_mode="quiet")
    names = {p.name for p in (tmp_path / "a").iterdir()}
    assert not names & {"occupancy.zarr", "figures", "report.html", "animation.gif", "animation.mp4",
                        "planefuse.mcap", "ros2_bag"}, names
    assert json.loads((tmp_path / "a" / "run_state.json").read_text())["chunk_steps"] == 3
    for dpi, name in ((40, "b"), (80, "c")):
        s = OutputSettings(figures=True, animation="none", report=False, figure_dpi=dpi)
        run_to_folder(short_recording, RunPlan(SystemParams(cameras=False), tmp_path / name, s), progress_mode="quiet")
    robotics = OutputSettings(figures=False, animation="none", report=False, mcap=True, ros2_bag=True)
    run_to_folder(short_recording, RunPlan(SystemParams(cameras=False), tmp_path / "d", robotics),
                  progress_mode="quiet")
    assert (tmp_path / "d" / "planefuse.mcap").is_file() and (tmp_path / "d" / "ros2_bag" / "metadata.yaml").is_file()
    import cv2

    small, large = (cv2.imread(str(next((tmp_path / n / "figures").glob("*.png")))) for n in ("b", "c"))
    assert large.shape[0] > 1.5 * small.shape[0]


# -- resuming: only what changes results restarts a run -------------------------------------------------------------
def test_resume_key_ignores_output_options_and_follows_models(short_recording, tmp_path):
    cfg = RunConfig(recording=Path("r"))
    key = resume_key(cfg.plan(), short_recording)
    for path, value in (("outputs.figures", False), ("outputs.out_dir", "elsewhere"), ("outputs.report", False),
                        ("outputs.animation", "none"), ("outputs.figure_dpi", 50), ("outputs.rerun", True),
                        ("outputs.animation_max_frames", None), ("outputs.camera_videos", True),
                        ("outputs.mcap", True), ("outputs.ros2_bag", True)):
        assert resume_key(config_from_dict(_nested(path, value)).plan(), short_recording) == key, path
    for path, value in (("models.filter.decay_rate_hz", 1.0), ("outputs.chunk_steps", 10), ("planes.heights_m", [1.0])):
        assert resume_key(config_from_dict(_nested(path, value)).plan(), short_recording) != key, path


def test_changing_only_output_options_resumes_an_interrupted_run(short_recording, tmp_path, monkeypatch):
    out = tmp_path / "out"
    cfg = config_from_dict({"recording": "r", "sensors": {"cameras": {"enabled": False}},
                            "outputs": {"out_dir": str(out), "chunk_steps": 3, "animation": "none",
                                        "report": False, "figures": False}})
    original = OutputWriter.write_occupancy

    def stop_at_6(self, k, *a, **kw):
        if k == 6:
            raise KeyboardInterrupt
        return original(self, k, *a, **kw)

    with monkeypatch.context() as m:
        m.setattr(OutputWriter, "write_occupancy", stop_at_6)
        with pytest.raises(KeyboardInterrupt):
            run_plan(short_recording, cfg.plan())
    changed = config_from_dict({**cfg.model_dump(mode="json"), "outputs": {
        **cfg.outputs.model_dump(mode="json"), "figures": True, "figure_dpi": 40, "report": True}})
    _, metrics = run_plan(short_recording, changed.plan(), progress_mode="quiet")
    assert metrics["resumed_at_step"] == 6
    assert (out / "report.html").is_file() and (out / "figures").is_dir()


# -- what run would refuse, check refuses first ------------------------------------------------------------------
@pytest.mark.parametrize("edit, field, words", [
    (("p_foreground_given_free: 0.2", "p_foreground_given_free: 0.95"), "sensors.cameras.p_foreground_given_free",
     "must be below P(foreground | occupied)"),
    (("model_path: null", "model_path: missing.npz"), "sensors.sound.model_path", "no file"),
    (("model_path: null", "model_path: garbage.npz"), "sensors.sound.model_path", "not a sensor model"),
    (("gate_m: 0.75", "gate_m: -0.5"), "models.detection.gate_m", "must be finite and > 0"),
    (("velocity_max_m_s: 1.5", "velocity_max_m_s: 5400"), "models.filter.velocity_max_m_s", "at most 10 m/s"),
])
def test_check_refuses_what_run_would_refuse(tmp_path, edit, field, words):
    (tmp_path / "garbage.npz").write_bytes(b"not a numpy archive")
    text = example_yaml("rec")
    assert edit[0] in text, edit
    p = tmp_path / "run.yaml"
    p.write_text(text.replace(edit[0], edit[1]))
    for command in ("check", "run"):
        r = runner.invoke(app, [command, str(p)], terminal_width=250)
        flat = " ".join(r.output.split())
        assert r.exit_code == 2, (command, r.output)
        assert field in flat and words in flat, flat
        assert "Traceback" not in r.output


def test_loaded_configuration_builds_exactly_the_default_system():
    cfg = load_config_text(example_yaml("rec"))
    assert cfg.system_params() == SystemParams()
    assert asdict(cfg.output_settings()) == asdict(OutputSettings())


def load_config_text(text: str) -> RunConfig:
    return config_from_dict(yaml.safe_load(text))


def test_tracks_prior_only_with_the_filter(short_recording):
    """``generative_track_prior_ratio`` feeds the tracker back into the generative camera model only with the filter:
    the "no filter" ablation keeps nothing from one step to the next (its tracks are formed, not fed back)."""
    on = {"recording": "r", "sensors": {"cameras": {"sensor_model": "generative", "generative_track_prior_ratio": 2.0}}}
    from planefuse.pipeline import SystemRun

    assert SystemRun(short_recording, config_from_dict(on).system_params())._track_prior()
    off = {**on, "models": {"filter": {"enabled": False}}}
    assert not SystemRun(short_recording, config_from_dict(off).system_params())._track_prior()
    assert not SystemRun(short_recording, SystemParams())._track_prior()
