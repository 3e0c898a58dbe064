"""BOF steps per second: the tiled, sparse filter against the dense kernel it replaced, in the same run.

Run: ``PYTHONPATH=src python benchmarks/bench_bof.py`` (10 planes x 200 x 200 cells of 0.05 m, 7 x 7 velocity
hypotheses, 0.1 s steps; scenes of 0, 6 and 20 people) and ``--demo-grid`` (the demo's 4 planes x 96 x 96
cells of 0.1 m, 0.04 s steps: 25 Hz cameras).

One step is what the tracking pipeline asks of the filter per fused batch: predict over ``dt``, update with
the summed log-odds, and the moments ``P(occ)``, ``E[V | occ]`` the clustering reads. The evidence is
synthetic and the same for every implementation: log-odds ``-2 + N(0, 1)`` on every cell (cameras seeing the
floor) and ``+3`` on a disc of 0.2 m radius around each person on the planes below 1.75 m; people walk at
0.5-1.4 m/s and bounce off the walls. Rows:

* ``dense kernel (main)``: the previous implementation (a copy of main's kernels, kept only here): one pass
  for the prediction with a padded copy of each plane, one for the update, one for the moments; with the
  same parameters as the rows below (the ratios' baseline), and with main's default sub-cell motion
  (bilinear, slower);
* ``tiled, dense``: the new kernels with every tile active (``sparse_min_excess=None``): fused passes only;
* ``tiled, sparse``: the defaults (cells far from any occupancy 0.01 above the prior carry no velocity distribution);
* ``tiled, sparse, 2 threads``: the same over ``numba.prange`` on 2 threads (identical results).

Speeds are CPU time of this process per step (single-threaded rows: core time, meaningful on a shared
machine) and wall time; ratios are against the main kernel in the same run.
"""

from __future__ import annotations

import argparse
import os
import time

import numba
import numpy as np

from planefuse.grid import PlaneStack
from planefuse.tracking import BayesianOccupancyFilter, BOFParams, bof_initial_state, transition_probabilities
from planefuse.tracking._bof import _motion_offsets, _velocity_mixing


# -- main's dense kernels (the baseline; not used by planefuse) -------------------------------------------------
@numba.njit(cache=True, fastmath=True)
def _main_predict(occ_v, free, oy, ox, ty, tx, bilinear, p_app, p_dis, prior, mix_src, mix_w, pad):
    L, K, ny, nx = occ_v.shape
    Hp, Wp = ny + 2 * pad, nx + 2 * pad
    a_out, b_out = np.float32(prior / K), np.float32((1.0 - prior) / K)
    s_occ, s_app, s_dis, s_free = np.float32(1.0 - p_dis), np.float32(p_app), np.float32(p_dis), np.float32(1 - p_app)
    invK = np.float32(1.0 / K)
    for l in range(L):
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
            y_off, x_off = oy[k] + pad, ox[k] + pad
            wy1, wx1 = np.float32(ty[k]), np.float32(tx[k])
            w00, w01, w10, w11 = (1 - wy1) * (1 - wx1), (1 - wy1) * wx1, wy1 * (1 - wx1), wy1 * wx1
            for iy in range(ny):
                y0 = iy + y_off
                for ix in range(nx):
                    x0 = ix + x_off
                    if bilinear:
                        a = (w00 * src[k, y0, x0] + w01 * src[k, y0, x0 + 1] + w10 * src[k, y0 + 1, x0]
                             + w11 * src[k, y0 + 1, x0 + 1])
                        b = (w00 * fsrc[y0, x0] + w01 * fsrc[y0, x0 + 1] + w10 * fsrc[y0 + 1, x0]
                             + w11 * fsrc[y0 + 1, x0 + 1])
                    else:
                        a, b = src[k, y0, x0], fsrc[y0, x0]
                    hat[k, iy, ix] = s_occ * a + s_app * b
                    free_hat[iy, ix] += s_dis * a + s_free * b
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
def _main_update(occ_v, free, log_odds, max_log_odds, max_posterior):
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
                f, so = free[l, iy, ix], s_occ[iy, ix]
                if so > 0 and f > 0:
                    prior = np.log(so) - np.log(f)
                    lam = min(max(lam, min(-max_posterior - prior, 0.0)), max(max_posterior - prior, 0.0))
                if lam >= 0:
                    e = np.float32(np.exp(-lam))
                    z = np.float32(1.0) / (so + f * e)
                    s_occ[iy, ix], free[l, iy, ix] = z, f * e * z
                else:
                    e = np.float32(np.exp(lam))
                    z = np.float32(1.0) / (so * e + f)
                    s_occ[iy, ix], free[l, iy, ix] = e * z, f * z
        for k in range(K):
            for iy in range(ny):
                for ix in range(nx):
                    occ_v[l, k, iy, ix] *= s_occ[iy, ix]


@numba.njit(cache=True, fastmath=True)
def _main_moments(occ_v, velocities, occ, vel):
    L, K, ny, nx = occ_v.shape
    for l in range(L):
        occ[l] = 0.0
        vel[l] = 0.0
        for k in range(K):
            vx, vy = velocities[k, 0], velocities[k, 1]
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


class MainKernelFilter:
    """main's per-step work: predict, update, moments, each a pass over the whole grid."""

    def __init__(self, stack: PlaneStack, params: BOFParams) -> None:
        self.params, self.state = params, bof_initial_state(stack, params)

    def step(self, dt_s: float, log_odds: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        st, p = self.state, self.params
        bilinear = p.subcell == "bilinear"
        oy, ox, ty, tx = _motion_offsets(st, dt_s, bilinear)
        p_app, p_dis, p_mix = transition_probabilities(dt_s, p)
        mix_src, mix_w = _velocity_mixing(p.n_velocities_per_axis, p_mix)
        pad = int(max(np.abs(oy).max(), np.abs(ox).max())) + 2
        _main_predict(st.occ_v, st.free, oy, ox, ty, tx, bilinear, p_app, p_dis, p.prior_occupancy, mix_src, mix_w,
                      pad)
        _main_update(st.occ_v, st.free, log_odds, np.float32(30.0), np.float32(60.0))
        occ = np.empty(st.free.shape, np.float32)
        vel = np.empty(st.free.shape + (2,), np.float32)
        _main_moments(st.occ_v, st.velocities_m_s.astype(np.float32), occ, vel)
        return occ, vel


class TiledFilter:
    """planefuse's filter: the same step through :class:`BayesianOccupancyFilter`."""

    def __init__(self, stack: PlaneStack, params: BOFParams) -> None:
        self.bof, self.t = BayesianOccupancyFilter(stack, params), 0.0
        self.bof.predict_to(0.0)

    def step(self, dt_s: float, log_odds: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        self.t += dt_s
        self.bof.predict_to(self.t)
        self.bof.update(log_odds)
        return self.bof.moments()


def scene_evidence(stack: PlaneStack, n_people: int, n_steps: int, dt_s: float, seed: int = 0) -> list[np.ndarray]:
    """Synthetic summed log-odds for ``n_steps`` steps (module docstring)."""
    rng = np.random.default_rng(seed)
    x0, x1, y0, y1 = stack.extent_m
    lo_xy, hi_xy = np.array([x0 + 0.3, y0 + 0.3]), np.array([x1 - 0.3, y1 - 0.3])
    pos = rng.uniform(lo_xy, hi_xy, (n_people, 2))
    ang = rng.uniform(0, 2 * np.pi, n_people)
    vel = rng.uniform(0.5, 1.4, n_people)[:, None] * np.stack([np.cos(ang), np.sin(ang)], -1)
    centres = stack.cell_centers_xy()
    below = np.asarray(stack.heights_m) < 1.75
    out = []
    for _ in range(n_steps):
        lo = (-2.0 + rng.normal(0.0, 1.0, stack.shape)).astype(np.float32)
        for p in pos:
            disc = np.sum((centres - p) ** 2, axis=-1) <= 0.2**2
            lo[below[:, None, None] & disc[None]] = 3.0
        out.append(lo)
        pos += vel * dt_s
        for a in range(2):  # bounce off the walls
            hit = (pos[:, a] < lo_xy[a]) | (pos[:, a] > hi_xy[a])
            vel[hit, a] *= -1
            pos[:, a] = np.clip(pos[:, a], lo_xy[a], hi_xy[a])
    return out


def time_filter(make, evidence: list[np.ndarray], dt_s: float, n_warm: int):
    """(CPU s, wall s) per step over ``evidence[n_warm:]``, after ``n_warm`` steps; the last P(occ); the filter."""
    f = make()
    for lo in evidence[:n_warm]:
        f.step(dt_s, lo)
    t0, c0 = time.perf_counter(), time.process_time()
    for lo in evidence[n_warm:]:
        out = f.step(dt_s, lo)
    n = len(evidence) - n_warm
    return (time.process_time() - c0) / n, (time.perf_counter() - t0) / n, out[0], f


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--demo-grid", action="store_true", help="4 planes x 96 x 96 cells of 0.1 m, 0.04 s steps")
    ap.add_argument("--people", default="0,6,20")
    ap.add_argument("--warm", type=int, default=15, help="steps before timing (the active tiles settle)")
    ap.add_argument("--steps", type=int, default=10, help="timed steps")
    args = ap.parse_args()
    if args.demo_grid:
        stack = PlaneStack.from_extent([0.1, 0.5, 1.0, 1.5], (0.2, 9.8), (0.2, 9.8), 0.1)
        dt = 0.04
    else:
        stack = PlaneStack.from_extent(np.linspace(0.1, 1.9, 10), (0.0, 10.0), (0.0, 10.0), 0.05)
        dt = 0.1
    params = BOFParams()
    threads = numba.get_num_threads()
    print(f"{stack.n_planes} planes x {stack.ny} x {stack.nx} cells x {params.n_velocities} velocities, "
          f"steps of {dt} s, subcell={params.subcell!r}; load average {os.getloadavg()[0]:.1f} on "
          f"{os.cpu_count()} cores (shared machine: compare ratios within this run)")
    print("| people | implementation | CPU ms/step | wall ms/step | steps per CPU-s | steps per wall-s | "
          "CPU vs main | active tiles | max abs P(occ) diff vs main |")
    print("|---|---|---|---|---|---|---|---|---|")
    impls = [
        ("dense kernel (main)", lambda: MainKernelFilter(stack, params), 1),
        ("dense kernel (main), bilinear (main's default)",
         lambda: MainKernelFilter(stack, BOFParams(subcell="bilinear")), 1),
        ("tiled, dense", lambda: TiledFilter(stack, BOFParams(sparse_min_excess=None)), 1),
        ("tiled, sparse", lambda: TiledFilter(stack, params), 1),
        (f"tiled, sparse, {threads} threads", lambda: TiledFilter(stack, params), threads),
    ]
    for n_people in (int(s) for s in args.people.split(",")):
        evidence = scene_evidence(stack, n_people, args.warm + args.steps, dt)
        base = dense_occ = None
        for name, make, n_threads in impls:
            numba.set_num_threads(n_threads)
            time_filter(make, evidence[:3], dt, 1)  # compile
            cpu, wall, occ, f = time_filter(make, evidence, dt, args.warm)
            numba.set_num_threads(threads)
            base = cpu if base is None else base
            dense_occ = occ if dense_occ is None else dense_occ
            active = f"{f.bof.state.tile_active.mean():.0%}" if isinstance(f, TiledFilter) else "all"
            same_params = "main's default" not in name
            diff = f"{np.abs(occ - dense_occ).max():.1e}" if same_params else "-"
            print(f"| {n_people} | {name} | {cpu * 1e3:.1f} | {wall * 1e3:.1f} | {1 / cpu:.1f} | {1 / wall:.1f} | "
                  f"{base / cpu:.1f}x | {active} | {diff} |", flush=True)


if __name__ == "__main__":
    main()
