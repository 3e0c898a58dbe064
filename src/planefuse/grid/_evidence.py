"""Contracts between sensors, the filter and the evaluation.

* :class:`Evidence` -- one sensor's observation registered on the plane stack:
  per-cell log-odds ``log P(Z | occupied) - log P(Z | free)`` of shape
  ``(L, ny, nx)``; 0 means "this sensor says nothing about the cell" (unknown),
  positive supports occupied, negative supports free. This is exactly the
  sensor model term of the Bayesian Occupancy Filter update (seed eq. 7).
* :class:`GroundDetections` -- people found on the ground plane at one instant.
"""

from __future__ import annotations

from dataclasses import InitVar, dataclass, field

import numpy as np

__all__ = [
    "Evidence",
    "GroundDetections",
    "log_odds_from_probability",
    "probability_from_log_odds",
]

#: Log-odds are clipped to +-LOG_ODDS_CLIP so that no single observation is certain.
LOG_ODDS_CLIP = 12.0


def log_odds_from_probability(p, eps: float = 1e-6) -> np.ndarray:
    """``log(p / (1 - p))`` with ``p`` clipped to ``[eps, 1 - eps]``; NaN (unknown) maps to 0."""
    p = np.asarray(p, dtype=float)
    q = np.clip(np.nan_to_num(p, nan=0.5), eps, 1.0 - eps)
    return np.log(q) - np.log1p(-q)


def probability_from_log_odds(l) -> np.ndarray:
    """Logistic function ``1 / (1 + exp(-l))``, numerically stable."""
    l = np.asarray(l, dtype=float)
    return 0.5 * (1.0 + np.tanh(0.5 * l))


@dataclass(frozen=True)
class Evidence:
    """A sensor's observation registered on every plane of the stack at one time.

    Attributes
    ----------
    time_s : float
        Time stamp of the observation [s], on the recording's common clock.
    sensor : str
        Sensor name (e.g. ``"cam0"``, ``"laser"``, ``"binaural"``).
    log_odds : ndarray, shape (L, ny, nx), float32
        ``log P(Z|occ) - log P(Z|free)`` per cell; 0 where the sensor is
        uninformative (cells it does not see), clipped to ``+-LOG_ODDS_CLIP``.
    copy : bool (init only)
        True (default): the evidence keeps its own copy of ``log_odds`` (the producer may reuse its array).
        False: the producer hands over a float32 array it will not touch again; it is kept as it is (made
        read-only) unless it must be clipped, which saves a copy of the grid per message.
    """

    time_s: float
    sensor: str
    log_odds: np.ndarray
    copy: InitVar[bool] = True

    def __post_init__(self, copy: bool) -> None:
        if not np.isfinite(self.time_s):
            raise ValueError(f"Evidence from {self.sensor!r}: time_s must be finite, got {self.time_s}")
        a = np.asarray(self.log_odds, dtype=np.float32)
        if a.ndim != 3:
            raise ValueError(f"Evidence from {self.sensor!r}: log_odds must have shape (L, ny, nx), got {a.shape}")
        # min and max are NaN where any cell is NaN, infinite where any is: one pass each, no temporary grid
        lo, hi = (float(a.min()), float(a.max())) if a.size else (0.0, 0.0)
        if not (np.isfinite(lo) and np.isfinite(hi)):
            raise ValueError(f"Evidence from {self.sensor!r}: log_odds has NaN/inf (use 0 for unknown cells)")
        fresh = a is not self.log_odds  # a converted copy already
        if lo < -LOG_ODDS_CLIP or hi > LOG_ODDS_CLIP:
            a = np.clip(a, -LOG_ODDS_CLIP, LOG_ODDS_CLIP, out=a if fresh else None)
        elif copy and not fresh:
            a = a.copy()
        elif not copy:
            a.flags.writeable = False
        object.__setattr__(self, "log_odds", a)


@dataclass(frozen=True)
class GroundDetections:
    """People detected on the ground plane at one instant.

    Attributes
    ----------
    time_s : float
        Time [s].
    xy_m : ndarray, shape (N, 2)
        Feet positions in world XY [m].
    confidence : ndarray, shape (N,)
        Score in [0, 1].
    height_m : ndarray, shape (N,)
        Estimated person height [m] (NaN if the source cannot tell).
    source : str
        What produced them (``"cameras"``, ``"laser"``, ``"bof"``...).
    """

    time_s: float
    xy_m: np.ndarray
    confidence: np.ndarray
    height_m: np.ndarray = field(default=None)  # type: ignore[assignment]
    source: str = ""

    def __post_init__(self) -> None:
        xy = np.asarray(self.xy_m, dtype=float).reshape(-1, 2) if np.size(self.xy_m) else np.zeros((0, 2))
        n = len(xy)
        conf = np.asarray(self.confidence, dtype=float).reshape(-1)
        h = np.full(n, np.nan) if self.height_m is None else np.asarray(self.height_m, dtype=float).reshape(-1)
        if conf.shape != (n,) or h.shape != (n,):
            raise ValueError(
                f"GroundDetections: xy_m {xy.shape}, confidence {conf.shape}, height_m {h.shape} disagree on N"
            )
        if not np.isfinite(xy).all():
            raise ValueError("GroundDetections: xy_m has non-finite entries")
        object.__setattr__(self, "xy_m", xy)
        object.__setattr__(self, "confidence", conf)
        object.__setattr__(self, "height_m", h)

    def __len__(self) -> int:
        return len(self.xy_m)
