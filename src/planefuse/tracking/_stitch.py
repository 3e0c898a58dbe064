r"""Offline stitching of a recorded run's tracks: tracklets joined across gaps by time, space and appearance.

The live tracker decides each step with what it has seen so far. After a run, every identity's whole life is
known: its *tracklet*, the span from its first to its last reported step, with its first and last positions and its
appearance model (:class:`planefuse.tracking.TrackAppearance`). A person lost and found again under a new identity
leaves two tracklets, one ending where and when the other begins, in the same colours. Offline trackers join such
pairs; here, a tracklet ``a`` may be continued by a tracklet ``b`` if (:class:`StitchParams`)::

    0 < t_start(b) - t_end(a) = gap <= max_gap_s
    |p_start(b) - p_end(a)| <= slack_m + max_speed_m_s x gap
    d_app(a, b) <= max_appearance_distance

``d_app`` the appearance distance of their models (:meth:`TrackAppearance.distance_to`; where either has none the
pair is not formed, unless ``require_appearance`` is False). Every tracklet is continued by at most one and
continues at most one; the pairs are chosen together (``scipy.optimize.linear_sum_assignment``) at least total cost
``d_app + gap / max_gap_s``, then chained: ``b`` takes ``a``'s identity (and a ``c`` continuing ``b`` too). The live
path is untouched: this is a pass over the reported tracks (``models.detection.stitch_max_gap_s``).
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from dataclasses import dataclass

import numpy as np
from scipy.optimize import linear_sum_assignment

from .._params import check_fields
from ._appearance import TrackAppearance

__all__ = ["StitchParams", "stitch_identities", "relabel_tracks"]


@dataclass(frozen=True)
class StitchParams:
    """Which tracklets may be joined (module docstring).

    Attributes
    ----------
    enabled : bool
        Whether a run stitches its tracks (:func:`planefuse.pipeline.run_plan`; the functions here always do).
    max_gap_s : float
        Longest gap [s] between a tracklet's end and its continuation's start.
    max_speed_m_s : float
        Fastest a person moves [m/s] while unseen.
    slack_m : float
        Distance [m] allowed at any gap (position noise, a person's own width).
    max_appearance_distance : float
        Largest appearance distance in [0, 1] of two joined tracklets.
    require_appearance : bool
        Join only tracklets whose appearance is known (False: time and space alone where it is not).
    """

    enabled: bool = False
    max_gap_s: float = 5.0
    max_speed_m_s: float = 1.5
    slack_m: float = 1.0
    max_appearance_distance: float = 0.3
    require_appearance: bool = True

    def __post_init__(self) -> None:
        check_fields(self, max_gap_s=">0", max_speed_m_s=">=0", slack_m=">=0", max_appearance_distance="[0,1]")


def stitch_identities(frames: Iterable, appearance: Mapping[int, TrackAppearance] | None = None,
                      params: StitchParams | None = None) -> dict[int, int]:
    """Which identity each tracklet of a run continues (module docstring).

    Parameters
    ----------
    frames : iterable of (time_s, ids (N,), xy_m (N, 2)) or objects with ``time_s, ids, xy_m``
        The reported tracks of every step, in time order.
    appearance : mapping of int to TrackAppearance, optional
        Each identity's appearance model (:attr:`MultiPersonTracker.appearance_by_id`).
    params : StitchParams, optional

    Returns
    -------
    dict of int to int
        Identity -> the identity it takes (only the identities that change).
    """
    p = params if params is not None else StitchParams()
    appearance = appearance or {}
    first: dict[int, tuple[float, np.ndarray]] = {}
    last: dict[int, tuple[float, np.ndarray]] = {}
    prev_t = -np.inf
    for f in frames:
        t, ids, xy = (f if isinstance(f, tuple) else (f.time_s, f.ids, f.xy_m))
        t = float(t)
        if t < prev_t:
            raise ValueError(f"frames must be in time order: {t} s after {prev_t} s")
        prev_t = t
        for i, q in zip(np.asarray(ids).reshape(-1), np.asarray(xy, float).reshape(-1, 2)):
            first.setdefault(int(i), (t, q.copy()))
            last[int(i)] = (t, q.copy())
    ids = sorted(first)
    if len(ids) < 2:
        return {}
    cost = np.full((len(ids), len(ids)), np.inf)
    for a_k, a in enumerate(ids):
        ta, pa = last[a]
        for b_k, b in enumerate(ids):
            tb, pb = first[b]
            gap = tb - ta
            if not 0 < gap <= p.max_gap_s or np.linalg.norm(pb - pa) > p.slack_m + p.max_speed_m_s * gap:
                continue
            d = (appearance[a].distance_to(appearance[b]) if a in appearance and b in appearance else float("nan"))
            if np.isnan(d):
                if p.require_appearance:
                    continue
                d = p.max_appearance_distance
            if d <= p.max_appearance_distance:
                cost[a_k, b_k] = d + gap / p.max_gap_s
    ok = np.isfinite(cost)
    if not ok.any():
        return {}
    big = 1e6
    rows, cols = linear_sum_assignment(np.where(ok, cost, big))
    successor = {ids[r]: ids[c] for r, c in zip(rows, cols) if ok[r, c]}
    predecessor = {b: a for a, b in successor.items()}
    out = {}
    for b in successor.values():
        root = b
        while root in predecessor:
            root = predecessor[root]
        out[b] = root
    return out


def relabel_tracks(frames: Iterable, mapping: Mapping[int, int]) -> list[tuple[float, np.ndarray, np.ndarray]]:
    """``frames`` ((time_s, ids, xy_m) or objects with those attributes) with each identity replaced through
    ``mapping`` (:func:`stitch_identities`)."""
    out = []
    for f in frames:
        t, ids, xy = (f if isinstance(f, tuple) else (f.time_s, f.ids, f.xy_m))
        new = np.array([mapping.get(int(i), int(i)) for i in np.asarray(ids).reshape(-1)], dtype=np.int64)
        out.append((float(t), new, np.asarray(xy, float).reshape(-1, 2)))
    return out
