"""MODA / MODP / precision / recall with Hungarian matching, cross-checked against motmetrics."""

from __future__ import annotations

import motmetrics as mm
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from planefuse.eval import detection_scores, match_detections


def test_match_is_one_to_one_and_maximal():
    # One detection between two ground-truth people: it can match only one; the far detection none.
    gt = [[0.0, 0.0], [0.8, 0.0]]
    det = [[0.4, 0.0], [5.0, 5.0]]
    gi, di, d = match_detections(gt, det, 0.5)
    assert len(gi) == 1 and di.tolist() == [0]
    np.testing.assert_allclose(d, [0.4])
    # Greedy nearest would pair det 0 with gt 1 (0.35) and leave gt 0 unmatched; Hungarian matches both.
    gi, di, _ = match_detections([[0.0, 0.0], [0.7, 0.0]], [[0.35, 0.0], [1.1, 0.0]], 0.5)
    assert sorted(zip(gi.tolist(), di.tolist())) == [(0, 0), (1, 1)]


def test_scores_analytic():
    frames = [
        ([[0, 0], [3, 3]], [[0.1, 0], [3, 3.25], [7, 7]]),  # 2 TP (d 0.1, 0.25), 1 FP
        ([[1, 1]], []),  # 1 FN
    ]
    s = detection_scores(frames, 0.5)
    assert (s.n_gt, s.tp, s.fp, s.fn) == (3, 2, 1, 1)
    assert s.moda == pytest.approx(1 - 2 / 3)
    assert s.modp == pytest.approx(((1 - 0.1 / 0.5) + (1 - 0.25 / 0.5)) / 2)
    assert s.precision == pytest.approx(2 / 3) and s.recall == pytest.approx(2 / 3)


def test_ignored_people_are_neither_fn_nor_fp():
    s = detection_scores([([[0, 0]], [[0, 0], [4, 4]], [[4.2, 4]])], 0.5)
    assert (s.tp, s.fp, s.fn) == (1, 0, 0)


def test_bad_input_raises():
    with pytest.raises(ValueError, match="match_distance_m"):
        match_detections([[0, 0]], [[0, 0]], 0.0)
    with pytest.raises(ValueError, match="det_xy"):
        match_detections([[0, 0]], [[0, 0, 0]], 0.5)


def test_agrees_with_motmetrics(rng):
    thr = 0.5
    frames = []
    acc = mm.MOTAccumulator(auto_id=True)
    next_id = 0
    for _ in range(40):
        gt = rng.uniform(0, 6, (rng.integers(0, 7), 2))
        kept = gt[rng.random(len(gt)) < 0.8]
        det = np.concatenate([kept + rng.normal(0, 0.25, kept.shape), rng.uniform(0, 6, (rng.integers(0, 3), 2))])
        det = det[rng.permutation(len(det))]
        frames.append((gt, det))
        dist = np.linalg.norm(gt[:, None] - det[None], axis=-1) if len(gt) and len(det) else np.zeros((len(gt), len(det)))
        dist = np.where(dist <= thr, dist, np.nan)
        # Fresh ids every frame: no identity switches, so MOTA reduces to MODA.
        ids = list(range(next_id, next_id + len(gt)))
        next_id += len(gt)
        acc.update(ids, list(range(100000 + next_id, 100000 + next_id + len(det))), dist)
    s = detection_scores(frames, thr)
    summary = mm.metrics.create().compute(acc, metrics=["num_false_positives", "num_misses", "num_detections",
                                                         "num_objects", "mota", "motp", "precision", "recall"])
    r = summary.iloc[0]
    assert (s.fp, s.fn, s.tp, s.n_gt) == (r.num_false_positives, r.num_misses, r.num_detections, r.num_objects)
    assert s.moda == pytest.approx(r.mota)
    assert s.mean_distance_m == pytest.approx(r.motp)  # motmetrics' MOTP: mean matched distance
    assert s.modp == pytest.approx(1 - r.motp / thr)
    assert s.precision == pytest.approx(r.precision) and s.recall == pytest.approx(r.recall)


def _brute_force_matching(gt, det, thr):
    """(largest number of pairs within thr, smallest total distance among those) by enumerating every
    one-to-one assignment: an oracle that shares nothing with the Hungarian solver."""
    from itertools import permutations

    g, d = np.asarray(gt, float), np.asarray(det, float)
    dist = np.linalg.norm(g[:, None] - d[None], axis=-1) if len(g) and len(d) else np.zeros((len(g), len(d)))
    best = (0, 0.0)
    small, large, flip = (g, d, False) if len(g) <= len(d) else (d, g, True)
    for perm in permutations(range(len(large)), len(small)):
        pairs = [(i, j) if not flip else (j, i) for i, j in enumerate(perm)]
        ok = [dist[i, j] for i, j in pairs if dist[i, j] <= thr]
        key = (len(ok), -sum(ok))
        if key > (best[0], -best[1]):
            best = (len(ok), sum(ok))
    return best


@settings(max_examples=200, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), n_gt=st.integers(0, 5), n_det=st.integers(0, 5),
       spread=st.floats(0.3, 2.0))
def test_match_is_maximal_then_minimal_like_brute_force(seed, n_gt, n_det, spread):
    rng = np.random.default_rng(seed)
    gt = rng.uniform(0, spread, (n_gt, 2))
    det = rng.uniform(0, spread, (n_det, 2))
    gi, di, d = match_detections(gt, det, 0.5)
    n_best, dist_best = _brute_force_matching(gt, det, 0.5)
    assert len(set(gi.tolist())) == len(gi) and len(set(di.tolist())) == len(di)  # one-to-one
    assert (d <= 0.5).all()
    np.testing.assert_allclose(d, np.linalg.norm(gt[gi] - det[di], axis=-1))
    assert len(gi) == n_best
    assert float(d.sum()) == pytest.approx(dist_best, abs=1e-9)


def test_maximal_matching_beats_nearest_pairs_issue_21_case():
    """The case of issue 21: the nearest pair (0,0)-(0.1,0) would leave both others unmatched; the maximal
    matching pairs (0,0)-(-0.45,0) and (0.55,0)-(0.1,0), both at 0.45 m: MODA 1.0, not 0.0."""
    gt, det = [[0.0, 0.0], [0.55, 0.0]], [[-0.45, 0.0], [0.1, 0.0]]
    gi, di, d = match_detections(gt, det, 0.5)
    assert sorted(zip(gi.tolist(), di.tolist())) == [(0, 0), (1, 1)]
    np.testing.assert_allclose(d, [0.45, 0.45])
    s = detection_scores([(gt, det)], 0.5)
    assert (s.tp, s.fp, s.fn) == (2, 0, 0) and s.moda == 1.0


@pytest.mark.parametrize("gt, det, thr", [
    ([[0.0, 0.0]], [[0.5, 0.0]], 0.5),                 # exactly representable distances
    ([[1.0, 2.0]], [[1.0, 2.25]], 0.25),
    ([[0.0, 0.0]], [[3.0, 4.0]], 5.0),
])
def test_threshold_is_inclusive(gt, det, thr):
    """A pair exactly at ``match_distance_m`` matches (documented as inclusive); one a hair farther does not."""
    gi, _, d = match_detections(gt, det, thr)
    assert len(gi) == 1 and d[0] == thr
    assert detection_scores([(gt, det)], thr).moda == 1.0
    assert len(match_detections(gt, det, np.nextafter(thr, 0))[0]) == 0
    assert detection_scores([(gt, det)], np.nextafter(thr, 0)).moda == -1.0
