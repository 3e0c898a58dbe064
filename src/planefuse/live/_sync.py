"""Frames of several cameras, arriving on their own, grouped into the synchronised instants the system fuses.

The rule is the offline run's (:func:`planefuse.vision.camera_instants`), applied to each camera's frames as they
arrive: with a rate ``max_rate_hz`` the instants are due every ``period_s = 1 / max_rate_hz`` from the first
frame's stamp ``t0``, and a camera's frame is taken for slot ``k = floor((t + early_s - t0) / period_s)``, the first
at or after ``t0 + k period_s - early_s`` (``early_s`` a quarter of the cameras' frame period: stamps jitter); the
frames before it in that slot are *skipped* (the rate is below the camera's). Without a rate, every frame is taken
(``period_s`` the frame period, ``early_s`` half of it). Instant ``k`` holds each camera's frame of slot ``k``
(None where a camera has none: unobserved) and is stamped at the earliest of them, so a live run on a recording's
frames stamped with the recording's times forms exactly the offline run's instants where every camera delivers
every frame (where a camera lost the frame at an instant, its next one in the slot is taken; the offline rule leaves
it missing); or, for frames stamped on arrival, at the slot's due time (``stamp``).

Each camera's taken frames wait in a queue of ``queue_frames``; when the system falls behind, the oldest is
*dropped* (counted on the camera), so the delay between a frame's arrival and its use stays bounded. An instant
is given when every camera that is delivering has a frame of that slot or a later one, or ``sync_wait_s`` after
the slot's first frame arrived (a camera late by more is missing from that instant).
"""

from __future__ import annotations

import math
import threading
import time
from collections import deque
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass

import numpy as np

from ._sources import SourceHealth

__all__ = ["LiveFrame", "LiveInstant", "FrameSynchroniser"]


@dataclass(frozen=True)
class LiveFrame:
    """One camera frame taken for an instant."""

    camera: int
    seq: int            # the frame's rank among those the camera delivered (0-based)
    stamp_s: float      # the time it stands for [s, run clock]
    arrival_s: float    # when it arrived [s, run clock]
    slot: int
    image: np.ndarray


@dataclass(frozen=True)
class LiveInstant:
    """A synchronised instant: its stamp [s], slot, each camera's frame (None: none) and when it was formed."""

    time_s: float
    slot: int
    frames: tuple[LiveFrame | None, ...]
    formed_s: float

    @property
    def images(self) -> list[np.ndarray | None]:
        return [None if f is None else f.image for f in self.frames]

    @property
    def arrival_s(self) -> float:
        """When the instant's last frame arrived [s, run clock]: it could not be fused before."""
        return max(f.arrival_s for f in self.frames if f is not None)


class FrameSynchroniser:
    """Per-camera slots and bounded queues, and the instants formed from them (module docstring).

    Parameters
    ----------
    names : sequence of str
        Camera names, in the recording's order.
    frame_s : float
        The cameras' (shortest) frame period [s].
    max_rate_hz : float or None
        Instants per second at most (None: every frame).
    queue_frames : int
        Frames each camera's queue holds before its oldest is dropped (>= 1).
    sync_wait_s : float or None
        Longest wait [s] for the other cameras after a slot's first frame (None: one ``period_s``).
    health : sequence of SourceHealth, optional
        Per camera, where the counts go (new ones by default).
    delivering : callable, optional
        ``delivering(camera_index)``: whether the camera is delivering now (worth waiting for); default always.
    clock : callable
        The run's clock [s].
    stamp : {"earliest", "slot"}
        An instant's time stamp: its earliest frame's (the offline rule: a live run on a recording's frames stamped
        with their times forms the offline run's instants), or its slot's due time ``t0 + k period_s`` (frames
        stamped on arrival: network delays jitter, the slots do not, so the filter's time steps stay regular and
        each instant at the output rate is an output step; every frame of the instant arrived within
        ``[-early_s, period_s - early_s)`` of it).
    """

    def __init__(self, names: Sequence[str], frame_s: float, max_rate_hz: float | None, queue_frames: int = 2,
                 sync_wait_s: float | None = None, health: Sequence[SourceHealth] | None = None,
                 delivering: Callable[[int], bool] | None = None, clock: Callable[[], float] = time.monotonic,
                 stamp: str = "earliest") -> None:
        if stamp not in ("earliest", "slot"):
            raise ValueError(f"stamp must be 'earliest' or 'slot', got {stamp!r}")
        self.stamp = stamp
        if not (frame_s > 0 and math.isfinite(frame_s)):
            raise ValueError(f"frame_s must be finite and > 0 [s], got {frame_s!r}")
        if max_rate_hz is not None and not (max_rate_hz > 0 and math.isfinite(max_rate_hz)):
            raise ValueError(f"max_rate_hz must be finite and > 0 [Hz] or None, got {max_rate_hz!r}")
        if int(queue_frames) < 1:
            raise ValueError(f"queue_frames must be >= 1, got {queue_frames!r}")
        self.names = list(names)
        self.period_s = frame_s if max_rate_hz is None else 1.0 / max_rate_hz
        self.early_s = 0.5 * frame_s if max_rate_hz is None else 0.25 * frame_s
        self.sync_wait_s = self.period_s if sync_wait_s is None else float(sync_wait_s)
        self.health = list(health) if health is not None else [SourceHealth(n) for n in self.names]
        self.delivering = delivering or (lambda c: True)
        self.clock = clock
        self.t0: float | None = None
        n = len(self.names)
        self._due = [-math.inf] * n
        self._queues: list[deque[LiveFrame]] = [deque() for _ in range(n)]
        self._queue_frames = int(queue_frames)
        self._seq = [0] * n
        self._last_stamp = [-math.inf] * n
        self._emitted_slot = -1
        #: frames stamped at or before this [s] are refused (a resumed run: its previous session's last instant)
        self.after_s = -math.inf
        self._cond = threading.Condition()
        self._closed = False
        self.finished: Callable[[], bool] = lambda: False

    def slot_time_s(self, slot: int) -> float:
        """Due time of ``slot`` [s, run clock] (the first frame's stamp ``t0`` + ``slot`` periods)."""
        return (self.t0 or 0.0) + slot * self.period_s

    def next_stamp_bound_s(self, slot: int) -> float:
        """Every instant after ``slot`` is stamped at or after this [s]."""
        return self.slot_time_s(slot + 1) - self.early_s

    def put(self, camera: int, image: np.ndarray, stamp_s: float, arrival_s: float) -> None:
        """A frame of ``camera`` stamped ``stamp_s`` arrived at ``arrival_s`` (thread-safe).

        Raises
        ------
        ValueError
            Stamps that do not increase (the stream's presentation times went back), or not after :attr:`after_s`.
        """
        if not stamp_s > self.after_s:
            raise ValueError(f"camera {self.names[camera]!r}: frame stamped {stamp_s!r} s, not after "
                             f"{self.after_s!r} s where the resumed run's previous session ended (its time stamps "
                             "must go on)")
        with self._cond:
            seq = self._seq[camera]
            self._seq[camera] += 1
            if not stamp_s > self._last_stamp[camera]:
                raise ValueError(f"camera {self.names[camera]!r}: frame stamped {stamp_s!r} s after one stamped "
                                 f"{self._last_stamp[camera]!r} s (time stamps must increase)")
            self._last_stamp[camera] = stamp_s
            h = self.health[camera]
            if self.t0 is None:
                self.t0 = stamp_s
                self._due = [stamp_s] * len(self.names)
            if stamp_s < self._due[camera] - self.early_s:
                h.skipped += 1
                return
            slot = int(math.floor((stamp_s + self.early_s - self.t0) / self.period_s))
            self._due[camera] = self.t0 + (slot + 1) * self.period_s
            if slot <= self._emitted_slot:
                h.late += 1
                return
            q = self._queues[camera]
            if len(q) >= self._queue_frames:
                q.popleft()
                h.dropped += 1
            q.append(LiveFrame(camera, seq, float(stamp_s), float(arrival_s), slot, image))
            self._cond.notify_all()

    def close(self) -> None:
        """No more instants: :meth:`instants` returns (thread-safe)."""
        with self._cond:
            self._closed = True
            self._cond.notify_all()

    def wake(self) -> None:
        """Re-check the waiting condition (a source changed state)."""
        with self._cond:
            self._cond.notify_all()

    def _next(self) -> LiveInstant | None:
        with self._cond:
            while True:
                if self._closed:
                    return None
                heads = [q[0] if q else None for q in self._queues]
                present = [h for h in heads if h is not None]
                if not present:
                    if self.finished():
                        return None
                    self._cond.wait(0.05)
                    continue
                k = min(h.slot for h in present)
                first = min(h.arrival_s for h in present if h.slot == k)
                waiting = [c for c, h in enumerate(heads) if h is None and self.delivering(c)]
                remaining = first + self.sync_wait_s - self.clock()
                if not waiting or remaining <= 0:
                    break
                self._cond.wait(min(remaining, 0.05))
            frames = tuple(self._queues[c].popleft() if h is not None and h.slot == k else None
                           for c, h in enumerate(heads))
            self._emitted_slot = k
            now = self.clock()
            for f in frames:
                if f is not None:
                    h = self.health[f.camera]
                    h.used += 1
                    h.lag_s = now - f.arrival_s
            stamp = (min(f.stamp_s for f in frames if f is not None) if self.stamp == "earliest"
                     else self.slot_time_s(k))
            return LiveInstant(stamp, k, frames, now)

    def instants(self) -> Iterator[LiveInstant]:
        """The instants in order, each as soon as it is complete (blocks; ends at :meth:`close` or when
        ``finished()`` holds and nothing is queued)."""
        while (inst := self._next()) is not None:
            yield inst
