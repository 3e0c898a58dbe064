"""Tracking metrics (motmetrics) on ground positions: analytic cases."""

from __future__ import annotations

import numpy as np
import pytest

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
