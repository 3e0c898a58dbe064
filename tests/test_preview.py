"""``planefuse check --figures``: the ground, the monitored area and the planes drawn on each camera (issue 38)."""

from __future__ import annotations

import numpy as np

from planefuse.grid import PlaneStack
from planefuse.pipeline import SystemParams, stack_for_recording
from planefuse.sim import default_scene_config, simulate
from planefuse.viz import area_outline_world, ground_grid_world, installation_preview


def test_area_outline_is_the_closed_border_of_the_stack_on_its_plane():
    stack = PlaneStack.from_extent((0.1, 1.0), (-1.0, 2.0), (0.5, 4.5), 0.5)
    line = area_outline_world(stack, 1.0, samples=10)
    assert line.shape == (41, 3) and np.allclose(line[0], line[-1]) and np.all(line[:, 2] == 1.0)
    x, y = line[:, 0], line[:, 1]
    on_border = np.isclose(x, -1.0) | np.isclose(x, 2.0) | np.isclose(y, 0.5) | np.isclose(y, 4.5)
    assert on_border.all() and (x.min(), x.max(), y.min(), y.max()) == (-1.0, 2.0, 0.5, 4.5)


def test_ground_grid_lines_are_on_the_metre_multiples_inside_the_area():
    stack = PlaneStack.from_extent((0.1,), (-1.3, 2.2), (0.5, 2.0), 0.1)
    lines = ground_grid_world(stack, 1.0)
    xs = sorted({round(float(l[0, 0]), 6) for l in lines if np.allclose(l[:, 0], l[0, 0])})
    ys = sorted({round(float(l[0, 1]), 6) for l in lines if np.allclose(l[:, 1], l[0, 1])})
    assert xs == [-1.0, 0.0, 1.0, 2.0] and ys == [1.0, 2.0] and np.all(lines[..., 2] == 0.0)


def test_installation_preview_draws_every_camera_and_the_coverage_map():
    rec = simulate(default_scene_config(duration_s=0.2, seed=1))
    stack = stack_for_recording(rec, SystemParams())
    pictures = installation_preview(rec, stack, frame_index=-1)
    assert sorted(pictures) == sorted([f"camera_{c.name}" for c in rec.cameras] + ["coverage"])
    assert all(png.startswith(b"\x89PNG") for png in pictures.values())


def test_animation_max_frames_subsamples_with_a_warning_and_none_shows_every_step(tmp_path):
    """Issue 38: the animation's step limit is a configuration field (outputs.animation_max_frames); None = all."""
    import warnings

    import imageio.v3 as iio
    import pytest

    from planefuse.viz import animate_stack

    stack = PlaneStack.from_extent((0.1, 1.0), (0.0, 1.0), (0.0, 1.0), 0.25)
    occ = np.random.default_rng(0).random((12,) + stack.shape).astype(np.float32)
    with pytest.warns(UserWarning, match=r"shows 5 of 12 steps.*animation_max_frames: null"):
        animate_stack(tmp_path / "a.gif", stack, occ, max_frames=5)
    assert iio.improps(tmp_path / "a.gif", index=None).shape[0] == 5
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        animate_stack(tmp_path / "b.gif", stack, occ, max_frames=None)
    assert iio.improps(tmp_path / "b.gif", index=None).shape[0] == 12


def test_camera_tracks_are_drawn_from_the_feet_to_the_head_in_their_floor_plan_colour():
    from planefuse.viz import plot_camera_tracks, track_colour

    rec = simulate(default_scene_config(duration_s=0.2, seed=1))
    cam = rec.cameras[0]
    image = rec.camera(cam.name).frame(0)[..., ::-1]
    tracks = {"step": np.array([0, 0]), "track_id": np.array([3, 7]), "x_m": np.array([4.0, 6.0]),
              "y_m": np.array([5.0, 4.0])}
    fig = plot_camera_tracks(cam, [(0, 0.0, image)], np.array([0.0]), tracks)
    ax = fig.axes[0]
    lines = [l for l in ax.get_lines() if l.get_linestyle() == "-"]
    assert len(lines) == 2 and "frame 0, t = 0.00 s (step 0): 2 tracks" in ax.get_title()
    for line, tid, x, y in zip(lines, (3, 7), (4.0, 6.0), (5.0, 4.0)):
        expected = cam.project(np.array([[x, y, 0.0], [x, y, 1.7]]))
        np.testing.assert_allclose(np.c_[line.get_xdata(), line.get_ydata()], expected)
        assert line.get_color() == track_colour(tid)


def test_camera_track_frames_draw_each_track_in_its_colour_at_its_step():
    from planefuse.viz import camera_track_frames, track_colour

    rec = simulate(default_scene_config(duration_s=0.4, seed=1))
    cam = rec.cameras[0]
    stream = rec.camera(cam.name)
    step_times = np.array([0.0, 0.2])
    tracks = {"step": np.array([1]), "track_id": np.array([2]), "x_m": np.array([4.0]), "y_m": np.array([5.0])}
    plain, drawn = list(camera_track_frames(cam, stream, step_times, tracks))
    i = int(np.argmin(np.abs(stream.times_s - 0.2)))
    uv = cam.project(np.array([[4.0, 5.0, 0.85]]))[0]  # the segment's middle
    u, v = (int(round(c)) for c in uv)
    b, g, r = (int(x) for x in drawn[v, u])
    expected = tuple(int(255 * c) for c in track_colour(2)[:3])
    assert max(abs(r - expected[0]), abs(g - expected[1]), abs(b - expected[2])) <= 2
    # step 0 has no track: only the label differs from the camera's frame
    frame0 = stream.frame(int(np.argmin(np.abs(stream.times_s))))
    assert np.array_equal(plain[40:], frame0[40:]) and not np.array_equal(drawn[40:], stream.frame(i)[40:])


def test_outputs_camera_videos_writes_one_video_per_camera_with_a_frame_per_step(tmp_path):
    import cv2

    from planefuse.outputs import OutputSettings
    from planefuse.pipeline import RunPlan, run_to_folder

    rec = simulate(default_scene_config(duration_s=1.4, seed=2))
    settings = OutputSettings(zarr=False, figures=False, animation="none", report=False, camera_videos=True)
    run_to_folder(rec, RunPlan(SystemParams(laser=False, sound=False), tmp_path / "out", settings),
                  progress_mode="quiet")
    for cam in rec.cameras:
        cap = cv2.VideoCapture(str(tmp_path / "out" / "figures" / f"camera_{cam.name}_tracks.mp4"))
        assert int(cap.get(cv2.CAP_PROP_FRAME_COUNT)) == 7  # 1.4 s at the output period 0.2 s
        cap.release()
    listed = (tmp_path / "out" / "figures" / ".planefuse-figures").read_text().split()
    assert sorted(listed) == sorted(f"camera_{c.name}_tracks.mp4" for c in rec.cameras)


def test_camera_tracks_figure_draws_this_cameras_person_boxes_of_the_step():
    from matplotlib.patches import Rectangle

    from planefuse.viz import plot_camera_tracks

    rec = simulate(default_scene_config(duration_s=0.2, seed=1))
    cam = rec.cameras[0]
    image = rec.camera(cam.name).frame(0)[..., ::-1]
    boxes = {"step": np.array([0, 0, 1]), "camera": np.array([cam.name, "other", cam.name], dtype=object),
             "left_px": np.array([10.0, 20.0, 30.0]), "top_px": np.array([5.0, 6.0, 7.0]),
             "width_px": np.array([20.0, 21.0, 22.0]), "height_px": np.array([40.0, 41.0, 42.0]),
             "score": np.array([0.91, 0.8, 0.7])}
    fig = plot_camera_tracks(cam, [(0, 0.0, image)], np.array([0.0, 0.2]), None, boxes=boxes)
    ax = fig.axes[0]
    rects = [p for p in ax.patches if isinstance(p, Rectangle)]
    assert len(rects) == 1  # this camera's box at step 0 only
    assert rects[0].get_xy() == (9.5, 4.5) and (rects[0].get_width(), rects[0].get_height()) == (20.0, 40.0)
    assert "1 person boxes" in ax.get_title() and any(t.get_text() == "0.91" for t in ax.texts)
