"""Synthetic per-plane evidence of people standing in the grid, for tests, benchmarks and ablations.

A person at ground position ``xy`` with height ``h`` is a vertical cylinder of radius ``radius_m``: every
cell of every plane at height ``<= h`` whose centre lies inside the cylinder gets ``log_odds_occ``; the other
cells the sensor sees get ``log_odds_free``; cells it does not see get 0 (unknown). Optional Gaussian
noise (seeded generator) is added to the seen cells.
"""

from __future__ import annotations

import numpy as np

from ..geometry._checks import check_points
from ..grid import Evidence, PlaneStack

__all__ = ["evidence_from_people"]


def evidence_from_people(
    stack: PlaneStack,
    time_s: float,
    xy_m,
    height_m,
    sensor: str = "synthetic",
    radius_m: float = 0.2,
    log_odds_occ: float = 2.0,
    log_odds_free: float = -1.0,
    seen=None,
    noise_std: float = 0.0,
    rng: np.random.Generator | None = None,
) -> Evidence:
    """Evidence of people modelled as cylinders (module docstring).

    Parameters
    ----------
    stack : PlaneStack
        The planes.
    time_s : float
        Time stamp [s].
    xy_m : array_like, shape (N, 2)
        Ground positions of the people (world XY) [m].
    height_m : array_like, shape (N,)
        Their heights [m].
    sensor : str
        Sensor name of the evidence.
    radius_m : float
        Cylinder radius [m].
    log_odds_occ, log_odds_free : float
        Log-odds given to occupied and to seen free cells.
    seen : array_like of bool, shape (L, ny, nx) or (ny, nx), optional
        Cells the sensor sees (default all).
    noise_std : float
        Standard deviation of Gaussian noise added to seen cells (needs ``rng`` when > 0).
    rng : numpy.random.Generator, optional
        Seeded generator for the noise.
    """
    xy = check_points(np.reshape(xy_m, (-1, 2)) if np.size(xy_m) else np.zeros((0, 2)), 2, "xy_m")
    h = np.asarray(height_m, dtype=float).reshape(-1)
    if h.shape != (len(xy),):
        raise ValueError(f"height_m must have shape ({len(xy)},), got {h.shape}")
    if noise_std > 0 and rng is None:
        raise ValueError("noise_std > 0 needs a seeded rng")
    centres = stack.cell_centers_xy()  # (ny, nx, 2)
    heights = np.asarray(stack.heights_m)
    occ = np.zeros(stack.shape, bool)
    for p, hp in zip(xy, h):  # one iteration per person, vectorised over cells
        inside = np.sum((centres - p) ** 2, axis=-1) <= radius_m**2
        occ |= (heights <= hp)[:, None, None] & inside[None]
    lo = np.where(occ, log_odds_occ, log_odds_free)
    if noise_std > 0:
        lo = lo + rng.normal(0.0, noise_std, lo.shape)
    if seen is not None:
        seen = np.broadcast_to(np.asarray(seen, dtype=bool), stack.shape)
        lo = np.where(seen, lo, 0.0)
    return Evidence(float(time_s), sensor, lo.astype(np.float32))
