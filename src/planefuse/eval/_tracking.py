"""Multi-object tracking metrics (CLEAR MOT and identity metrics) on ground-plane positions, via motmetrics.

Ground truth and hypotheses are sequences of frames, each with a time [s], identities and world XY
positions [m]. A hypothesis and a ground-truth object can match when their ground distance is at most
``match_distance_m`` (0.5 m by default, the usual threshold for people on the ground plane).
"""

from __future__ import annotations

from collections.abc import Iterable
from typing import Any

import numpy as np
from scipy.spatial.distance import cdist

__all__ = ["tracking_metrics"]

_METRICS = {
    "mota": "mota",
    "motp_m": "motp",
    "idf1": "idf1",
    "idp": "idp",
    "idr": "idr",
    "precision": "precision",
    "recall": "recall",
    "num_switches": "num_switches",
    "num_false_positives": "num_false_positives",
    "num_misses": "num_misses",
    "num_objects": "num_objects",
    "num_unique_objects": "num_unique_objects",
    "mostly_tracked": "mostly_tracked",
    "mostly_lost": "mostly_lost",
    "num_fragmentations": "num_fragmentations",
}


def _frame(f: Any, what: str, i: int) -> tuple[float, np.ndarray, np.ndarray]:
    """``(time_s, ids (N,), xy_m (N, 2))`` from a tuple or an object with ``time_s, ids, xy_m``."""
    if isinstance(f, tuple) and len(f) == 3:
        t, ids, xy = f
    elif all(hasattr(f, a) for a in ("time_s", "ids", "xy_m")):
        t, ids, xy = f.time_s, f.ids, f.xy_m
    else:
        raise ValueError(f"{what}[{i}] must be (time_s, ids, xy_m) or have those attributes, got {type(f).__name__}")
    ids = np.asarray(ids).reshape(-1)
    xy = np.asarray(xy, dtype=float).reshape(-1, 2) if np.size(xy) else np.zeros((0, 2))
    if len(ids) != len(xy):
        raise ValueError(f"{what}[{i}]: {len(ids)} ids but {len(xy)} positions")
    if not np.isfinite(float(t)):
        raise ValueError(f"{what}[{i}]: time_s must be finite, got {t}")
    return float(t), ids, xy


def tracking_metrics(
    ground_truth: Iterable,
    hypotheses: Iterable,
    match_distance_m: float = 0.5,
    time_tolerance_s: float = 1e-3,
    switch_events: bool = False,
    identity_bounds: bool = False,
) -> dict[str, float]:
    """MOTA, MOTP, IDF1, identity switches and friends for people tracked on the ground plane.

    Parameters
    ----------
    ground_truth : iterable of frames
        One frame per evaluated instant: ``(time_s, ids (N,), xy_m (N, 2))`` or any object with attributes
        ``time_s, ids, xy_m`` [s, -, m]. Every ground-truth frame is evaluated.
    hypotheses : iterable of frames
        Tracker output frames, same layout (e.g. :class:`planefuse.tracking.Tracks`). Each ground-truth
        frame is paired with the hypothesis frame nearest in time within ``time_tolerance_s``; a
        ground-truth frame without one counts all its objects as misses. Hypothesis frames paired with no
        ground-truth frame are not evaluated (their number is returned as ``num_unpaired_hypothesis_frames``).
    match_distance_m : float
        Largest ground distance [m] for a match (motmetrics' distance threshold).
    time_tolerance_s : float
        Largest time difference [s] between paired frames.
    switch_events : bool
        Also list the identity switches: ``switch_events``, one ``(time_s, truth id, previous track id, new track
        id)`` per switch, in time order (the previous track id is the one last matched to that person).
    identity_bounds : bool
        Also return two labelled upper bounds of IDF1 that tell identity errors from detection errors, both
        ``2 IDTP / (num_objects + num hypotheses)`` with the IDTP an ideal labelling would get:
        ``idf1_max_tracklets``, every track given the person it is within ``match_distance_m`` of in the most
        frames (IDF1's own count; no joining of whole tracks into identities, without cutting them, can do
        better), and ``idf1_max_detections``, every position that CLEAR MOT matches given its person's identity
        (about the best any labelling of these positions can do: the detection F1). They need the ground
        truth's identities, so they bound a system; they are not a system's score.

    Returns
    -------
    dict
        ``mota, motp_m`` (mean distance of the matches [m]), ``idf1, idp, idr, precision, recall`` (floats,
        NaN when undefined), counts ``num_switches, num_false_positives, num_misses, num_objects,
        num_unique_objects, mostly_tracked, mostly_lost, num_fragmentations, num_frames,
        num_unpaired_hypothesis_frames``; with ``identity_bounds`` also ``idf1_max_tracklets,
        idf1_max_detections``.
    """
    if not (np.isfinite(match_distance_m) and match_distance_m > 0):
        raise ValueError(f"match_distance_m must be finite and > 0, got {match_distance_m}")
    gt = [_frame(f, "ground_truth", i) for i, f in enumerate(ground_truth)]
    hyp = [_frame(f, "hypotheses", i) for i, f in enumerate(hypotheses)]
    if not gt:
        raise ValueError("ground_truth holds no frame")
    hyp_t = np.array([h[0] for h in hyp]) if hyp else np.zeros(0)
    used = np.zeros(len(hyp), bool)
    import motmetrics as mm  # and pandas (~0.5 s): only where a run is scored

    acc = mm.MOTAccumulator(auto_id=True)
    near: dict = {}  # (track id, person id) -> frames within match_distance_m (identity_bounds)
    n_hyp = 0
    for t, gid, gxy in gt:
        hid, hxy = np.zeros(0, dtype=np.int64), np.zeros((0, 2))
        if hyp:
            j = int(np.argmin(np.abs(hyp_t - t)))
            if abs(hyp_t[j] - t) <= time_tolerance_s:
                _, hid, hxy = hyp[j]
                used[j] = True
        d = cdist(gxy, hxy) if len(gxy) and len(hxy) else np.zeros((len(gxy), len(hxy)))
        d = np.where(d <= match_distance_m, d, np.nan)
        acc.update(list(gid), list(hid), d)
        if identity_bounds:
            n_hyp += len(hid)
            for gi, hi in zip(*np.nonzero(np.isfinite(d))):
                key = (_plain(hid[hi]), _plain(gid[gi]))
                near[key] = near.get(key, 0) + 1
    summary = mm.metrics.create().compute(acc, metrics=list(_METRICS.values()), name="all")
    out = {k: float(summary[v].iloc[0]) for k, v in _METRICS.items()}
    for k in _METRICS:
        if k.startswith("num_") or k.startswith("mostly_"):
            out[k] = int(out[k])
    out["num_frames"] = len(gt)
    if switch_events:
        out["switch_events"] = _switch_events(acc, [g[0] for g in gt])
    if identity_bounds:
        out.update(_identity_bounds(acc, near, out["num_objects"] + n_hyp))
    out["num_unpaired_hypothesis_frames"] = int((~used).sum())
    return out


def _switch_events(acc, times_s: list[float]) -> list[tuple[float, Any, Any, Any]]:
    """``(time_s, truth id, previous track id, new track id)`` of every SWITCH event of a motmetrics accumulator
    (frames numbered 0.. in the order of ``times_s``)."""
    last: dict = {}
    out = []
    ev = acc.mot_events
    for (frame, _), row in zip(ev.index, ev.itertuples(index=False)):
        if row.Type not in ("MATCH", "SWITCH"):
            continue
        oid, hid = row.OId, row.HId
        if row.Type == "SWITCH":
            prev = last.get(oid)
            out.append((float(times_s[int(frame)]), _plain(oid), _plain(prev), _plain(hid)))
        last[oid] = hid
    return out


def _identity_bounds(acc, near: dict, n_points: int) -> dict[str, float]:
    """``idf1_max_tracklets`` and ``idf1_max_detections`` (:func:`tracking_metrics`) from a motmetrics accumulator
    and the count of frames each (track, person) pair was within the match distance; ``n_points`` = ground-truth
    objects + hypotheses of the evaluated frames."""
    if n_points == 0:
        return {"idf1_max_tracklets": float("nan"), "idf1_max_detections": float("nan")}
    best: dict = {}
    for (hid, _), n in near.items():  # each track's best single person: IDF1's own count of frames together
        best[hid] = max(best.get(hid, 0), n)
    n_matched = int(acc.mot_events.Type.isin(("MATCH", "SWITCH")).sum())
    return {"idf1_max_tracklets": 2.0 * sum(best.values()) / n_points,
            "idf1_max_detections": 2.0 * n_matched / n_points}


def _plain(v):
    """A numpy scalar as a Python one (JSON); a whole float (motmetrics keeps integer ids as floats) as an int."""
    v = v.item() if hasattr(v, "item") else v
    return int(v) if isinstance(v, float) and v.is_integer() else v
