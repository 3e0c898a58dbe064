r"""Multi-person tracker on the BOF clusters ("fast clustering-tracking", Mekhnacha et al. 2008).

Each step:

1. predict every track with its BOF velocity: ``x_pred = x + v dt``;
2. associate clusters to tracks with the Hungarian algorithm (``scipy.optimize.linear_sum_assignment``) on
   the Euclidean distance ``|x_pred - x_cluster|`` [m], pairs farther than ``gate_m`` forbidden; confirmed
   tracks are served first, tentative ones get the remaining clusters;
3. a matched track takes the cluster position and height and blends its velocity with the cluster's BOF
   velocity, ``v <- (1 - a) v + a v_cluster`` (``a = velocity_gain``);
4. a confirmed track left without a cluster but predicted within the gate of a cluster taken by another
   confirmed track moving differently (two people merged while crossing: velocities differing by at
   least ``share_min_relative_speed_m_s``) shares it for at most ``max_shared_s``: both keep their own
   predicted positions and velocities;
5. an unmatched track coasts on its prediction and counts a miss; a tentative track is confirmed after
   ``confirm_hits`` consecutive hits and dropped at its first miss, a confirmed track is deleted after more
   than ``max_misses`` consecutive misses or when its prediction leaves the grid;
6. an unmatched cluster farther than ``birth_exclusion_m`` from every confirmed track starts a tentative
   track with a new id.

Reported tracks are the confirmed ones with at most ``max_coast_report`` consecutive misses; their
confidence is the last cluster confidence times ``0.5 ** misses``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import linear_sum_assignment

from .._state import StateDict, float_or_none, get, optional_float
from ._clustering import Clusters
from .._params import check_fields

__all__ = ["MultiPersonTracker", "TrackerParams", "Tracks"]


@dataclass(frozen=True)
class TrackerParams:
    """Parameters of :class:`MultiPersonTracker` (see the module docstring).

    Attributes
    ----------
    gate_m : float
        Largest association distance [m].
    confirm_hits : int
        Consecutive hits that confirm a tentative track.
    max_misses : int
        Consecutive misses after which a confirmed track is deleted.
    max_coast_report : int
        Confirmed tracks with more consecutive misses than this are not reported (still kept).
    velocity_gain : float
        ``a`` in (0, 1]: weight of the cluster's BOF velocity in the track velocity.
    max_shared_s : float
        Longest time [s] a track may share another track's cluster (people merged while crossing).
    share_min_relative_speed_m_s : float
        Tracks share a cluster only if their velocities differ by at least this [m/s] (people crossing;
        a track moving with the cluster's owner is a duplicate and is left to die).
    birth_exclusion_m : float
        No track is started on a cluster closer than this [m] to a confirmed track.
    """

    gate_m: float = 0.75
    confirm_hits: int = 3
    max_misses: int = 10
    max_coast_report: int = 2
    velocity_gain: float = 0.7
    max_shared_s: float = 1.0
    share_min_relative_speed_m_s: float = 0.3
    birth_exclusion_m: float = 0.5

    def __post_init__(self) -> None:
        check_fields(self, gate_m=">0", confirm_hits="int>=1", max_misses="int>=0", max_coast_report="int>=0",
                     max_shared_s=">=0", birth_exclusion_m=">=0", velocity_gain="(0,1]")


@dataclass(frozen=True)
class Tracks:
    """Reported tracks at one instant.

    Attributes
    ----------
    time_s : float
        Time [s].
    ids : ndarray, shape (N,), int64
        Track identities (unique over the tracker's life).
    xy_m : ndarray, shape (N, 2)
        Ground positions (world XY) [m].
    velocity_m_s : ndarray, shape (N, 2)
        Velocities (vx, vy) [m/s].
    height_m : ndarray, shape (N,)
        Heights [m] (NaN if unknown).
    confidence : ndarray, shape (N,)
        In [0, 1].
    misses : ndarray, shape (N,), int64
        Consecutive steps without a cluster (0 = observed now, > 0 = coasting on the prediction).
    """

    time_s: float
    ids: np.ndarray
    xy_m: np.ndarray
    velocity_m_s: np.ndarray
    height_m: np.ndarray
    confidence: np.ndarray
    misses: np.ndarray

    def __len__(self) -> int:
        return len(self.ids)


@dataclass
class _Track:
    id: int
    xy: np.ndarray
    v: np.ndarray
    height: float
    confidence: float
    hits: int = 1
    misses: int = 0
    confirmed: bool = False
    pred: np.ndarray | None = None  # position predicted for the current step
    v_before: np.ndarray | None = None  # velocity before the current step's correction
    cluster: int = -1  # cluster matched in the current step
    shared_s: float = 0.0  # time [s] this track has been sharing another track's cluster


class MultiPersonTracker:
    """Track people from successive :class:`~planefuse.tracking.Clusters`.

    Parameters
    ----------
    params : TrackerParams, optional
        Tracker parameters.
    extent_m : tuple of float, optional
        ``(x_min, x_max, y_min, y_max)`` [m]; a coasting track predicted outside is deleted.
    """

    def __init__(self, params: TrackerParams | None = None, extent_m=None) -> None:
        self.params = params if params is not None else TrackerParams()
        self.extent_m = extent_m
        self.tracks: list[_Track] = []
        self.time_s: float | None = None
        self._next_id = 1

    def _associate(self, tracks: list[_Track], pred: np.ndarray, clusters: Clusters, free: np.ndarray):
        """Hungarian matching of ``tracks`` to the still-free clusters; returns (track_idx, cluster_idx) pairs."""
        det = np.flatnonzero(free)
        if not tracks or det.size == 0:
            return []
        d = np.linalg.norm(pred[:, None, :] - clusters.xy_m[det][None, :, :], axis=-1)
        big = 1e6
        rows, cols = linear_sum_assignment(np.where(d <= self.params.gate_m, d, big))
        return [(r, det[c]) for r, c in zip(rows, cols) if d[r, c] <= self.params.gate_m]

    def step(self, clusters: Clusters) -> Tracks:
        """Advance to ``clusters.time_s`` and associate; return the reported tracks."""
        p = self.params
        t = float(clusters.time_s)
        dt = 0.0 if self.time_s is None else t - self.time_s
        if dt < 0:
            raise ValueError(f"clusters.time_s {t} is before the tracker time {self.time_s}")
        self.time_s = t
        for tr in self.tracks:
            tr.xy = tr.xy + tr.v * dt
            tr.pred = tr.xy.copy()
        free = np.ones(len(clusters), bool)
        matched: set[int] = set()
        for group in ([tr for tr in self.tracks if tr.confirmed], [tr for tr in self.tracks if not tr.confirmed]):
            pred = np.array([tr.xy for tr in group]).reshape(-1, 2)
            for ti, ci in self._associate(group, pred, clusters, free):
                tr = group[ti]
                tr.v_before = tr.v.copy()
                tr.cluster = ci
                free[ci] = False
                matched.add(tr.id)
                tr.xy = clusters.xy_m[ci].copy()
                tr.v = (1 - p.velocity_gain) * tr.v + p.velocity_gain * clusters.velocity_m_s[ci]
                if np.isfinite(clusters.height_m[ci]):
                    tr.height = float(clusters.height_m[ci])
                tr.confidence = float(clusters.confidence[ci])
                tr.hits += 1
                tr.misses = 0
                tr.shared_s = 0.0
                tr.confirmed = tr.confirmed or tr.hits >= p.confirm_hits
        self._share_merged_clusters(matched, clusters, dt)
        alive = []
        for tr in self.tracks:
            if tr.id not in matched:
                tr.misses += 1
                if not tr.confirmed or tr.misses > p.max_misses or not self._inside(tr.xy):
                    continue
            alive.append(tr)
        confirmed_xy = np.array([tr.xy for tr in alive if tr.confirmed]).reshape(-1, 2)
        for ci in np.flatnonzero(free):
            near = np.linalg.norm(confirmed_xy - clusters.xy_m[ci], axis=-1)
            if near.size and near.min() < p.birth_exclusion_m:
                continue  # a second mode of someone already tracked, not a new person
            alive.append(_Track(self._next_id, clusters.xy_m[ci].copy(), clusters.velocity_m_s[ci].copy(),
                                float(clusters.height_m[ci]), float(clusters.confidence[ci]),
                                confirmed=p.confirm_hits <= 1))
            self._next_id += 1
        self.tracks = alive
        return self.reported()

    def _share_merged_clusters(self, matched: set[int], clusters: Clusters, dt: float) -> None:
        """People passing close merge into one cluster: a confirmed track left without a cluster whose
        prediction lies within the gate of a cluster taken by another confirmed track shares that cluster,
        for at most ``max_shared_s`` in a row. Both tracks keep their own predicted position and velocity
        (the merged cluster's mean velocity belongs to neither) and the sharer counts no miss."""
        owners = {tr.cluster: tr for tr in self.tracks if tr.confirmed and tr.id in matched}
        if not owners:
            return
        cis = np.array(list(owners))
        for tr in self.tracks:
            if not tr.confirmed or tr.id in matched:
                continue
            d = np.linalg.norm(clusters.xy_m[cis] - tr.pred, axis=-1)
            if d.min() > self.params.gate_m or tr.shared_s + dt > self.params.max_shared_s:
                continue
            owner = owners[int(cis[np.argmin(d)])]
            if np.linalg.norm(tr.v - owner.v_before) < self.params.share_min_relative_speed_m_s:
                continue  # moving with the owner: a duplicate of the same person, not a crossing
            owner.xy, owner.v = owner.pred.copy(), owner.v_before.copy()
            tr.xy, tr.shared_s = tr.pred.copy(), tr.shared_s + dt
            matched.add(tr.id)

    def _inside(self, xy: np.ndarray) -> bool:
        if self.extent_m is None:
            return True
        x0, x1, y0, y1 = self.extent_m
        return bool(x0 <= xy[0] <= x1 and y0 <= xy[1] <= y1)

    # -- checkpoint ------------------------------------------------------------------------------------------------
    _TRACK_FIELDS = ("id", "xy", "v", "height", "confidence", "hits", "misses", "confirmed", "shared_s")

    def state_dict(self) -> StateDict:
        """Every track (tentative ones included), the clock and the next identity, as arrays.

        The per-step scratch of a track (prediction, matched cluster) is not saved: :meth:`step` sets it
        before use.
        """
        tr = self.tracks
        return {
            "time_s": optional_float(self.time_s),
            "next_id": np.asarray(self._next_id, dtype=np.int64),
            "id": np.array([t.id for t in tr], dtype=np.int64),
            "xy": np.array([t.xy for t in tr], dtype=float).reshape(-1, 2),
            "v": np.array([t.v for t in tr], dtype=float).reshape(-1, 2),
            "height": np.array([t.height for t in tr], dtype=float),
            "confidence": np.array([t.confidence for t in tr], dtype=float),
            "hits": np.array([t.hits for t in tr], dtype=np.int64),
            "misses": np.array([t.misses for t in tr], dtype=np.int64),
            "confirmed": np.array([t.confirmed for t in tr], dtype=bool),
            "shared_s": np.array([t.shared_s for t in tr], dtype=float),
        }

    def load_state_dict(self, state) -> None:
        """Restore what :meth:`state_dict` saved."""
        cols = {k: get(state, k, "tracker") for k in self._TRACK_FIELDS}
        n = len(cols["id"])
        if any(len(c) != n for c in cols.values()):
            raise ValueError(f"tracker state: track fields disagree in length "
                             f"({ {k: len(c) for k, c in cols.items()} })")
        self.tracks = [
            _Track(int(cols["id"][i]), cols["xy"][i].astype(float), cols["v"][i].astype(float),
                   float(cols["height"][i]), float(cols["confidence"][i]), hits=int(cols["hits"][i]),
                   misses=int(cols["misses"][i]), confirmed=bool(cols["confirmed"][i]),
                   shared_s=float(cols["shared_s"][i]))
            for i in range(n)
        ]
        self.time_s = float_or_none(get(state, "time_s", "tracker"))
        self._next_id = int(get(state, "next_id", "tracker"))

    def reported(self) -> Tracks:
        """Confirmed tracks with at most ``max_coast_report`` consecutive misses."""
        rep = [tr for tr in self.tracks if tr.confirmed and tr.misses <= self.params.max_coast_report]
        return Tracks(
            float(self.time_s) if self.time_s is not None else float("nan"),
            np.array([tr.id for tr in rep], dtype=np.int64),
            np.array([tr.xy for tr in rep]).reshape(-1, 2),
            np.array([tr.v for tr in rep]).reshape(-1, 2),
            np.array([tr.height for tr in rep], dtype=float),
            np.array([tr.confidence * 0.5**tr.misses for tr in rep], dtype=float),
            np.array([tr.misses for tr in rep], dtype=np.int64),
        )
