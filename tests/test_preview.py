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
