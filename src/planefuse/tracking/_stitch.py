r"""Offline stitching of a recorded run's tracks: tracklets joined across gaps by time, space and appearance.

The live tracker decides each step with what it has seen so far. After a run, every identity's whole life is
known: its *tracklet*, the span from its first to its last reported step, with its first and last positions and its
appearance model (:class:`planefuse.tracking.TrackAppearance`). A person lost and found again under a new identity
leaves two tracklets, one ending where and when the other begins, in the same colours. Offline trackers join such
pairs; here, a tracklet ``a`` may be continued by a tracklet ``b`` if (:class:`StitchParams`)::

    0 < t_start(b) - t_end(a) = gap <= max_gap_s
    r = |p_start(b) - p_end(a)| <= R(gap) = slack_m + max_speed_m_s x gap
    d_app(a, b) <= max_appearance_distance

``d_app`` the appearance distance of their models (:meth:`TrackAppearance.distance_to`; where either has none the
pair is not formed, unless ``require_appearance`` is False, and then its appearance term is 0). Such a *link* costs,
in the tracker's units (``-2 ln`` of a likelihood ratio, docs/identities.md)::

    c(a, b) = appearance_weight (d_app - appearance_reference_distance) + (r / R(gap))^2 + gap / max_gap_s

and leaving a tracklet's end unlinked (the person left) or its start unlinked (a new person came) costs
``new_person_cost / 2`` each. The links are chosen **together**, as one assignment at least total cost over every
tracklet (Jaqaman et al., Nature Methods 2008, "u-track": the links block beside the diagonal blocks of the ends'
and the starts' own costs, ``scipy.optimize.linear_sum_assignment``): every tracklet is continued by at most one and
continues at most one, and a link is taken only where the whole is cheaper with it, so two tracklets that both fit
one end are resolved by the one whose colours and place fit better, not by which comes first. The links are then
chained: ``b`` takes ``a``'s identity (and a ``c`` continuing ``b`` too).

:func:`fill_gaps` then (``max_fill_gap_s``) places each identity on the steps of a gap of at most that length
between two of its reports, on the straight line between them: the person was there, unseen. Last,
:func:`smooth_positions` (``smooth_sigma_s``) replaces each position by the Gaussian-weighted mean in time of its
identity's positions within 3 sigma: the noise of a real detector's positions averages out, as a smoother that
knows the future can afford.

The live path is untouched: this is a pass over the reported tracks (``models.detection.stitch``).
"""

from __future__ import annotations

from collections import defaultdict
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, replace

import numpy as np
from scipy.optimize import linear_sum_assignment

from .._params import check_fields
from ._appearance import TrackAppearance
from ._tracker import Tracks

__all__ = ["StitchParams", "stitch_identities", "tracklet_links", "chain_links", "relabel_tracks", "fill_gaps",
           "fill_track_gaps", "link_costs",
           "smooth_positions", "smooth_track_positions"]


@dataclass(frozen=True)
class StitchParams:
    """Which tracklets may be joined and what a link costs (module docstring).

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
    appearance_weight : float
        Cost of a link per unit of appearance distance (``-2 ln`` likelihood ratio per unit).
    appearance_reference_distance : float
        Appearance distance at which "same person" and "someone else" are equally likely (cost 0).
    new_person_cost : float
        Cost of a tracklet's end and of another's start both left unlinked (a person left, another came): a link
        costs less than this, or is not taken.
    max_fill_gap_s : float or None
        :func:`fill_gaps`: longest gap [s] within one identity filled on the straight line; None: no filling.
    smooth_sigma_s : float or None
        :func:`smooth_positions`: standard deviation [s] of the Gaussian in time over each identity's positions
        (after the filling); None: positions as reported.
    split_window_s : float or None
        Before the association, each tracklet is cut where its views' colours change
        (:func:`planefuse.tracking.split_times`): the span [s] of views compared on each side; None: no cutting.
    split_min_distance : float
        Appearance distance in [0, 1] between the two sides above which a tracklet is cut.
    split_min_views : int
        Fewest views on each side of a cut.

    Notes
    -----
    The appearance weight and reference distance are the tracker's (docs/identities.md: ``-2 ln LR`` of the colour
    histograms crosses 0 near 0.3 with a slope of 16-36 per unit). The gates were chosen on EPFL terrace frames
    0-1499 (YOLOX front end, appearance and re-identification on; cold starts at frames 0, 500 and 1000 every 5th
    frame and at 0 every 10th) and simulated seeds 1-3 (6 s, every scenario): a gap of 10 s and an appearance gate
    of 0.4 give mean IDF1 0.874 against 0.866 (5 s, 0.3) on the terrace, the same on the seeds (0.944); on 30 s
    scenes of seeds 1-3 (crowd, occluders, camera_dropout) 0.909 against 0.905 for the previous stitching (5 s, 0.3,
    every allowed pair taken; gate 0.5: 0.910). The new person's cost (2, 4, 8 or none) and ``require_appearance``
    changed IDF1 by at most 0.001. Filling gaps up to 4 s gave
    terrace IDF1 / MOTA 0.884 / 0.773 against 0.874 / 0.760 without (2 s: 0.878 / 0.765) but 0.943 / 0.894 against
    0.944 / 0.897 on the seeds: off by default, 4 s in the real-video profile (``planefuse.config.REAL_VIDEO``).
    Smoothing (after a 4 s filling) with sigma 0.2 / 0.4 / 0.6 / 0.8 / 1.0 s gave terrace IDF1 / MOTA 0.886 / 0.777,
    0.894 / 0.794, **0.903 / 0.810**, 0.899 / 0.802, 0.891 / 0.786 against 0.884 / 0.773, but on the seeds, whose
    positions are precise, 0.945 / 0.898 at 0.4 s and 0.932 / 0.871 at 0.6 s against 0.944 / 0.897: off by default,
    0.6 s in the real-video profile.
    Cutting tracklets where their colours change (``split_*``; window 6 s, distance 0.35, 5 views a side), chosen on
    seeds 1-3: on 30 s scenes mean IDF1 0.919 against 0.909 without (crowd 0.811 against 0.777, occluders 0.962
    against 0.966, camera_dropout unchanged; windows 4 s and 10 s: 0.917 and 0.918; distance 0.3: 0.914), on the
    6 s scenes 0.945 against 0.944 (crowd 0.914 against 0.907, the others unchanged); the terrace's cold starts above
    unchanged (0.903, no cut kept).
    """

    enabled: bool = False
    max_gap_s: float = 10.0
    max_speed_m_s: float = 1.5
    slack_m: float = 1.0
    max_appearance_distance: float = 0.4
    require_appearance: bool = True
    appearance_weight: float = 16.0
    appearance_reference_distance: float = 0.3
    new_person_cost: float = 4.0
    max_fill_gap_s: float | None = None
    smooth_sigma_s: float | None = None
    split_window_s: float | None = 6.0
    split_min_distance: float = 0.35
    split_min_views: int = 5

    def __post_init__(self) -> None:
        check_fields(self, max_gap_s=">0", max_speed_m_s=">=0", slack_m=">=0", max_appearance_distance="[0,1]",
                     appearance_weight=">=0", appearance_reference_distance="[0,1]", new_person_cost=">=0")
        if self.max_fill_gap_s is not None:
            check_fields(self, max_fill_gap_s=">0")
        if self.smooth_sigma_s is not None:
            check_fields(self, smooth_sigma_s=">0")
        if self.split_window_s is not None:
            check_fields(self, split_window_s=">0")
        check_fields(self, split_min_distance="[0,1]", split_min_views="int>=1")


def _tracklets(frames: Iterable) -> tuple[dict, dict]:
    """First and last (time_s, xy_m (2,)) of every identity of ``frames`` (checked in time order)."""
    first: dict[int, tuple[float, np.ndarray]] = {}
    last: dict[int, tuple[float, np.ndarray]] = {}
    prev_t = -np.inf
    for f in frames:
        t, ids, xy = _unpack(f)
        if t < prev_t:
            raise ValueError(f"frames must be in time order: {t} s after {prev_t} s")
        prev_t = t
        for i, q in zip(ids, xy):
            first.setdefault(int(i), (t, q.copy()))
            last[int(i)] = (t, q.copy())
    return first, last


def _unpack(f) -> tuple[float, np.ndarray, np.ndarray]:
    t, ids, xy = (f if isinstance(f, tuple) else (f.time_s, f.ids, f.xy_m))
    return float(t), np.asarray(ids).reshape(-1), np.asarray(xy, float).reshape(-1, 2)


def link_costs(frames: Iterable, appearance: Mapping[int, TrackAppearance] | None = None,
               params: StitchParams | None = None) -> tuple[list[int], np.ndarray]:
    """The identities of ``frames`` (sorted) and the cost (N, N) of each link ``a -> b`` (row ``a`` continued by
    column ``b``; module docstring), +inf where the pair is not allowed."""
    p = params if params is not None else StitchParams()
    appearance = appearance or {}
    first, last = _tracklets(frames)
    ids = sorted(first)
    cost = np.full((len(ids), len(ids)), np.inf)
    for a_k, a in enumerate(ids):
        ta, pa = last[a]
        for b_k, b in enumerate(ids):
            tb, pb = first[b]
            gap = tb - ta
            if not 0 < gap <= p.max_gap_s:
                continue
            reach_m = p.slack_m + p.max_speed_m_s * gap
            r = float(np.linalg.norm(pb - pa))
            if r > reach_m:
                continue
            d = (appearance[a].distance_to(appearance[b]) if a in appearance and b in appearance else float("nan"))
            if np.isnan(d):
                if p.require_appearance:
                    continue
                app_cost = 0.0
            elif d > p.max_appearance_distance:
                continue
            else:
                app_cost = p.appearance_weight * (d - p.appearance_reference_distance)
            cost[a_k, b_k] = app_cost + (r / reach_m) ** 2 + gap / p.max_gap_s
    return ids, cost


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
    return chain_links(tracklet_links(frames, appearance, params))


def tracklet_links(frames: Iterable, appearance: Mapping[int, TrackAppearance] | None = None,
                   params: StitchParams | None = None) -> dict[int, int]:
    """The links chosen together (module docstring): tracklet -> the tracklet that continues it."""
    p = params if params is not None else StitchParams()
    ids, cost = link_costs(frames, appearance, p)
    n = len(ids)
    ok = np.isfinite(cost)
    if n < 2 or not ok.any():
        return {}
    # u-track's square matrix: [[links, ends left], [starts left, 0]]; a pair that is not allowed gets a cost no
    # solution takes while another exists (the diagonal blocks always give one)
    big = 2.0 * (np.abs(cost[ok]).sum() + n * p.new_person_cost) + 1.0
    half = 0.5 * p.new_person_cost
    aug = np.full((2 * n, 2 * n), big)
    aug[:n, :n] = np.where(ok, cost, big)
    aug[:n, n:][np.diag_indices(n)] = half
    aug[n:, :n][np.diag_indices(n)] = half
    aug[n:, n:] = 0.0
    rows, cols = linear_sum_assignment(aug)
    return {ids[r]: ids[c] for r, c in zip(rows, cols) if r < n and c < n and ok[r, c]}


def chain_links(successor: Mapping[int, int]) -> dict[int, int]:
    """Links ``a -> b`` (each tracklet continued by at most one, continuing at most one) as identities: each
    continuation -> the first tracklet of its chain."""
    predecessor = {b: a for a, b in successor.items()}
    if len(predecessor) != len(successor):
        raise ValueError("links: a tracklet continues more than one")
    out = {}
    for b in successor.values():
        root, seen = b, {b}
        while root in predecessor:
            root = predecessor[root]
            if root in seen:
                raise ValueError(f"links: a cycle through tracklet {b}")
            seen.add(root)
        out[b] = root
    return out


def relabel_tracks(frames: Iterable, mapping: Mapping[int, int]) -> list[tuple[float, np.ndarray, np.ndarray]]:
    """``frames`` ((time_s, ids, xy_m) or objects with those attributes) with each identity replaced through
    ``mapping`` (:func:`stitch_identities`)."""
    out = []
    for f in frames:
        t, ids, xy = _unpack(f)
        new = np.array([mapping.get(int(i), int(i)) for i in ids], dtype=np.int64)
        out.append((t, new, xy))
    return out


def _gap_fills(steps: list, max_gap_s: float) -> dict[int, list[tuple[int, np.ndarray, np.ndarray, int]]]:
    """Per step index, the entries :func:`fill_gaps` adds: (identity, xy_m (2,), velocity_m_s (2,) of the straight
    line, steps since the identity's last report)."""
    if not (np.isfinite(max_gap_s) and max_gap_s > 0):
        raise ValueError(f"max_gap_s must be finite and > 0, got {max_gap_s}")
    times = np.array([t for t, _, _ in steps])
    if np.any(np.diff(times) < 0):
        raise ValueError("frames must be in time order")
    seen: dict[int, list[tuple[int, np.ndarray]]] = defaultdict(list)
    for k, (t, ids, xy) in enumerate(steps):
        if len(np.unique(ids)) != len(ids):
            raise ValueError(f"the step at {t} s reports an identity twice: {ids.tolist()}")
        for i, q in zip(ids, xy):
            seen[int(i)].append((k, q))
    added: dict[int, list] = defaultdict(list)
    for i in sorted(seen):
        for (k0, q0), (k1, q1) in zip(seen[i], seen[i][1:]):
            span_s = times[k1] - times[k0]
            if k1 - k0 < 2 or span_s > max_gap_s:
                continue
            v = (q1 - q0) / span_s
            for k in range(k0 + 1, k1):
                added[k].append((i, q0 + v * (times[k] - times[k0]), v, k - k0))
    return added


def fill_gaps(frames: Iterable, max_gap_s: float) -> list[tuple[float, np.ndarray, np.ndarray]]:
    """``frames`` ((time_s, ids (N,), xy_m (N, 2)) or objects with those attributes, in time order) with each
    identity also placed at the steps between two of its reports at most ``max_gap_s`` [s] apart, on the straight
    line between them (linear in time); the added entries follow each step's own, in identity order.

    An identity reported twice at one step is refused (it would be two people), as are frames out of time order.
    """
    steps = [_unpack(f) for f in frames]
    added = _gap_fills(steps, max_gap_s)
    out = []
    for k, (t, ids, xy) in enumerate(steps):
        ids = ids.astype(np.int64)
        if added[k]:
            ids = np.concatenate([ids, np.array([a[0] for a in added[k]], dtype=np.int64)])
            xy = np.concatenate([xy, np.array([a[1] for a in added[k]])])
        out.append((t, ids, xy))
    return out


def fill_track_gaps(tracks: Sequence[Tracks], max_gap_s: float) -> list[Tracks]:
    """:func:`fill_gaps` on the tracker's outputs: an added entry has the straight line's velocity, an unknown
    height (NaN), confidence 0 and ``misses`` the steps since its identity's last report (it was not seen)."""
    steps = [_unpack(tr) for tr in tracks]
    added = _gap_fills(steps, max_gap_s)
    out = []
    for k, tr in enumerate(tracks):
        a = added[k]
        if not a:
            out.append(tr)
            continue
        out.append(Tracks(
            tr.time_s, np.concatenate([np.asarray(tr.ids, np.int64), np.array([e[0] for e in a], np.int64)]),
            np.concatenate([np.asarray(tr.xy_m, float).reshape(-1, 2), np.array([e[1] for e in a])]),
            np.concatenate([np.asarray(tr.velocity_m_s, float).reshape(-1, 2), np.array([e[2] for e in a])]),
            np.concatenate([np.asarray(tr.height_m, float), np.full(len(a), np.nan)]),
            np.concatenate([np.asarray(tr.confidence, float), np.zeros(len(a))]),
            np.concatenate([np.asarray(tr.misses, np.int64), np.array([e[3] for e in a], np.int64)])))
    return out


def _smoothed_xy(steps: list, sigma_s: float) -> list[np.ndarray]:
    """Each step's positions (N, 2) after :func:`smooth_positions` (``steps``: unpacked frames)."""
    if not (np.isfinite(sigma_s) and sigma_s > 0):
        raise ValueError(f"sigma_s must be finite and > 0, got {sigma_s}")
    where: dict[int, list[tuple[int, int]]] = defaultdict(list)
    prev_t = -np.inf
    for k, (t, ids, _) in enumerate(steps):
        if t < prev_t:
            raise ValueError(f"frames must be in time order: {t} s after {prev_t} s")
        prev_t = t
        if len(np.unique(ids)) != len(ids):
            raise ValueError(f"the step at {t} s reports an identity twice: {ids.tolist()}")
        for j, i in enumerate(ids):
            where[int(i)].append((k, j))
    out = [xy.copy() for _, _, xy in steps]
    for i, kj in where.items():
        t = np.array([steps[k][0] for k, _ in kj])
        q = np.array([steps[k][2][j] for k, j in kj])
        w = np.exp(-0.5 * ((t[:, None] - t[None]) / sigma_s) ** 2)  # (n, n): row = the smoothed position
        w[np.abs(t[:, None] - t[None]) > 3.0 * sigma_s * (1.0 + 1e-9)] = 0.0  # times summed in floats: symmetric
        smoothed = (w @ q) / w.sum(axis=1, keepdims=True)
        for (k, j), p in zip(kj, smoothed):
            out[k][j] = p
    return out


def smooth_positions(frames: Iterable, sigma_s: float) -> list[tuple[float, np.ndarray, np.ndarray]]:
    """``frames`` ((time_s, ids (N,), xy_m (N, 2)) or objects with those attributes, in time order) with each
    position replaced by ``sum_k w_k p_k / sum_k w_k`` over its identity's positions ``p_k`` at times ``t_k`` within
    ``3 sigma_s`` [s], ``w_k = exp(-(t_k - t)^2 / (2 sigma_s^2))`` (a Gaussian kernel smoother in time: a straight
    walk at constant speed is left as it is, except near the ends of a tracklet, where the kernel is one-sided)."""
    steps = [_unpack(f) for f in frames]
    return [(t, ids.astype(np.int64), xy) for (t, ids, _), xy in zip(steps, _smoothed_xy(steps, sigma_s))]


def smooth_track_positions(tracks: Sequence[Tracks], sigma_s: float) -> list[Tracks]:
    """:func:`smooth_positions` on the tracker's outputs (the other fields as they were)."""
    steps = [_unpack(tr) for tr in tracks]
    return [replace(tr, xy_m=xy) for tr, xy in zip(tracks, _smoothed_xy(steps, sigma_s))]
