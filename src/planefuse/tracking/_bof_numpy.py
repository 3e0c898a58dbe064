"""Plain-numpy Bayesian Occupancy Filter: the reference the numba kernels are tested and benchmarked against.

Same equations as :mod:`planefuse.tracking._bof` written with whole-array numpy operations (one Python
iteration per velocity hypothesis, none per cell). Slower; use :func:`~planefuse.tracking.bof_predict`.
"""

from __future__ import annotations

import numpy as np

from ._bof import (
    MAX_POSTERIOR_LOG_ODDS,
    MAX_UPDATE_LOG_ODDS,
    BOFParams,
    BOFState,
    _motion_offsets,
    _velocity_mixing,
    transition_probabilities,
)

__all__ = ["bof_predict_numpy", "bof_update_numpy"]


def bof_predict_numpy(state: BOFState, dt_s: float, params: BOFParams) -> BOFState:
    """Numpy twin of :func:`~planefuse.tracking.bof_predict` (in place, same arguments)."""
    if not np.isfinite(dt_s) or dt_s < 0:
        raise ValueError(f"dt_s must be finite and >= 0, got {dt_s}")
    if dt_s == 0:
        return state
    if not state.tile_active.all():
        raise ValueError("the numpy reference handles dense states only (every tile active)")
    L, K, ny, nx = state.occ_v.shape
    bilinear = params.subcell == "bilinear"
    oy, ox, ty, tx = _motion_offsets(state, dt_s, bilinear)
    p_app, p_dis, p_mix = transition_probabilities(dt_s, params)
    mix_src, mix_w = _velocity_mixing(int(params.n_velocities_per_axis), p_mix)
    p0 = params.prior_occupancy
    pad = int(max(np.abs(oy).max(), np.abs(ox).max())) + 2
    src = np.pad(state.occ_v, ((0, 0), (0, 0), (pad, pad), (pad, pad)), constant_values=p0 / K)
    fsrc = np.pad(state.free / K, ((0, 0), (pad, pad), (pad, pad)), constant_values=(1 - p0) / K)
    hat = np.empty_like(state.occ_v)
    free_hat = np.zeros_like(state.free)
    for k in range(K):
        y0, x0 = oy[k] + pad, ox[k] + pad
        if bilinear:
            w = ((1 - ty[k]) * (1 - tx[k]), (1 - ty[k]) * tx[k], ty[k] * (1 - tx[k]), ty[k] * tx[k])
            corners = ((0, 0), (0, 1), (1, 0), (1, 1))
            a = sum(wi * src[:, k, y0 + cy:y0 + cy + ny, x0 + cx:x0 + cx + nx] for wi, (cy, cx) in zip(w, corners))
            b = sum(wi * fsrc[:, y0 + cy:y0 + cy + ny, x0 + cx:x0 + cx + nx] for wi, (cy, cx) in zip(w, corners))
        else:
            a = src[:, k, y0:y0 + ny, x0:x0 + nx]
            b = fsrc[:, y0:y0 + ny, x0:x0 + nx]
        hat[:, k] = (1 - p_dis) * a + p_app * b
        free_hat += p_dis * a + (1 - p_app) * b
    mixed = np.einsum("kj,lkjyx->lkyx", mix_w.astype(np.float32), hat[:, mix_src])
    z = mixed.sum(axis=1) + free_hat
    state.occ_v[...] = mixed / z[:, None]
    state.free[...] = free_hat / z
    if state.time_s is not None:
        state.time_s += dt_s
    return state


def bof_update_numpy(state: BOFState, evidence_log_odds) -> BOFState:
    """Numpy twin of :func:`~planefuse.tracking.bof_update` (in place)."""
    lo = np.clip(np.asarray(evidence_log_odds, dtype=np.float64), -MAX_UPDATE_LOG_ODDS, MAX_UPDATE_LOG_ODDS)
    so = state.occ_v.sum(axis=1, dtype=np.float64)
    f = state.free.astype(np.float64)
    with np.errstate(divide="ignore", invalid="ignore"):
        prior = np.where((so > 0) & (f > 0), np.log(so) - np.log(f), 0.0)
    lo = np.clip(lo, np.minimum(-MAX_POSTERIOR_LOG_ODDS - prior, 0.0), np.maximum(MAX_POSTERIOR_LOG_ODDS - prior, 0.0))
    # divide numerator and denominator by max(1, e^lam) to avoid overflow
    e_occ = np.exp(np.minimum(lo, 0.0))
    e_free = np.exp(-np.maximum(lo, 0.0))
    z = so * e_occ + f * e_free
    state.occ_v *= (e_occ / z)[:, None].astype(np.float32)
    state.free[...] = f * e_free / z
    return state
