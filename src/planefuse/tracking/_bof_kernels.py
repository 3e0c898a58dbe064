"""numba kernels of the Bayesian Occupancy Filter, over square tiles of cells (see :mod:`planefuse.tracking._bof`).

Tiles of ``TILE x TILE`` cells are *active* (the joint ``P(occ, v_k)`` is held for every ``k``) or *inactive*
(the cell's velocity is uniform and only its total is held, in the zero-velocity slot ``k0``; the other
slots are 0, so ``sum_k occ_v[:, k]`` is the occupancy everywhere). Every kernel loops over a list of
tiles, and every tile is computed from the previous state alone and writes only its own cells, so
:func:`step_kernel` (tiles on numba's threads, ``numba.prange``) and :func:`step_kernel_serial` give the
same numbers.
"""

from __future__ import annotations

import numba
import numpy as np
from numba import prange

#: Side of a tile [cells].
TILE = 8


@numba.njit(cache=True, inline="always", fastmath=True)
def _predict_hat_k(src, sy, sx, fsrc, fy, fx, h, w, wy1, wx1, bilinear, coef, inv_k, hat_k, fhat,
                   ohat):  # pragma: no cover - numba
    """One hypothesis of the transition: ``occ_hat_k = (1 - p_dis) alpha_k + p_app beta_k`` into ``hat_k``
    (and added to ``ohat``), ``p_dis alpha_k + (1 - p_app) beta_k`` added to ``fhat``; the antecedent of the
    tile's cell (iy, ix) is at (sy + iy, sx + ix) in ``src`` (2-D, ``P(occ, v_k)``) and (fy + iy, fx + ix)
    in ``fsrc`` (2-D, ``P(free)``), with bilinear weights ``(wy1, wx1)`` towards the next row and column."""
    s_occ, s_app, s_dis, s_free = coef[0], coef[1], coef[2], coef[3]
    w00, w01 = (1 - wy1) * (1 - wx1), (1 - wy1) * wx1
    w10, w11 = wy1 * (1 - wx1), wy1 * wx1
    for iy in range(h):
        y, yf = sy + iy, fy + iy
        if bilinear:
            for ix in range(w):
                x, xf = sx + ix, fx + ix
                a = w00 * src[y, x] + w01 * src[y, x + 1] + w10 * src[y + 1, x] + w11 * src[y + 1, x + 1]
                b = (w00 * fsrc[yf, xf] + w01 * fsrc[yf, xf + 1]
                     + w10 * fsrc[yf + 1, xf] + w11 * fsrc[yf + 1, xf + 1]) * inv_k
                o = s_occ * a + s_app * b
                hat_k[iy, ix] = o
                ohat[iy, ix] += o
                fhat[iy, ix] += s_dis * a + s_free * b
        else:
            for ix in range(w):
                a = src[y, sx + ix]
                b = fsrc[yf, fx + ix] * inv_k
                o = s_occ * a + s_app * b
                hat_k[iy, ix] = o
                ohat[iy, ix] += o
                fhat[iy, ix] += s_dis * a + s_free * b


@numba.njit(cache=True, inline="always", fastmath=True)
def _update_scales(so, f, lam, bounds):  # pragma: no cover - numba
    """Scale factors ``(s_occ, s_free)`` of Bayes' rule with log-odds ``lam`` for a cell holding ``P(occ) = so``
    and ``P(free) = f`` (module docstring of ``_bof``), no overflow. ``bounds`` = (bound on ``|lam|``, bound
    ``B`` on the posterior log-odds, ``e^B``, ``e^-B``): ``lam`` is reduced so that the posterior log-odds
    ``log(so / f) + lam`` do not pass ``B`` (or ``-B``) where they would; ``log`` is only taken then."""
    lam = min(max(lam, -bounds[0]), bounds[0])
    if lam == 0:
        return np.float32(1.0), np.float32(1.0)
    if lam > 0:
        e = np.float32(np.exp(-lam))
        if so > f * e * bounds[2] and so > 0 and f > 0:  # posterior odds so / (f e) above e^B
            e = np.float32(np.exp(-max(bounds[1] - np.log(so / f), 0.0)))
        z = np.float32(1.0) / (so + f * e)
        return z, e * z
    e = np.float32(np.exp(lam))
    if so * e < f * bounds[3] and so > 0 and f > 0:  # posterior odds so e / f below e^-B
        e = np.float32(np.exp(min(-bounds[1] - np.log(so / f), 0.0)))
    z = np.float32(1.0) / (so * e + f)
    return e * z, z


@numba.njit(cache=True, inline="always", fastmath=True)
def _velocity_noise(hat, scale, mix_src, mix_w, velocities, out_v, l, y0, x0, h, w, mo, mx, my):  # pragma: no cover
    """``occ_tilde_k = sum_j mix_w[k, j] occ_hat[mix_src[k, j]]`` over the tile's first ``h x w`` cells, times
    ``scale``, into ``out_v``; its sums over ``k`` of ``occ_tilde_k`` and ``occ_tilde_k v_k`` added to
    ``(mo, mx, my)``."""
    acc = np.empty((TILE, TILE), np.float32)
    for k in range(hat.shape[0]):
        vx, vy = velocities[k, 0], velocities[k, 1]
        acc[:] = 0.0
        for j in range(mix_src.shape[1]):
            wkj = np.float32(mix_w[k, j])
            hat_j = hat[mix_src[k, j]]
            for iy in range(h):
                for ix in range(w):
                    acc[iy, ix] += wkj * hat_j[iy, ix]
        for iy in range(h):
            for ix in range(w):
                m = acc[iy, ix] * scale[iy, ix]
                out_v[l, k, y0 + iy, x0 + ix] = m
                mo[iy, ix] += m
                mx[iy, ix] += m * vx
                my[iy, ix] += m * vy


@numba.njit(cache=True, fastmath=True)
def _active_tile(occ_v, free, out_v, out_f, active, l, ty, tx, oy, ox, wy, wx, bilinear, coef, prior, mix_src,
                 mix_w, k0, log_odds, do_update, bounds, velocities, occ, vel):  # pragma: no cover - numba
    """A tile holding every hypothesis: prediction (module docstring of ``_bof``), normalisation, update and
    moments, from ``(occ_v, free)`` into ``(out_v, out_f)`` and ``(occ, vel)``."""
    L, K, ny, nx = occ_v.shape
    y0, x0 = ty * TILE, tx * TILE
    h, w = min(TILE, ny - y0), min(TILE, nx - x0)
    inv_k = np.float32(1.0 / K)
    a_out = np.float32(prior / K)
    # the antecedents are read in place when all lie in the grid, in active tiles; else gathered
    ya, yb, xa, xb = y0 + oy.min(), y0 + h + oy.max(), x0 + ox.min(), x0 + w + ox.max()
    gather = ya < 0 or xa < 0 or yb >= ny or xb >= nx
    if not gather:
        for jy in range(ya // TILE, yb // TILE + 1):
            for jx in range(xa // TILE, xb // TILE + 1):
                if not active[l, jy, jx]:
                    gather = True
    hat = np.empty((K, TILE, TILE), np.float32)
    fhat = np.zeros((TILE, TILE), np.float32)
    ohat = np.zeros((TILE, TILE), np.float32)
    if gather:  # copy each hypothesis' antecedents: the prior outside the grid, uniform in inactive tiles
        ly0, lx0 = y0 + oy.min(), x0 + ox.min()
        sy, sx = h + oy.max() - oy.min() + 1, w + ox.max() - ox.min() + 1
        fsrc = np.empty((sy, sx), np.float32)  # P(free) over the window of every hypothesis' antecedents
        code = np.empty((sy, sx), np.int8)  # 0: outside the grid, 1: active tile, 2: inactive tile
        for yy in range(sy):
            y = ly0 + yy
            for xx in range(sx):
                x = lx0 + xx
                if y < 0 or y >= ny or x < 0 or x >= nx:
                    code[yy, xx] = 0
                    fsrc[yy, xx] = np.float32(1.0 - prior)
                else:
                    code[yy, xx] = 1 if active[l, y // TILE, x // TILE] else 2
                    fsrc[yy, xx] = free[l, y, x]
        src = np.empty((TILE + 1, TILE + 1), np.float32)
        for k in range(K):
            by, bx = y0 + oy[k] - ly0, x0 + ox[k] - lx0
            for yy in range(h + 1):
                for xx in range(w + 1):
                    c = code[by + yy, bx + xx]
                    if c == 1:
                        src[yy, xx] = occ_v[l, k, ly0 + by + yy, lx0 + bx + xx]
                    elif c == 2:
                        src[yy, xx] = occ_v[l, k0, ly0 + by + yy, lx0 + bx + xx] * inv_k
                    else:
                        src[yy, xx] = a_out
            _predict_hat_k(src, 0, 0, fsrc, by, bx, h, w, np.float32(wy[k]), np.float32(wx[k]), bilinear, coef,
                           inv_k, hat[k], fhat, ohat)
    else:
        for k in range(K):
            y, x = y0 + oy[k], x0 + ox[k]
            _predict_hat_k(occ_v[l, k], y, x, free[l], y, x, h, w, np.float32(wy[k]), np.float32(wx[k]), bilinear,
                           coef, inv_k, hat[k], fhat, ohat)
    # normalisation (the velocity noise moves occupied mass between hypotheses and keeps its sum) and update
    scale = np.empty((TILE, TILE), np.float32)
    for iy in range(h):
        for ix in range(w):
            inv = np.float32(1.0) / (fhat[iy, ix] + ohat[iy, ix])
            f = fhat[iy, ix] * inv
            if do_update:
                s_o, s_f = _update_scales(ohat[iy, ix] * inv, f, log_odds[l, y0 + iy, x0 + ix], bounds)
                scale[iy, ix] = inv * s_o
                f *= s_f
            else:
                scale[iy, ix] = inv
            out_f[l, y0 + iy, x0 + ix] = f
    # velocity noise occ_tilde_k = sum_j mix_w[k, j] occ_hat[mix_src[k, j]], written with the moments
    mo = np.zeros((TILE, TILE), np.float32)
    mx = np.zeros((TILE, TILE), np.float32)
    my = np.zeros((TILE, TILE), np.float32)
    if h == TILE and w == TILE:  # a whole tile: loops of constant length, which LLVM vectorises
        _velocity_noise(hat, scale, mix_src, mix_w, velocities, out_v, l, y0, x0, TILE, TILE, mo, mx, my)
    else:
        _velocity_noise(hat, scale, mix_src, mix_w, velocities, out_v, l, y0, x0, h, w, mo, mx, my)
    for iy in range(h):
        for ix in range(w):
            occ[l, y0 + iy, x0 + ix] = mo[iy, ix]
            vel[l, y0 + iy, x0 + ix, 0] = mx[iy, ix]
            vel[l, y0 + iy, x0 + ix, 1] = my[iy, ix]
    _finish_moments(occ, vel, l, y0, x0, h, w)


@numba.njit(cache=True, inline="always", fastmath=True)
def _finish_moments(occ, vel, l, y0, x0, h, w):  # pragma: no cover - numba
    """E[V | occ] = sum_k P(occ, v_k) v_k / P(occ); P(occ) clipped to [0, 1] (float32 sums of K masses)."""
    for iy in range(y0, y0 + h):
        for ix in range(x0, x0 + w):
            o = occ[l, iy, ix]
            if o > 0:
                vel[l, iy, ix, 0] /= o
                vel[l, iy, ix, 1] /= o
            occ[l, iy, ix] = min(o, np.float32(1.0))


@numba.njit(cache=True, fastmath=True)
def _inactive_tile(occ_v, free, out_v, out_f, dirty_out, l, ty, tx, coef, k0, log_odds, do_update, bounds,
                   occ, vel):  # pragma: no cover - numba
    """A tile of uniform-velocity cells: the transition alone (no motion), then the update, on the totals."""
    L, K, ny, nx = occ_v.shape
    y0, x0 = ty * TILE, tx * TILE
    h, w = min(TILE, ny - y0), min(TILE, nx - x0)
    s_occ, s_app, s_dis, s_free = coef[0], coef[1], coef[2], coef[3]
    if dirty_out[l, ty, tx]:  # the output buffer last held this tile active: clear its other slots
        for k in range(K):
            if k != k0:
                out_v[l, k, y0:y0 + h, x0:x0 + w] = 0.0
        dirty_out[l, ty, tx] = False
    for iy in range(y0, y0 + h):
        for ix in range(x0, x0 + w):
            o, f = occ_v[l, k0, iy, ix], free[l, iy, ix]
            o, f = s_occ * o + s_app * f, s_dis * o + s_free * f
            z = np.float32(1.0) / (o + f)
            o *= z
            f *= z
            if do_update:
                s_o, s_f = _update_scales(o, f, log_odds[l, iy, ix], bounds)
                o *= s_o
                f *= s_f
            out_v[l, k0, iy, ix] = o
            out_f[l, iy, ix] = f
            occ[l, iy, ix] = min(o, np.float32(1.0))
            vel[l, iy, ix, 0] = 0.0
            vel[l, iy, ix, 1] = 0.0


@numba.njit(cache=True, parallel=True, fastmath=True)
def step_kernel(occ_v, free, out_v, out_f, active, dirty_out, act_tiles, inact_tiles, oy, ox, wy, wx, bilinear,
                coef, prior, mix_src, mix_w, k0, log_odds, do_update, bounds, velocities,
                occ, vel):  # pragma: no cover - numba
    """Prediction (and, if ``do_update``, the update) of every tile from ``(occ_v, free)`` into
    ``(out_v, out_f)``; the moments ``P(occ)``, ``E[V | occ]`` of the result into ``(occ, vel)``. Tiles on
    numba's threads."""
    for i in prange(act_tiles.shape[0]):
        _active_tile(occ_v, free, out_v, out_f, active, act_tiles[i, 0], act_tiles[i, 1], act_tiles[i, 2], oy, ox,
                     wy, wx, bilinear, coef, prior, mix_src, mix_w, k0, log_odds, do_update, bounds, velocities,
                     occ, vel)
    for i in prange(inact_tiles.shape[0]):
        _inactive_tile(occ_v, free, out_v, out_f, dirty_out, inact_tiles[i, 0], inact_tiles[i, 1],
                       inact_tiles[i, 2], coef, k0, log_odds, do_update, bounds, occ, vel)


@numba.njit(cache=True, fastmath=True)
def step_kernel_serial(occ_v, free, out_v, out_f, active, dirty_out, act_tiles, inact_tiles, oy, ox, wy, wx, bilinear,
                       coef, prior, mix_src, mix_w, k0, log_odds, do_update, bounds, velocities,
                       occ, vel):  # pragma: no cover - numba
    """:func:`step_kernel` on the calling thread (the same numbers: the tiles are independent)."""
    for i in range(act_tiles.shape[0]):
        _active_tile(occ_v, free, out_v, out_f, active, act_tiles[i, 0], act_tiles[i, 1], act_tiles[i, 2], oy, ox,
                     wy, wx, bilinear, coef, prior, mix_src, mix_w, k0, log_odds, do_update, bounds, velocities,
                     occ, vel)
    for i in range(inact_tiles.shape[0]):
        _inactive_tile(occ_v, free, out_v, out_f, dirty_out, inact_tiles[i, 0], inact_tiles[i, 1],
                       inact_tiles[i, 2], coef, k0, log_odds, do_update, bounds, occ, vel)


@numba.njit(cache=True, fastmath=True)
def update_kernel(occ_v, free, active, tiles, k0, log_odds, bounds, velocities, occ, vel):  # pragma: no cover
    """Bayes update in place (no prediction) and the moments of the result."""
    L, K, ny, nx = occ_v.shape
    for i in prange(tiles.shape[0]):
        l, ty, tx = tiles[i, 0], tiles[i, 1], tiles[i, 2]
        y0, x0 = ty * TILE, tx * TILE
        h, w = min(TILE, ny - y0), min(TILE, nx - x0)
        if active[l, ty, tx]:
            for iy in range(y0, y0 + h):
                for ix in range(x0, x0 + w):
                    so = np.float32(0.0)
                    for k in range(K):
                        so += occ_v[l, k, iy, ix]
                    s_o, s_f = _update_scales(so, free[l, iy, ix], log_odds[l, iy, ix], bounds)
                    free[l, iy, ix] *= s_f
                    o, mx, my = np.float32(0.0), np.float32(0.0), np.float32(0.0)
                    for k in range(K):
                        m = occ_v[l, k, iy, ix] * s_o
                        occ_v[l, k, iy, ix] = m
                        o += m
                        mx += m * velocities[k, 0]
                        my += m * velocities[k, 1]
                    occ[l, iy, ix], vel[l, iy, ix, 0], vel[l, iy, ix, 1] = o, mx, my
            _finish_moments(occ, vel, l, y0, x0, h, w)
        else:
            for iy in range(y0, y0 + h):
                for ix in range(x0, x0 + w):
                    o, f = occ_v[l, k0, iy, ix], free[l, iy, ix]
                    s_o, s_f = _update_scales(o, f, log_odds[l, iy, ix], bounds)
                    occ_v[l, k0, iy, ix] = o * s_o
                    free[l, iy, ix] = f * s_f
                    occ[l, iy, ix] = min(o * s_o, np.float32(1.0))
                    vel[l, iy, ix, 0] = 0.0
                    vel[l, iy, ix, 1] = 0.0


@numba.njit(cache=True, fastmath=True)
def moments_kernel(occ_v, active, tiles, k0, velocities, occ, vel):  # pragma: no cover - numba
    """``P(occ) = sum_k P(occ, v_k)`` and ``E[V | occ]`` per cell (0 in inactive tiles)."""
    L, K, ny, nx = occ_v.shape
    for i in prange(tiles.shape[0]):
        l, ty, tx = tiles[i, 0], tiles[i, 1], tiles[i, 2]
        y0, x0 = ty * TILE, tx * TILE
        h, w = min(TILE, ny - y0), min(TILE, nx - x0)
        if active[l, ty, tx]:
            for iy in range(y0, y0 + h):
                for ix in range(x0, x0 + w):
                    o, mx, my = np.float32(0.0), np.float32(0.0), np.float32(0.0)
                    for k in range(K):
                        m = occ_v[l, k, iy, ix]
                        o += m
                        mx += m * velocities[k, 0]
                        my += m * velocities[k, 1]
                    occ[l, iy, ix], vel[l, iy, ix, 0], vel[l, iy, ix, 1] = o, mx, my
            _finish_moments(occ, vel, l, y0, x0, h, w)
        else:
            for iy in range(y0, y0 + h):
                for ix in range(x0, x0 + w):
                    occ[l, iy, ix] = min(occ_v[l, k0, iy, ix], np.float32(1.0))
                    vel[l, iy, ix, 0] = 0.0
                    vel[l, iy, ix, 1] = 0.0


@numba.njit(cache=True, fastmath=True)
def retile_kernel(occ_v, tiles, to_active, k0):  # pragma: no cover - numba
    """Change the representation of ``tiles`` in place: to active (the total spread uniformly over the K
    hypotheses) or to inactive (the K hypotheses summed into slot ``k0``, the others set to 0)."""
    L, K, ny, nx = occ_v.shape
    inv_k = np.float32(1.0 / K)
    for i in prange(tiles.shape[0]):
        l, ty, tx = tiles[i, 0], tiles[i, 1], tiles[i, 2]
        y0, x0 = ty * TILE, tx * TILE
        h, w = min(TILE, ny - y0), min(TILE, nx - x0)
        for iy in range(y0, y0 + h):
            for ix in range(x0, x0 + w):
                if to_active:
                    m = occ_v[l, k0, iy, ix] * inv_k
                    for k in range(K):
                        occ_v[l, k, iy, ix] = m
                else:
                    s = np.float32(0.0)
                    for k in range(K):
                        s += occ_v[l, k, iy, ix]
                        occ_v[l, k, iy, ix] = 0.0
                    occ_v[l, k0, iy, ix] = s


@numba.njit(cache=True, fastmath=True)
def active_tiles(free, threshold, reach):  # pragma: no cover - numba
    """Tiles within ``reach`` cells (Chebyshev distance) of a cell with ``P(occ) = 1 - P(free) > threshold``,
    shape (L, ceil(ny / TILE), ceil(nx / TILE)), bool."""
    L, ny, nx = free.shape
    nty, ntx = (ny + TILE - 1) // TILE, (nx + TILE - 1) // TILE
    out = np.zeros((L, nty, ntx), np.bool_)
    f_max = np.float32(1.0 - threshold)
    for l in range(L):
        for iy in range(ny):
            for ix in range(nx):
                if free[l, iy, ix] < f_max:
                    for jy in range(max(iy - reach, 0) // TILE, min(iy + reach, ny - 1) // TILE + 1):
                        for jx in range(max(ix - reach, 0) // TILE, min(ix + reach, nx - 1) // TILE + 1):
                            out[l, jy, jx] = True
    return out
