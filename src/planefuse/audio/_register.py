"""Registration of the auditory saliency map on every plane of a :class:`~planefuse.grid.PlaneStack`.

The azimuth plane of arrival at ``theta`` is the vertical plane (in the head
frame) through the head's z axis at azimuth ``theta``; it cuts every plane
z = h in a line through the foot of the head. Two ears on the y axis measure the
lateral angle only, so the plane at ``theta`` and at ``pi - theta`` (behind) are
the same measurement: **both half-lines carry the evidence** (the model's span is
[-90, 90] deg and every cell is looked up at its own lateral angle).

What log-odds does a wedge deserve? Sound says "someone is on this line", not
where along it, and a silent person makes no sound. Model an occupied cell as a
speaker with probability ``rho`` (its saliency then follows the cell's lateral
angle) and otherwise as unrelated to the measurement, like a free cell:

    P(Z | occ) / P(Z | free) = 1 - rho + rho * A * s(theta_cell)

with ``s`` the saliency (a distribution over the A azimuths, uniform = 1/A).
Away from the wedge this tends to ``1 - rho`` (a weak free-space hint, log(1 -
rho) ~ -0.1 for rho = 0.1, never strong); along the wedge it is positive and
capped at ``max_log_odds``.
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np
from scipy.ndimage import gaussian_filter1d

from ..geometry import apply_transform, check_transform, invert_transform
from ..grid import Evidence, PlaneStack

__all__ = ["evidence_from_saliency", "lateral_angle_of_cells"]


def lateral_angle_of_cells(stack: PlaneStack, T_world_head) -> tuple[np.ndarray, np.ndarray]:
    """Lateral angle [rad] (L, ny, nx) of every cell's azimuth plane in the head frame, and its range [m].

    The lateral angle ``asin(sin(atan2(y_h, x_h)))`` folds back azimuths onto the
    front: a cell behind the head at azimuth ``pi - theta`` gets ``theta``. The
    range is the horizontal distance (in the head frame) from the head's axis.
    """
    T = check_transform(T_world_head, "T_world_head")
    p = apply_transform(invert_transform(T), stack.cell_centers_world().reshape(-1, 3))
    az = np.arctan2(p[:, 1], p[:, 0])
    rng = np.hypot(p[:, 0], p[:, 1])
    return np.arcsin(np.clip(np.sin(az), -1, 1)).reshape(stack.shape), rng.reshape(stack.shape)


@lru_cache(maxsize=4)
def _cell_angles(stack: PlaneStack, T_world_head_bytes: bytes) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """:func:`lateral_angle_of_cells` and each cell's angular half-width [rad] seen from the head, for a head
    pose given as the bytes of its float64 (4, 4) transform: computed once per pose (a head on a fixed mount has
    one), read-only."""
    T = np.frombuffer(T_world_head_bytes, dtype=float).reshape(4, 4)
    lat, rng = lateral_angle_of_cells(stack, T)
    half = np.arctan2(0.5 * np.sqrt(2) * stack.cell_size_m, np.maximum(rng, 1e-9))
    for a in (lat, rng, half):
        a.setflags(write=False)
    return lat, rng, half


def evidence_from_saliency(
    saliency,
    azimuth_rad,
    T_world_head,
    stack: PlaneStack,
    time_s: float,
    sensor: str = "binaural",
    speaker_probability: float = 0.1,
    max_log_odds: float = 2.0,
    min_range_m: float = 0.2,
    wedge_sigma_rad: float = np.deg2rad(4.0),
) -> Evidence:
    """Register an auditory saliency map as wedge log-odds on every plane.

    Parameters
    ----------
    saliency : array_like, shape (A,)
        Saliency over the model's azimuths (e.g. ``Localization.saliency``), >= 0;
        normalised here to sum to 1. All zeros (no evidence) gives all-zero log-odds.
    azimuth_rad : array_like, shape (A,)
        The azimuths [rad], increasing, within [-pi/2, pi/2] (lateral angles).
    T_world_head : array_like, shape (4, 4)
        Head pose at ``time_s``.
    stack : PlaneStack
        Planes and grid to register on.
    time_s : float
        Time stamp of the evidence [s].
    sensor : str
        Sensor name in the evidence.
    speaker_probability : float
        ``rho``: probability that an occupied cell holds a sound source, in (0, 1).
    max_log_odds : float
        Cap of the positive evidence along the wedge.
    min_range_m : float
        Cells closer than this to the head's vertical axis get 0 (the azimuth is undefined there).
    wedge_sigma_rad : float
        The saliency is blurred by a Gaussian of this width [rad] before registration: the
        angular uncertainty of the estimate (about twice its mean error), which sets the wedge's width.

    Returns
    -------
    Evidence
        ``log_odds`` (L, ny, nx) float32: ``log(1 - rho + rho A s(theta_cell))`` clipped to
        ``[log(1 - rho), max_log_odds]``; a cell is looked up at its centre and at the
        edges of its angular extent (the largest counts), so a wedge thinner than a cell
        still marks the cells it crosses.
    """
    s = np.asarray(saliency, dtype=float).reshape(-1)
    grid = np.asarray(azimuth_rad, dtype=float).reshape(-1)
    if s.shape != grid.shape or s.size < 2:
        raise ValueError(f"saliency {s.shape} and azimuth_rad {grid.shape} must be equal 1-D shapes (A >= 2)")
    if not np.isfinite(s).all() or np.any(s < 0):
        raise ValueError("saliency must be finite and >= 0")
    if np.any(np.diff(grid) <= 0) or np.abs(grid).max() > np.pi / 2 + 1e-9:
        raise ValueError("azimuth_rad must increase within [-pi/2, pi/2] (lateral angles)")
    if not 0 < speaker_probability < 1:
        raise ValueError(f"speaker_probability must be in (0, 1), got {speaker_probability}")
    if s.sum() == 0:
        return Evidence(float(time_s), sensor, np.zeros(stack.shape, np.float32))
    s = gaussian_filter1d(s / s.sum(), wedge_sigma_rad / np.mean(np.diff(grid)), mode="constant")
    s = s / s.sum()
    T = check_transform(T_world_head, "T_world_head")
    lat, rng, half = _cell_angles(stack, T.astype(float).tobytes())
    look = np.max([np.interp(lat + d * half, grid, s, left=0.0, right=0.0) for d in (-1.0, 0.0, 1.0)], axis=0)
    rho = speaker_probability
    lo = np.log(1 - rho + rho * grid.size * look)
    lo = np.clip(lo, np.log1p(-rho), max_log_odds)
    lo[rng < min_range_m] = 0.0
    return Evidence(float(time_s), sensor, lo.astype(np.float32))
