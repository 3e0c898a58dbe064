"""Offline stitching: the tracklets' links chosen together (u-track's assignment with a new person's cost), their
cost as documented, tracklets cut where their colours change (the tracker's exchanges undone), the gaps within one
identity filled on the straight line, and its positions smoothed in time."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from planefuse.tracking import (StitchParams, TrackAppearance, Tracks, TrackViews, ViewDescriptors, fill_gaps,
                                fill_track_gaps, link_costs, relabel_tracks, smooth_positions, smooth_track_positions,
                                split_times, split_tracklets, stitch_identities, stitch_tracks)


def _app(weights) -> TrackAppearance:
    """A one-camera model whose two body parts have the histogram ``weights`` (4 bins, normalised here)."""
    h = np.asarray(weights, float)
    return TrackAppearance(np.tile(h / h.sum(), (1, 2, 1)), np.ones(1))


def _two_ends_two_starts():
    """Tracklets 1 and 2 end at t = 1 s at x = 0 and x = 3 m; 3 starts at x = 1.2 m and 4 at x = -1.4 m at t = 2 s,
    all in one colour. 3 is the nearest start to 1's end, but 4 is reachable from 1 alone and 3 from both."""
    return [(0.0, [1, 2], [[0.0, 0.0], [3.0, 0.0]]), (1.0, [1, 2], [[0.0, 0.0], [3.0, 0.0]]),
            (2.0, [3, 4], [[1.2, 0.0], [-1.4, 0.0]]), (3.0, [3, 4], [[1.2, 0.0], [-1.4, 0.0]])]


def test_links_chosen_together_where_the_cheapest_link_first_is_wrong():
    frames = _two_ends_two_starts()
    app = {i: _app([1, 0, 0, 0]) for i in (1, 2, 3, 4)}
    ids, cost = link_costs(frames, app)
    # reach 1 m + 1.5 m/s x 1 s = 2.5 m: 1 -> 3 (1.2 m) and 1 -> 4 (1.4 m), 2 -> 3 (1.8 m); 2 -> 4 (4.4 m) too far
    assert ids == [1, 2, 3, 4]
    assert np.isfinite(cost[0, 2]) and np.isfinite(cost[0, 3]) and np.isfinite(cost[1, 2])
    assert np.isinf(cost[1, 3])
    # taking the cheapest link first (1 -> 3) leaves 2 and 4 unlinked; together both people are continued
    assert cost[0, 2] < cost[0, 3] and cost[0, 2] < cost[1, 2]
    assert stitch_identities(frames, app) == {4: 1, 3: 2}


def test_a_link_costs_as_documented():
    # c = w (d - d0) + (r / R)^2 + gap / max_gap: d = 0.25 (Hellinger of two 4-bin histograms), r = 1.2 m, R = 2.5 m
    frames = _two_ends_two_starts()
    p, q = np.array([0.5, 0.5, 0, 0]), np.array([0.5, 0.25, 0.25, 0])
    app = {1: _app(p), 2: _app(p), 3: _app(q), 4: _app(p)}
    d = np.sqrt(1 - np.sum(np.sqrt(p * q)))
    params = StitchParams(appearance_weight=10.0, appearance_reference_distance=0.2, max_gap_s=4.0)
    _, cost = link_costs(frames, app, params)
    assert cost[0, 2] == pytest.approx(10.0 * (d - 0.2) + (1.2 / 2.5) ** 2 + 1.0 / 4.0)


def test_a_link_is_taken_only_where_cheaper_than_a_new_person():
    # one end, one start, colours 0.38 apart (within the 0.4 gate): a link costing c is taken iff c < new_person_cost
    frames = [(0.0, [1], [[0.0, 0.0]]), (1.0, [1], [[0.0, 0.0]]), (2.0, [2], [[0.5, 0.0]])]
    p, q = np.array([1.0, 0, 0, 0]), np.array([0.0, 1, 0, 0])
    w = 0.73  # Hellinger distance 0.38 between the mixtures
    app = {1: _app(p), 2: _app(w * p + (1 - w) * q)}
    _, cost = link_costs(frames, app)
    c = float(cost[0, 1])
    assert 0 < c < StitchParams().new_person_cost
    assert stitch_identities(frames, app) == {2: 1}
    assert stitch_identities(frames, app, StitchParams(new_person_cost=0.99 * c)) == {}
    assert stitch_identities(frames, app, StitchParams(new_person_cost=1.01 * c)) == {2: 1}
    # beyond the appearance gate: never, whatever a new person costs
    assert stitch_identities(frames, app, StitchParams(max_appearance_distance=0.3, new_person_cost=1e9)) == {}


def test_chains_take_the_first_identity_and_overlapping_tracklets_are_never_joined():
    frames = [(0.0, [1, 9], [[0.0, 0.0], [5.0, 5.0]]), (1.0, [2, 9], [[0.5, 0.0], [5.0, 5.0]]),
              (2.0, [3, 9], [[1.0, 0.0], [5.0, 5.0]])]
    app = {i: _app([1, 0, 0, 0]) for i in (1, 2, 3, 9)}
    mapping = stitch_identities(frames, app, StitchParams(max_gap_s=1.5))
    assert mapping == {2: 1, 3: 1}
    assert [ids.tolist() for _, ids, _ in relabel_tracks(frames, mapping)] == [[1, 9], [1, 9], [1, 9]]


def test_bad_stitching_parameters_are_refused():
    with pytest.raises(ValueError, match="new_person_cost"):
        StitchParams(new_person_cost=-1.0)
    with pytest.raises(ValueError, match="max_fill_gap_s"):
        StitchParams(max_fill_gap_s=0.0)
    with pytest.raises(ValueError, match="time order"):
        stitch_identities([(1.0, [1], [[0.0, 0.0]]), (0.0, [2], [[0.0, 0.0]])])


# -- gaps within one identity ----------------------------------------------------------------------------------------
def test_fill_gaps_places_the_identity_on_the_straight_line_within_the_longest_gap():
    frames = [(0.0, [1, 2], [[0.0, 0.0], [5.0, 5.0]]), (1.0, [2], [[5.0, 5.0]]), (2.0, [], np.zeros((0, 2))),
              (3.0, [1, 2], [[3.0, 6.0], [5.0, 5.0]]), (9.0, [1], [[0.0, 0.0]]), (10.0, [], np.zeros((0, 2))),
              (11.0, [1], [[0.0, 0.0]])]
    out = fill_gaps(frames, max_gap_s=3.0)
    assert [ids.tolist() for _, ids, _ in out] == [[1, 2], [2, 1], [1, 2], [1, 2], [1], [1], [1]]
    np.testing.assert_allclose(out[1][2][1], [1.0, 2.0])
    np.testing.assert_allclose(out[2][2], [[2.0, 4.0], [5.0, 5.0]])
    # 2 is reported at 0 s and 1 s (no step between), the 3 -> 9 s gap is longer than 3 s: nothing there
    assert fill_gaps(frames, max_gap_s=2.5)[1][1].tolist() == [2]
    with pytest.raises(ValueError, match="twice"):
        fill_gaps([(0.0, [1, 1], [[0.0, 0.0], [1.0, 1.0]])], 1.0)
    with pytest.raises(ValueError, match="max_gap_s"):
        fill_gaps(frames, 0.0)


def test_fill_track_gaps_marks_the_added_entries_unseen():
    def tracks(t, ids, xy):
        n = len(ids)
        return Tracks(t, np.array(ids, np.int64), np.array(xy, float).reshape(-1, 2), np.zeros((n, 2)),
                      np.full(n, 1.7), np.ones(n), np.zeros(n, np.int64))

    got = fill_track_gaps([tracks(0.0, [4], [[0.0, 0.0]]), tracks(0.5, [], []), tracks(1.0, [], []),
                           tracks(1.5, [4], [[3.0, 0.0]])], max_gap_s=2.0)
    mid = got[2]
    assert mid.ids.tolist() == [4]
    np.testing.assert_allclose(mid.xy_m, [[2.0, 0.0]])
    np.testing.assert_allclose(mid.velocity_m_s, [[2.0, 0.0]])
    assert np.isnan(mid.height_m[0]) and mid.confidence[0] == 0.0 and mid.misses.tolist() == [2]
    assert got[0] is not None and got[0].height_m.tolist() == [1.7]


@settings(max_examples=40, deadline=None)
@given(st.lists(st.tuples(st.integers(0, 3), st.floats(-5, 5), st.floats(-5, 5)), min_size=1, max_size=30),
       st.floats(0.2, 6.0))
def test_fill_gaps_keeps_every_report_and_adds_only_points_between_two_of_them(reports, max_gap_s):
    # reports: (identity, x, y) at steps 0, 1, 2, ... (0.5 s apart), at most one identity per step here
    frames = [(0.5 * k, [i], [[x, y]]) for k, (i, x, y) in enumerate(reports)]
    out = fill_gaps(frames, max_gap_s)
    for (t, ids, xy), (t2, ids2, xy2) in zip(frames, out):
        assert t2 == t and ids2[:1].tolist() == ids and np.array_equal(xy2[:1], np.asarray(xy, float))
        for i, q in zip(ids2[1:], xy2[1:]):
            steps = [k for k, r in enumerate(reports) if r[0] == i]
            k = int(round(t / 0.5))
            k0, k1 = max(s for s in steps if s < k), min(s for s in steps if s > k)
            assert 0.5 * (k1 - k0) <= max_gap_s + 1e-9
            a, b = np.array(reports[k0][1:]), np.array(reports[k1][1:])
            np.testing.assert_allclose(q, a + (b - a) * (k - k0) / (k1 - k0), atol=1e-9)


# -- smoothing in time -----------------------------------------------------------------------------------------------
def test_smoothing_is_the_gaussian_weighted_mean_of_the_identity_s_own_positions_within_three_sigma():
    # identity 1 at t = 0, 1, 2, 5 s; identity 2 beside it (never mixed in); sigma 1 s: t = 5 is beyond 3 sigma of 0, 1
    frames = [(0.0, [1, 2], [[0.0, 0.0], [9.0, 9.0]]), (1.0, [1, 2], [[1.0, 3.0], [-9.0, 9.0]]),
              (2.0, [1], [[4.0, 0.0]]), (5.0, [1], [[7.0, 7.0]])]
    out = smooth_positions(frames, sigma_s=1.0)
    w = np.exp(-0.5 * np.array([1.0, 0.0, 1.0]))  # around t = 1: the points at 0, 1, 2 s
    expected = (w[0] * np.array([0.0, 0.0]) + w[1] * np.array([1.0, 3.0]) + w[2] * np.array([4.0, 0.0])) / w.sum()
    np.testing.assert_allclose(out[1][2][0], expected)
    w5 = np.exp(-0.5 * np.array([9.0, 0.0]))  # around t = 5: t = 2 (3 sigma away) and itself
    np.testing.assert_allclose(out[3][2][0], (w5[0] * np.array([4.0, 0.0]) + w5[1] * np.array([7.0, 7.0])) / w5.sum())
    e = np.exp(-0.5)  # identity 2 at t = 0: its own two positions alone (9 and -9 in x), 1 s apart
    np.testing.assert_allclose(out[0][2][1], [(9.0 - 9.0 * e) / (1.0 + e), 9.0])
    assert [ids.tolist() for _, ids, _ in out] == [[1, 2], [1, 2], [1], [1]]
    with pytest.raises(ValueError, match="sigma_s"):
        smooth_positions(frames, 0.0)


@settings(max_examples=30, deadline=None)
@given(st.floats(-3, 3), st.floats(-3, 3), st.floats(-2, 2), st.floats(-2, 2), st.floats(0.1, 1.0))
def test_smoothing_leaves_a_walk_at_constant_speed_where_the_kernel_is_whole(x0, y0, vx, vy, sigma_s):
    dt = 0.2
    t = dt * np.arange(41)
    frames = [(float(tk), [7], [[x0 + vx * tk, y0 + vy * tk]]) for tk in t]
    out = smooth_positions(frames, sigma_s)
    inner = (t >= t[0] + 3 * sigma_s + dt) & (t <= t[-1] - 3 * sigma_s - dt)
    for k in np.flatnonzero(inner):
        np.testing.assert_allclose(out[k][2][0], frames[k][2][0], atol=1e-9)


def test_smooth_track_positions_changes_the_positions_alone():
    tr = [Tracks(float(k), np.array([3], np.int64), np.array([[float(k % 2), 0.0]]), np.ones((1, 2)),
                 np.array([1.8]), np.array([0.9]), np.array([0], np.int64)) for k in range(5)]
    out = smooth_track_positions(tr, 1.0)
    assert all(o.velocity_m_s.tolist() == [[1.0, 1.0]] and o.height_m.tolist() == [1.8] for o in out)
    assert 0.0 < out[2].xy_m[0, 0] < 1.0


# -- cutting tracklets where their colours change --------------------------------------------------------------------
def _views_of(track_colours: dict[int, list[int]], dt: float = 0.2, rng=None) -> TrackViews:
    """A view log: track ``i`` took, at steps 0, 1, ... (``dt`` apart), one view per step of the colour (a bin
    index of 4) listed, in two cameras, with small seeded noise."""
    rng = rng if rng is not None else np.random.default_rng(0)
    views = TrackViews()
    n = max(len(c) for c in track_colours.values())
    for k in range(n):
        for i, colours in sorted(track_colours.items()):
            if k < len(colours):
                h = np.full((2, 2, 4), 0.02) + rng.uniform(0, 0.02, (2, 2, 4))
                h[:, :, colours[k]] += 1.0
                views.add(k * dt, i, ViewDescriptors(h[None] / h.sum(-1, keepdims=True)[None], np.ones((1, 2), bool)),
                          0)
    return views


def test_a_tracklet_is_cut_where_its_views_change_colour_and_nowhere_else():
    views = _views_of({1: [0] * 20 + [2] * 20, 2: [1] * 40, 3: [0] * 6 + [2] * 3})
    cuts = split_times(views, window_s=2.0, min_distance=0.35, min_views=5)
    assert cuts[1] == [pytest.approx(20 * 0.2)]  # the first view of the new colours
    assert cuts[2] == []
    assert cuts[3] == []  # 3 views after the change: fewer than min_views
    assert split_times(views, window_s=2.0, min_distance=0.99, min_views=5)[1] == []
    with pytest.raises(ValueError, match="window_s"):
        split_times(views, 0.0, 0.35, 5)


def test_two_people_exchanged_by_the_tracker_get_their_own_identities_back():
    # A walks along y = 0 in colour 0, B along y = 1 in colour 2 (0.5 m/s); at t = 4 s the tracker exchanged them:
    # track 1 follows A then B, track 2 B then A
    dt, n, swap = 0.2, 40, 20
    t = dt * np.arange(n)
    a_xy = np.stack([0.5 * t, np.zeros(n)], axis=1)
    b_xy = np.stack([0.5 * t, np.ones(n)], axis=1)
    frames = [(float(t[k]), [1, 2], [a_xy[k], b_xy[k]] if k < swap else [b_xy[k], a_xy[k]]) for k in range(n)]
    views = _views_of({1: [0] * swap + [2] * (n - swap), 2: [2] * swap + [0] * (n - swap)})
    params = StitchParams(split_window_s=2.0, slack_m=1.5)
    _, out = stitch_tracks(frames, {}, views, params)
    person_a = {int(ids[np.argmin(np.abs(xy[:, 1]))]) for _, ids, xy in out}
    person_b = {int(ids[np.argmax(xy[:, 1])]) for _, ids, xy in out}
    assert len(person_a) == 1 and len(person_b) == 1 and person_a != person_b
    # without the cutting the exchange stays
    _, kept = stitch_tracks(frames, {}, views, StitchParams(split_window_s=None, slack_m=1.5))
    assert len({int(ids[np.argmin(np.abs(xy[:, 1]))]) for _, ids, xy in kept}) == 2


@settings(max_examples=30, deadline=None)
@given(st.integers(0, 2**31 - 1))
def test_finalized_tracks_give_the_cuts_and_pieces_of_their_views(seed):
    # an identity that ended is reduced to its cuts and its pieces' means: the offline pass cannot tell the difference
    rng = np.random.default_rng(seed)
    colours = {i: [int(c) for c in np.repeat(rng.integers(0, 4, 3), rng.integers(1, 15, 3))] for i in (1, 2, 3, 4)}
    split = (2.0, 0.35, 5)
    whole, reduced = _views_of(colours, rng=np.random.default_rng(seed)), _views_of(colours,
                                                                                  rng=np.random.default_rng(seed))
    reduced.split = split
    for i in rng.permutation(4)[:rng.integers(1, 5)]:
        reduced.finalize(int(i + 1))
    assert len(reduced.track_id) < len(whole.track_id) and len(reduced) == len(whole)
    cuts = split_times(whole, *split)
    assert split_times(reduced, *split) == cuts
    frames = [(0.2 * k, [1, 2, 3, 4], np.zeros((4, 2))) for k in range(max(map(len, colours.values())))]
    got, want = split_tracklets(frames, reduced, cuts), split_tracklets(frames, whole, cuts)
    assert got[2] == want[2] and set(got[1]) == set(want[1])
    for j, app in want[1].items():
        np.testing.assert_allclose(got[1][j].hist, app.hist, atol=1e-12)
        np.testing.assert_array_equal(got[1][j].count, app.count)
    # a finalized identity takes no more views, and its cuts hold for the settings that made them only
    with pytest.raises(ValueError, match="was finalized"):
        reduced.add(99.0, next(iter(reduced.final)), ViewDescriptors(np.ones((1, 2, 2, 4)) / 4, np.ones((1, 2), bool)),
                    0)
    with pytest.raises(ValueError, match="finalized with the cutting"):
        split_times(reduced, 3.0, 0.35, 5)


def test_a_cut_that_nobody_takes_over_is_undone():
    # one person whose colours change (a new side, another light) and nobody else: one identity throughout
    frames = [(0.2 * k, [4], [[0.1 * k, 0.0]]) for k in range(40)]
    views = _views_of({4: [0] * 20 + [2] * 20})
    assert split_times(views, 2.0, 0.35, 5)[4]  # it is cut...
    _, out = stitch_tracks(frames, {}, views, StitchParams(split_window_s=2.0))
    assert {int(i) for _, ids, _ in out for i in ids} == {4}  # ...and joined again
    cut, _, pieces = split_tracklets(frames, views, {4: [4.0]})
    assert pieces == {4: [4, 5]} and [int(ids[0]) for _, ids, _ in cut] == [4] * 20 + [5] * 20


def test_a_run_into_a_folder_writes_the_stitched_tracks_a_run_in_memory_returns(tmp_path):
    # the offline pass with every step (cutting, association, filling, smoothing): tracks_stitched.csv, made from
    # the tables read back, holds exactly the tracks run_system gives
    from dataclasses import replace

    from planefuse.outputs import OutputSettings
    from planefuse.pipeline import RunPlan, SystemParams, run_system, run_to_folder
    from planefuse.sim import default_scene_config, simulate

    rec = simulate(default_scene_config(duration_s=3.0, seed=2))
    base = SystemParams(laser=False, sound=False)
    params = replace(base, tracking=replace(base.tracking, tracker=replace(
        base.tracking.tracker, appearance_weight=8.0, reid_max_s=5.0)), stitch=StitchParams(
        enabled=True, max_fill_gap_s=1.0, smooth_sigma_s=0.3, split_window_s=1.0))
    settings = OutputSettings(zarr=False, figures=False, animation="none", report=False)
    run_to_folder(rec, RunPlan(params, tmp_path / "run", settings), progress_mode="quiet")
    rows = np.loadtxt(tmp_path / "run" / "tracks_stitched.csv", delimiter=",", skiprows=1, ndmin=2)
    result = run_system(rec, params)
    expected = [(k, o.time_s, i, q) for k, o in enumerate(result.outputs) for i, q in zip(o.tracks.ids, o.tracks.xy_m)]
    assert len(rows) == len(expected) > 0
    np.testing.assert_array_equal(rows[:, [0, 2]], [[k, i] for k, _, i, _ in expected])
    np.testing.assert_allclose(rows[:, 3:5], [q for *_, q in expected], rtol=0, atol=1e-12)


def test_a_run_reduces_the_views_of_ended_tracks_and_stitches_the_same(monkeypatch):
    # the tracker finalizes an identity once it has ended for good (dropped, or past re-identification): a run's
    # stitched tracks are those of a run that kept every view
    from dataclasses import replace

    from planefuse.pipeline import SystemParams, SystemRun, run_system
    from planefuse.sim import scenario_config, simulate

    rec = simulate(scenario_config("crowd", seed=1, duration_s=8.0))
    base = SystemParams(laser=False, sound=False)
    params = replace(base, tracking=replace(base.tracking, tracker=replace(
        base.tracking.tracker, appearance_weight=16.0, reid_max_s=1.0)), stitch=StitchParams(enabled=True))
    reduced = SystemRun(rec, params)
    outputs = list(reduced.outputs())
    log = reduced.tracker.tracker.view_log
    assert log.final and len(log.track_id) < len(log)  # ended identities were reduced
    _, got = reduced.stitch([(o.time_s, o.tracks.ids, o.tracks.xy_m) for o in outputs])
    monkeypatch.setattr(TrackViews, "finalize", lambda self, track_id: None)
    kept = run_system(rec, params)
    assert len(got) == len(kept.outputs)
    for (t, ids, xy), o in zip(got, kept.outputs):
        assert t == o.time_s
        np.testing.assert_array_equal(ids, o.tracks.ids)
        np.testing.assert_array_equal(xy, o.tracks.xy_m)
