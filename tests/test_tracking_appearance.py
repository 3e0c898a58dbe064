"""Appearance of tracks from every camera: the descriptor distance, views hidden by nearer people, identities kept
through a bounce-back crossing by colour, a person hidden for 3 s re-identified, appearance off changes nothing."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from planefuse.eval import tracking_metrics
from planefuse.geometry import default_camera_ring
from planefuse.occupancy import silhouettes_from_cameras
from planefuse.tracking import (AppearanceObserver, AppearanceParams, Clusters, MultiPersonTracker, StitchParams,
                                TrackAppearance, TrackerParams, describe_positions, descriptor_distance, relabel_tracks,
                                stitch_identities)

CAMERAS = default_camera_ring(2, room_size_m=8.0)[:2]  # at (0.3, 0.3) and (7.7, 0.3), 3 m and 2.8 m up
PARAMS = AppearanceParams()
DT = 0.2
#: (torso, legs) BGR of each simulated person
COLOURS = {1: ((40, 40, 200), (150, 60, 30)), 2: ((60, 170, 60), (40, 40, 40)), 3: ((200, 120, 40), (200, 200, 200))}
ON = dict(appearance_weight=8.0, reid_max_s=5.0)


def render(xy_m: np.ndarray, people: list[int], rng: np.random.Generator) -> list[np.ndarray]:
    """Each camera's frame (H, W, 3) uint8 BGR of people ``people`` standing at ``xy_m`` (N, 2): the person
    volume's box, torso colour over its upper half and leg colour below, drawn far to near (nearer people hide
    farther ones), on a noisy grey floor."""
    boxes = silhouettes_from_cameras(CAMERAS, np.asarray(xy_m, float).reshape(-1, 2), PARAMS.person()).boxes_px
    out = []
    for c, cam in enumerate(CAMERAS):
        img = rng.normal(128, 6, (cam.intrinsics.height_px, cam.intrinsics.width_px, 3)).clip(0, 255).astype(np.uint8)
        depth = np.hypot(*(np.asarray(xy_m, float).reshape(-1, 2) - cam.center_world[:2]).T)
        for i in np.argsort(-depth):
            x0, y0, x1, y1 = boxes[c, i]
            if x0 < 0:
                continue
            w = x1 - x0 + 1
            xa, xb = x0 + w // 5, x1 - w // 5 + 1  # the body, narrower than the cylinder's box
            ym = (y0 + y1) // 2
            img[y0:ym, xa:xb] = COLOURS[people[i]][0]
            img[ym:y1 + 1, xa:xb] = COLOURS[people[i]][1]
        out.append(img)
    return out


def clusters_at(t: float, xy_m: np.ndarray) -> Clusters:
    """Position-only clusters (no velocity information) at ``xy_m`` (N, 2)."""
    xy = np.asarray(xy_m, float).reshape(-1, 2)
    n = len(xy)
    return Clusters(t, xy, np.zeros((n, 2)), np.full(n, 1.75), np.ones(n), np.zeros((0, 0)))


def run(frames: list, tracker_params: TrackerParams) -> list:
    """Tracker outputs over ``frames``: (t, people ids (N,), people xy (N, 2), cluster xy (M, 2)) per step."""
    tracker = MultiPersonTracker(tracker_params, extent_m=(0.0, 8.0, 0.0, 8.0))
    observer = AppearanceObserver(CAMERAS, PARAMS)
    tracker.observer = observer
    rng = np.random.default_rng(0)
    outs = []
    for t, ids, xy, cl in frames:
        observer.add_frames(t, render(xy, list(ids), rng))
        outs.append(tracker.step(clusters_at(t, cl)))
    return outs


# -- the descriptor distance ------------------------------------------------------------------------------------------
hist = arrays(np.float64, (2, 8), elements=st.floats(0.0, 1.0, allow_nan=False)).filter(
    lambda h: np.all(h.sum(axis=1) > 1e-6)).map(lambda h: h / h.sum(axis=1, keepdims=True))


@settings(max_examples=60, deadline=None)
@given(hist, hist)
def test_descriptor_distance_is_zero_on_itself_symmetric_and_in_0_1(p, q):
    assert descriptor_distance(p, p) == pytest.approx(0.0, abs=1e-6)
    assert descriptor_distance(p, q) == pytest.approx(descriptor_distance(q, p), abs=1e-12)
    assert 0.0 <= descriptor_distance(p, q) <= 1.0


def test_descriptor_distance_is_one_for_disjoint_histograms_and_refuses_other_shapes():
    p, q = np.zeros((2, 4)), np.zeros((2, 4))
    p[:, 0], q[:, 1] = 1.0, 1.0
    assert descriptor_distance(p, q) == pytest.approx(1.0)
    with pytest.raises(ValueError, match="shape"):
        descriptor_distance(np.ones((3, 4)), np.ones((3, 4)))


# -- which views are taken --------------------------------------------------------------------------------------------
def test_a_person_hidden_behind_a_nearer_one_in_one_view_is_described_from_the_other_view_only():
    # both on the line from camera 0's centre: the far one is hidden in camera 0, the two stand apart in camera 1
    c0 = CAMERAS[0].center_world[:2]
    direction = (np.array([4.0, 4.0]) - c0) / np.linalg.norm(np.array([4.0, 4.0]) - c0)
    xy = np.array([c0 + 3.5 * direction, c0 + 6.0 * direction])
    imgs = render(xy, [1, 2], np.random.default_rng(1))
    views = describe_positions(imgs, CAMERAS, xy, PARAMS)
    assert views.valid[0].all()  # the near person: both views
    assert not views.valid[1, 0] and views.valid[1, 1]  # the far person: camera 1 only
    alone = describe_positions(render(xy[1:], [2], np.random.default_rng(1)), CAMERAS, xy[1:], PARAMS)
    # what camera 1 gives of the far person is its own colours (as when it stands alone)
    assert descriptor_distance(views.hist[1, 1], alone.hist[0, 1]) < 0.15
    # an ignore region over camera 1's view of the far person removes that view too
    mask = np.zeros((288, 360), bool)
    x0, y0, x1, y1 = silhouettes_from_cameras(CAMERAS, xy[1:], PARAMS.person()).boxes_px[1, 0]
    mask[y0:y1 + 1, x0:x1 + 1] = True
    assert not describe_positions(imgs, CAMERAS, xy, PARAMS, [None, mask]).valid[1].any()


def test_a_person_behind_a_declared_pillar_is_not_described_from_that_camera():
    c0 = CAMERAS[0].center_world[:2]
    direction = (np.array([4.0, 4.0]) - c0) / np.linalg.norm(np.array([4.0, 4.0]) - c0)
    person, pillar = c0 + 6.0 * direction, c0 + 3.5 * direction
    box = (pillar[0] - 0.3, pillar[0] + 0.3, pillar[1] - 0.3, pillar[1] + 0.3, 0.0, 2.5)
    imgs = render(person[None], [1], np.random.default_rng(2))  # the pillar is not drawn: only declared
    free = AppearanceObserver(CAMERAS)
    hidden = AppearanceObserver(CAMERAS, occluder_boxes_m=[box])
    for obs in (free, hidden):
        obs.add_frames(0.0, imgs)
    assert free(0.0, person[None]).valid[0].all()
    assert hidden(0.0, person[None]).valid[0].tolist() == [False, True]
    assert not free(1.0, person[None]).valid.any()  # no frame near t = 1 s: no view


def test_a_track_takes_no_appearance_from_the_view_where_it_is_hidden():
    c0 = CAMERAS[0].center_world[:2]
    direction = (np.array([4.0, 4.0]) - c0) / np.linalg.norm(np.array([4.0, 4.0]) - c0)
    near, far = c0 + 3.5 * direction, c0 + 6.0 * direction
    frames = [(k * DT, [1, 2], np.array([near, far]), np.array([near, far])) for k in range(10)]
    tracker = MultiPersonTracker(TrackerParams(**ON), extent_m=(0.0, 8.0, 0.0, 8.0))
    tracker.observer = AppearanceObserver(CAMERAS, PARAMS)
    rng = np.random.default_rng(0)
    for t, ids, xy, cl in frames:
        tracker.observer.add_frames(t, render(xy, ids, rng))
        tracker.step(clusters_at(t, cl))
    by_xy = {int(np.argmin(np.linalg.norm(np.array([near, far]) - tr.x[:2], axis=1))): tr for tr in tracker.tracks}
    assert by_xy[0].app.count.tolist() == [10, 10]
    assert by_xy[1].app.count[0] == 0 and by_xy[1].app.count[1] == 10


# -- identities -------------------------------------------------------------------------------------------------------
def _bounce(t: float) -> np.ndarray:
    """Person 1 walks +x and person 2 -x at 1 m/s, 0.3 m apart in y; they meet at x = 4 at t = 2 s, stand together
    for 0.6 s, and each walks back the way it came."""
    s = np.where(t < 2.0, 2.0 - t, np.where(t < 2.6, 0.0, t - 2.6))
    return np.array([[4.0 - s, 4.0], [4.0 + s, 4.3]])


def _bounce_frames() -> list:
    frames = []
    for k in range(int(5.0 / DT)):
        t = k * DT
        xy = _bounce(t)
        merged = np.linalg.norm(xy[0] - xy[1]) < 0.8
        frames.append((t, np.array([1, 2]), xy, xy.mean(axis=0, keepdims=True) if merged else xy))
    return frames


def _metrics(frames, outs) -> dict:
    return tracking_metrics([(t, ids, xy) for t, ids, xy, _ in frames], outs)


def test_two_people_of_different_colours_meeting_and_turning_back_keep_their_identities():
    frames = _bounce_frames()
    assert sum(len(cl) == 1 for *_, cl in frames) >= 4  # one merged blob for most of a second
    blind = _metrics(frames, run(frames, TrackerParams()))
    assert blind["num_switches"] >= 1  # position and velocity alone carry each track on past the other person
    seen = _metrics(frames, run(frames, TrackerParams(**ON)))
    assert seen["num_switches"] == 0
    assert seen["idf1"] > blind["idf1"]


def _hidden_frames(hidden_s: float = 3.0, newcomer: bool = False) -> list:
    """Person 1 walks +y at 0.5 m/s on x = 3 for 7 s, hidden (no cluster, no box) from 2 s for ``hidden_s``; person
    2 stands at (6, 5). ``newcomer``: person 3, other colours, appears at person 1's last position while it is
    hidden."""
    frames = []
    for k in range(int(7.0 / DT)):
        t = k * DT
        p1 = np.array([3.0, 2.0 + 0.5 * t])
        ids, xy = [2], [np.array([6.0, 5.0])]
        if not 2.0 <= t < 2.0 + hidden_s:
            ids, xy = [1, 2], [p1, xy[0]]
        elif newcomer and t >= 3.0:
            ids, xy = [3, 2], [np.array([3.2, 3.0]), xy[0]]
        xy = np.array(xy)
        frames.append((t, np.array(ids), xy, xy))
    return frames


def _ids_of(frames, outs, person: int) -> set[int]:
    """Track identities reported within 0.5 m of ``person``."""
    got = set()
    for (t, ids, xy, _), o in zip(frames, outs):
        if person in ids and len(o.ids):
            d = np.linalg.norm(o.xy_m - xy[list(ids).index(person)], axis=1)
            got |= {int(o.ids[np.argmin(d)])} if d.min() < 0.5 else set()
    return got


def test_a_person_hidden_for_3_s_is_re_identified():
    frames = _hidden_frames()
    assert len(_ids_of(frames, run(frames, TrackerParams()), 1)) == 2  # a new identity after the gap
    assert len(_ids_of(frames, run(frames, TrackerParams(**ON)), 1)) == 1
    # not when the gap is longer than reid_max_s
    assert len(_ids_of(frames, run(frames, TrackerParams(**{**ON, "reid_max_s": 2.0})), 1)) == 2


def test_a_newcomer_of_other_colours_does_not_take_a_hidden_person_s_identity():
    frames = _hidden_frames(newcomer=True)
    outs = run(frames, TrackerParams(**ON))
    assert not _ids_of(frames, outs, 1) & _ids_of(frames, outs, 3)


def test_appearance_off_gives_the_tracker_s_outputs_and_state_without_it():
    frames = _bounce_frames() + [(5.0 + k * DT, *f[1:]) for k, f in enumerate(_hidden_frames())]
    plain = MultiPersonTracker(TrackerParams(), extent_m=(0.0, 8.0, 0.0, 8.0))
    outs = run(frames, TrackerParams())  # an observer is attached, but nothing asks it
    for (t, _, _, cl), o in zip(frames, outs):
        ref = plain.step(clusters_at(t, cl))
        assert np.array_equal(ref.ids, o.ids) and np.array_equal(ref.xy_m, o.xy_m)
    assert not any(k.startswith(("app_", "lost_", "by_id")) for k in plain.state_dict())


def test_tracker_state_with_appearance_round_trips():
    frames = _hidden_frames(newcomer=True)
    a = MultiPersonTracker(TrackerParams(**ON), extent_m=(0.0, 8.0, 0.0, 8.0))
    a.observer = AppearanceObserver(CAMERAS, PARAMS)
    rng = np.random.default_rng(0)
    for t, ids, xy, cl in frames[:20]:
        a.observer.add_frames(t, render(xy, list(ids), rng))
        a.step(clusters_at(t, cl))
    b = MultiPersonTracker(TrackerParams(**ON), extent_m=(0.0, 8.0, 0.0, 8.0))
    b.observer = a.observer
    b.load_state_dict(a.state_dict())
    for t, ids, xy, cl in frames[20:]:
        a.observer.add_frames(t, render(xy, list(ids), rng))
        ra, rb = a.step(clusters_at(t, cl)), b.step(clusters_at(t, cl))
        assert np.array_equal(ra.ids, rb.ids) and np.allclose(ra.xy_m, rb.xy_m)
    assert a.appearance_summary(PARAMS) == b.appearance_summary(PARAMS)
    words = a.appearance_summary(PARAMS, ["c0", "c1"])
    # person 1 (red shirt, blue trousers) and person 2 (green shirt, black trousers) in words
    assert any("upper red" in w and "lower blue" in w for w in words.values()), words
    assert any("upper green" in w and "lower black" in w for w in words.values()), words


@pytest.mark.parametrize("field, value", [("appearance_weight", -1.0), ("appearance_update_rate", 0.0),
                                          ("reid_max_appearance_distance", 1.5), ("reid_max_s", -2.0)])
def test_bad_appearance_parameters_are_refused(field, value):
    with pytest.raises(ValueError, match=f"TrackerParams.{field}"):
        replace(TrackerParams(), **{field: value})


def test_bad_appearance_extraction_parameters_are_refused():
    with pytest.raises(ValueError, match="AppearanceParams.upper_rows"):
        AppearanceParams(upper_rows=(0.6, 0.4))
    with pytest.raises(ValueError, match="expected 2 images"):
        AppearanceObserver(CAMERAS).add_frames(0.0, [None])


# -- offline stitching ------------------------------------------------------------------------------------------------
def _app(colour: int) -> TrackAppearance:
    h = np.zeros((1, 2, 4))
    h[0, :, colour] = 1.0
    return TrackAppearance(h, np.ones(1))


def test_stitching_joins_a_tracklet_to_its_continuation_by_time_space_and_appearance():
    # 1 ends at (2, 2) at t = 1 s; 3 starts at (2.5, 2) at t = 2 s in 1's colours; 4 starts there too, other colours;
    # 2 is alive all along (never joined: it overlaps everyone)
    frames = [(0.0, [1, 2], [[1.0, 2.0], [5.0, 5.0]]), (1.0, [1, 2], [[2.0, 2.0], [5.0, 5.0]]),
              (2.0, [2, 3, 4], [[5.0, 5.0], [2.5, 2.0], [2.6, 2.4]]), (3.0, [2, 3, 4], [[5.0, 5.0], [3.0, 2.0],
                                                                                [3.0, 2.4]])]
    app = {1: _app(0), 2: _app(0), 3: _app(0), 4: _app(1)}
    assert stitch_identities(frames, app) == {3: 1}
    assert [list(ids) for _, ids, _ in relabel_tracks(frames, {3: 1})] == [[1, 2], [1, 2], [2, 1, 4], [2, 1, 4]]
    # a gap longer than max_gap_s, a jump farther than slack + speed x gap, no appearance: not joined
    assert stitch_identities(frames, app, StitchParams(max_gap_s=0.5)) == {}
    assert stitch_identities(frames, app, StitchParams(slack_m=0.1, max_speed_m_s=0.2)) == {}
    assert stitch_identities(frames, {}) == {}
    assert stitch_identities(frames, {}, StitchParams(require_appearance=False)) in ({3: 1}, {4: 1})


def test_stitching_a_run_without_re_identification_joins_the_hidden_person_s_tracklets():
    frames = _hidden_frames()
    tracker = MultiPersonTracker(TrackerParams(appearance_weight=8.0), extent_m=(0.0, 8.0, 0.0, 8.0))
    tracker.observer = AppearanceObserver(CAMERAS, PARAMS)
    rng = np.random.default_rng(0)
    outs = []
    for t, ids, xy, cl in frames:
        tracker.observer.add_frames(t, render(xy, list(ids), rng))
        outs.append(tracker.step(clusters_at(t, cl)))
    assert len(_ids_of(frames, outs, 1)) == 2
    stitched = relabel_tracks(outs, stitch_identities(outs, tracker.appearance_by_id))
    got = [type(o)(t, ids, xy, o.velocity_m_s, o.height_m, o.confidence, o.misses)
           for o, (t, ids, xy) in zip(outs, stitched)]
    assert len(_ids_of(frames, got, 1)) == 1


def test_a_run_with_appearance_and_stitching_explains_its_identities(tmp_path):
    import json

    from planefuse.outputs import OutputSettings
    from planefuse.pipeline import RunPlan, SystemParams, run_to_folder
    from planefuse.sim import default_scene_config, simulate

    rec = simulate(default_scene_config(duration_s=3.0, seed=2))
    base = SystemParams(laser=False, sound=False)
    params = replace(base, tracking=replace(base.tracking, tracker=replace(base.tracking.tracker, **ON)),
                     stitch=replace(base.stitch, enabled=True))
    settings = OutputSettings(zarr=False, figures=False, animation="none", report=False)
    _, metrics = run_to_folder(rec, RunPlan(params, tmp_path / "run", settings), progress_mode="quiet")
    saved = json.loads((tmp_path / "run" / "metrics.json").read_text())
    assert saved["track_appearance"] and all("views" in v for v in saved["track_appearance"].values())
    assert isinstance(saved["id_switch_events"], dict) and len(saved["id_switch_events"]) == saved["id_switches"]
    # the labelled bounds: no joining of whole tracks beats the first, the run's own IDF1 stays under it
    assert saved["idf1"] <= saved["idf1_max_tracklets"] + 1e-12 and 0 < saved["idf1_max_detections"] <= 1
    assert set(saved["stitched"]) == {"mota", "idf1", "id_switches", "idf1_max_tracklets", "idf1_max_detections"}
    assert (tmp_path / "run" / "tracks_stitched.csv").read_text().startswith("step,time_s,track_id,x_m,y_m")
    # the stitched tracks in MOTChallenge rows, as tracks_mot.txt: the same positions and identities, read back
    import motmetrics as mm

    csv = np.genfromtxt(tmp_path / "run" / "tracks_stitched.csv", delimiter=",", names=True)
    mot = mm.io.loadtxt(tmp_path / "run" / "tracks_stitched_mot.txt", fmt="mot15-2D")
    assert len(mot) == len(csv)
    np.testing.assert_array_equal(mot.index.get_level_values("FrameId"), csv["step"] + 1)
    np.testing.assert_array_equal(mot.index.get_level_values("Id"), csv["track_id"])
    # the footprint's centre (motmetrics' loader takes MOTChallenge's 1-based pixel origin off the box: + 1)
    np.testing.assert_allclose(mot["X"] + 1 + mot["Width"] / 2, csv["x_m"], atol=1e-4)
    np.testing.assert_allclose(mot["Y"] + 1 + mot["Height"] / 2, csv["y_m"], atol=1e-4)


def test_the_camera_source_hands_no_black_or_frozen_frame_to_the_appearance():
    from planefuse.pipeline._streams import _tapped

    live = np.random.default_rng(3).integers(0, 255, (288, 360, 3), dtype=np.uint8)
    black = np.zeros_like(live)
    frames = [(0.0, [live, live.copy()]), (0.2, [black, live.copy()]), (0.4, [live, None])]
    got = []
    assert [t for t, _ in _tapped(iter(frames), lambda t, imgs: got.append(imgs))] == [0.0, 0.2, 0.4]
    # camera 1 frozen at 0.2 s (bit-identical to its previous frame), camera 0 black; then camera 1 missing
    assert [[img is not None for img in imgs] for imgs in got] == [[True, True], [False, False], [True, False]]
