"""Detection scores on the ground plane: MODA, MODP, precision, recall (CLEAR-MOD, distance based).

Per frame, ground-truth and detected feet positions are matched one-to-one by
the Hungarian algorithm on their Euclidean distance, pairs farther apart than
``match_distance_m`` being forbidden (so the number of matches is maximal, then their
total distance minimal). Over all frames, with N_gt ground-truth people, TP
matches, FP unmatched detections, FN unmatched ground truth::

    MODA      = 1 - (FN + FP) / N_gt
    MODP      = mean over matches of (1 - d / match_distance_m)
    precision = TP / (TP + FP)          recall = TP / N_gt

Ground-truth positions may be given as "ignore" (people the evaluation cannot
vouch for, e.g. seen by one camera only): a detection matched to one of them is
neither a TP nor an FP, and they are never FN.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Iterable

import numpy as np
from scipy.optimize import linear_sum_assignment

from ..geometry import check_points

__all__ = ["DetectionScores", "detection_scores", "match_detections"]


def _xy(a, name: str) -> np.ndarray:
    if a is None or np.size(a) == 0:
        return np.zeros((0, 2))
    p = check_points(a, 2, name)
    if p.ndim != 2:
        raise ValueError(f"{name} must have shape (N, 2), got {p.shape}")
    return p


def match_detections(gt_xy, det_xy, match_distance_m: float = 0.5) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """One-to-one matching of detections to ground truth within ``match_distance_m``.

    Parameters
    ----------
    gt_xy : array_like, shape (G, 2)
        Ground-truth positions [m].
    det_xy : array_like, shape (D, 2)
        Detected positions [m].
    match_distance_m : float
        Largest distance of a match [m] (inclusive).

    Returns
    -------
    gt_index, det_index : ndarray (K,), int64
        Matched pairs.
    distance_m : ndarray (K,)
        Their distances [m].
    """
    if not match_distance_m > 0:
        raise ValueError(f"match_distance_m must be > 0, got {match_distance_m}")
    g = _xy(gt_xy, "gt_xy")
    d = _xy(det_xy, "det_xy")
    if len(g) == 0 or len(d) == 0:
        e = np.zeros(0, dtype=np.int64)
        return e, e.copy(), np.zeros(0)
    dist = np.linalg.norm(g[:, None, :] - d[None, :, :], axis=-1)
    allowed = dist <= match_distance_m
    # A forbidden pair costs more than any full set of allowed ones: maximal matching first.
    big = match_distance_m * (min(len(g), len(d)) + 1)
    rows, cols = linear_sum_assignment(np.where(allowed, dist, big))
    ok = allowed[rows, cols]
    return rows[ok].astype(np.int64), cols[ok].astype(np.int64), dist[rows[ok], cols[ok]]


@dataclass(frozen=True)
class DetectionScores:
    """Counts and scores over a sequence (see module doc).

    Attributes
    ----------
    n_frames, n_gt, tp, fp, fn : int
    sum_similarity : float
        Sum over matches of ``1 - d / match_distance_m``.
    sum_distance_m : float
        Sum of match distances [m].
    match_distance_m : float
    """

    n_frames: int
    n_gt: int
    tp: int
    fp: int
    fn: int
    sum_similarity: float
    sum_distance_m: float
    match_distance_m: float

    @property
    def moda(self) -> float:
        """Multiple object detection accuracy, ``1 - (FN + FP) / N_gt`` (NaN without ground truth)."""
        return 1.0 - (self.fn + self.fp) / self.n_gt if self.n_gt else float("nan")

    @property
    def modp(self) -> float:
        """Multiple object detection precision, mean ``1 - d / threshold`` over matches."""
        return self.sum_similarity / self.tp if self.tp else float("nan")

    @property
    def precision(self) -> float:
        """``TP / (TP + FP)``."""
        return self.tp / (self.tp + self.fp) if self.tp + self.fp else float("nan")

    @property
    def recall(self) -> float:
        """``TP / N_gt``."""
        return self.tp / self.n_gt if self.n_gt else float("nan")

    @property
    def mean_distance_m(self) -> float:
        """Mean distance of the matches [m]."""
        return self.sum_distance_m / self.tp if self.tp else float("nan")

    def as_dict(self) -> dict[str, float]:
        """Scores and counts as a flat dict (for tables and JSON)."""
        return {"frames": self.n_frames, "gt": self.n_gt, "tp": self.tp, "fp": self.fp, "fn": self.fn,
                "moda": self.moda, "modp": self.modp, "precision": self.precision, "recall": self.recall,
                "mean_distance_m": self.mean_distance_m, "match_distance_m": self.match_distance_m}


def detection_scores(frames: Iterable, match_distance_m: float = 0.5) -> DetectionScores:
    """Score detections against ground truth over many frames.

    Parameters
    ----------
    frames : iterable of (gt_xy, det_xy) or (gt_xy, det_xy, ignore_xy)
        Per frame: ground truth (G, 2), detections (D, 2) and optionally
        positions to ignore (I, 2), all world XY [m].
    match_distance_m : float
        Match distance [m].

    Returns
    -------
    DetectionScores
    """
    n_frames = n_gt = tp = fp = fn = 0
    sim = dist_sum = 0.0
    for item in frames:
        gt, det = _xy(item[0], "gt_xy"), _xy(item[1], "det_xy")
        ign = _xy(item[2], "ignore_xy") if len(item) > 2 else np.zeros((0, 2))
        gi, di, d = match_detections(gt, det, match_distance_m)
        unmatched = np.setdiff1d(np.arange(len(det)), di)
        n_fp = len(unmatched)
        if len(ign) and n_fp:
            _, ui, _ = match_detections(ign, det[unmatched], match_distance_m)
            n_fp -= len(ui)
        n_frames += 1
        n_gt += len(gt)
        tp += len(gi)
        fn += len(gt) - len(gi)
        fp += n_fp
        sim += float(np.sum(1.0 - d / match_distance_m))
        dist_sum += float(np.sum(d))
    return DetectionScores(n_frames, n_gt, tp, fp, fn, sim, dist_sum, float(match_distance_m))
