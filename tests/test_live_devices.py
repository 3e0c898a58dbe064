"""planefuse.live: what a camera source is, and local devices as far as a machine without a camera allows.

No camera and no v4l2loopback here (a container: no /dev/video*, no kernel modules to load), so a device that
delivers frames is not tested; its refusal when absent, and the classification of every kind of source, are.
"""

from __future__ import annotations

import sys

import pytest

from planefuse.live import LiveRun, LiveSettings, device_path, source_kind
from planefuse.pipeline import SystemParams
from planefuse.sim import default_scene_config, simulate


@pytest.mark.parametrize("source, kind", [
    ("rtsp://10.0.0.21/stream1", "ffmpeg"), ("rtsps://cam/x", "ffmpeg"), ("http://h:8080/video.mjpg", "mjpeg"),
    ("https://h/v.mjpg", "mjpeg"), (0, "device"), (3, "device"), ("/dev/video2", "device"),
    ("videos/cam3.mp4", "file"), ("/data/c.avi", "file"), ("file:///data/c.avi", "file")])
def test_source_kind(source, kind):
    assert source_kind(source) == kind


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="index -> /dev/videoN is Linux's (V4L2)")
def test_device_path_of_an_index_is_its_video_node():
    assert str(device_path(4)) == "/dev/video4" and str(device_path("/dev/video1")) == "/dev/video1"


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="index -> /dev/videoN is Linux's (V4L2)")
def test_a_missing_device_is_an_error_of_its_camera_not_retried():
    """Devices absent from the start (a wrong index or node): each camera stops with a one-line error naming the
    device, no retry, and the run ends by itself."""
    missing = [n for n in range(90, 100) if not device_path(n).exists()][:2]
    rec = simulate(default_scene_config(duration_s=0.5, seed=4))
    cams = {"cam0": missing[0], "cam1": f"/dev/video{missing[1]}", "cam2": missing[0], "cam3": missing[1]}
    live = LiveRun(rec, SystemParams(laser=False, sound=False), LiveSettings(cameras=cams, serve=False))
    summary = live.run(duration_s=20.0)  # ends at once: every source failed for good
    h = {c["name"]: c for c in summary.health}
    assert summary.instants == 0 and all(c["state"] == "error" and c["reconnects"] == 0 for c in h.values())
    assert h["cam0"]["last_error"] == f"device {missing[0]}: /dev/video{missing[0]} does not exist (no such camera " \
                                      "on this machine)"
    assert h["cam1"]["last_error"].startswith(f"device '/dev/video{missing[1]}': /dev/video{missing[1]} does not")
