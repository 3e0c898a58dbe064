r"""From filtered occupancy on every plane to person hypotheses on the ground ("fast clustering").

A person standing on cell ``c`` occupies the planes of its column from the ground band up to its head.
The column evidence of ``c`` combines, over the *body planes* (planes no higher than
``body_max_height_m``, which every person reaches), the filtered log-odds relative to the prior, each
smoothed over the person's cross-section (``G``: Gaussian of ``smoothing_m``; legs and thin silhouettes
spread into one blob) and capped above at ``plane_cap``::

    D_l(c) = G * [ logit P_l(occ) - logit p0 ](c)
    S(c)   = sum_{l in body, |D_l(c)| > observed_min} min(D_l(c), plane_cap) / max(n_observed(c), 1)

i.e. the mean, over the body planes whose belief departs from the prior (observed planes), of the capped
log-odds. The cap and the mean make it a soft AND over planes: a column occupied on some body planes but
observed free on another (a multi-camera "ghost", where silhouette rays of different people cross at some
heights only) is pulled down by the free plane instead of being carried by the occupied ones, and a
column must be occupied on every plane that was observed. A plane no sensor has seen stays at the prior
and does not count, so a person seen only by the laser (one plane) or only by sound still produces a
column. Modes of ``S`` above ``threshold`` (local maxima at least
``min_separation_m`` apart) are refined by mean-shift steps with a flat disc kernel of radius
``person_radius_m`` on ``max(S, 0)``. Each cluster reports

* position: the mean-shift mode [m];
* velocity: the occupancy-weighted mean of the BOF cell velocities ``E[V | occ]`` over the disc and the
  body planes, weights ``max(P_l - p0, 0)`` [m/s];
* velocity variance: with the same weights, the law of total variance over those cells,
  ``Var = E_w[Var(V | occ, cell)] + E_w[(E[V | occ, cell] - v)^2]`` per axis [m^2/s^2]: the BOF's own
  uncertainty (large where it has no motion information, e.g. without temporal filtering) plus the spread
  of the cell velocities (large for a blob of two people walking apart), so that the tracker weighs a
  merged blob's mean velocity, which belongs to neither person, accordingly;
* height: the highest plane whose disc-maximum occupancy reaches 0.5, linearly interpolated with the plane
  above it to the height where the profile crosses 0.5 [m] (NaN if no plane reaches 0.5);
* confidence: ``logistic(S(mode) - threshold)``.

Positions from the step's own evidence (:func:`positions_from_step_evidence`,
``ClusterParams.position_from_step_evidence``). The filtered occupancy is the posterior over every frame of evidence
of the last second or so: its mode is a smoothed, lagging estimate of a person's position (behind a walker; at a
stop or a turn carried on along the old motion by the prediction, whose camera evidence is weighted by its
correlation time). The tracker's Kalman filter does the temporal filtering of positions itself: fed the filter's
modes, it filters twice, as if each step's mode were a new measurement. Measured on the tuning seeds 1-3 (30 s
baseline scenes, 6 people): the filtered clusters lie 0.08 m from people walking steadily (0.06 m behind) and
0.13 m from people stopping or turning (0.07 m *ahead* along the old motion), the unfiltered ones 0.04 and 0.03 m.
So the BOF decides *which* people there are (the modes, their confidence, velocity and height), and each mode's
*position* is then moved by mean-shift, the same flat disc, from the BOF's mode on ``max(S_step, 0)``, ``S_step``
the column evidence of the log-odds fused since the previous output step alone (:func:`column_log_odds` of
``logistic(logit p0 + sum of the step's log-odds)``). Where the step's evidence
has no positive mass in the disc (a person hidden, a camera gone) the BOF's mode stays.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import cv2
import numpy as np
from scipy import ndimage

from ..grid import (GroundDetections, PlaneStack, disc_offsets, log_odds_from_probability,
                    probability_from_log_odds)
from .._params import check_fields

__all__ = ["ClusterParams", "Clusters", "cluster_occupancy", "column_log_odds", "positions_from_step_evidence",
           "velocity_variance_m2_s2"]


@dataclass(frozen=True)
class ClusterParams:
    """Parameters of the column clustering.

    Attributes
    ----------
    body_max_height_m : float
        Planes at or below this height [m] form the column evidence (every person reaches them).
    plane_cap : float
        Largest contribution of one plane to ``S`` (> 0).
    observed_min : float
        A body plane counts as observed at a cell where its smoothed log-odds departs from the prior's by
        more than this.
    threshold : float
        Minimum column evidence ``S`` of a mode (mean capped log-odds per observed plane).
    smoothing_m : float
        Standard deviation [m] of the Gaussian smoothing of each plane's log-odds.
    person_radius_m : float
        Radius [m] of the mean-shift disc and of the velocity/height aggregation.
    min_separation_m : float
        Modes closer than this [m] are merged (the higher one wins).
    mean_shift_iterations : int
        Mean-shift refinements of each mode.
    position_from_step_evidence : bool
        Move each filtered mode onto the column evidence of the output step's own evidence
        (:func:`positions_from_step_evidence`, module docstring; applied by
        :class:`~planefuse.tracking.EvidenceTracker`); False: the filter's mode is the position.
    """

    body_max_height_m: float = 1.5
    plane_cap: float = 4.0
    observed_min: float = 0.5
    threshold: float = 1.5
    smoothing_m: float = 0.1
    person_radius_m: float = 0.3
    min_separation_m: float = 0.4
    mean_shift_iterations: int = 3
    position_from_step_evidence: bool = True

    def __post_init__(self) -> None:
        check_fields(self, smoothing_m=">=0", person_radius_m=">=0", min_separation_m=">=0", threshold="finite",
                     plane_cap=">0", mean_shift_iterations="int>=0")


@dataclass(frozen=True)
class Clusters:
    """Person hypotheses at one instant.

    Attributes
    ----------
    time_s : float
        Time [s].
    xy_m : ndarray, shape (N, 2)
        Ground positions (world XY) [m].
    velocity_m_s : ndarray, shape (N, 2)
        Mean BOF velocity (vx, vy) [m/s].
    height_m : ndarray, shape (N,)
        Estimated height [m]; NaN where no plane reaches occupancy 0.5.
    confidence : ndarray, shape (N,)
        In [0, 1].
    column_log_odds : ndarray, shape (ny, nx)
        The column evidence ``S``.
    velocity_var_m2_s2 : ndarray, shape (N, 2), optional
        Variance [m^2/s^2] of the velocity (vx, vy) over the cluster's occupied mass: the BOF's own velocity
        variance in its cells plus the spread of the cell velocities (two people moving apart in one blob).
        None: unknown (no motion information; infinite in :meth:`velocity_variance`).
    """

    time_s: float
    xy_m: np.ndarray
    velocity_m_s: np.ndarray
    height_m: np.ndarray
    confidence: np.ndarray
    column_log_odds: np.ndarray
    velocity_var_m2_s2: np.ndarray | None = None

    def __len__(self) -> int:
        return len(self.xy_m)

    def velocity_variance(self) -> np.ndarray:
        """:attr:`velocity_var_m2_s2`, infinite where it is None (unknown); shape (N, 2) [m^2/s^2]."""
        if self.velocity_var_m2_s2 is None:
            return np.full((len(self), 2), np.inf)
        return np.asarray(self.velocity_var_m2_s2, dtype=float).reshape(-1, 2)

    def to_ground_detections(self) -> GroundDetections:
        """The clusters as :class:`~planefuse.grid.GroundDetections` (source ``"bof"``)."""
        return GroundDetections(self.time_s, self.xy_m, self.confidence, self.height_m, source="bof")


def _body_planes(stack: PlaneStack, params: ClusterParams) -> np.ndarray:
    body = np.flatnonzero(np.asarray(stack.heights_m) <= params.body_max_height_m)
    if body.size == 0:
        raise ValueError(f"no plane of the stack (heights {stack.heights_m}) is at or below "
                         f"body_max_height_m={params.body_max_height_m}")
    return body


def column_log_odds(occupancy, stack: PlaneStack, prior_occupancy: float, params: ClusterParams) -> np.ndarray:
    """Column evidence ``S`` (module docstring), shape (ny, nx).

    Parameters
    ----------
    occupancy : array_like, shape (L, ny, nx)
        Filtered ``P(occ)`` per plane.
    stack : PlaneStack
        The planes (their heights select the body planes).
    prior_occupancy : float
        ``p0`` of the filter.
    params : ClusterParams
        Clustering parameters.
    """
    occ = np.asarray(occupancy, dtype=float)
    if occ.shape != stack.shape:
        raise ValueError(f"occupancy must have shape {stack.shape}, got {occ.shape}")
    body = _body_planes(stack, params)
    d = log_odds_from_probability(occ[body]) - log_odds_from_probability(prior_occupancy)
    if params.smoothing_m > 0:
        sigma = params.smoothing_m / stack.cell_size_m
        d = ndimage.gaussian_filter(d, (0, sigma, sigma), mode="nearest")
    observed = np.abs(d) > params.observed_min
    return np.where(observed, np.minimum(d, params.plane_cap), 0.0).sum(axis=0) / np.maximum(observed.sum(axis=0), 1)


def velocity_variance_m2_s2(occ_v, velocities_m_s, occupancy, velocity_m_s) -> np.ndarray:
    """Per-cell ``Var[V | occ]`` of a velocity-hypothesis grid: ``sum_k P(occ, v_k) v_k^2 / P(occ) - E[V | occ]^2``.

    Parameters
    ----------
    occ_v : array_like, shape (L, K, *cells)
        Joint ``P(occ, v_k)`` per plane, hypothesis and cell (the BOF state; ``cells`` e.g. ``(ny, nx)``).
    velocities_m_s : array_like, shape (K, 2)
        The hypotheses ``v_k`` (vx, vy) [m/s].
    occupancy : array_like, shape (L, *cells)
        ``P(occ)``.
    velocity_m_s : array_like, shape (L, *cells, 2)
        ``E[V | occ]`` [m/s].

    Returns
    -------
    ndarray, shape (L, *cells, 2), float32
        Variance per axis [m^2/s^2], >= 0 (0 where ``P(occ) = 0``).
    """
    v2 = np.asarray(velocities_m_s, dtype=np.float32) ** 2
    m2 = np.moveaxis(np.tensordot(v2, np.asarray(occ_v), axes=([0], [1])), 0, -1)  # (L, *cells, 2)
    occ = np.asarray(occupancy, dtype=np.float32)[..., None]
    m2 = np.divide(m2, occ, out=np.zeros_like(m2), where=occ > 0)
    return np.maximum(m2 - np.asarray(velocity_m_s, dtype=np.float32) ** 2, 0.0)


def _disc_window(radius_cells: float, shape: tuple[int, int]):
    """``window(c)``: the indices ``(iy, ix)`` of the cells of a grid of ``shape`` within ``radius_cells`` of the
    cell nearest the fractional index ``c = (iy, ix)``."""
    dy, dx = disc_offsets(radius_cells)
    ny, nx = shape

    def window(c):
        iy = np.rint(c[0]).astype(int) + dy
        ix = np.rint(c[1]).astype(int) + dx
        ok = (iy >= 0) & (iy < ny) & (ix >= 0) & (ix < nx)
        return iy[ok], ix[ok]

    return window


def _mean_shift(centres: np.ndarray, w_map: np.ndarray, window, iterations: int) -> None:
    """Mean-shift of ``centres`` (n, 2) fractional (iy, ix), in place, with a flat disc kernel (``window``) on the
    non-negative weights ``w_map``; a centre whose disc holds no weight stays."""
    for _ in range(int(iterations)):
        for i, c in enumerate(centres):
            iy, ix = window(c)
            w = w_map[iy, ix]
            if w.sum() > 0:
                centres[i] = (np.sum(w * iy) / w.sum(), np.sum(w * ix) / w.sum())


def positions_from_step_evidence(clusters: Clusters, step_log_odds, stack: PlaneStack, prior_occupancy: float,
                                 params: ClusterParams | None = None) -> Clusters:
    """``clusters`` with each position moved onto the output step's own evidence (module docstring).

    Parameters
    ----------
    clusters : Clusters
        The filter's clusters (:func:`cluster_occupancy`).
    step_log_odds : array_like, shape (L, ny, nx)
        Sum of the log-odds fused since the previous output step (as the filter took them in).
    stack : PlaneStack
        The planes.
    prior_occupancy : float
        ``p0`` of the filter.
    params : ClusterParams, optional
        Clustering parameters (body planes, cap, smoothing, disc radius, iterations).

    Returns
    -------
    Clusters
        The same clusters (velocity, height, confidence and column evidence unchanged) at the mean-shift modes of
        the step's column evidence started from their positions; positions without positive step evidence in
        their disc unchanged.
    """
    params = params if params is not None else ClusterParams()
    L = np.asarray(step_log_odds, dtype=float)
    if L.shape != stack.shape:
        raise ValueError(f"step_log_odds must have shape {stack.shape}, got {L.shape}")
    if not len(clusters):
        return clusters
    p_step = probability_from_log_odds(log_odds_from_probability(prior_occupancy) + L)
    S_step = column_log_odds(p_step, stack, prior_occupancy, params)
    centres = np.stack(stack.fractional_index_from_xy(clusters.xy_m), axis=1)
    _mean_shift(centres, np.maximum(S_step, 0.0), _disc_window(params.person_radius_m / stack.cell_size_m,
                                                                S_step.shape), params.mean_shift_iterations)
    return replace(clusters, xy_m=stack.xy_from_index(centres[:, 0], centres[:, 1]))



def _height_from_profile(profile: np.ndarray, heights_m: np.ndarray) -> float:
    """Height [m] where the occupancy profile (per plane, bottom up) last crosses 0.5; NaN if never >= 0.5."""
    above = np.flatnonzero(profile >= 0.5)
    if above.size == 0:
        return float("nan")
    top = above[-1]
    if top == len(profile) - 1:
        return float(heights_m[top])
    p_lo, p_hi = profile[top], profile[top + 1]
    frac = (p_lo - 0.5) / max(p_lo - p_hi, 1e-12)
    return float(heights_m[top] + frac * (heights_m[top + 1] - heights_m[top]))


def cluster_occupancy(
    time_s: float,
    occupancy,
    velocity_m_s,
    stack: PlaneStack,
    prior_occupancy: float,
    params: ClusterParams | None = None,
    velocity_hypotheses=None,
) -> Clusters:
    """Find person hypotheses in the filtered plane stack (module docstring).

    Parameters
    ----------
    time_s : float
        Time of the occupancy [s].
    occupancy : array_like, shape (L, ny, nx)
        Filtered ``P(occ)`` per plane.
    velocity_m_s : array_like, shape (L, ny, nx, 2)
        BOF ``E[V | occ]`` per cell (vx, vy) [m/s].
    stack : PlaneStack
        The plane stack.
    prior_occupancy : float
        ``p0`` of the filter.
    params : ClusterParams, optional
        Clustering parameters.
    velocity_hypotheses : (ndarray (L, K, ny, nx), ndarray (K, 2)), optional
        The BOF's joint ``P(occ, v_k)`` and its hypotheses ``v_k`` [m/s] (``BOFState.occ_v``,
        ``BOFState.velocities_m_s``), for the within-cell velocity variance of each cluster
        (:func:`velocity_variance_m2_s2`, evaluated in the clusters' discs only); None: the clusters'
        velocity variance is unknown (``Clusters.velocity_var_m2_s2`` None: no motion information).
    """
    params = params if params is not None else ClusterParams()
    occ = np.asarray(occupancy, dtype=float)
    vel = np.asarray(velocity_m_s, dtype=float)
    if vel.shape != stack.shape + (2,):
        raise ValueError(f"velocity_m_s must have shape {stack.shape + (2,)}, got {vel.shape}")
    if velocity_hypotheses is not None:
        occ_v, v_k = velocity_hypotheses
        K = len(v_k)
        if np.shape(occ_v) != (occ.shape[0], K) + occ.shape[1:] or np.shape(v_k) != (K, 2):
            raise ValueError(f"velocity_hypotheses must be (L, K, ny, nx) and (K, 2) arrays with (L, ny, nx) = "
                             f"{occ.shape}, got {np.shape(occ_v)} and {np.shape(v_k)}")
    S = column_log_odds(occ, stack, prior_occupancy, params)
    cell = stack.cell_size_m

    # modes: local maxima of the smoothed evidence, one per plateau, at least min_separation apart
    r_sep = max(int(round(params.min_separation_m / cell)), 1)
    yy, xx = np.mgrid[-r_sep:r_sep + 1, -r_sep:r_sep + 1]
    disc = ((yy**2 + xx**2) <= r_sep**2).astype(np.uint8)
    peaks = S == cv2.dilate(S, disc, borderType=cv2.BORDER_REPLICATE)  # the disc's maximum, edges replicated
    peaks &= S >= params.threshold
    lab, n = ndimage.label(peaks)
    if n == 0:
        empty = np.zeros((0, 2))
        return Clusters(float(time_s), empty, empty.copy(), np.zeros(0), np.zeros(0), S,
                        None if velocity_hypotheses is None else empty.copy())
    # each plateau's centre (n, 2) as (iy, ix): the mean index of its cells
    iy_p, ix_p = np.nonzero(peaks)
    label_p = lab[iy_p, ix_p]
    count = np.bincount(label_p, minlength=n + 1)[1:]
    centres = np.stack([np.bincount(label_p, iy_p, n + 1)[1:], np.bincount(label_p, ix_p, n + 1)[1:]], axis=1)
    centres /= count[:, None]

    window = _disc_window(params.person_radius_m / cell, S.shape)
    _mean_shift(centres, np.maximum(S, 0.0), window, params.mean_shift_iterations)
    # modes that converged onto each other: keep the strongest
    strength = ndimage.map_coordinates(S, centres.T, order=1, mode="nearest")
    order = np.argsort(-strength)
    keep: list[int] = []
    for i in order:
        if all(np.hypot(*(centres[i] - centres[j])) * cell >= params.min_separation_m for j in keep):
            keep.append(i)
    centres, strength = centres[keep], strength[keep]

    body = _body_planes(stack, params)
    occ_body, vel_body = occ[body], vel[body]
    excess = np.maximum(occ_body - prior_occupancy, 0.0)
    heights = np.asarray(stack.heights_m)
    v_out = np.zeros((len(centres), 2))
    var_out = np.zeros((len(centres), 2)) if velocity_hypotheses is not None else None
    h_out = np.full(len(centres), np.nan)
    for i, c in enumerate(centres):
        iy, ix = window(c)
        w = excess[:, iy, ix]
        if w.sum() > 0:
            v_cells = vel_body[:, iy, ix]
            v_out[i] = np.einsum("lc,lcd->d", w, v_cells) / w.sum()
            if var_out is not None:
                # law of total variance over the cells: mean within-cell variance + spread of the cell means
                var_cells = velocity_variance_m2_s2(occ_v[:, :, iy, ix][body], v_k, occ_body[:, iy, ix], v_cells)
                var_out[i] = np.einsum("lc,lcd->d", w, var_cells + (v_cells - v_out[i]) ** 2) / w.sum()
        h_out[i] = _height_from_profile(occ[:, iy, ix].max(axis=1), heights)
    xy = stack.xy_from_index(centres[:, 0], centres[:, 1])
    conf = probability_from_log_odds(strength - params.threshold)
    return Clusters(float(time_s), xy, v_out, h_out, conf, S, var_out)
