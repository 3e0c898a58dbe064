"""Named configuration profiles (issue 38): real video gets the terrace's settings, simulated recordings the library's
defaults; the monitored area proposed from the ground two cameras see; warnings about the cameras' placement."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import yaml
from pydantic import BaseModel

from planefuse.config import PROFILES, REAL_VIDEO, SIMULATED, RunConfig, config_for_recording, config_from_dict, \
    profile_for_recording
from planefuse.geometry import CameraIntrinsics, PinholeCamera, T_world_cam_look_at
from planefuse.grid import PlaneStack
from planefuse.io import Recording
from planefuse.registration import camera_view_findings, cameras_per_cell, proposed_area_xy_m

REPO = Path(__file__).resolve().parents[1]


def _value(cfg, path: str):
    obj = cfg
    for part in path.split("."):
        obj = getattr(obj, part)
    return obj


def test_every_profile_setting_is_a_valid_configuration_field():
    for profile in PROFILES.values():
        cfg = config_from_dict({"recording": "x", **profile.changes()})
        for s in profile.settings:
            got = _value(cfg, s.field)
            assert (list(got) if isinstance(got, tuple) else got) == s.value, s.field
            assert s.why, s.field  # every value says what measurement chose it


def test_the_simulated_profile_is_the_library_defaults():
    assert SIMULATED.settings == () and SIMULATED.changes() == {}


def test_scripts_terrace_yaml_runs_the_real_video_profile():
    """The experiment's configuration holds no knowledge the product lacks: every field of scripts/terrace.yaml that
    differs from the defaults is the recording's (planes, sensors, outputs) or the real-video profile's, at its value,
    and every profile field is in it at the profile's value."""
    terrace = config_from_dict(yaml.safe_load((REPO / "scripts" / "terrace.yaml").read_text()))
    default = RunConfig(recording=Path("x"))
    profile = REAL_VIDEO.notes()
    for s in REAL_VIDEO.settings:
        got = _value(terrace, s.field)
        assert (list(got) if isinstance(got, tuple) else got) == s.value, s.field

    def walk(a, b, prefix=""):
        for name in type(a).model_fields:
            x, y = getattr(a, name), getattr(b, name)
            if isinstance(x, BaseModel):
                yield from walk(x, y, f"{prefix}{name}.")
            elif x != y:
                yield f"{prefix}{name}"

    own = {"recording", "planes.x_range_m", "planes.y_range_m", "sensors.laser.enabled", "sensors.sound.enabled"}
    extra = {f for f in walk(default, terrace) if f not in own and not f.startswith("outputs.")}
    assert extra <= set(profile), extra - set(profile)


def _rec(source: str, cameras=(), room=(0.0, 4.0, 0.0, 3.0)) -> Recording:
    rec = Recording(duration_s=1.0, source=source, room_xy_m=room, root=Path("/nonexistent/rec"))
    for cam in cameras:
        rec.camera_streams[cam.name] = _Stream(cam)
    return rec


class _Stream:
    def __init__(self, cam):
        self.camera = cam


def _nadir(name: str, x_m: float, height_m: float = 5.0, f_px: float = 100.0) -> PinholeCamera:
    """A camera looking straight down from (x_m, 0, height_m); 100 x 80 px: ground footprint 5 m x 4 m at 5 m."""
    T = np.eye(4)
    T[:3, :3] = np.diag([1.0, -1.0, -1.0])
    T[:3, 3] = (x_m, 0.0, height_m)
    K = np.array([[f_px, 0.0, 50.0], [0.0, f_px, 40.0], [0.0, 0.0, 1.0]])
    return PinholeCamera(CameraIntrinsics(K, 100, 80), T, name)


def test_profile_is_chosen_from_what_the_recording_is():
    cams = [_nadir("a", 0.0), _nadir("b", 2.0)]
    assert profile_for_recording(_rec("planefuse simulate (seed 4)", cams))[0] is SIMULATED
    assert profile_for_recording(_rec("planefuse import out --camera ...", cams))[0] is REAL_VIDEO
    assert profile_for_recording(_rec("", cams))[0] is REAL_VIDEO  # a real recording written by hand
    assert profile_for_recording(_rec("planefuse import out"))[0] is SIMULATED  # no camera: nothing to set


def test_proposed_area_is_the_ground_both_nadir_cameras_see():
    """Two cameras looking down from 5 m, 2 m apart, f = 100 px on 100 x 80 px: footprints x in [-2.5, 2.5] and
    [-0.5, 4.5], y in [-2, 2]; the ground both see is x in [-0.5, 2.5], y in [-2, 2]."""
    cams = [_nadir("a", 0.0), _nadir("b", 2.0)]
    assert proposed_area_xy_m(cams) == pytest.approx((-0.5, 2.5, -2.0, 2.0))
    assert proposed_area_xy_m(cams, min_cameras=1) == pytest.approx((-2.5, 4.5, -2.0, 2.0))
    assert proposed_area_xy_m(cams[:1]) is None  # one camera cannot give two views
    far = [_nadir("a", 0.0), _nadir("b", 20.0)]
    assert proposed_area_xy_m(far) is None  # no shared ground


def test_cameras_per_cell_counts_views_and_drops_people_too_small_to_see():
    cams = [_nadir("a", 0.0), _nadir("b", 2.0)]
    stack = PlaneStack.from_extent((0.0,), (-3.0, 5.0), (-1.0, 1.0), 0.5)
    n = cameras_per_cell(cams, stack)[0]
    x = stack.cell_centers_xy()[0, :, 0]
    np.testing.assert_array_equal(n[0], ((x > -2.5) & (x < 2.5)).astype(int) + ((x > -0.5) & (x < 4.5)))
    # a person 1.7 m tall 5 m away is 34 px at f = 100: below 40 px no cell counts
    assert cameras_per_cell(cams, stack, min_person_px=40.0).sum() == 0


def test_config_for_a_simulated_recording_is_the_library_defaults_and_real_video_gets_the_profile():
    cams = [_nadir("a", 0.0), _nadir("b", 2.0)]
    sim = config_for_recording(_rec("planefuse simulate (seed 1)", cams))
    assert sim.profile is SIMULATED
    assert sim.config.model_dump(exclude={"recording", "sensors"}) == \
        RunConfig(recording=Path("x")).model_dump(exclude={"recording", "sensors"})
    real = config_for_recording(_rec("planefuse import x", cams))
    assert real.profile is REAL_VIDEO and real.config.sensors.cameras.sensor_model == "generative"
    assert real.config.planes.x_range_m == (0.0, 4.0) and real.config.planes.y_range_m == (0.0, 3.0)
    # no monitored area: proposed (and said), for either profile
    for source in ("planefuse import x", "planefuse simulate (seed 1)"):
        fit = config_for_recording(_rec(source, cams, room=None))
        assert (*fit.config.planes.x_range_m, *fit.config.planes.y_range_m) == pytest.approx((-0.5, 2.5, -2.0, 2.0))
        assert any("monitored area proposed" in m for m in fit.messages)
    # no shared ground: a configuration to edit (no error that sends the user back), and the message saying what to set
    fit = config_for_recording(_rec("planefuse import x", [_nadir("a", 0.0), _nadir("b", 20.0)], room=None))
    assert fit.config.planes.x_range_m is None
    assert any("set planes.x_range_m and planes.y_range_m" in m for m in fit.messages)
    with pytest.raises(ValueError, match="unknown profile 'indoor'"):
        config_for_recording(_rec("planefuse import x", cams), "indoor")


def test_camera_view_findings_warn_about_low_horizontal_and_barely_overlapping_cameras():
    K = np.array([[300.0, 0.0, 180.0], [0.0, 300.0, 144.0], [0.0, 0.0, 1.0]])
    low = PinholeCamera(CameraIntrinsics(K, 360, 288), T_world_cam_look_at([0.0, -6.0, 1.9], [0.0, 4.0, 1.2]), "low")
    stack = PlaneStack.from_extent((0.1,), (-3.0, 3.0), (-1.0, 5.0), 0.25)
    found = camera_view_findings([low], stack)
    texts = " | ".join(m for _, s, m in found if s == "low")
    assert "1.9 m above the ground" in texts and "looks nearly horizontally" in texts
    assert any(s == "cameras" and "seen by one camera only" in m for _, s, m in found)
    good = [_nadir("a", 0.0), _nadir("b", 0.5)]
    stack = PlaneStack.from_extent((0.1,), (-1.5, 2.0), (-1.5, 1.5), 0.25)
    assert camera_view_findings(good, stack) == []
    apart = [_nadir("a", 0.0), _nadir("b", 4.8)]
    found = camera_view_findings(apart, stack)
    assert any(s == "a+b" and "barely overlap" in m for _, s, m in found), found


def test_a_person_model_turns_the_detector_on_with_the_librarys_box_settings():
    cams = [_nadir("a", 0.0), _nadir("b", 2.0)]
    fit = config_for_recording(_rec("planefuse import x", cams), person_model="models/yolox_nano.onnx")
    c = fit.config.sensors.cameras
    assert (c.person_detector, c.person_model) == ("yolox", "models/yolox_nano.onnx")
    assert c.box_free_log_odds is None and c.person_input_px is None and c.person_likelihood is None  # the defaults
    assert any("person detector: YOLOX" in m for m in fit.messages)
    assert config_for_recording(_rec("planefuse import x", cams)).config.sensors.cameras.person_detector is None
