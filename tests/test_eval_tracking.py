"""Tracking metrics (motmetrics) on ground positions: analytic cases."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from planefuse.eval import tracking_metrics
from planefuse.tracking import Tracks

T = np.arange(20) * 0.1


def _gt():
    return [(t, [10, 20], [[t, 0.0], [0.0, 3.0 - t]]) for t in T]


def test_perfect_tracks():
    m = tracking_metrics(_gt(), [(t, [1, 2], xy) for t, _, xy in _gt()])
    assert m["mota"] == 1.0 and m["idf1"] == 1.0 and m["motp_m"] == 0.0
    assert m["num_switches"] == 0 and m["num_objects"] == 40 and m["num_frames"] == 20


def test_offset_gives_motp_in_metres_and_threshold_applies():
    hyp = [(t, [1, 2], np.asarray(xy) + [0.24, 0.32]) for t, _, xy in _gt()]  # 0.4 m away: a match
    m = tracking_metrics(_gt(), hyp)
    assert m["mota"] == 1.0 and m["motp_m"] == pytest.approx(0.4)
    m = tracking_metrics(_gt(), hyp, match_distance_m=0.39)  # now every object is missed, every track an FP
    assert m["num_misses"] == 40 and m["num_false_positives"] == 40 and m["mota"] == -1.0


def test_identity_swap_counts_switches_and_halves_idf1():
    hyp = [(t, [1, 2] if i < 10 else [2, 1], xy) for i, (t, _, xy) in enumerate(_gt())]
    m = tracking_metrics(_gt(), hyp)
    assert m["num_switches"] == 2
    assert m["idf1"] == pytest.approx(0.5)
    assert m["mota"] == pytest.approx(1 - 2 / 40)
    # each switch listed: when, which person, from which track to which
    t10 = _gt()[10][0]
    assert tracking_metrics(_gt(), hyp, switch_events=True)["switch_events"] == [(t10, 10, 1, 2), (t10, 20, 2, 1)]


def test_frames_paired_by_time_and_tracks_objects_accepted():
    gt = _gt()
    hyp = [Tracks(t + 1e-4, np.array([1, 2]), np.asarray(xy), np.zeros((2, 2)), np.zeros(2), np.ones(2),
                  np.zeros(2, int)) for t, _, xy in gt[:15]]
    hyp.append((99.0, [1], [[0.0, 0.0]]))
    m = tracking_metrics(gt, hyp)
    assert m["num_misses"] == 10  # the last 5 ground-truth frames have no hypothesis frame
    assert m["recall"] == pytest.approx(30 / 40) and m["precision"] == 1.0
    assert m["num_unpaired_hypothesis_frames"] == 1


def test_bad_input_raises():
    with pytest.raises(ValueError, match="ground_truth holds no frame"):
        tracking_metrics([], [])
    with pytest.raises(ValueError, match="2 ids but 1 positions"):
        tracking_metrics([(0.0, [1, 2], [[0, 0]])], [])
    with pytest.raises(ValueError, match="match_distance_m"):
        tracking_metrics(_gt(), [], match_distance_m=0)
    with pytest.raises(ValueError, match="time_s, ids, xy_m"):
        tracking_metrics([object()], [])


def test_identity_bounds_tell_a_swap_from_a_fragment():
    # the swap: no joining of whole tracks undoes it (each track is half one person, half the other), a labelling
    # of each position does
    swap = [(t, [1, 2] if i < 10 else [2, 1], xy) for i, (t, _, xy) in enumerate(_gt())]
    m = tracking_metrics(_gt(), swap, identity_bounds=True)
    assert m["idf1"] == pytest.approx(0.5)
    assert m["idf1_max_tracklets"] == pytest.approx(2 * (10 + 10) / 80)
    assert m["idf1_max_detections"] == pytest.approx(1.0)
    # the fragment: person 10's track ends and track 3 takes over; joining tracks 1 and 3 would give 1.0
    frag = [(t, [1 if i < 10 else 3, 2], xy) for i, (t, _, xy) in enumerate(_gt())]
    m = tracking_metrics(_gt(), frag, identity_bounds=True)
    assert m["idf1"] == pytest.approx(2 * (10 + 20) / 80)
    assert m["idf1_max_tracklets"] == pytest.approx(1.0)
    # a false track adds to the hypotheses, not to what can be matched; a missed person to the objects
    fp = [(t, [1, 2, 7], np.vstack([xy, [[50.0, 50.0]]])) for t, _, xy in _gt()]
    m = tracking_metrics(_gt(), fp, identity_bounds=True)
    assert m["idf1_max_detections"] == pytest.approx(2 * 40 / (40 + 60))
    assert m["idf1_max_tracklets"] == pytest.approx(m["idf1"])
    assert "idf1_max_tracklets" not in tracking_metrics(_gt(), fp)


@settings(max_examples=40, deadline=None)
@given(st.integers(0, 2**31 - 1))
def test_identity_bounds_bound_idf1(seed):
    # random tracks: noisy copies of the people with ids shuffled at random instants, false tracks, misses
    rng = np.random.default_rng(seed)
    hyp, ids = [], np.array([1, 2])
    for t, _, xy in _gt():
        if rng.random() < 0.2:
            ids = rng.permutation(np.append(ids, rng.integers(3, 9)))[:2]
        keep = rng.random(2) < 0.85
        pts = np.asarray(xy) + rng.normal(0, 0.3, (2, 2))
        extra = rng.random() < 0.2
        hyp.append((t, np.append(ids[keep], [99] if extra else []),
                    np.vstack([pts[keep]] + ([rng.uniform(-1, 3, (1, 2))] if extra else []))))
    m = tracking_metrics(_gt(), hyp, identity_bounds=True)
    assert m["idf1"] <= m["idf1_max_tracklets"] + 1e-12
    assert 0.0 <= m["idf1_max_detections"] <= 1.0
