"""The BOF against oracles that share nothing with its code: a per-cell reference written from the module
docstring's equations, and invariants (mass conservation, [0, 1], revisability after saturation).

The numpy twin in ``planefuse.tracking._bof_numpy`` reuses the kernels' helpers (motion offsets, velocity
mixing), so a bug in those helpers is invisible to ``test_numba_matches_numpy_reference``; the reference
here recomputes the antecedents, the bilinear read, the transition and the velocity mixing from scratch.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from planefuse.grid import PlaneStack
from planefuse.tracking import BOFParams, bof_initial_state, bof_predict, bof_update

CELL_M = 0.1
TINY = PlaneStack.from_extent([0.3, 1.2], (0.0, 1.0), (0.0, 0.8), CELL_M)  # 2 planes x 8 x 10 cells


def _random_state(params, rng, stack=TINY):
    """A valid state with a non-uniform velocity distribution in every cell."""
    s = bof_initial_state(stack, params)
    s.occ_v[...] = rng.random(s.occ_v.shape) ** 4
    s.free[...] = rng.random(s.free.shape)
    z = s.occ_v.sum(axis=1) + s.free
    s.occ_v /= z[:, None]
    s.free /= z
    return s


def _reference_velocities(n: int, v_max: float) -> list[tuple[int, int, float, float]]:
    """(iv_y, iv_x, vx, vy) for k = iv_y * n + iv_x, written from the BOFParams docstring."""
    axis = [-v_max + 2 * v_max * i / (n - 1) for i in range(n)] if n > 1 else [0.0]
    return [(iy, ix, axis[ix], axis[iy]) for iy in range(n) for ix in range(n)]


def reference_predict(occ_v, free, dt, params: BOFParams):
    """Module-docstring prediction, one cell and hypothesis at a time, float64 (bilinear sub-cell motion)."""
    L, K, ny, nx = occ_v.shape
    n = params.n_velocities_per_axis
    p0 = params.prior_occupancy
    q = 1.0 - math.exp(-params.decay_rate_hz * dt)
    p_app, p_dis = p0 * q, (1.0 - p0) * q
    p_mix = 1.0 - math.exp(-params.velocity_noise_rate_hz * dt)
    vels = _reference_velocities(n, params.velocity_max_m_s)

    def read(img, x, y, outside):
        x0, y0 = math.floor(x), math.floor(y)
        fx, fy = x - x0, y - y0
        total = 0.0
        for yy, wy in ((y0, 1 - fy), (y0 + 1, fy)):
            for xx, wx in ((x0, 1 - fx), (x0 + 1, fx)):
                v = img[yy, xx] if (0 <= yy < ny and 0 <= xx < nx) else outside
                total += wy * wx * v
        return total

    out_occ = np.zeros((L, K, ny, nx))
    out_free = np.zeros((L, ny, nx))
    for l in range(L):
        hat = np.zeros((K, ny, nx))
        free_hat = np.zeros((ny, nx))
        for k, (_, _, vx, vy) in enumerate(vels):
            for iy in range(ny):
                for ix in range(nx):
                    # antecedent a_k(c) = c - v_k dt / cell (x along columns, y along rows)
                    xa, ya = ix - vx * dt / CELL_M, iy - vy * dt / CELL_M
                    alpha = read(occ_v[l, k].astype(float), xa, ya, p0 / K)
                    beta = read(free[l].astype(float) / K, xa, ya, (1 - p0) / K)
                    hat[k, iy, ix] = (1 - p_dis) * alpha + p_app * beta
                    free_hat[iy, ix] += p_dis * alpha + (1 - p_app) * beta
        # velocity noise, scatter form: hypothesis j keeps 1 - p_mix and gives p_mix / |N(j)| to each neighbour
        tilde = np.zeros_like(hat)
        for j, (jy, jx, _, _) in enumerate(vels):
            nbrs = [k for k, (ky, kx, _, _) in enumerate(vels) if abs(ky - jy) + abs(kx - jx) == 1]
            if not nbrs:
                tilde[j] += hat[j]
                continue
            tilde[j] += (1 - p_mix) * hat[j]
            for k in nbrs:
                tilde[k] += p_mix / len(nbrs) * hat[j]
        z = tilde.sum(axis=0) + free_hat
        out_occ[l] = tilde / z
        out_free[l] = free_hat / z
    return out_occ, out_free


def reference_update(occ_v, free, log_odds):
    """Seed eq. 7 with the documented clips (summed log-odds to +-30, posterior log-odds to +-60), float64."""
    lam = np.clip(np.asarray(log_odds, float), -30.0, 30.0)
    occ = occ_v.astype(float).sum(axis=1)
    f = free.astype(float)
    posterior = np.clip(np.log(occ / f) + lam, -60.0, 60.0)
    lam = posterior - np.log(occ / f)
    z = np.exp(lam) * occ + f
    return occ_v.astype(float) * (np.exp(lam) / z)[:, None], f / z


@pytest.mark.parametrize("n, v_max, dts", [
    (3, 1.2, (0.07, 0.35)),          # sub-cell and multi-cell displacements, corner hypotheses
    (5, 0.9, (0.13,)),                # hypotheses with 2, 3 and 4 neighbours
])
def test_predict_matches_independent_reference(n, v_max, dts, rng):
    params = BOFParams(n_velocities_per_axis=n, velocity_max_m_s=v_max, prior_occupancy=0.07,
                       decay_rate_hz=0.6, velocity_noise_rate_hz=2.5, subcell="bilinear", sparse_min_excess=None)
    s = _random_state(params, rng)
    for dt in dts:
        ref_occ, ref_free = reference_predict(s.occ_v, s.free, dt, params)
        bof_predict(s, dt, params)
        np.testing.assert_allclose(s.occ_v, ref_occ, atol=3e-7, rtol=1e-4)
        np.testing.assert_allclose(s.free, ref_free, atol=3e-7, rtol=1e-4)


def test_accumulate_moves_whole_cells_like_the_reference(rng):
    """Displacements of exactly one cell per step: 'accumulate' and the bilinear reference coincide."""
    params = BOFParams(n_velocities_per_axis=3, velocity_max_m_s=1.0, subcell="accumulate",
                       velocity_noise_rate_hz=1.5, sparse_min_excess=None)
    s = _random_state(params, rng)
    for _ in range(3):
        ref_occ, ref_free = reference_predict(s.occ_v, s.free, 0.1, params)  # 1 m/s * 0.1 s = 1 cell
        bof_predict(s, 0.1, params)
        np.testing.assert_allclose(s.occ_v, ref_occ, atol=3e-7, rtol=1e-4)
        np.testing.assert_allclose(s.free, ref_free, atol=3e-7, rtol=1e-4)


@settings(max_examples=25, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), lam=st.floats(-80.0, 80.0), spread=st.floats(0.0, 60.0))
def test_update_matches_independent_reference(seed, lam, spread):
    rng = np.random.default_rng(seed)
    params = BOFParams(n_velocities_per_axis=3)
    s = _random_state(params, rng)
    lo = (lam + spread * rng.standard_normal(TINY.shape)).astype(np.float32)
    ref_occ, ref_free = reference_update(s.occ_v, s.free, lo)
    bof_update(s, lo)
    # relative comparison: a hypothesis that underflows to 0 where the reference keeps e^-30 fails it
    np.testing.assert_allclose(s.occ_v, ref_occ, rtol=2e-4, atol=1e-30)
    np.testing.assert_allclose(s.free, ref_free, rtol=2e-4, atol=1e-30)


@pytest.mark.parametrize("n", [2, 3, 5])
def test_velocity_noise_conserves_occupied_mass_of_non_uniform_velocities(n, rng):
    """All hypotheses at rest (v_max = 0, so no cell exchanges mass with another) and no decay: the
    velocity mixing only moves mass between hypotheses, so P(occ) of every cell and the grid's total are
    unchanged whatever the (non-uniform) velocity distribution, corner hypotheses included; the velocity
    distribution follows the scatter-form reference."""
    params = BOFParams(n_velocities_per_axis=n, velocity_max_m_s=0.0, decay_rate_hz=0.0,
                       velocity_noise_rate_hz=4.0)
    s = _random_state(params, rng)
    s.occ_v[:, 0] *= 20.0  # pile mass on a corner hypothesis, renormalised
    z = s.occ_v.sum(axis=1) + s.free
    s.occ_v /= z[:, None]
    s.free /= z
    occ0 = s.occ_v.astype(float).sum(axis=1)
    corner0 = float(s.occ_v[:, 0].sum())
    for dt in (0.05, 0.4, 1.3):
        ref_occ, _ = reference_predict(s.occ_v, s.free, dt, params)
        bof_predict(s, dt, params)
        np.testing.assert_allclose(s.occ_v.sum(axis=1), occ0, atol=2e-6)
        assert abs(float(s.occ_v.astype(float).sum()) - float(occ0.sum())) < 1e-4 * occ0.size
        np.testing.assert_allclose(s.occ_v, ref_occ, atol=3e-7, rtol=1e-4)
    assert float(s.occ_v[:, 0].sum()) < 0.8 * corner0  # mass did leave the corner


@settings(max_examples=20, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), dts=st.lists(st.floats(0.001, 3.0), min_size=1, max_size=5),
       prior=st.floats(0.02, 0.9), rate=st.floats(0.05, 3.0))
def test_any_cell_decays_to_the_prior_at_the_documented_rate(seed, dts, prior, rate):
    """P_t(occ) = p0 + (P_0(occ) - p0) exp(-lambda t) for every cell of an arbitrary state with a
    non-uniform velocity distribution (hypotheses at rest, so cells do not interact)."""
    rng = np.random.default_rng(seed)
    params = BOFParams(n_velocities_per_axis=3, velocity_max_m_s=0.0, prior_occupancy=prior,
                       decay_rate_hz=rate, velocity_noise_rate_hz=3.0)
    s = _random_state(params, rng)
    p_start = s.occ_v.astype(float).sum(axis=1)
    t = 0.0
    for dt in dts:
        bof_predict(s, dt, params)
        t += dt
        expected = prior + (p_start - prior) * np.exp(-rate * t)
        np.testing.assert_allclose(s.occ_v.sum(axis=1), expected, atol=3e-6)


@settings(max_examples=30, deadline=None)
@given(seed=st.integers(0, 2**32 - 1),
       steps=st.lists(st.tuples(st.sampled_from([0.0, 1e-3, 0.1, 2.0]),
                                st.sampled_from([-1e30, -1e4, -31.0, -5.0, 0.0, 5.0, 31.0, 1e4, 1e30])),
                      min_size=1, max_size=12))
def test_probabilities_stay_in_unit_interval_after_extreme_evidence(seed, steps):
    rng = np.random.default_rng(seed)
    params = BOFParams(n_velocities_per_axis=3, velocity_max_m_s=1.0)
    s = _random_state(params, rng)
    for dt, lam in steps:
        bof_predict(s, dt, params)
        bof_update(s, np.full(TINY.shape, lam, np.float32) * rng.random(TINY.shape).astype(np.float32))
        assert np.isfinite(s.occ_v).all() and np.isfinite(s.free).all()
        assert s.occ_v.min() >= 0 and s.free.min() >= 0
        occ = s.occupancy
        assert occ.min() >= 0 and occ.max() <= 1 and s.free.max() <= 1
        np.testing.assert_allclose(s.occ_v.sum(axis=1) + s.free, 1.0, atol=1e-5)


@pytest.mark.parametrize("sign", [1.0, -1.0])
def test_a_saturated_cell_is_revised_by_contrary_evidence(sign):
    """The module docstring: clipping each update keeps both hypotheses of a cell non-zero, so a later
    update can always revise it. Evidence of any strength, then the opposite: back to the prior."""
    params = BOFParams(n_velocities_per_axis=3)
    s = bof_initial_state(TINY, params)
    bof_update(s, np.full(TINY.shape, sign * 1e4, np.float32))
    assert s.occupancy.min() > 0 and s.free.min() > 0
    bof_update(s, np.full(TINY.shape, -sign * 1e4, np.float32))
    np.testing.assert_allclose(s.occupancy, params.prior_occupancy, rtol=1e-4)
    np.testing.assert_allclose(s.occ_v / s.occupancy[:, None], 1.0 / params.n_velocities, rtol=1e-4)


def test_repeated_saturating_updates_without_prediction_stay_revisable():
    """Regression: four updates of +-30 in a row (no prediction between them, e.g. evidence stamped at the
    same time) used to underflow the other hypothesis to exactly 0 in float32, and no later update could
    revise the cell; the posterior log-odds are now bounded to +-60."""
    params = BOFParams(n_velocities_per_axis=3)
    for sign in (1.0, -1.0):
        s = bof_initial_state(TINY, params)
        for _ in range(6):
            bof_update(s, np.full(TINY.shape, sign * 1e4, np.float32))
        assert s.occupancy.min() > 0 and s.free.min() > 0
        for _ in range(3):
            bof_update(s, np.full(TINY.shape, -sign * 1e4, np.float32))
        assert (s.occupancy < 0.5).all() if sign > 0 else (s.occupancy > 0.5).all()
