"""Person boxes registered on the planes (:mod:`planefuse.vision._boxes`): foot points and head heights recovered
from boxes drawn by projecting known people through the camera (lens distortion included), the foot covariance's
growth with distance and box size, the rules for boxes that give nothing, and the evidence's bumps on the planes of
the body."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from planefuse.geometry import CameraIntrinsics, PinholeCamera, T_world_cam_look_at
from planefuse.grid import PlaneStack
from planefuse.vision import BoxEvidenceParams, PersonBoxes, box_evidence, box_feet

K = np.array([[400.0, 0.0, 320.0], [0.0, 400.0, 240.0], [0.0, 0.0, 1.0]])


def camera(center=(0.0, -6.0, 3.0), target=(0.0, 2.0, 0.0), dist=(0.0, 0.0, 0.0, 0.0, 0.0), name="cam"):
    return PinholeCamera(CameraIntrinsics(K, 640, 480, np.array(dist)), T_world_cam_look_at(center, target), name)


def drawn_box(cam: PinholeCamera, xy, head_m: float, width_px: float = 30.0) -> np.ndarray:
    """The box (l, t, w, h) px whose bottom centre is the projection of the foot point and whose top centre lies on
    the head's ray: the foot's and the head's pixels share a column only in the image of a vertical line, so the
    box's top centre is taken where the vertical line's image crosses the head's row."""
    foot = cam.project(np.array([[xy[0], xy[1], 0.0]]))[0]
    head = cam.project(np.array([[xy[0], xy[1], head_m]]))[0]
    assert abs(foot[0] - head[0]) < 1e-6, "these tests keep the person on the image's vertical centre line"
    return np.array([foot[0] - width_px / 2, head[1], width_px, foot[1] - head[1]])


@settings(max_examples=30, deadline=None)
@given(y=st.floats(-2.0, 6.0), head=st.floats(1.2, 2.0))
def test_foot_point_and_head_height_of_a_drawn_box_are_recovered(y, head):
    cam = camera()
    box = drawn_box(cam, (0.0, y), head)
    xy, cov, head_m, used = box_feet(cam, PersonBoxes(box[None], np.ones(1)))
    assert used.all()
    np.testing.assert_allclose(xy[0], [0.0, y], atol=1e-6)
    assert head_m[0] == pytest.approx(head, abs=1e-6)
    assert np.all(np.linalg.eigvalsh(cov[0]) > 0)


def test_foot_point_through_a_distorted_lens():
    cam = camera(dist=(-0.2, 0.05, 0.0, 0.0, 0.0))
    xy_true = np.array([0.0, 1.0])
    foot = cam.project(np.array([[*xy_true, 0.0]]))[0]
    box = np.array([[foot[0] - 15, foot[1] - 100, 30.0, 100.0]])
    xy, _, _, used = box_feet(cam, PersonBoxes(box, np.ones(1)))
    np.testing.assert_allclose(xy[0], xy_true, atol=1e-6)


def test_covariance_grows_with_distance_and_with_the_box_and_has_its_floor():
    cam = camera()
    near, far = drawn_box(cam, (0.0, 0.0), 1.7), drawn_box(cam, (0.0, 6.0), 1.7)
    _, cov, _, _ = box_feet(cam, PersonBoxes(np.stack([near, far]), np.ones(2)), foot_std_frac=0.05,
                            min_std_m=0.1)
    # the same share of the box height: the far box is smaller in pixels but each pixel covers more ground
    assert np.trace(cov[1]) > np.trace(cov[0])
    big = near.copy()
    big[1] -= 40
    big[3] += 40  # a taller box, same foot pixel
    _, cov_big, _, _ = box_feet(cam, PersonBoxes(big[None], np.ones(1)), foot_std_frac=0.05, min_std_m=0.1)
    assert np.trace(cov_big[0]) > np.trace(cov[0])
    _, cov0, _, _ = box_feet(cam, PersonBoxes(near[None], np.ones(1)), foot_std_frac=1e-9, min_std_m=0.1)
    np.testing.assert_allclose(cov0[0], 0.01 * np.eye(2), atol=1e-9)
    # along the viewing ray (world y here) the ground stretches: the larger axis is y
    assert cov[1][1, 1] > cov[1][0, 0]


def test_boxes_that_give_no_foot_point():
    cam = camera()
    ok = drawn_box(cam, (0.0, 2.0), 1.7)
    cut = ok.copy()
    cut[3] = 480 - cut[1]  # the bottom on the image's bottom edge: feet cut off
    sky = np.array([300.0, 0.0, 40.0, 60.0])  # bottom above the horizon: its ray never meets the ground
    hidden = ok.copy()
    ignore = np.zeros((480, 640), bool)
    foot_row = int(ok[1] + ok[3])
    ignore[foot_row - 2:foot_row + 2, :] = True
    boxes = PersonBoxes(np.stack([ok, cut, sky]), np.ones(3))
    _, _, _, used = box_feet(cam, boxes)
    assert used.tolist() == [True, False, False]
    _, _, _, used = box_feet(cam, PersonBoxes(hidden[None], np.ones(1)), ignore_mask=ignore)
    assert used.tolist() == [False]


def test_evidence_bumps_the_planes_of_the_body_only():
    cam = camera()
    stack = PlaneStack.from_extent((0.1, 0.5, 1.0, 1.5, 1.9), (-3.05, 2.95), (-1.05, 4.95), 0.1)
    box = drawn_box(cam, (0.0, 2.0), 1.2)  # a cell centre; the head between the planes at 1.0 and 1.5 m
    params = BoxEvidenceParams(log_odds=3.0, free_log_odds=0.0)
    L = box_evidence([cam], [PersonBoxes(box[None], np.ones(1))], stack, params)
    iy, ix = stack.index_from_xy(np.array([0.0, 2.0]))
    assert L[:3, iy, ix] == pytest.approx([3.0, 3.0, 3.0], rel=1e-6)
    assert (L[3:] == 0).all()
    assert np.unravel_index(np.argmax(L[0]), L[0].shape) == (iy, ix)
    # the bump's shape is the foot point's Gaussian, cut at 3 standard deviations
    xy, cov, _, _ = box_feet(cam, PersonBoxes(box[None], np.ones(1)), params.foot_std_frac, params.min_std_m)
    d = stack.cell_centers_xy() - xy[0]
    m2 = np.einsum("...i,ij,...j->...", d, np.linalg.inv(cov[0]), d)
    expected = np.where(m2 <= 9.0, 3.0 * np.exp(-0.5 * m2), 0.0)
    np.testing.assert_allclose(L[0], expected, atol=1e-5)


def test_views_add_and_one_views_boxes_do_not():
    c0, c1 = camera(), camera(center=(6.0, 2.0, 3.0), target=(-2.0, 2.0, 0.0), name="c1")
    stack = PlaneStack.from_extent((0.1,), (-3.05, 2.95), (-1.05, 4.95), 0.1)
    xy = (0.0, 2.0)
    b0 = PersonBoxes(drawn_box(c0, xy, 1.7)[None], np.ones(1))
    foot1 = c1.project(np.array([[*xy, 0.0]]))[0]
    b1 = PersonBoxes(np.array([[foot1[0] - 15, foot1[1] - 120, 30.0, 120.0]]), np.ones(1))
    params = BoxEvidenceParams(log_odds=2.0, free_log_odds=0.0)
    iy, ix = stack.index_from_xy(np.array(xy))
    one = box_evidence([c0, c1], [b0, None], stack, params)
    both = box_evidence([c0, c1], [b0, b1], stack, params)
    twice = box_evidence([c0, c1], [PersonBoxes(np.repeat(b0.ltwh_px, 2, axis=0), np.ones(2)), None], stack, params)
    assert one[0, iy, ix] == pytest.approx(2.0, rel=1e-5)
    assert both[0, iy, ix] == pytest.approx(4.0, rel=1e-3)
    np.testing.assert_array_equal(twice, one)
    assert (box_evidence([c0, c1], [b0, b1], stack, BoxEvidenceParams(log_odds=0.0, free_log_odds=0.0)) == 0).all()


def test_bad_box_settings_are_refused_naming_the_field():
    for change, field in [(dict(log_odds=-1.0), "log_odds"), (dict(foot_std_frac=0.0), "foot_std_frac"),
                          (dict(min_std_m=0.0), "min_std_m")]:
        with pytest.raises(ValueError, match=field):
            BoxEvidenceParams(**change)
    with pytest.raises(ValueError, match="boxes: expected 1 entries"):
        box_evidence([camera()], [], PlaneStack.from_extent((0.1,), (0, 1), (0, 1), 0.1), BoxEvidenceParams(1.0, free_log_odds=0.0))


def test_free_space_where_the_camera_sees_the_ground_outside_every_box():
    from planefuse.vision import lookups_from_cameras

    cam = camera()
    stack = PlaneStack.from_extent((0.1, 1.0), (-3.05, 2.95), (-1.05, 4.95), 0.1)
    lk = lookups_from_cameras([cam], stack)[0]
    box = drawn_box(cam, (0.0, 2.0), 1.7, width_px=40.0)
    params = BoxEvidenceParams(log_odds=0.0, free_log_odds=-1.5)
    L = box_evidence([cam], [PersonBoxes(box[None], np.ones(1))], stack, params, lookups=[lk])
    seen = lk.visible[0]
    pix = lk.pixel_index[0]
    uu, vv = pix % lk.width_px, pix // lk.width_px
    inside = seen & (uu >= np.floor(box[0])) & (uu < np.ceil(box[0] + box[2])) & (vv >= np.floor(box[1])) & \
        (vv < np.ceil(box[1] + box[3]))
    expected = np.where(seen & ~inside, -1.5, 0.0)
    np.testing.assert_array_equal(L[0], expected)
    np.testing.assert_array_equal(L[1], expected)  # every plane of the column
    iy, ix = stack.index_from_xy(np.array([0.0, 2.0]))
    assert L[0, iy, ix] == 0.0                       # the detected person
    iy2, ix2 = stack.index_from_xy(np.array([0.0, 3.0]))
    assert L[0, iy2, ix2] == 0.0                     # behind him: hidden, no evidence
    assert (L[0][~seen] == 0).all()                  # not seen: nothing
    # no frame (None): nothing; a frame without boxes: all the seen ground
    assert (box_evidence([cam], [None], stack, params, lookups=[lk]) == 0).all()
    np.testing.assert_array_equal(box_evidence([cam], [PersonBoxes.empty()], stack, params, lookups=[lk])[0],
                                  np.where(seen, -1.5, 0.0))
    with pytest.raises(ValueError, match="free_log_odds needs one lookup per camera"):
        box_evidence([cam], [PersonBoxes.empty()], stack, params)
    with pytest.raises(ValueError, match="free_log_odds must be <= 0"):
        BoxEvidenceParams(free_log_odds=0.5)


def test_each_detectors_default_box_evidence():
    """The documented defaults: YOLOX's boxes give foot points of log-odds 1 and -3 of free space, HOG's neither;
    a set value is kept; unresolved parameters are refused."""
    yolox = BoxEvidenceParams().for_detector("yolox")
    assert (yolox.log_odds, yolox.free_log_odds) == (1.0, -3.0) and yolox.active
    for other in ("hog", None):
        p = BoxEvidenceParams().for_detector(other)
        assert (p.log_odds, p.free_log_odds) == (0.0, 0.0) and not p.active
    kept = BoxEvidenceParams(log_odds=0.0, free_log_odds=-1.0).for_detector("yolox")
    assert (kept.log_odds, kept.free_log_odds) == (0.0, -1.0)
    with pytest.raises(ValueError, match="resolve log_odds and free_log_odds"):
        box_evidence([camera()], [None], PlaneStack.from_extent((0.1,), (0, 1), (0, 1), 0.1), BoxEvidenceParams())
    with pytest.raises(ValueError, match="resolve log_odds and free_log_odds"):
        box_evidence([camera()], [None], PlaneStack.from_extent((0.1,), (0, 1), (0, 1), 0.1),
                     BoxEvidenceParams(free_log_odds=0.0))