"""Known static occluders: the cells they hide from a camera (against the laser ray caster), exactly zero
evidence from that camera there, no evidence in the cells they fill, and the system's configuration."""

from __future__ import annotations

import numpy as np
import pytest

from planefuse.geometry import default_camera_ring
from planefuse.grid import Evidence, PlaneStack, cells_filled_by_occluders, cells_hidden_by_occluders
from planefuse.laser import HIT_BOX, raycast
from planefuse.pipeline import SystemParams
from planefuse.registration import CameraRegistration
from planefuse.tracking import EvidenceTracker, TrackingParams
from planefuse.vision import CameraFusion, CameraParams

STACK = PlaneStack.from_extent([0.1, 0.5, 1.0, 1.5], (0.0, 10.0), (0.0, 10.0), 0.1)
#: a pillar (2.8 m high) and a counter (1.1 m high) [x_min, x_max, y_min, y_max, z_min, z_max] [m]
# (not on the cell grid's lines: no ray exactly tangent to a box edge)
BOXES = np.array([[3.213, 3.817, 3.191, 3.793, 0.0, 2.8], [6.107, 7.911, 2.653, 3.347, 0.0, 1.1]])


@pytest.mark.parametrize("camera", range(4))
def test_hidden_cells_agree_with_the_laser_ray_caster(camera):
    """A cell is hidden iff a ray cast from the camera's centre towards the cell centre hits a box (the
    laser's slab intersection, an independent implementation) nearer than the cell."""
    cam = default_camera_ring()[camera]
    o = np.asarray(cam.center_world, dtype=float)
    hidden = cells_hidden_by_occluders(o, STACK, BOXES)
    p = STACK.cell_centers_world().reshape(-1, 3)
    dist = np.linalg.norm(p - o, axis=1)
    r, kind, _ = raycast(np.broadcast_to(o, p.shape), (p - o) / dist[:, None], None, None, (-50, 50, -50, 50),
                         0.0, 1e3, boxes=BOXES, return_hits=True)
    expected = (kind == HIT_BOX) & (r < dist)
    margin = np.abs(r - dist) > 1e-6  # a cell centre on a box face is either
    np.testing.assert_array_equal(hidden.reshape(-1)[margin], expected[margin])
    assert 0 < hidden.sum() < hidden.size / 2
    inside = cells_filled_by_occluders(STACK, BOXES)
    centres_inside = np.zeros(STACK.shape, bool)
    for b in BOXES:
        c = STACK.cell_centers_world()
        centres_inside |= np.all((c >= b[0::2]) & (c <= b[1::2]), axis=-1)
    assert hidden[centres_inside].all()  # a cell inside a box is hidden from every camera outside it
    assert inside[centres_inside].all()


def test_a_cell_in_front_of_an_occluder_is_not_hidden():
    box = np.array([[4.0, 5.0, -1.0, 1.0, 0.0, 2.0]])
    stack = PlaneStack.from_extent([0.5, 2.5], (0.0, 10.0), (-0.5, 0.5), 0.5)  # cell centres x 0.25..9.75, y 0
    hidden = cells_hidden_by_occluders([0.0, 0.0, 3.0], stack, box)
    x = stack.cell_centers_xy()[0, :, 0]
    # plane 0.5 m: the line of sight from (0, 0, 3) to (x, 0, 0.5) is below z = 2 from x = 1.2 x / 2.5 on; it
    # crosses the box (x 4..5) iff it reaches x = 5 below 2 m (x > 5 and 3 - 2.5 * 5 / x < 2), or the cell is in it
    z_at_5 = 3.0 - 2.5 * 5.0 / x
    np.testing.assert_array_equal(hidden[0, 0], ((x > 5.0) & (z_at_5 < 2.0)) | ((x > 4.0) & (x < 5.0)))
    assert not hidden[1].any()  # plane 2.5 m, above the box top, from a camera above it
    filled = cells_filled_by_occluders(stack, box)
    np.testing.assert_array_equal(filled[0, 0], (x + 0.25 > 4.0) & (x - 0.25 < 5.0))
    assert not filled[1].any()


def test_a_cell_hidden_by_an_occluder_gets_exactly_zero_evidence_from_that_camera():
    """Each camera alone, its whole image background (then foreground): the cells the occluders hide from it
    get exactly 0, every other cell it sees the sensor model's full free (occupied) evidence."""
    cams = default_camera_ring()
    reg = CameraRegistration(cams, STACK, occluder_boxes_m=BOXES)
    plain = CameraRegistration(cams, STACK)
    fusion = CameraFusion(reg.lookups_at(0.0), STACK)
    seen_without = CameraFusion(plain.lookups_at(0.0), STACK)
    for c, cam in enumerate(cams):
        hidden = cells_hidden_by_occluders(cam.center_world, STACK, BOXES)
        size = (cam.intrinsics.height_px, cam.intrinsics.width_px)
        one = [None] * len(cams)
        seen = seen_without.cameras_seeing(np.arange(len(cams)) == c) > 0
        assert (hidden & seen).sum() > 100
        for level, sign in ((0.0, -1), (1.0, 1)):
            one[c] = np.full(size, level, np.float32)
            lo = fusion.log_odds(one)
            assert np.all(lo[hidden] == 0.0)
            assert np.all(np.sign(lo[seen & ~hidden]) == sign)
            assert np.all(seen_without.log_odds(one)[hidden & seen] != 0.0)  # without: it was evidence


def test_cells_filled_by_an_occluder_hold_no_person_whatever_the_sensors_say():
    """A laser "hitting" the boxes' faces and everything around them: the cells a box fills stay free of
    people (the mass the prediction moves in from occupied neighbours included), the others fill up."""
    filled = cells_filled_by_occluders(STACK, BOXES)
    tr = EvidenceTracker(STACK, TrackingParams(window_s=0.0), static_cells=filled)
    for t in np.arange(10) * 0.1:
        list(tr.push(Evidence(float(t), "laser", np.full(STACK.shape, 2.0, np.float32))))
    occ, _ = tr.bof.moments()
    assert np.all(occ[filled] < 1e-3) and np.all(occ[~filled] > 0.9)
    with pytest.raises(ValueError, match="static_cells"):
        EvidenceTracker(STACK, static_cells=filled[:2])


def test_system_params_check_occluder_boxes():
    p = SystemParams(occluder_boxes_m=[[1, 2, 1, 2, 0, 1]])
    assert p.occluder_boxes_m == ((1.0, 2.0, 1.0, 2.0, 0.0, 1.0),)
    with pytest.raises(ValueError, match=r"SystemParams.occluder_boxes_m.*minimum must be below"):
        SystemParams(occluder_boxes_m=[[2, 1, 1, 2, 0, 1]])
    with pytest.raises(ValueError, match=r"SystemParams.occluder_boxes_m.*\(B, 6\)"):
        SystemParams(occluder_boxes_m=[[1, 2, 1, 2]])
    with pytest.raises(ValueError, match=r"SystemParams.occluder_boxes_m.*non-finite"):
        SystemParams(occluder_boxes_m=[[1, 2, 1, np.nan, 0, 1]])
    with pytest.raises(ValueError, match="per-cell sensor model"):
        SystemParams(occluder_boxes_m=[[1, 2, 1, 2, 0, 1]], camera_params=CameraParams(sensor_model="generative"))
    with pytest.raises(ValueError, match="inside occluder box"):
        cells_hidden_by_occluders([1.5, 1.5, 0.5], STACK, [[1, 2, 1, 2, 0, 1]])


def test_run_configuration_declares_the_occluders(tmp_path):
    from planefuse.config import ConfigError, load_config

    good = tmp_path / "run.yaml"
    good.write_text("recording: rec\nscene:\n  occluder_boxes_m:\n    - [3.2, 3.8, 3.2, 3.8, 0.0, 2.8]\n")
    assert load_config(good).system_params().occluder_boxes_m == ((3.2, 3.8, 3.2, 3.8, 0.0, 2.8),)
    bad = tmp_path / "bad.yaml"
    bad.write_text("recording: rec\nscene:\n  occluder_boxes_m:\n    - [3.8, 3.2, 3.2, 3.8, 0.0, 2.8]\n")
    with pytest.raises(ConfigError, match=r"bad.yaml:3: scene.occluder_boxes_m: boxes\[0\]"):
        load_config(bad)


def test_an_occluder_box_in_millimetres_is_refused_naming_the_field():
    """A box 1000x too far (millimetres in a metre configuration) would hide nothing, silently: refused."""
    from planefuse.grid import PlaneStack
    from planefuse.pipeline._system import check_occluders_against_stack

    stack = PlaneStack.from_extent((0.1, 1.0), (0.0, 10.0), (0.0, 8.0), 0.1)
    check_occluders_against_stack([(4.0, 4.5, 3.0, 3.5, 0.0, 2.0), (-20.0, -19.0, 0.0, 1.0, 0.0, 3.0)], stack)
    with pytest.raises(ValueError, match=r"scene\.occluder_boxes_m: box 1 .* millimetres"):
        check_occluders_against_stack([(4.0, 4.5, 3.0, 3.5, 0.0, 2.0),
                                       (4000.0, 4500.0, 3000.0, 3500.0, 0.0, 2000.0)], stack)
