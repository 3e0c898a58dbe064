r"""Bayesian Occupancy Filter (BOF) on every plane of a :class:`~planefuse.grid.PlaneStack`.

After Coue et al., "Bayesian Occupancy Filtering for Multitarget Tracking: an Automotive Application"
(IJRR 2006) and Mekhnacha et al., "Bayesian occupancy filter based fast clustering-tracking" (IROS 2008),
as used per plane ``l`` by the seed (eq. 7)::

    P(A_c^{t-1} O_c^{t-1} O_c^t V_c^t Z_1^t..Z_S^t)
        = P(A_c^{t-1}) P(V_c^t | A_c^{t-1}) P(O_c^{t-1} | A_c^{t-1}) P(O_c^t | O_c^{t-1}) prod_i P(Z_i^t | O_c^t)

State
-----
Per plane ``l``, cell ``c`` and velocity hypothesis ``v_k`` (a regular ``n x n`` grid of velocities in
m/s, ``K = n^2``) the filter holds the joint ``P(O_c = occ, V_c = v_k)`` in ``occ_v[l, k, iy, ix]`` and
``P(O_c = free)`` in ``free[l, iy, ix]``; a free cell carries no motion, its velocity is uniform. Every
cell is normalised: ``sum_k occ_v[l, k, c] + free[l, c] = 1``. ``P(O_c = occ) = sum_k occ_v[l, k, c]``.

Prediction over an elapsed time ``dt`` (antecedent form)
--------------------------------------------------------
The antecedent of cell ``c`` under hypothesis ``v_k`` is the cell ``a_k(c) = c - v_k dt / cell_size``.
With ``alpha_k(c) = P(occ, v_k)[a_k(c)]`` and ``beta_k(c) = P(free)[a_k(c)] / K`` (antecedents outside
the grid hold the prior ``p0``: ``alpha = p0 / K``, ``beta = (1 - p0) / K``)::

    occ_hat_k(c)  = (1 - p_dis) alpha_k(c) + p_app beta_k(c)                      (occupancy transition)
    free_hat(c)   = sum_k [ p_dis alpha_k(c) + (1 - p_app) beta_k(c) ]
    occ_tilde_k   = (1 - p_mix) occ_hat_k + sum_{j in N(k)} p_mix / |N(j)| occ_hat_j  (velocity noise)
    P(occ, v_k)   = occ_tilde_k / Z,  P(free) = free_hat / Z,  Z = sum_k occ_tilde_k + free_hat

with ``N(k)`` the 4-neighbours of ``v_k`` in the velocity grid. The transition is the continuous-time
two-state Markov chain of rate ``lambda = decay_rate_hz`` whose stationary law is the prior ``p0``::

    p_app = p0 (1 - exp(-lambda dt)),  p_dis = (1 - p0) (1 - exp(-lambda dt)),  p_mix = 1 - exp(-mu dt)

so an unobserved cell (in a locally uniform neighbourhood) relaxes to the prior exactly as

    P_t(occ) = p0 + (P_0(occ) - p0) exp(-lambda t),

whatever the sequence of time steps that covers ``t`` (the documented drift rate of unknown cells).

Sub-cell motion: ``subcell="bilinear"`` (default) reads the antecedent at its fractional position with
bilinear interpolation; it diffuses mass by ``f (1 - f)`` cells^2 per step and axis for a fractional shift
``f``, which the updates sharpen again. ``subcell="accumulate"`` moves mass by whole cells, rounding the
displacement ``v_k dt / cell + r_k`` and keeping the remainder ``r_k`` (one per hypothesis, in the state)
for the next prediction: no diffusion and 1.5x faster, but the rounding phase is global, so an object of
one cell whose cell changes out of phase with it is predicted one cell ahead or behind every few steps
(objects of several cells, such as people, are not affected).

Update with the sensors present at time t (seed eq. 7)
------------------------------------------------------
With ``Lambda(c) = sum_i log P(Z_i|occ)/P(Z_i|free)`` (the sum of the sensors' log-odds, see
:class:`~planefuse.grid.Evidence`)::

    P(occ, v_k | Z) = P(occ, v_k) e^Lambda / (e^Lambda P(occ) + P(free)),
    P(free | Z)     = P(free) / (e^Lambda P(occ) + P(free)),

``Lambda`` is clipped to ``+-MAX_UPDATE_LOG_ODDS = 30`` per update, and so that the cell's posterior log-odds
stay within ``+-MAX_POSTERIOR_LOG_ODDS = 60`` (an update never pushes them further out): in float32 neither
hypothesis of a cell underflows to exactly 0, even after many saturating updates with no prediction between
them, and a later update can always revise it. The update leaves the velocity
distribution of the occupied mass unchanged (the sensors see no velocity); velocities are observed through
the motion of the occupied mass over successive updates.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numba
import numpy as np

from .._state import StateDict, float_or_none, get_shaped, optional_float
from ..grid import PlaneStack
from .._params import check_fields, require

__all__ = [
    "BOFParams",
    "BOFState",
    "BayesianOccupancyFilter",
    "bof_initial_state",
    "bof_predict",
    "bof_update",
    "transition_probabilities",
    "velocity_grid_m_s",
]


#: Bound on the summed log-odds of one update (see the module docstring).
MAX_UPDATE_LOG_ODDS = 30.0
#: Bound on a cell's posterior log-odds that an update may reach (see the module docstring).
MAX_POSTERIOR_LOG_ODDS = 60.0


@dataclass(frozen=True)
class BOFParams:
    """Parameters of the Bayesian Occupancy Filter.

    Attributes
    ----------
    n_velocities_per_axis : int
        ``n``: the velocity hypotheses are the ``n x n`` grid ``linspace(-v_max, v_max, n)`` on world X, Y
        (``K = n^2`` hypotheses per cell). Odd ``n`` includes the zero velocity.
    velocity_max_m_s : float
        ``v_max`` [m/s], largest speed along each axis.
    prior_occupancy : float
        ``p0`` in (0, 1): prior (and stationary) occupancy probability of a cell.
    decay_rate_hz : float
        ``lambda`` [1/s] >= 0: rate at which an unobserved cell relaxes to the prior,
        ``P_t - p0 = (P_0 - p0) exp(-lambda t)``.
    velocity_noise_rate_hz : float
        ``mu`` [1/s] >= 0: a fraction ``1 - exp(-mu dt)`` of each hypothesis' mass moves to its
        4-neighbours in the velocity grid per prediction.
    subcell : {"accumulate", "bilinear"}
        Sub-cell motion model (see the module docstring).
    """

    n_velocities_per_axis: int = 7
    velocity_max_m_s: float = 1.5
    prior_occupancy: float = 0.05
    decay_rate_hz: float = 0.5
    velocity_noise_rate_hz: float = 1.0
    subcell: str = "bilinear"

    def __post_init__(self) -> None:
        check_fields(self, n_velocities_per_axis="int>=1", velocity_max_m_s=">=0", prior_occupancy="(0,1)",
                     decay_rate_hz=">=0", velocity_noise_rate_hz=">=0")
        # a walking or running person: a larger value is a unit error (km/h, mm/s) or a wasted velocity grid
        require(self.velocity_max_m_s <= 10.0, self, "velocity_max_m_s",
                f"must be at most 10 m/s, got {self.velocity_max_m_s}")
        require(self.subcell in ("accumulate", "bilinear"), self, "subcell",
                f"must be 'accumulate' or 'bilinear', got {self.subcell!r}")

    @property
    def n_velocities(self) -> int:
        """Number ``K`` of velocity hypotheses per cell."""
        return int(self.n_velocities_per_axis) ** 2


def velocity_grid_m_s(params: BOFParams) -> np.ndarray:
    """Velocity hypotheses ``v_k`` [m/s], shape (K, 2) as (vx, vy); ``k = iv_y * n + iv_x``."""
    n = int(params.n_velocities_per_axis)
    axis = np.linspace(-params.velocity_max_m_s, params.velocity_max_m_s, n) if n > 1 else np.zeros(1)
    vx, vy = np.meshgrid(axis, axis)
    return np.stack([vx.ravel(), vy.ravel()], axis=-1)


@dataclass
class BOFState:
    """Mutable state of the filter over a plane stack (see the module docstring).

    Attributes
    ----------
    occ_v : ndarray, shape (L, K, ny, nx), float32
        ``P(O = occ, V = v_k)`` per plane, hypothesis and cell.
    free : ndarray, shape (L, ny, nx), float32
        ``P(O = free)`` per cell.
    velocities_m_s : ndarray, shape (K, 2), float64
        The hypotheses ``v_k`` (vx, vy) [m/s].
    cell_size_m : float
        Grid cell side [m].
    residual_cells : ndarray, shape (K, 2), float64
        Sub-cell displacement (dx, dy) [cells] not yet applied (``subcell="accumulate"``).
    time_s : float or None
        Time of the state [s]; None before the first update.
    """

    occ_v: np.ndarray
    free: np.ndarray
    velocities_m_s: np.ndarray
    cell_size_m: float
    residual_cells: np.ndarray = field(default=None)  # type: ignore[assignment]
    time_s: float | None = None

    def __post_init__(self) -> None:
        if self.residual_cells is None:
            self.residual_cells = np.zeros((len(self.velocities_m_s), 2))

    @property
    def occupancy(self) -> np.ndarray:
        """``P(O = occ) = sum_k P(occ, v_k)`` per cell, shape (L, ny, nx), float32."""
        return self.moments()[0]

    @property
    def velocity_m_s(self) -> np.ndarray:
        """Posterior mean velocity of the occupied mass ``E[V | occ]`` [m/s], shape (L, ny, nx, 2), float32."""
        return self.moments()[1]

    def moments(self) -> tuple[np.ndarray, np.ndarray]:
        """``(P(occ), E[V | occ])``: shapes (L, ny, nx) and (L, ny, nx, 2) [m/s], float32, in one pass."""
        occ = np.empty(self.free.shape, np.float32)
        vel = np.empty(self.free.shape + (2,), np.float32)
        _moments_kernel(self.occ_v, self.velocities_m_s.astype(np.float32), occ, vel)
        # float32 sums of K masses can exceed 1 by an ulp when a cell is (almost) surely occupied.
        np.clip(occ, 0.0, 1.0, out=occ)
        return occ, vel

    def copy(self) -> "BOFState":
        return BOFState(self.occ_v.copy(), self.free.copy(), self.velocities_m_s.copy(), self.cell_size_m,
                        self.residual_cells.copy(), self.time_s)


def bof_initial_state(stack: PlaneStack, params: BOFParams) -> BOFState:
    """State where every cell holds the prior: ``P(occ, v_k) = p0 / K``, ``P(free) = 1 - p0``."""
    K = params.n_velocities
    L, ny, nx = stack.shape
    occ_v = np.full((L, K, ny, nx), params.prior_occupancy / K, dtype=np.float32)
    free = np.full((L, ny, nx), 1.0 - params.prior_occupancy, dtype=np.float32)
    return BOFState(occ_v, free, velocity_grid_m_s(params), float(stack.cell_size_m))


# --------------------------------------------------------------------------------------------------------------
# numba kernels
# --------------------------------------------------------------------------------------------------------------
@numba.njit(cache=True, fastmath=True)
def _predict_kernel(occ_v, free, oy, ox, ty, tx, bilinear, p_app, p_dis, prior, mix_src, mix_w,
                    pad):  # pragma: no cover - numba
    L, K, ny, nx = occ_v.shape
    Hp = ny + 2 * pad
    Wp = nx + 2 * pad
    a_out = np.float32(prior / K)
    b_out = np.float32((1.0 - prior) / K)
    s_occ = np.float32(1.0 - p_dis)
    s_app = np.float32(p_app)
    s_dis = np.float32(p_dis)
    s_free = np.float32(1.0 - p_app)
    invK = np.float32(1.0 / K)
    for l in range(L):
        # padded copies: antecedents outside the grid hold the prior
        src = np.empty((K, Hp, Wp), np.float32)
        fsrc = np.empty((Hp, Wp), np.float32)
        fsrc[:, :] = b_out
        fsrc[pad:pad + ny, pad:pad + nx] = free[l] * invK
        for k in range(K):
            src[k, :, :] = a_out
            src[k, pad:pad + ny, pad:pad + nx] = occ_v[l, k]
        hat = np.empty((K, ny, nx), np.float32)
        free_hat = np.zeros((ny, nx), np.float32)
        for k in range(K):
            y_off = oy[k] + pad
            x_off = ox[k] + pad
            if bilinear:
                wy1 = np.float32(ty[k])
                wx1 = np.float32(tx[k])
                w00 = (1 - wy1) * (1 - wx1)
                w01 = (1 - wy1) * wx1
                w10 = wy1 * (1 - wx1)
                w11 = wy1 * wx1
                for iy in range(ny):
                    y0 = iy + y_off
                    for ix in range(nx):
                        x0 = ix + x_off
                        a = (w00 * src[k, y0, x0] + w01 * src[k, y0, x0 + 1]
                             + w10 * src[k, y0 + 1, x0] + w11 * src[k, y0 + 1, x0 + 1])
                        b = (w00 * fsrc[y0, x0] + w01 * fsrc[y0, x0 + 1]
                             + w10 * fsrc[y0 + 1, x0] + w11 * fsrc[y0 + 1, x0 + 1])
                        hat[k, iy, ix] = s_occ * a + s_app * b
                        free_hat[iy, ix] += s_dis * a + s_free * b
            else:
                for iy in range(ny):
                    y0 = iy + y_off
                    for ix in range(nx):
                        x0 = ix + x_off
                        a = src[k, y0, x0]
                        b = fsrc[y0, x0]
                        hat[k, iy, ix] = s_occ * a + s_app * b
                        free_hat[iy, ix] += s_dis * a + s_free * b
        # velocity noise (mixing with neighbouring hypotheses) and normalisation
        total = free_hat.copy()
        for k in range(K):
            for iy in range(ny):
                for ix in range(nx):
                    acc = np.float32(0.0)
                    for j in range(mix_src.shape[1]):
                        acc += np.float32(mix_w[k, j]) * hat[mix_src[k, j], iy, ix]
                    occ_v[l, k, iy, ix] = acc
                    total[iy, ix] += acc
        for iy in range(ny):
            for ix in range(nx):
                total[iy, ix] = np.float32(1.0) / total[iy, ix]
                free[l, iy, ix] = free_hat[iy, ix] * total[iy, ix]
        for k in range(K):
            for iy in range(ny):
                for ix in range(nx):
                    occ_v[l, k, iy, ix] *= total[iy, ix]


@numba.njit(cache=True, fastmath=True)
def _update_kernel(occ_v, free, log_odds, max_log_odds, max_posterior):  # pragma: no cover - numba
    L, K, ny, nx = occ_v.shape
    for l in range(L):
        s_occ = np.zeros((ny, nx), np.float32)
        for k in range(K):
            for iy in range(ny):
                for ix in range(nx):
                    s_occ[iy, ix] += occ_v[l, k, iy, ix]
        for iy in range(ny):
            for ix in range(nx):
                lam = min(max(log_odds[l, iy, ix], -max_log_odds), max_log_odds)
                f = free[l, iy, ix]
                so = s_occ[iy, ix]
                if so > 0 and f > 0:
                    prior = np.log(so) - np.log(f)
                    lam = min(max(lam, min(-max_posterior - prior, 0.0)), max(max_posterior - prior, 0.0))
                # scale occupied by e^lam and free by 1 (or occupied by 1 and free by e^-lam): no overflow
                if lam >= 0:
                    e = np.float32(np.exp(-lam))
                    z = np.float32(1.0) / (so + f * e)
                    s_occ[iy, ix] = z
                    free[l, iy, ix] = f * e * z
                else:
                    e = np.float32(np.exp(lam))
                    z = np.float32(1.0) / (so * e + f)
                    s_occ[iy, ix] = e * z
                    free[l, iy, ix] = f * z
        for k in range(K):
            for iy in range(ny):
                for ix in range(nx):
                    occ_v[l, k, iy, ix] *= s_occ[iy, ix]


@numba.njit(cache=True, fastmath=True)
def _moments_kernel(occ_v, velocities, occ, vel):  # pragma: no cover - numba
    L, K, ny, nx = occ_v.shape
    for l in range(L):
        occ[l] = 0.0
        vel[l] = 0.0
        for k in range(K):
            vx = velocities[k, 0]
            vy = velocities[k, 1]
            for iy in range(ny):
                for ix in range(nx):
                    m = occ_v[l, k, iy, ix]
                    occ[l, iy, ix] += m
                    vel[l, iy, ix, 0] += m * vx
                    vel[l, iy, ix, 1] += m * vy
        for iy in range(ny):
            for ix in range(nx):
                if occ[l, iy, ix] > 0:
                    vel[l, iy, ix, 0] /= occ[l, iy, ix]
                    vel[l, iy, ix, 1] /= occ[l, iy, ix]


# --------------------------------------------------------------------------------------------------------------
# procedural core
# --------------------------------------------------------------------------------------------------------------
def _velocity_mixing(n: int, p_mix: float) -> tuple[np.ndarray, np.ndarray]:
    """Gather form of the velocity-noise matrix: ``occ_tilde_k = sum_j mix_w[k, j] occ_hat[mix_src[k, j]]``."""
    K = n * n
    iy, ix = np.divmod(np.arange(K), n)
    nbr = []
    for dy, dx in ((-1, 0), (1, 0), (0, -1), (0, 1)):
        jy, jx = iy + dy, ix + dx
        ok = (jy >= 0) & (jy < n) & (jx >= 0) & (jx < n)
        nbr.append(np.where(ok, jy * n + jx, -1))
    nbr = np.stack(nbr, axis=1)  # (K, 4), -1 where outside the grid
    n_nb = (nbr >= 0).sum(axis=1)
    mix_src = np.empty((K, 5), np.int64)
    mix_w = np.zeros((K, 5), np.float64)
    mix_src[:, 0] = np.arange(K)
    mix_w[:, 0] = np.where(n_nb > 0, 1.0 - p_mix, 1.0)
    valid = nbr >= 0
    mix_src[:, 1:] = np.where(valid, nbr, np.arange(K)[:, None])
    mix_w[:, 1:] = np.where(valid, p_mix / np.maximum(n_nb[np.maximum(nbr, 0)], 1), 0.0)
    return mix_src, mix_w


def _motion_offsets(state: BOFState, dt_s: float, bilinear: bool):
    """Antecedent offsets ``a_k(c) - c`` split into integer (oy, ox) and fractional (ty, tx) parts [cells]."""
    d = state.velocities_m_s * (dt_s / state.cell_size_m)  # (K, 2) displacement (dx, dy) [cells]
    if bilinear:
        back = -d
        o = np.floor(back)
        t = back - o
    else:
        total = d + state.residual_cells
        shift = np.round(total)
        state.residual_cells = total - shift
        o = -shift
        t = np.zeros_like(o)
    o = o.astype(np.int64)
    return o[:, 1].copy(), o[:, 0].copy(), t[:, 1].copy(), t[:, 0].copy()


def transition_probabilities(dt_s: float, params: BOFParams) -> tuple[float, float, float]:
    """``(p_app, p_dis, p_mix)`` for an elapsed time ``dt_s`` [s] (module docstring)."""
    q = -np.expm1(-params.decay_rate_hz * dt_s)
    p_mix = -np.expm1(-params.velocity_noise_rate_hz * dt_s)
    return params.prior_occupancy * q, (1.0 - params.prior_occupancy) * q, p_mix


def bof_predict(state: BOFState, dt_s: float, params: BOFParams) -> BOFState:
    """Predict the state ``dt_s`` seconds ahead, in place (equations in the module docstring).

    Parameters
    ----------
    state : BOFState
        Filter state; modified in place and returned. ``state.time_s`` advances by ``dt_s`` if set.
    dt_s : float
        Elapsed time [s] >= 0. ``dt_s == 0`` leaves the state unchanged.
    params : BOFParams
        Must be the parameters the state was built with (same K).
    """
    if not np.isfinite(dt_s) or dt_s < 0:
        raise ValueError(f"dt_s must be finite and >= 0, got {dt_s}")
    if state.occ_v.shape[1] != params.n_velocities:
        raise ValueError(f"state has {state.occ_v.shape[1]} velocity hypotheses, params {params.n_velocities}")
    if dt_s == 0:
        return state
    bilinear = params.subcell == "bilinear"
    oy, ox, ty, tx = _motion_offsets(state, dt_s, bilinear)
    p_app, p_dis, p_mix = transition_probabilities(dt_s, params)
    mix_src, mix_w = _velocity_mixing(int(params.n_velocities_per_axis), p_mix)
    pad = int(max(np.abs(oy).max(), np.abs(ox).max())) + 2
    _predict_kernel(state.occ_v, state.free, oy, ox, ty, tx, bilinear, p_app, p_dis, params.prior_occupancy,
                    mix_src, mix_w, pad)
    if state.time_s is not None:
        state.time_s += dt_s
    return state


def bof_update(state: BOFState, evidence_log_odds) -> BOFState:
    """Bayes update with the summed sensor log-odds (seed eq. 7), in place.

    Parameters
    ----------
    state : BOFState
        Filter state; modified in place and returned.
    evidence_log_odds : array_like, shape (L, ny, nx)
        ``sum_i log P(Z_i|occ) - log P(Z_i|free)`` over the sensors observed at this time (0 = unknown).
    """
    lo = np.asarray(evidence_log_odds, dtype=np.float32)
    if lo.shape != state.free.shape:
        raise ValueError(f"evidence_log_odds must have shape {state.free.shape}, got {lo.shape}")
    if not np.isfinite(lo).all():
        raise ValueError("evidence_log_odds has NaN/inf (use 0 for unknown cells)")
    _update_kernel(state.occ_v, state.free, np.ascontiguousarray(lo), np.float32(MAX_UPDATE_LOG_ODDS),
                   np.float32(MAX_POSTERIOR_LOG_ODDS))
    return state


class BayesianOccupancyFilter:
    """One BOF per plane of a stack, filterpy-style thin object around :func:`bof_predict` / :func:`bof_update`.

    Parameters
    ----------
    stack : PlaneStack
        The planes and their grid.
    params : BOFParams, optional
        Filter parameters.

    Examples
    --------
    >>> bof = BayesianOccupancyFilter(stack)            # doctest: +SKIP
    >>> bof.predict_to(0.1); bof.update(evidence.log_odds)  # doctest: +SKIP
    >>> bof.occupancy, bof.velocity_m_s                   # doctest: +SKIP
    """

    def __init__(self, stack: PlaneStack, params: BOFParams | None = None) -> None:
        self.stack = stack
        self.params = params if params is not None else BOFParams()
        self.state = bof_initial_state(stack, self.params)

    @property
    def time_s(self) -> float | None:
        """Time of the current state [s] (None before the first :meth:`predict_to`)."""
        return self.state.time_s

    def predict(self, dt_s: float) -> None:
        """Predict ``dt_s`` [s] ahead."""
        bof_predict(self.state, dt_s, self.params)

    def predict_to(self, time_s: float) -> None:
        """Predict up to ``time_s`` [s]; the first call only sets the clock. Raises if ``time_s`` is in the past."""
        if self.state.time_s is None:
            self.state.time_s = float(time_s)
            return
        dt = float(time_s) - self.state.time_s
        if dt < 0:
            raise ValueError(f"time_s {time_s} is before the filter time {self.state.time_s} (buffer out-of-order "
                             "evidence with AsyncEvidenceBuffer)")
        bof_predict(self.state, dt, self.params)

    def update(self, log_odds) -> None:
        """Update with summed sensor log-odds, shape (L, ny, nx)."""
        bof_update(self.state, log_odds)

    @property
    def occupancy(self) -> np.ndarray:
        """``P(occ)`` per cell, shape (L, ny, nx)."""
        return self.state.occupancy

    def state_dict(self) -> StateDict:
        """The filter state as arrays (see :mod:`planefuse._state`): ``occ_v``, ``free``, ``residual_cells``,
        ``time_s`` (NaN before the first update)."""
        st = self.state
        return {"occ_v": st.occ_v.copy(), "free": st.free.copy(), "residual_cells": st.residual_cells.copy(),
                "time_s": optional_float(st.time_s)}

    def load_state_dict(self, state) -> None:
        """Restore what :meth:`state_dict` saved; shapes must match this filter's planes and velocities."""
        st = self.state
        st.occ_v = get_shaped(state, "occ_v", st.occ_v.shape, "filter").astype(np.float32, copy=True)
        st.free = get_shaped(state, "free", st.free.shape, "filter").astype(np.float32, copy=True)
        st.residual_cells = get_shaped(state, "residual_cells", st.residual_cells.shape, "filter").astype(float)
        st.time_s = float_or_none(get_shaped(state, "time_s", (), "filter"))

    @property
    def velocity_m_s(self) -> np.ndarray:
        """``E[V | occ]`` per cell [m/s], shape (L, ny, nx, 2) as (vx, vy)."""
        return self.state.velocity_m_s
