"""Silhouettes projected from calibrated cameras (planefuse.occupancy.silhouettes_from_cameras), checked against
OpenCV's projectPoints, with partial views at the image border and volumes behind a camera."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from planefuse.geometry import default_camera_ring
from planefuse.grid import PlaneStack
from planefuse.occupancy import PersonVolume, locations_from_stack, silhouettes_from_cameras


def _opencv_box(cam, pts):
    """Inclusive pixel box of points projected by OpenCV (independent of PinholeCamera.project)."""
    T = cam.T_cam_world
    rvec, _ = cv2.Rodrigues(T[:3, :3])
    uv, _ = cv2.projectPoints(pts.reshape(-1, 1, 3), rvec, T[:3, 3], cam.K, cam.intrinsics.dist)
    uv = uv.reshape(-1, 2)
    return np.floor(uv.min(axis=0) + 0.5), np.floor(uv.max(axis=0) + 0.5)


def test_boxes_match_opencv_projection_of_the_cylinder():
    cams = default_camera_ring(4)
    person = PersonVolume(radius_m=0.3, height_range_m=(0.0, 1.7))
    xy = np.array([[5.0, 5.0], [3.0, 6.5], [7.2, 2.1]])
    sil = silhouettes_from_cameras(cams, xy, person)
    pts = person.surface_points(xy)
    for c, cam in enumerate(cams):
        w, h = cam.intrinsics.width_px, cam.intrinsics.height_px
        for k in range(len(xy)):
            lo, hi = _opencv_box(cam, pts[k])
            expect = [max(lo[0], 0), max(lo[1], 0), min(hi[0], w - 1), min(hi[1], h - 1)]
            assert sil.boxes_px[c, k].tolist() == [int(v) for v in expect]
    # the person's foot and head points are inside every box
    for c, cam in enumerate(cams):
        for k in range(len(xy)):
            for z in (0.0, 1.7):
                u, v = cam.project(np.array([[*xy[k], z]]))[0]
                x0, y0, x1, y1 = sil.boxes_px[c, k]
                if 0 <= u < cam.intrinsics.width_px and 0 <= v < cam.intrinsics.height_px:
                    assert x0 - 0.5 <= u <= x1 + 0.5 and y0 - 0.5 <= v <= y1 + 0.5


def test_partial_view_clipped_to_border_and_invisible_dropped():
    cam = default_camera_ring(1)[0]
    w, h = cam.intrinsics.width_px, cam.intrinsics.height_px
    # walk a location across the image border: find one whose unclipped box straddles the left/right edge
    xs = np.linspace(-5, 15, 400)
    xy = np.stack([xs, np.full_like(xs, 8.0)], axis=1)
    person = PersonVolume()
    sil = silhouettes_from_cameras([cam], xy, person)
    lo_hi = [_opencv_box(cam, p) for p in person.surface_points(xy)]
    straddle = [k for k, (lo, hi) in enumerate(lo_hi) if (lo[0] < 0 <= hi[0]) or (lo[0] <= w - 1 < hi[0])]
    assert straddle, "scene has no location across the image border"
    for k in straddle:
        b = sil.boxes_px[0, k]
        assert b[0] >= 0 and (b[0] == 0 or b[2] == w - 1)
    outside = [k for k, (lo, hi) in enumerate(lo_hi) if hi[0] < 0 or lo[0] > w - 1]
    assert outside and (sil.boxes_px[0, outside] == -1).all()
    # a minimum visible fraction drops slivers
    strict = silhouettes_from_cameras([cam], xy, PersonVolume(min_visible_fraction=0.9))
    assert strict.visible.sum() < sil.visible.sum()


def test_volume_behind_camera_is_not_visible():
    cam = default_camera_ring(1)[0]
    c = cam.center_world
    sil = silhouettes_from_cameras([cam], np.array([c[:2]]), PersonVolume(height_range_m=(0.0, c[2] + 1.0)))
    assert not sil.visible[0, 0]


def test_stack_locations_are_its_cells_row_major():
    stack = PlaneStack.from_extent([0.1, 0.9, 1.6], (0, 10), (0, 8), 0.5)
    xy = locations_from_stack(stack)
    assert xy.shape == (stack.ny * stack.nx, 2)
    iy, ix = stack.index_from_xy(xy)
    assert (iy * stack.nx + ix == np.arange(len(xy))).all()
    sil = silhouettes_from_cameras(default_camera_ring(2), stack)
    assert sil.boxes_px.shape == (2, stack.ny * stack.nx, 4)
    assert PersonVolume.from_stack(stack).height_range_m == (stack.band_edges_m[0], stack.band_edges_m[-1])


def test_bad_person_volume_and_locations_refused():
    with pytest.raises(ValueError, match="height_range_m"):
        PersonVolume(height_range_m=(1.8, 0.0))
    with pytest.raises(ValueError, match="radius_m"):
        PersonVolume(radius_m=float("nan"))
    with pytest.raises(ValueError, match="locations"):
        silhouettes_from_cameras(default_camera_ring(1), np.array([[1.0, np.nan]]))
    with pytest.raises(ValueError, match="at least one camera"):
        silhouettes_from_cameras([], np.zeros((1, 2)))
