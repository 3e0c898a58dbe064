"""Asynchronous sensors: re-order evidence inside a time window and group what arrived at the same instant.

Sensors publish at their own rates and their messages reach the filter late and out of order (network,
processing latency). :class:`AsyncEvidenceBuffer` holds every message until the newest time stamp seen is
``window_s`` past it, then releases the held messages in time order; messages whose stamps agree within
``merge_tolerance_s`` are released together as one :class:`EvidenceBatch` whose log-odds are the sum of the
sensors' log-odds (the product over sensors of seed eq. 7). A message older than what was already released
cannot be used any more without re-running the filter: it is counted in :attr:`AsyncEvidenceBuffer.n_late`,
kept in :attr:`AsyncEvidenceBuffer.late` and a :class:`LateEvidenceWarning` is issued.

Temporally correlated sensor errors
-----------------------------------
The filter's update (seed eq. 7) takes every message as an observation independent of the sensor's previous
one. A camera's errors are not: the ghost where silhouette rays of two standing people cross, a single
view's ray through cells no other camera sees, a shadow, a camera that dropped out (fewer views to
disagree) persist over many frames. Summing ``N`` such frames gives ``N`` times the log-odds of one, and a
filter that remembers ``1 / decay_rate_hz`` seconds turns a persistent error of a 25 Hz camera into
near-certainty, drowning the other sensors (a laser's free space). With a correlation time ``tau_s`` [s]
per sensor ``s``, the buffer weighs the ``i``-th message of ``s``, time-stamped ``t_i``, by its share of that
time::

    w_i = min(1, (t_i - t_{i-1}) / tau_s)        (w_1 = 1; tau_s = 0: w_i = 1, independent messages)
    Lambda(c) = sum_{messages i of the batch} w_i log P(Z_i | occ) / P(Z_i | free)

so that, over a span ``T >> tau_s``, a sensor brings about ``T / tau_s`` observations' worth of log-odds
whatever its frame rate (``T / dt`` unweighted), and a message after a gap (dropped frames, a slow
sensor) counts more, up to one whole observation.
"""

from __future__ import annotations

import heapq
import warnings
from collections.abc import Iterator, Mapping
from dataclasses import dataclass

import numpy as np

from .._state import StateDict, get, strings
from ..grid import Evidence

__all__ = ["AsyncEvidenceBuffer", "EvidenceBatch", "LateEvidenceWarning"]


class LateEvidenceWarning(UserWarning):
    """Evidence arrived after the filter had already passed its time stamp (older than the window)."""


@dataclass(frozen=True)
class EvidenceBatch:
    """Evidence of every sensor observed at one instant.

    Attributes
    ----------
    time_s : float
        Time stamp of the batch [s] (the earliest stamp among the merged messages).
    sensors : tuple of str
        Sensors whose messages were merged, in arrival order.
    log_odds : ndarray, shape (L, ny, nx), float32
        Sum over the merged messages of ``log P(Z_i|occ) - log P(Z_i|free)``.
    """

    time_s: float
    sensors: tuple[str, ...]
    log_odds: np.ndarray


class AsyncEvidenceBuffer:
    """Re-ordering buffer in front of the filter.

    Parameters
    ----------
    window_s : float
        How long [s] a message is held for older ones to arrive: a message with stamp ``t`` is released once
        a message with stamp ``>= t + window_s`` has been pushed (or on :meth:`flush`). 0 releases at once.
    merge_tolerance_s : float
        Messages whose stamps differ by at most this [s] form one batch.
    shape : tuple of int, optional
        Expected ``(L, ny, nx)`` of every message's log-odds; checked on push if given.
    correlation_s : mapping of str to float, optional
        Error correlation time ``tau_s`` [s] >= 0 per sensor name (module docstring): each message's
        log-odds are weighted by ``min(1, dt / tau_s)``, ``dt`` the time since that sensor's previous
        message. Sensors not listed, and ``tau_s = 0``, are not weighted.
    """

    def __init__(self, window_s: float = 0.2, merge_tolerance_s: float = 1e-6, shape=None,
                 correlation_s: Mapping[str, float] | None = None) -> None:
        if not (np.isfinite(window_s) and window_s >= 0):
            raise ValueError(f"window_s must be finite and >= 0, got {window_s}")
        if not (np.isfinite(merge_tolerance_s) and merge_tolerance_s >= 0):
            raise ValueError(f"merge_tolerance_s must be finite and >= 0, got {merge_tolerance_s}")
        self.window_s = float(window_s)
        self.merge_tolerance_s = float(merge_tolerance_s)
        self.shape = None if shape is None else tuple(int(s) for s in shape)
        self.correlation_s = dict(correlation_s or {})
        for name, tau in self.correlation_s.items():
            if not (np.isfinite(tau) and tau >= 0):
                raise ValueError(f"correlation_s[{name!r}] must be finite and >= 0 s, got {tau}")
        #: time stamp [s] of each weighted sensor's last released message
        self.last_time_s: dict[str, float] = {}
        self._heap: list[tuple[float, int, Evidence]] = []
        self._next_seq = 0
        self._newest_s = -np.inf
        self.released_until_s: float = -np.inf
        self.late: list[Evidence] = []

    @property
    def n_late(self) -> int:
        """Number of messages that arrived older than the already released time (not used by the filter)."""
        return len(self.late)

    @property
    def n_pending(self) -> int:
        """Number of messages held in the buffer."""
        return len(self._heap)

    def add(self, evidence: Evidence) -> bool:
        """Hold one message without releasing anything; False (and a warning) if it arrived too late."""
        if not isinstance(evidence, Evidence):
            raise ValueError(f"evidence must be a planefuse.grid.Evidence, got {type(evidence).__name__}")
        if self.shape is not None and evidence.log_odds.shape != self.shape:
            raise ValueError(f"Evidence from {evidence.sensor!r} has shape {evidence.log_odds.shape}, "
                             f"expected {self.shape}")
        t = float(evidence.time_s)
        if t < self.released_until_s - self.merge_tolerance_s:
            self.late.append(evidence)
            warnings.warn(
                f"Evidence from {evidence.sensor!r} at t={t:.6f} s arrived after the filter reached "
                f"t={self.released_until_s:.6f} s (older than the {self.window_s} s window); not fused "
                f"({self.n_late} late so far)", LateEvidenceWarning, stacklevel=3)
            return False
        heapq.heappush(self._heap, (t, self._next_seq, evidence))
        self._next_seq += 1
        self._newest_s = max(self._newest_s, t)
        return True

    def ready(self, final: bool = False, until_s: float | None = None) -> Iterator[EvidenceBatch]:
        """Release the batches that are ready (all of them if ``final``), one at a time and in time order;
        with ``until_s`` [s] also those stamped at or before it (the caller knows no message stamped before
        ``until_s + merge_tolerance_s`` is still to come).

        A batch leaves the buffer only when it is taken, so the buffer's state (:meth:`state_dict`) is
        consistent between any two batches.
        """
        until = np.inf if final else self._newest_s - self.window_s
        if until_s is not None:
            until = max(until, float(until_s))
        while (batch := self._pop_batch(until)) is not None:
            yield batch

    def push(self, evidence: Evidence) -> list[EvidenceBatch]:
        """Add one message; return the batches that became ready, in time order."""
        self.add(evidence)
        return list(self.ready())

    def flush(self) -> list[EvidenceBatch]:
        """Release everything still held, in time order."""
        return list(self.ready(final=True))

    def _pop_batch(self, until_s: float) -> EvidenceBatch | None:
        if not self._heap or self._heap[0][0] > until_s:
            return None
        t0 = self._heap[0][0]
        group = []
        while self._heap and self._heap[0][0] <= t0 + self.merge_tolerance_s:
            group.append(heapq.heappop(self._heap)[2])
        # a message at the time already released is one more measurement of that instant (dt = 0)
        t_batch = max(t0, self.released_until_s)
        weights = [self._weight(e) for e in group]
        if all(w == 1.0 for w in weights):
            log_odds = np.sum([e.log_odds for e in group], axis=0, dtype=np.float32)
        else:
            log_odds = np.zeros(group[0].log_odds.shape, np.float32)
            for w, e in zip(weights, group):
                log_odds += np.float32(w) * e.log_odds
        self.released_until_s = t_batch
        return EvidenceBatch(t_batch, tuple(e.sensor for e in group), log_odds)

    def _weight(self, evidence: Evidence) -> float:
        """``w_i = min(1, (t_i - t_{i-1}) / tau_s)`` of a released message (module docstring)."""
        tau = self.correlation_s.get(evidence.sensor, 0.0)
        if tau <= 0:
            return 1.0
        t = float(evidence.time_s)
        prev = self.last_time_s.get(evidence.sensor)
        self.last_time_s[evidence.sensor] = t if prev is None else max(prev, t)
        return 1.0 if prev is None else min(1.0, max(t - prev, 0.0) / tau)

    # -- checkpoint ------------------------------------------------------------------------------------------------
    def state_dict(self) -> StateDict:
        """Held and late messages, the clock and each weighted sensor's last time stamp, as arrays
        (see :mod:`planefuse._state`)."""
        held = sorted(self._heap, key=lambda item: item[:2])
        return {
            **_pack_evidence("held", [e for _, _, e in held]),
            "held_seq": np.array([s for _, s, _ in held], dtype=np.int64),
            **_pack_evidence("late", self.late),
            "next_seq": np.asarray(self._next_seq),
            "newest_s": np.asarray(self._newest_s),  # -inf before the first message
            "released_until_s": np.asarray(self.released_until_s),
            "last_sensor": strings(list(self.last_time_s)),
            "last_time_s": np.array(list(self.last_time_s.values()), dtype=float),
        }

    def load_state_dict(self, state: Mapping[str, np.ndarray]) -> None:
        """Restore what :meth:`state_dict` saved."""
        held = _unpack_evidence("held", state, self.shape)
        seq = get(state, "held_seq", "evidence buffer")
        if len(seq) != len(held):
            raise ValueError(f"evidence buffer state: {len(held)} held messages but {len(seq)} sequence numbers")
        self._heap = [(float(e.time_s), int(s), e) for s, e in zip(seq, held)]
        heapq.heapify(self._heap)
        self.late = _unpack_evidence("late", state, self.shape)
        self._next_seq = int(get(state, "next_seq", "evidence buffer"))
        self._newest_s = float(get(state, "newest_s", "evidence buffer"))
        self.released_until_s = float(get(state, "released_until_s", "evidence buffer"))
        names, times = get(state, "last_sensor", "evidence buffer"), get(state, "last_time_s", "evidence buffer")
        if len(names) != len(times):
            raise ValueError(f"evidence buffer state: {len(names)} sensors but {len(times)} last time stamps")
        self.last_time_s = {str(n): float(t) for n, t in zip(names, times)}


def _pack_evidence(name: str, items: list[Evidence]) -> StateDict:
    return {
        f"{name}_time_s": np.array([e.time_s for e in items], dtype=float),
        f"{name}_sensor": strings([e.sensor for e in items]),
        f"{name}_log_odds": (np.stack([e.log_odds for e in items]) if items
                             else np.zeros((0, 0, 0, 0), np.float32)),
    }


def _unpack_evidence(name: str, state: Mapping[str, np.ndarray], shape) -> list[Evidence]:
    times = get(state, f"{name}_time_s", "evidence buffer")
    sensors = get(state, f"{name}_sensor", "evidence buffer")
    log_odds = get(state, f"{name}_log_odds", "evidence buffer")
    if not (len(times) == len(sensors) == len(log_odds)):
        raise ValueError(f"evidence buffer state: {name} messages disagree in number ({len(times)} times, "
                         f"{len(sensors)} sensors, {len(log_odds)} grids)")
    if len(times) and shape is not None and log_odds.shape[1:] != tuple(shape):
        raise ValueError(f"evidence buffer state: {name} grids have shape {log_odds.shape[1:]}, expected {shape}")
    return [Evidence(float(t), str(s), g) for t, s, g in zip(times, sensors, log_odds)]
