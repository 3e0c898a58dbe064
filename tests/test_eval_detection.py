"""MODA / MODP / precision / recall with Hungarian matching, cross-checked against motmetrics."""

from __future__ import annotations

import motmetrics as mm
import numpy as np
import pytest

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
    with pytest.raises(ValueError, match="threshold_m"):
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
