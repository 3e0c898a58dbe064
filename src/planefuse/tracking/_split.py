r"""Offline splitting of a recorded run's tracklets where their colours change: the online tracker's swaps undone.

Two people who walk side by side, or cross while hiding each other, can leave the online tracker with their two
tracks exchanged: track 1 follows A and then B, track 2 B and then A. No joining of whole tracklets undoes that.
But the views each track took before the exchange are A's colours and after it B's. After a run, every view a
track took is known (:class:`TrackViews`, recorded by the tracker where the offline pass asks for it), so a
tracklet is cut at the instant ``t`` that best separates its views, where (:func:`split_times`)::

    D(t) = d_app(mean of the views in [t - w, t), mean of the views in [t, t + w))  >  min_distance

``d_app`` the tracks' appearance distance (per camera where both windows hold at least 2 views, the Hellinger
distance of :func:`planefuse.tracking.descriptor_distance`, averaged), ``w`` = ``window_s``, and at least
``min_views`` views on each side of the cut in the whole tracklet. Each piece is cut again the same way until no cut
passes. The pieces get new identities (above every identity of the run) and an appearance model each, the mean of
their own views (:func:`split_tracklets`); the global association (:func:`planefuse.tracking.stitch_identities`)
then joins A's pieces and B's pieces, each by its colours. A cut is undone where the association continues neither
its earlier piece nor its later one by another tracklet (:func:`stitch_tracks`): the colours changed, but nobody
took the person over, as a person seen from a new side or in another light does.

The settings (``StitchParams.split_window_s``, ``split_min_distance``, ``split_min_views``) were chosen on simulated
seeds 1-3 (docs/identities.md).
"""

from __future__ import annotations

from collections import defaultdict
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field

import numpy as np

from ._appearance import TrackAppearance, ViewDescriptors, descriptor_distance

__all__ = ["TrackViews", "split_times", "split_tracklets", "stitch_tracks"]


@dataclass
class TrackViews:
    """Every view a track took into its appearance model, in time order: what :func:`split_times` reads.

    Attributes
    ----------
    time_s : list of float
        The step of each view [s].
    track_id : list of int
        The identity that took it (at that step).
    hist : list of ndarray, shape (C, 2, B), float32
        The view's descriptor per camera (:class:`ViewDescriptors`).
    valid : list of ndarray, shape (C,), bool
        The cameras where it has one.
    split : (float, float, int) or None
        ``(window_s, min_distance, min_views)`` of the cutting (:func:`split_times`) that the run will apply. With
        them, :meth:`finalize` reduces an identity that can take no more views to its cuts and its pieces' mean
        colours; None: every view is kept to the end.

    Notes
    -----
    About ``C x 2 x B x 4`` bytes per track and step (2 cameras, 40 bins: 640 B; 10 people tracked for an hour at
    5 Hz: 115 MB) while a track lives; once it has ended for good (:meth:`finalize`, which the tracker calls), a few
    hundred bytes per piece. A run keeps them only where ``StitchParams.split_window_s`` is set. A resumed run keeps
    the views taken since the resume.
    """

    time_s: list = field(default_factory=list)
    track_id: list = field(default_factory=list)
    hist: list = field(default_factory=list)
    valid: list = field(default_factory=list)
    split: tuple[float, float, int] | None = None
    #: identity -> (its cuts [s], its pieces' appearance in time order, None where a piece has no view)
    final: dict = field(default_factory=dict)
    #: views taken in all, those of finalized identities included
    n_taken: int = 0

    def add(self, time_s: float, track_id: int, views: ViewDescriptors, k: int) -> None:
        """Note that ``track_id`` took person ``k`` of ``views`` at ``time_s`` [s]."""
        if int(track_id) in self.final:
            raise ValueError(f"track {track_id} was finalized: it can take no more views")
        self.time_s.append(float(time_s))
        self.track_id.append(int(track_id))
        self.hist.append(views.hist[k].astype(np.float32))
        self.valid.append(views.valid[k].copy())
        self.n_taken += 1

    def __len__(self) -> int:
        return self.n_taken

    def ids(self) -> set[int]:
        """Every identity that took a view (finalized ones included)."""
        return set(self.track_id) | set(self.final)

    def by_track(self) -> dict[int, tuple[np.ndarray, np.ndarray, np.ndarray]]:
        """Per identity not finalized: times (n,) [s], descriptors (n, C, 2, B) and valid (n, C), in time order."""
        idx: dict[int, list[int]] = defaultdict(list)
        for j, i in enumerate(self.track_id):
            idx[i].append(j)
        return {i: self._gather(js) for i, js in idx.items()}

    def _gather(self, js: list[int]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Views ``js`` (indices into the lists) as times (n,) [s], descriptors (n, C, 2, B), valid (n, C), in time
        order."""
        t = np.array([self.time_s[j] for j in js])
        order = np.argsort(t, kind="stable")
        return (t[order], np.array([self.hist[j] for j in js], dtype=float)[order],
                np.array([self.valid[j] for j in js], dtype=bool)[order])

    def finalize(self, track_id: int) -> None:
        """``track_id`` has ended for good (no re-identification can revive it): keep its cuts (:func:`split_times`
        with :attr:`split`) and the mean colours of its pieces, drop its views. The offline pass then gives what it
        gives with every view kept. Nothing without :attr:`split` or without views of ``track_id``."""
        track_id = int(track_id)
        if self.split is None or track_id in self.final or track_id not in self.track_id:
            return
        keep = [j for j, i in enumerate(self.track_id) if i != track_id]
        t, hist, valid = self._gather([j for j, i in enumerate(self.track_id) if i == track_id])
        cuts = _cuts_of(t, hist, valid, *self.split)
        piece = _piece_index(cuts, t)
        pieces = [_mean_views(hist[piece == k], valid[piece == k]) if valid[piece == k].any() else None
                  for k in range(len(cuts) + 1)]
        self.final[track_id] = (cuts, pieces)
        for name in ("time_s", "track_id", "hist", "valid"):
            values = getattr(self, name)
            setattr(self, name, [values[j] for j in keep])


def _piece_index(cuts_s, t_s):
    """Which piece of a tracklet cut at ``cuts_s`` (sorted) [s] holds each instant ``t_s`` [s]: 0 before the first
    cut, k from the k-th cut on (an instant at a cut, to 1 ns, belongs to the piece it starts)."""
    return np.searchsorted(np.asarray(cuts_s, dtype=float) - 1e-9, t_s, side="right")


def _mean_views(hist: np.ndarray, valid: np.ndarray) -> TrackAppearance:
    """The mean per camera of views ``hist`` (n, C, 2, B) where ``valid`` (n, C)."""
    n = valid.sum(axis=0).astype(float)
    total = np.einsum("nc,ncpb->cpb", valid.astype(float), hist)
    return TrackAppearance(total / np.maximum(n, 1.0)[:, None, None], n)


def _best_cut(t: np.ndarray, hist: np.ndarray, valid: np.ndarray, window_s: float,
              min_views: int) -> tuple[int, float]:
    """Index of the best cut of one tracklet's views and its distance ``D`` (module docstring); (-1, nan) if none."""
    n = len(t)
    if n < 2 * min_views:
        return -1, float("nan")
    w = valid.astype(float)
    cum_h = np.concatenate([np.zeros((1,) + hist.shape[1:]), np.cumsum(w[:, :, None, None] * hist, axis=0)])
    cum_n = np.concatenate([np.zeros((1, w.shape[1])), np.cumsum(w, axis=0)])
    best, best_d = -1, -np.inf
    for s in range(min_views, n - min_views + 1):
        a = int(np.searchsorted(t, t[s] - window_s, side="left"))
        b = int(np.searchsorted(t, t[s] + window_s, side="left"))
        n1, n2 = cum_n[s] - cum_n[a], cum_n[b] - cum_n[s]
        both = (n1 >= 2) & (n2 >= 2)
        if not both.any():
            continue
        m1 = (cum_h[s] - cum_h[a])[both] / n1[both, None, None]
        m2 = (cum_h[b] - cum_h[s])[both] / n2[both, None, None]
        d = float(np.mean(descriptor_distance(m1, m2)))
        if d > best_d:
            best, best_d = s, d
    return (best, best_d) if best >= 0 else (-1, float("nan"))


def _cuts_of(t: np.ndarray, hist: np.ndarray, valid: np.ndarray, window_s: float, min_distance: float,
             min_views: int) -> list[float]:
    """The cut instants [s] of one tracklet's views (:func:`split_times`), sorted."""
    cuts: list[float] = []
    pieces = [(0, len(t))]
    while pieces:
        lo, hi = pieces.pop()
        s, d = _best_cut(t[lo:hi], hist[lo:hi], valid[lo:hi], window_s, int(min_views))
        if s >= 0 and d > min_distance:
            cuts.append(float(t[lo + s]))
            pieces += [(lo, lo + s), (lo + s, hi)]
    return sorted(cuts)


def split_times(views: TrackViews, window_s: float, min_distance: float, min_views: int) -> dict[int, list[float]]:
    """Per identity of ``views``, the instants [s] its tracklet is cut at (module docstring; sorted, maybe empty):
    from the first piece cut at its best instant where ``D > min_distance``, each piece cut again likewise. A
    finalized identity (:meth:`TrackViews.finalize`) gives the cuts it kept, which the same settings found."""
    if not (np.isfinite(window_s) and window_s > 0):
        raise ValueError(f"window_s must be finite and > 0, got {window_s}")
    if int(min_views) != min_views or min_views < 1:
        raise ValueError(f"min_views must be an integer >= 1, got {min_views}")
    if views.final and views.split != (window_s, min_distance, int(min_views)):
        raise ValueError(f"views: tracks were finalized with the cutting {views.split} (window_s, min_distance, "
                         f"min_views), not {(window_s, min_distance, int(min_views))}")
    out: dict[int, list[float]] = {i: list(cuts) for i, (cuts, _) in views.final.items()}
    for i, (t, hist, valid) in views.by_track().items():
        out[i] = _cuts_of(t, hist, valid, window_s, min_distance, int(min_views))
    return out


def split_tracklets(frames: Iterable, views: TrackViews, cuts: Mapping[int, list[float]],
                    appearance: Mapping[int, TrackAppearance] | None = None,
                    ) -> tuple[list[tuple[float, np.ndarray, np.ndarray]], dict[int, TrackAppearance],
                               dict[int, list[int]]]:
    """``frames`` ((time_s, ids (N,), xy_m (N, 2)) or objects with those attributes) with each identity of ``cuts``
    given a new identity from each cut instant on (the pieces after the first: above every identity of ``frames``
    and ``views``, in order of identity and time), the appearance of every identity: the mean of its own views
    (per piece), else ``appearance``'s model of it, and per identity cut, its pieces in time order (itself first)."""
    steps = [(float(f[0]), np.asarray(f[1]).reshape(-1).astype(np.int64), np.asarray(f[2], float).reshape(-1, 2))
             if isinstance(f, tuple) else (float(f.time_s), np.asarray(f.ids).astype(np.int64),
                                           np.asarray(f.xy_m, float).reshape(-1, 2)) for f in frames]
    top = max([int(i) for _, ids, _ in steps for i in ids] + list(views.ids()) + [0])
    new_ids: dict[int, list[tuple[float, int]]] = {}
    for i in sorted(cuts):
        for c in sorted(cuts[i]):
            top += 1
            new_ids.setdefault(i, []).append((c, top))

    def piece(i: int, t: float) -> int:
        new = new_ids.get(i, ())
        k = int(_piece_index([c for c, _ in new], t))
        return new[k - 1][1] if k else i

    relabelled = [(t, np.array([piece(int(i), t) for i in ids], dtype=np.int64), xy) for t, ids, xy in steps]
    app = dict(appearance or {})
    for i, (_, pieces) in views.final.items():  # finalized: its pieces' means, kept in time order
        for j, mean in zip([i] + [j for _, j in new_ids.get(i, ())], pieces):
            if mean is not None:
                app[int(j)] = mean
    for i, (t, hist, valid) in views.by_track().items():
        labels = np.array([piece(i, tk) for tk in t])
        for j in np.unique(labels):
            m = labels == j
            if valid[m].any():
                app[int(j)] = _mean_views(hist[m], valid[m])
    return relabelled, app, {i: [i] + [j for _, j in new] for i, new in new_ids.items()}


def stitch_tracks(frames: Iterable, appearance: Mapping[int, TrackAppearance] | None, views: TrackViews | None,
                  params) -> tuple[dict[int, int], list[tuple[float, np.ndarray, np.ndarray]]]:
    """The offline association of a run's tracks ``frames`` ((time_s, ids, xy_m) per step, in time order) as
    ``params`` (:class:`planefuse.tracking.StitchParams`) asks: where ``split_window_s`` is set and ``views`` holds
    views, the tracklets first cut (:func:`split_times`, :func:`split_tracklets`), then joined
    (:func:`planefuse.tracking.stitch_identities`). Returns the joins (identity or piece -> the identity it takes)
    and ``frames`` relabelled (each step's entries in order). Filling and smoothing are not applied here."""
    from ._stitch import chain_links, relabel_tracks, tracklet_links

    steps = [(float(f[0]), np.asarray(f[1]).reshape(-1), np.asarray(f[2], float).reshape(-1, 2))
             if isinstance(f, tuple) else (float(f.time_s), np.asarray(f.ids).reshape(-1),
                                           np.asarray(f.xy_m, float).reshape(-1, 2)) for f in frames]
    app = dict(appearance or {})
    pieces: dict[int, list[int]] = {}
    if params.split_window_s is not None and views is not None and len(views):
        cuts = split_times(views, params.split_window_s, params.split_min_distance, params.split_min_views)
        steps, app, pieces = split_tracklets(steps, views, cuts, app)
    links = tracklet_links(steps, app, params)
    continued = set(links.values())
    for parts in pieces.values():  # a cut that no other tracklet takes over on either side is undone
        for before, after in zip(parts, parts[1:]):
            if before not in links and after not in continued:
                links[before] = after
                continued.add(after)
    mapping = chain_links(links)
    return mapping, relabel_tracks(steps, mapping)
