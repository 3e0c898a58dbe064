"""Multi-view fusion of foreground likelihoods on every plane (Khan & Shah), as log-odds.

Model (per plane, per cell X, cameras i = 1..C that see X; see docs/cameras.md)::

    f_i       = foreground likelihood of the pixel of camera i that sees X     (registration: one gather)
    P(F_i | X occupied) = p_d        P(F_i | X free) = p_fa                    (sensor model)
    soft observation:  P(f_i | occ) = f_i p_d  + (1 - f_i)(1 - p_d)
                       P(f_i | free) = f_i p_fa + (1 - f_i)(1 - p_fa)
    log-odds(X) = sum_i log P(f_i | occ) - log P(f_i | free)                   (views independent given X)

Khan & Shah's synergy map ``prod_i f_i`` is the limit ``p_fa -> 0`` of this
product of per-view likelihoods; ``p_fa > 0`` keeps one background view from
vetoing a cell outright, and ``p_d < 1`` bounds what one foreground view can say.
Cameras that do not see X contribute nothing (log-odds 0 = unknown), so a cell
seen by no camera stays unknown, never free.

The hot loop (one gather per camera and cell, table look-up, sum) is a numba
kernel over foreground likelihoods quantised to 256 levels.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass
from typing import Sequence

import cv2
import numpy as np
from numba import njit

from ..grid import Evidence, PlaneStack
from ..registration import ImagePlaneLookup
from .._params import check_fields, require

__all__ = ["CameraFusion", "FusionParams", "NEUTRAL_FOREGROUND", "NEUTRAL_LEVEL", "log_odds_table",
           "max_log_ratio", "quantise_foreground"]

_LEVELS = 256

#: The foreground likelihood that is no evidence either way: ``P(f | occ) = P(f | free)`` at ``f = 1/2`` for every
#: ``p_d``, ``p_fa`` (module docstring). A pixel the camera does not observe gets it; quantised, it is level 128,
#: whose log-likelihood ratio is ``log((1 + (2 p_d - 1) / 255) / (1 + (2 p_fa - 1) / 255))`` (0.0055 at the
#: defaults, against 1.5 for a certain foreground pixel).
NEUTRAL_FOREGROUND = 0.5
#: :data:`NEUTRAL_FOREGROUND` as a quantised level (:func:`quantise_foreground`'s rounding).
NEUTRAL_LEVEL = int(np.rint((_LEVELS - 1) * NEUTRAL_FOREGROUND))


@dataclass(frozen=True)
class FusionParams:
    """Camera sensor model.

    Attributes
    ----------
    p_detect : float
        P(pixel is foreground | the cell it sees is occupied).
    p_false_alarm : float
        P(pixel is foreground | the cell it sees is free) -- covers noise and,
        mostly, the person standing in front of or behind the cell on the ray.
    """

    p_detect: float = 0.9
    p_false_alarm: float = 0.2

    def __post_init__(self) -> None:
        check_fields(self, p_detect="(0,1)", p_false_alarm="(0,1)")
        require(self.p_false_alarm < self.p_detect, self, "p_false_alarm",
                f"P(foreground | free) = {self.p_false_alarm} must be below P(foreground | occupied) = "
                f"{self.p_detect} (otherwise foreground would be evidence of free space)")


def max_log_ratio(params: FusionParams) -> float:
    """Largest per-view log-likelihood ratio ``log(p_d / p_fa)`` (a certain foreground pixel)."""
    return float(np.log(params.p_detect / params.p_false_alarm))


def log_odds_table(params: FusionParams) -> np.ndarray:
    """Per-view log-likelihood ratio for each quantised foreground likelihood ``q / 255``.

    Returns
    -------
    ndarray, shape (256,), float32
        ``log P(f | occ) - log P(f | free)`` for ``f = q / 255``, q = 0..255.
    """
    f = np.arange(_LEVELS) / (_LEVELS - 1.0)
    pd, pfa = params.p_detect, params.p_false_alarm
    return (np.log(f * pd + (1 - f) * (1 - pd)) - np.log(f * pfa + (1 - f) * (1 - pfa))).astype(np.float32)


def quantise_foreground(fg: np.ndarray) -> np.ndarray:
    """A foreground likelihood in [0, 1] (float) as the fusion's 256 levels, uint8 ``round(255 f)``."""
    return cv2.convertScaleAbs(np.asarray(fg, dtype=np.float32), alpha=_LEVELS - 1.0)


@njit(cache=True, boundscheck=False)
def _fuse_kernel(fg_q, lut, active, table, weights, out):  # pragma: no cover - compiled
    # out[n] = sum over active cameras c seeing cell n of weights[c] table[fg_q[lut[c, n]]]
    n_cam, n_cell = lut.shape
    out[:] = 0.0
    for c in range(n_cam):
        if not active[c]:
            continue
        row = lut[c]
        w = weights[c]  # 1.0 for a camera at full weight: the product is exact, the sums the unweighted ones
        for n in range(n_cell):
            k = row[n]
            if k >= 0:
                out[n] += w * table[fg_q[k]]


class CameraFusion:
    """Precomputed fusion of C cameras onto a plane stack.

    Parameters
    ----------
    lookups : sequence of ImagePlaneLookup
        One per camera, all built on ``stack``.
    stack : PlaneStack
    params : FusionParams
    names : sequence of str, optional
        Camera names (``cam0``... by default) for reports and errors.

    Notes
    -----
    Cameras that see no cell of the grid are kept (they simply add nothing)
    and listed in :attr:`blind_cameras` with a warning.
    """

    def __init__(self, lookups: Sequence[ImagePlaneLookup], stack: PlaneStack,
                 params: FusionParams = FusionParams(), names: Sequence[str] | None = None) -> None:
        if len(lookups) == 0:
            raise ValueError("lookups must hold at least one camera")
        self.names = [f"cam{i}" for i in range(len(lookups))] if names is None else list(names)
        if len(self.names) != len(lookups):
            raise ValueError(f"names has {len(self.names)} entries for {len(lookups)} lookups")
        for name, lk in zip(self.names, lookups):
            if lk.stack != stack:
                raise ValueError(f"{name}: lookup was built for another plane stack")
        self.stack = stack
        self.params = params
        self.sizes = [(lk.height_px, lk.width_px) for lk in lookups]
        offsets = np.concatenate([[0], np.cumsum([h * w for h, w in self.sizes])])
        self._offsets = offsets
        self._fg_q = np.zeros(int(offsets[-1]), dtype=np.uint8)
        lut = np.empty((len(lookups), int(np.prod(stack.shape))), dtype=np.int64)
        for c, lk in enumerate(lookups):
            idx = lk.pixel_index.reshape(-1).astype(np.int64)
            lut[c] = np.where(idx < lk.sentinel, idx + offsets[c], -1)
        if offsets[-1] >= np.iinfo(np.int32).max:
            raise ValueError("total image size of all cameras too large for an int32 lookup")
        self._lut = lut.astype(np.int32)
        self._table = log_odds_table(params)
        self._views: dict[tuple, np.ndarray] = {}
        self.active = np.ones(len(lookups), dtype=np.bool_)
        self._unit_weights = np.ones(len(lookups), dtype=np.float32)
        self.blind_cameras = [n for n, row in zip(self.names, self._lut) if not np.any(row >= 0)]
        if self.blind_cameras:
            warnings.warn(f"cameras {self.blind_cameras} see no cell of the plane stack; they add no evidence",
                          stacklevel=2)

    @property
    def n_cameras(self) -> int:
        """Number of cameras C."""
        return len(self.names)

    def cameras_seeing(self, active=None) -> np.ndarray:
        """Number of cameras seeing each cell, shape (L, ny, nx), float32.

        ``active`` (C,) bool restricts the count to cameras that delivered a
        frame (all by default). Cached per set of active cameras.
        """
        key = tuple(np.ones(self.n_cameras, bool) if active is None else np.asarray(active, bool))
        if key not in self._views:
            seen = (self._lut[np.asarray(key)] >= 0).sum(axis=0)
            self._views[key] = seen.reshape(self.stack.shape).astype(np.float32)
        return self._views[key]

    def log_odds(self, foregrounds: Sequence[np.ndarray | None], out: np.ndarray | None = None,
                 weights: Sequence[float] | None = None) -> np.ndarray:
        """Fused per-plane log-odds of occupancy from one instant's foreground likelihoods.

        Parameters
        ----------
        foregrounds : sequence of C arrays (height_px, width_px) or None
            Foreground likelihood in [0, 1] (float) or 0..255 (uint8) per
            camera; ``None`` for a camera without a frame at this instant (it
            then contributes nothing).
        out : ndarray, shape (L, ny, nx), float32, optional
        weights : sequence of C floats in [0, 1], optional
            Each camera's log-likelihood ratios are multiplied by its weight (its share of an independent
            observation, :func:`planefuse.vision.camera_detections` ``correlation_s``); default 1.

        The cameras that delivered a frame are left in :attr:`active` (C,) bool;
        ``cameras_seeing(self.active)`` counts the views behind each cell.

        Returns
        -------
        ndarray, shape (L, ny, nx), float32
            ``sum_i w_i (log P(f_i | occ) - log P(f_i | free))`` over the cameras
            seeing each cell; 0 where none does.
        """
        if len(foregrounds) != self.n_cameras:
            raise ValueError(f"expected {self.n_cameras} foreground images (None for missing), got {len(foregrounds)}")
        if weights is None:
            w = self._unit_weights
        else:
            w = np.asarray(weights, dtype=np.float32)
            if w.shape != (self.n_cameras,) or not np.all((w >= 0) & (w <= 1)):
                raise ValueError(f"weights must be {self.n_cameras} values in [0, 1], got {np.asarray(weights)!r}")
        active = np.zeros(self.n_cameras, dtype=np.bool_)
        for c, fg in enumerate(foregrounds):
            if fg is None:
                continue
            img = np.asarray(fg)
            if img.shape != self.sizes[c]:
                raise ValueError(
                    f"{self.names[c]}: foreground must be {self.sizes[c][0]}x{self.sizes[c][1]} (rows x cols) "
                    f"as in the camera's calibration, got shape {img.shape}"
                )
            dst = self._fg_q[self._offsets[c]:self._offsets[c + 1]]
            if img.dtype == np.uint8:
                dst[:] = img.reshape(-1)
            else:
                dst[:] = quantise_foreground(img).reshape(-1)
            active[c] = True
        if out is None:
            out = np.empty(self.stack.shape, dtype=np.float32)
        elif out.shape != self.stack.shape or out.dtype != np.float32:
            raise ValueError(f"out must be float32 of shape {self.stack.shape}, got {out.dtype} {out.shape}")
        _fuse_kernel(self._fg_q, self._lut, active, self._table, w, out.reshape(-1))
        self.active = active
        return out

    def evidence(self, foregrounds: Sequence[np.ndarray | None], time_s: float, sensor: str = "cameras",
                 weights: Sequence[float] | None = None) -> Evidence:
        """:meth:`log_odds` wrapped in the :class:`~planefuse.grid.Evidence` contract."""
        return Evidence(float(time_s), sensor, self.log_odds(foregrounds, weights=weights), copy=False)  # a new grid
