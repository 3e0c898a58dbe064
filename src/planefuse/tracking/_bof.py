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

Sub-cell motion
---------------
The antecedent offset ``v_k dt / cell_size`` is rarely a whole number of cells: at the pipeline's steps
(0.025-0.1 s) a walker at 1 m/s moves 0.25-1 cell of 0.1 m per step.

``subcell="accumulate"`` (default) moves mass by whole cells only and keeps the rest of the displacement
for later, one remainder ``r_k`` (dx, dy) [cells] per hypothesis, in the state::

    s_k = round(v_k dt / cell_size + r_k),   r_k <- v_k dt / cell_size + r_k - s_k,   a_k(c) = c - s_k

so the mass of hypothesis ``k`` is displaced by ``s_k`` cells, and over any sequence of steps its total
displacement is the exact ``v_k t / cell_size`` to within half a cell (``|r_k| <= 1/2``): a blob moving
at ``v_k`` stays a blob. The price is a global rounding phase: a one-cell object whose cell boundary is
crossed out of phase with ``r_k`` is predicted one cell ahead or behind every few steps.

``subcell="bilinear"`` reads the antecedent at its fractional position ``f`` with bilinear weights. This
is numerical diffusion: every step spreads the mass by a variance of ``f (1 - f)`` cells^2 per axis, so
the smaller the steps the more the spread per second, ``f (1 - f) / dt`` (at 0.04 s steps and 1 m/s on
0.1 m cells: 4 cells^2 per second, 0.2 m of standard deviation after one second). Measured (the test
``test_prediction_keeps_a_moving_blob_together``): after one second of prediction without updates at
0.04 s steps, the bilinear scheme keeps 56 % of a learnt blob's excess mass within one cell of its true
footprint, ``accumulate`` 95 %; ``accumulate`` is the default. The velocity noise (``mu``, below) is a
modelled spread, not a numerical one: at ``mu = 1``/s it moves 63 % of the mass to neighbouring hypotheses
(0.5 m/s apart by default) every second, which is also what lets the filter represent a velocity between
two hypotheses; on simulated seeds 1-3, ``mu = 0.3``/s tracked no better within the run-to-run noise,
so it stays at 1/s (docs/results.md).

Sparse tiles
------------
The grid is cut into tiles of ``TILE x TILE`` (8 x 8) cells. Before each prediction, the tiles within the
step's reach ``R = max_k |a_k(c) - c|`` (+1 for bilinear) cells of a cell with ``P(occ) >
p0 + sparse_min_excess`` are *active* and carry the joint above; the others are *inactive*: their cells
carry ``P(occ)`` and ``P(free)`` only, with a uniform velocity distribution, and are predicted by the
transition alone,

    P(occ) <- (1 - p_dis) P(occ) + p_app P(free),

which is what the equations above give for a cell whose neighbourhood holds the same uniform state. The
approximation: occupancy less than ``sparse_min_excess`` (default 0.01) above the prior, farther than one
step from anything more occupied, is not moved (an empty floor seen by the sensors lies below the prior,
an unobserved region at it). A tile that becomes active starts with the uniform
distribution ``P(occ, v_k) = P(occ) / K``; one that becomes inactive forgets its velocities. An
unobserved or empty region therefore costs a few operations per cell, and the cost of a step follows
the occupied area. ``sparse_min_excess=None`` keeps every tile active (the dense filter).

One pass, threads
-----------------
The prediction, the update and the moments ``P(occ)``, ``E[V | occ]`` are computed tile by tile in one
pass (:func:`bof_predict_update`; :class:`BayesianOccupancyFilter` holds a prediction until the next
update for this). From ``MIN_PARALLEL_TILES`` active tiles on, tiles are spread over numba's threads
(``numba.prange``); each is computed from the previous state alone and writes only its own cells, so the
result is the same, bit for bit, for any number of threads (``numba.set_num_threads(1)`` or
``NUMBA_NUM_THREADS=1`` for one core).

Update with the sensors present at time t (seed eq. 7)
------------------------------------------------------
With ``Lambda(c) = sum_i log P(Z_i|occ)/P(Z_i|free)`` (the sum of the sensors' log-odds, see
:class:`~planefuse.grid.Evidence`; :class:`~planefuse.tracking.EvidenceTracker` weighs each message by its share
of its sensor's error correlation time first, :mod:`planefuse.tracking._async`)::

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
from ._bof_kernels import (TILE, active_tiles, moments_kernel, retile_kernel, step_kernel, step_kernel_serial,
                           update_kernel)

__all__ = [
    "BOFParams",
    "BOFState",
    "BayesianOccupancyFilter",
    "bof_initial_state",
    "bof_predict",
    "bof_predict_update",
    "bof_update",
    "transition_probabilities",
    "velocity_grid_m_s",
]


#: Bound on the summed log-odds of one update (see the module docstring).
MAX_UPDATE_LOG_ODDS = 30.0
#: Bound on a cell's posterior log-odds that an update may reach (see the module docstring).
MAX_POSTERIOR_LOG_ODDS = 60.0
#: the bounds as the kernels take them: (update, posterior, e^posterior, e^-posterior)
#: Active tiles from which a prediction is spread over numba's threads (below, thread start-up costs more).
MIN_PARALLEL_TILES = 64
_BOUNDS = np.array([MAX_UPDATE_LOG_ODDS, MAX_POSTERIOR_LOG_ODDS, np.exp(MAX_POSTERIOR_LOG_ODDS),
                    np.exp(-MAX_POSTERIOR_LOG_ODDS)], np.float32)


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
        4-neighbours in the velocity grid per prediction (changes of a walker's velocity).
    subcell : {"accumulate", "bilinear"}
        Sub-cell motion model (see the module docstring).
    sparse_min_excess : float or None
        Cells farther than one step's motion from any cell with ``P(occ) > p0 + sparse_min_excess`` carry
        no velocity distribution and are predicted without motion (module docstring, "Sparse tiles");
        None: every cell carries one (the dense filter).
    """

    n_velocities_per_axis: int = 7
    velocity_max_m_s: float = 1.5
    prior_occupancy: float = 0.05
    decay_rate_hz: float = 0.5
    velocity_noise_rate_hz: float = 1.0
    subcell: str = "accumulate"
    sparse_min_excess: float | None = 0.01

    def __post_init__(self) -> None:
        check_fields(self, n_velocities_per_axis="int>=1", velocity_max_m_s=">=0", prior_occupancy="(0,1)",
                     decay_rate_hz=">=0", velocity_noise_rate_hz=">=0", sparse_min_excess="?>=0")
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
        ``P(O = occ, V = v_k)`` per plane, hypothesis and cell in active tiles; in inactive tiles the cell's
        ``P(O = occ)`` in the zero-velocity slot ``k0 = K // 2`` and 0 elsewhere (its velocity is uniform),
        so that ``occ_v.sum(axis=1)`` is the occupancy everywhere.
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
    tile_active : ndarray, shape (L, ceil(ny / TILE), ceil(nx / TILE)), bool
        Which tiles of ``TILE x TILE`` cells hold a velocity distribution (all of them in a new state).
    """

    occ_v: np.ndarray
    free: np.ndarray
    velocities_m_s: np.ndarray
    cell_size_m: float
    residual_cells: np.ndarray = field(default=None)  # type: ignore[assignment]
    time_s: float | None = None
    tile_active: np.ndarray = field(default=None)  # type: ignore[assignment]
    #: the second buffer the prediction writes into, and which of its tiles hold stale hypotheses (not state)
    _spare: tuple[np.ndarray, np.ndarray, np.ndarray] | None = field(default=None, repr=False, compare=False)
    #: P(occ), E[V | occ] computed by the last kernel (not state)
    _moments: tuple[np.ndarray, np.ndarray] | None = field(default=None, repr=False, compare=False)

    def __post_init__(self) -> None:
        if self.residual_cells is None:
            self.residual_cells = np.zeros((len(self.velocities_m_s), 2))
        if self.tile_active is None:
            L, _, ny, nx = self.occ_v.shape
            self.tile_active = np.ones((L, -(-ny // TILE), -(-nx // TILE)), bool)

    @property
    def k0(self) -> int:
        """Slot of the zero velocity (odd ``n``), where inactive tiles keep ``P(occ)``; -1 for even ``n``."""
        K = self.occ_v.shape[1]
        return K // 2 if int(round(np.sqrt(K))) % 2 == 1 else -1

    @property
    def occupancy(self) -> np.ndarray:
        """``P(O = occ) = sum_k P(occ, v_k)`` per cell, shape (L, ny, nx), float32."""
        return self.moments()[0]

    @property
    def velocity_m_s(self) -> np.ndarray:
        """Posterior mean velocity of the occupied mass ``E[V | occ]`` [m/s], shape (L, ny, nx, 2), float32."""
        return self.moments()[1]

    def moments(self) -> tuple[np.ndarray, np.ndarray]:
        """``(P(occ), E[V | occ])``: shapes (L, ny, nx) and (L, ny, nx, 2) [m/s], float32, in one pass
        (``E[V | occ] = 0`` in inactive tiles, the mean of the uniform velocity distribution)."""
        occ = np.empty(self.free.shape, np.float32)
        vel = np.empty(self.free.shape + (2,), np.float32)
        tiles = np.argwhere(np.ones_like(self.tile_active))
        moments_kernel(self.occ_v, self.tile_active, tiles, max(self.k0, 0), self.velocities_m_s.astype(np.float32),
                       occ, vel)
        return occ, vel

    def copy(self) -> "BOFState":
        return BOFState(self.occ_v.copy(), self.free.copy(), self.velocities_m_s.copy(), self.cell_size_m,
                        self.residual_cells.copy(), self.time_s, self.tile_active.copy())


def bof_initial_state(stack: PlaneStack, params: BOFParams) -> BOFState:
    """State where every cell holds the prior: ``P(occ, v_k) = p0 / K``, ``P(free) = 1 - p0`` (all tiles
    active; the first prediction makes the cold ones inactive)."""
    K = params.n_velocities
    L, ny, nx = stack.shape
    occ_v = np.full((L, K, ny, nx), params.prior_occupancy / K, dtype=np.float32)
    free = np.full((L, ny, nx), 1.0 - params.prior_occupancy, dtype=np.float32)
    return BOFState(occ_v, free, velocity_grid_m_s(params), float(stack.cell_size_m))


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


def _check_log_odds(state: BOFState, evidence_log_odds) -> np.ndarray:
    lo = np.asarray(evidence_log_odds, dtype=np.float32)
    if lo.shape != state.free.shape:
        raise ValueError(f"evidence_log_odds must have shape {state.free.shape}, got {lo.shape}")
    if not np.isfinite(lo).all():
        raise ValueError("evidence_log_odds has NaN/inf (use 0 for unknown cells)")
    return np.ascontiguousarray(lo)


def _active_tiles(state: BOFState, params: BOFParams, reach_cells: int) -> np.ndarray:
    """Tiles to hold a velocity distribution over the next prediction: those within ``reach_cells`` of a cell
    with ``P(occ) > p0 + sparse_min_excess`` (all tiles where that is None or ``n`` is even)."""
    if params.sparse_min_excess is None or state.k0 < 0:
        return np.ones_like(state.tile_active)
    threshold = params.prior_occupancy + params.sparse_min_excess
    return active_tiles(state.free, np.float32(min(threshold, 1.0)), int(reach_cells))


def _retile(state: BOFState, active: np.ndarray) -> None:
    """Switch the representation of the tiles whose activity changes (``retile_kernel``)."""
    off = np.argwhere(state.tile_active & ~active)
    on = np.argwhere(active & ~state.tile_active)
    if len(off):
        retile_kernel(state.occ_v, off, False, state.k0)
    if len(on):
        retile_kernel(state.occ_v, on, True, state.k0)
    state.tile_active = active


def bof_predict_update(state: BOFState, dt_s: float, evidence_log_odds, params: BOFParams) -> BOFState:
    """Predict ``dt_s`` seconds ahead and, unless ``evidence_log_odds`` is None, update, in one pass over
    the active tiles (in place; equations in the module docstring).

    Parameters
    ----------
    state : BOFState
        Filter state; modified in place and returned. ``state.time_s`` advances by ``dt_s`` if set.
    dt_s : float
        Elapsed time [s] >= 0. ``dt_s == 0``: the update alone.
    evidence_log_odds : array_like, shape (L, ny, nx), or None
        Summed sensor log-odds at the new time (as :func:`bof_update`); None: prediction only.
    params : BOFParams
        Must be the parameters the state was built with (same K).
    """
    if not np.isfinite(dt_s) or dt_s < 0:
        raise ValueError(f"dt_s must be finite and >= 0, got {dt_s}")
    if state.occ_v.shape[1] != params.n_velocities:
        raise ValueError(f"state has {state.occ_v.shape[1]} velocity hypotheses, params {params.n_velocities}")
    lo = None if evidence_log_odds is None else _check_log_odds(state, evidence_log_odds)
    if dt_s == 0:
        return state if lo is None else bof_update(state, lo)
    occ = np.empty(state.free.shape, np.float32)
    vel = np.empty(state.free.shape + (2,), np.float32)
    bilinear = params.subcell == "bilinear"
    oy, ox, wy, wx = _motion_offsets(state, dt_s, bilinear)
    p_app, p_dis, p_mix = transition_probabilities(dt_s, params)
    coef = np.array([1.0 - p_dis, p_app, p_dis, 1.0 - p_app], np.float32)
    mix_src, mix_w = _velocity_mixing(int(params.n_velocities_per_axis), p_mix)
    reach = int(max(np.abs(oy).max(), np.abs(ox).max())) + (1 if bilinear else 0)
    _retile(state, _active_tiles(state, params, reach))
    if state._spare is None:
        state._spare = (np.zeros_like(state.occ_v), np.zeros_like(state.free), np.zeros_like(state.tile_active))
    out_v, out_f, dirty = state._spare
    active = state.tile_active
    act_tiles = np.argwhere(active)
    threads = numba.get_num_threads() > 1 and len(act_tiles) >= MIN_PARALLEL_TILES
    (step_kernel if threads else step_kernel_serial)(
        state.occ_v, state.free, out_v, out_f, active, dirty, act_tiles, np.argwhere(~active), oy, ox, wy, wx,
        bilinear, coef, params.prior_occupancy, mix_src, mix_w, max(state.k0, 0),
        lo if lo is not None else state.free, lo is not None, _BOUNDS, state.velocities_m_s.astype(np.float32),
        occ, vel)
    # the old buffer becomes the spare; its active tiles hold hypotheses the next inactive write must clear
    state._spare = (state.occ_v, state.free, active.copy())
    state.occ_v, state.free = out_v, out_f
    state._moments = (occ, vel)
    if state.time_s is not None:
        state.time_s += dt_s
    return state


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
    return bof_predict_update(state, dt_s, None, params)


def bof_update(state: BOFState, evidence_log_odds) -> BOFState:
    """Bayes update with the summed sensor log-odds (seed eq. 7), in place.

    Parameters
    ----------
    state : BOFState
        Filter state; modified in place and returned.
    evidence_log_odds : array_like, shape (L, ny, nx)
        ``sum_i log P(Z_i|occ) - log P(Z_i|free)`` over the sensors observed at this time (0 = unknown).
    """
    lo = _check_log_odds(state, evidence_log_odds)
    occ = np.empty(state.free.shape, np.float32)
    vel = np.empty(state.free.shape + (2,), np.float32)
    update_kernel(state.occ_v, state.free, state.tile_active, np.argwhere(np.ones_like(state.tile_active)),
                  max(state.k0, 0), lo, _BOUNDS, state.velocities_m_s.astype(np.float32), occ, vel)
    state._moments = (occ, vel)
    return state


class BayesianOccupancyFilter:
    """One BOF per plane of a stack, filterpy-style thin object around :func:`bof_predict_update`.

    A prediction is held until the next update (or until the state is read) and then done in the same
    pass over the grid as the update: ``predict_to(t); update(z)`` is :func:`bof_predict_update`.

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
    >>> occupancy, velocity_m_s = bof.moments()         # doctest: +SKIP
    """

    def __init__(self, stack: PlaneStack, params: BOFParams | None = None) -> None:
        self.stack = stack
        self.params = params if params is not None else BOFParams()
        self._state = bof_initial_state(stack, self.params)
        self._pending_s = 0.0  # prediction [s] not yet applied

    @property
    def state(self) -> BOFState:
        """The filter state, with any held prediction applied."""
        self._flush()
        return self._state

    def _flush(self) -> None:
        if self._pending_s > 0:
            dt, self._pending_s = self._pending_s, 0.0
            bof_predict_update(self._state, dt, None, self.params)

    @property
    def time_s(self) -> float | None:
        """Time of the current state [s] (None before the first :meth:`predict_to`)."""
        t = self._state.time_s
        return None if t is None else t + self._pending_s

    def predict(self, dt_s: float) -> None:
        """Predict ``dt_s`` [s] ahead."""
        if not np.isfinite(dt_s) or dt_s < 0:
            raise ValueError(f"dt_s must be finite and >= 0, got {dt_s}")
        self._flush()
        self._pending_s = float(dt_s)

    def predict_to(self, time_s: float) -> None:
        """Predict up to ``time_s`` [s]; the first call only sets the clock. Raises if ``time_s`` is in the past."""
        if self._state.time_s is None:
            self._state.time_s = float(time_s)
            return
        dt = float(time_s) - self.time_s
        if dt < 0:
            raise ValueError(f"time_s {time_s} is before the filter time {self.time_s} (buffer out-of-order "
                             "evidence with AsyncEvidenceBuffer)")
        self.predict(dt)

    def update(self, log_odds) -> None:
        """Update with summed sensor log-odds, shape (L, ny, nx) (after the held prediction, in one pass)."""
        dt, self._pending_s = self._pending_s, 0.0
        bof_predict_update(self._state, dt, log_odds, self.params)

    def moments(self) -> tuple[np.ndarray, np.ndarray]:
        """``(P(occ), E[V | occ])`` per cell, shapes (L, ny, nx) and (L, ny, nx, 2) [m/s]: computed by the last
        prediction or update in the same pass, new arrays at every step."""
        st = self.state
        if st._moments is None:
            st._moments = st.moments()
        return st._moments

    @property
    def occupancy(self) -> np.ndarray:
        """``P(occ)`` per cell, shape (L, ny, nx)."""
        return self.moments()[0]

    @property
    def velocity_m_s(self) -> np.ndarray:
        """``E[V | occ]`` per cell [m/s], shape (L, ny, nx, 2) as (vx, vy)."""
        return self.moments()[1]

    def state_dict(self) -> StateDict:
        """The filter state as arrays (see :mod:`planefuse._state`): ``occ_v``, ``free``, ``residual_cells``,
        ``tile_active``, ``time_s`` (NaN before the first update), the held prediction applied."""
        st = self.state
        return {"occ_v": st.occ_v.copy(), "free": st.free.copy(), "residual_cells": st.residual_cells.copy(),
                "tile_active": st.tile_active.copy(), "time_s": optional_float(st.time_s)}

    def load_state_dict(self, state) -> None:
        """Restore what :meth:`state_dict` saved; shapes must match this filter's planes and velocities."""
        st = self._state
        self._pending_s = 0.0
        st.occ_v = get_shaped(state, "occ_v", st.occ_v.shape, "filter").astype(np.float32, copy=True)
        st.free = get_shaped(state, "free", st.free.shape, "filter").astype(np.float32, copy=True)
        st.residual_cells = get_shaped(state, "residual_cells", st.residual_cells.shape, "filter").astype(float)
        st.tile_active = get_shaped(state, "tile_active", st.tile_active.shape, "filter").astype(bool)
        st.time_s = float_or_none(get_shaped(state, "time_s", (), "filter"))
        st._spare = st._moments = None
