"""Video camera streams (recording format 2) and ignore regions."""

from __future__ import annotations

import cv2
import numpy as np
import pytest
import yaml

from planefuse.geometry import CameraIntrinsics, PinholeCamera, T_world_cam_look_at
from planefuse.grid import PlaneStack
from planefuse.io import load_manifest, read_recording
from planefuse.registration import ImagePlaneLookup
from planefuse.vision import CameraFusion, FusionParams

W, H = 64, 48


def _frames(n: int) -> list[np.ndarray]:
    rng = np.random.default_rng(0)
    return [rng.integers(0, 256, (H, W, 3), dtype=np.uint8) for _ in range(n)]


def _write_video(path, frames, fps=25.0) -> None:
    writer = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"FFV1"), fps, (W, H))  # lossless
    for f in frames:
        writer.write(f)
    writer.release()


def _manifest(root, **camera) -> None:
    cam = {"type": "camera", "name": "cam0", "width_px": W, "height_px": H,
           "K": [[50.0, 0, 31.5], [0, 50.0, 23.5], [0, 0, 1]],
           "T_world_cam": [[1, 0, 0, 0], [0, -1, 0, 0], [0, 0, -1, 3.0], [0, 0, 0, 1]],
           "rate_hz": 25.0, "n_frames": 10, "video_file": "cam0.mkv"}
    cam.update(camera)
    (root / "scene.yaml").write_text(yaml.safe_dump({"format": "planefuse-recording", "format_version": 2,
                                                     "duration_s": 0.4, "sensors": [cam]}))


def test_video_stream_round_trip_and_seeking(tmp_path):
    frames = _frames(10)
    _write_video(tmp_path / "cam0.mkv", frames)
    _manifest(tmp_path, start_time_s=2.0)
    cs = read_recording(tmp_path).camera("cam0")
    np.testing.assert_allclose(cs.times_s, 2.0 + np.arange(10) / 25.0)
    for i in (0, 1, 7, 3, 9, 0, 5):  # forward, backward (reopens), forward again
        np.testing.assert_array_equal(cs.frame(i), frames[i])
    assert [fr.index for fr in cs] == list(range(10))


def test_video_stream_times_file_subsample(tmp_path):
    frames = _frames(10)
    _write_video(tmp_path / "cam0.mkv", frames)
    (tmp_path / "times.csv").write_text("time_s,frame_index\n0.0,0\n0.16,4\n0.32,8\n")
    _manifest(tmp_path, times_file="times.csv", n_frames=3, rate_hz=6.25)
    cs = read_recording(tmp_path).camera("cam0")
    np.testing.assert_array_equal(cs.times_s, [0.0, 0.16, 0.32])
    for i, k in [(2, 8), (0, 0), (1, 4)]:
        np.testing.assert_array_equal(cs.frame(i), frames[k])


def test_video_shorter_than_its_times_names_camera_frame_and_time(tmp_path):
    _write_video(tmp_path / "cam0.mkv", _frames(4))
    _manifest(tmp_path)  # says 10 frames
    with pytest.raises(ValueError, match=r"cam0\.mkv: camera 'cam0' video has 4 frames, shorter than its times: "
                                         r"frame 4 \(video frame 4, t=0\.16 s\)"):
        read_recording(tmp_path)


def test_video_decode_failure_is_reported(tmp_path):
    frames = _frames(10)
    _write_video(tmp_path / "cam0.mkv", frames)
    _manifest(tmp_path)
    cs = read_recording(tmp_path).camera("cam0")
    data = (tmp_path / "cam0.mkv").read_bytes()
    (tmp_path / "cam0.mkv").write_bytes(data[: len(data) // 3])  # truncated after it was opened
    with pytest.raises(ValueError, match=r"camera 'cam0' frame \d+ \(video frame \d+, t=[0-9.]+ s\)"):
        for i in range(10):
            cs.frame(i)


def test_video_of_wrong_size_and_missing_file(tmp_path):
    _write_video(tmp_path / "cam0.mkv", _frames(10))
    _manifest(tmp_path, width_px=32)
    with pytest.raises(ValueError, match="video is 64x48 px, its calibration 32x48 px"):
        read_recording(tmp_path)
    _manifest(tmp_path, video_file="nope.mp4")
    with pytest.raises(ValueError, match="nope.mp4: video file not found"):
        read_recording(tmp_path)


def test_format_1_refuses_video_and_ignore_regions(tmp_path):
    _manifest(tmp_path)
    m = yaml.safe_load((tmp_path / "scene.yaml").read_text())
    m["format_version"] = 1
    (tmp_path / "scene.yaml").write_text(yaml.safe_dump(m))
    with pytest.raises(ValueError, match="need format_version 2"):
        load_manifest(tmp_path / "scene.yaml")


def test_ignore_regions_from_rectangles_and_mask_file_round_trip(tmp_path):
    _write_video(tmp_path / "cam0.mkv", _frames(10))
    extra = np.zeros((H, W), np.uint8)
    extra[0:2, 0:3] = 255
    cv2.imwrite(str(tmp_path / "ignore.png"), extra)
    _manifest(tmp_path, ignore_rects_px=[[10, 20, 30, 25]], ignore_mask_file="ignore.png")
    rec = read_recording(tmp_path)
    mask = rec.camera("cam0").ignore_mask
    assert mask.sum() == 20 * 5 + 6 and mask[20:25, 10:30].all() and mask[0:2, 0:3].all()
    rec.write(tmp_path / "copy")
    np.testing.assert_array_equal(read_recording(tmp_path / "copy").camera("cam0").ignore_mask, mask)
    _manifest(tmp_path, ignore_rects_px=[[30, 20, 10, 25]])
    with pytest.raises(ValueError, match="ignore rectangle"):
        read_recording(tmp_path)


@pytest.mark.parametrize("fg_value", [0.0, 1.0])
def test_ignored_pixels_give_exactly_zero_evidence(fg_value):
    stack = PlaneStack.from_extent([0.0, 1.0], (-2.0, 2.0), (-2.0, 2.0), 0.1)
    intr = CameraIntrinsics(np.array([[60.0, 0, 31.5], [0, 60.0, 23.5], [0, 0, 1]]), W, H)
    cams = [PinholeCamera(intr, T_world_cam_look_at([0.0, -4.0, 2.5], [0, 0, 0.5]), "a"),
            PinholeCamera(intr, T_world_cam_look_at([4.0, 0.0, 2.5], [0, 0, 0.5]), "b")]
    ignore = np.zeros((H, W), bool)
    ignore[10:40, 20:50] = True
    full = [ImagePlaneLookup.from_camera(c, stack) for c in cams]
    lookups = [full[0].without_pixels(ignore), full[1]]
    hidden = full[0].visible & ~lookups[0].visible
    assert hidden.sum() > 100
    fg = np.full((H, W), fg_value, np.float32)
    fusion = CameraFusion(lookups, stack, FusionParams())
    only_a = fusion.log_odds([fg, None])
    assert np.all(only_a[hidden] == 0.0)  # unobserved: no evidence either way
    assert np.all(only_a[lookups[0].visible] != 0.0)
    both = fusion.log_odds([fg, fg])
    only_b = CameraFusion([full[1]], stack, FusionParams()).log_odds([fg])
    np.testing.assert_array_equal(both[hidden], only_b[hidden])  # camera a adds exactly nothing there
    assert np.all(fusion.cameras_seeing()[hidden] == full[1].visible[hidden])
