"""People on the ground from per-plane occupancy log-odds (multi-plane column model).

A person standing at ground cell X with their head between planes k and k+1
occupies the vertical column over X on planes 0..k and leaves planes above free.
With the planes' observations independent given the column state, the
log-likelihood ratio of "person whose top plane is k" against "empty column" is
(the free planes above k cancel)::

    S_k(X) = sum_{l <= k} L_l(X)                 L_l = per-plane log-odds (Khan & Shah synergy per plane)

The person's top plane is ``k*(X) = argmax_{k >= k_min} S_k(X)``, where
``k_min`` is the highest plane every person reaches (``min_height_m``): a column
must be occupied from the ground up to at least that plane. ``k*`` gives the
height estimate.

A person fills only part of its footprint disc (radius ``radius_m``) on a
plane: low planes cut two legs, and the space between them is seen as
background. So before the column sum each plane's log-odds are max-pooled over
the footprint disc (``L_l <- max_{|X'-X| <= r} L_l(X')``): "something of the
person is within r of X on every plane up to k".

``S`` grows with the number of views behind it (cells seen by 2 cameras cannot
collect the evidence of cells seen by 4), so detection uses the *agreement*::

    A(X) = mean_{footprint} S_{k*}(X') / (N_{k*}(X') log(p_d / p_fa))    N_k = (camera, plane) views in the column

the per-view log-likelihood ratio normalised by its largest possible value
(1 when every view of every plane of the column sees foreground), averaged over
the footprint disc so that its maximum sits at the person's centre. Local maxima of
``A`` at least ``nms_radius_m`` apart with ``A >= min_agreement`` on cells seen
by at least ``min_cameras`` cameras are the feet positions, with confidence A.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import cv2
import numpy as np

from ..grid import GroundDetections, PlaneStack, disc_offsets
from .._params import check_fields

__all__ = ["PersonParams", "ground_detections_from_log_odds", "person_score_map"]


@dataclass(frozen=True)
class PersonParams:
    """Multi-plane person model and peak extraction.

    Attributes
    ----------
    min_height_m : float
        Every person reaches at least this height [m]: all planes at or below
        it must be occupied (the lowest plane is always required).
    radius_m : float
        Radius of a person's footprint [m] (per-plane max-pooling and
        smoothing disc).
    nms_radius_m : float
        Minimum distance between two detections [m].
    min_agreement : float
        Smallest normalised agreement A in (0, 1] of a detection.
    min_cameras : int
        Cells on the ground plane seen by fewer cameras are not searched (one
        view cannot place a person along its ray).
    """

    min_height_m: float = 1.0
    radius_m: float = 0.25
    nms_radius_m: float = 0.45
    min_agreement: float = 0.7
    min_cameras: int = 2

    def __post_init__(self) -> None:
        check_fields(self, min_height_m=">=0", radius_m=">0", nms_radius_m=">0", min_agreement="(0,1]",
                     min_cameras="int>=1")



#: Agreement values within this of a peak belong to its plateau (position = plateau centroid).
_PLATEAU = 0.02


@lru_cache(maxsize=16)
def _disc(radius_cells: float) -> np.ndarray:
    """Cells within ``radius_cells`` of the centre, (2r+1, 2r+1) bool (read-only, cached)."""
    r = max(int(np.floor(radius_cells)), 0)
    y, x = np.mgrid[-r:r + 1, -r:r + 1]
    disc = (x * x + y * y) <= radius_cells * radius_cells + 1e-9
    disc.flags.writeable = False
    return disc


@lru_cache(maxsize=16)
def _disc_u8(radius_cells: float) -> np.ndarray:
    """:func:`_disc` as an OpenCV structuring element (uint8, read-only, cached)."""
    disc = _disc(radius_cells).astype(np.uint8)
    disc.flags.writeable = False
    return disc


def person_score_map(log_odds, views, stack: PlaneStack, max_log_ratio: float,
                     params: PersonParams = PersonParams()):
    """Ground-plane person agreement and top-plane index from per-plane log-odds.

    Parameters
    ----------
    log_odds : ndarray, shape (L, ny, nx)
        Per-plane occupancy log-odds (e.g. :meth:`CameraFusion.log_odds`).
    views : ndarray, shape (L, ny, nx)
        Number of cameras behind each cell's log-odds
        (:meth:`CameraFusion.cameras_seeing`).
    stack : PlaneStack
    max_log_ratio : float
        Largest per-view log-likelihood ratio, ``log(p_d / p_fa)``.
    params : PersonParams

    Returns
    -------
    agreement : ndarray, shape (ny, nx), float32
        Normalised footprint agreement ``A`` (see module doc); -1 where not searched.
    top_plane : ndarray, shape (ny, nx), int64
        Arg-max plane index k* (the person's top occupied plane) per cell.
    """
    L = np.asarray(log_odds, dtype=np.float32)
    N = np.asarray(views, dtype=np.float32)
    if L.shape != stack.shape or N.shape != stack.shape:
        raise ValueError(f"log_odds and views must have shape {stack.shape}, got {L.shape} and {N.shape}")
    if not max_log_ratio > 0:
        raise ValueError(f"max_log_ratio must be > 0, got {max_log_ratio}")
    heights = np.asarray(stack.heights_m)
    k_min = max(int(np.searchsorted(heights, params.min_height_m, side="right")) - 1, 0)
    disc = _disc(params.radius_m / stack.cell_size_m)
    # A person fills only part of its footprint on a plane (two legs low down): per plane, the best
    # cell within the footprint speaks for the column.
    disc_u8 = _disc_u8(params.radius_m / stack.cell_size_m)
    # Column sums S_k up the planes and the best k >= k_min per cell, with the views behind it: the values of
    # np.cumsum (the same float32 additions in the same order) and of argmax (the first maximum) with
    # take_along_axis, in one pass over the planes.
    top = np.zeros(L.shape[1:], dtype=np.int64)
    col = n_col = s_k = n_k = None
    for k in range(len(L)):
        pooled = cv2.dilate(L[k], disc_u8, borderType=cv2.BORDER_CONSTANT, borderValue=0.0)
        s_k, n_k = (pooled, N[k]) if k == 0 else (s_k + pooled, n_k + N[k])
        if k == k_min:
            col, n_col = s_k, n_k
        elif k > k_min:
            better = s_k > col
            top[better] = k - k_min
            col, n_col = np.where(better, s_k, col), np.where(better, n_k, n_col)
    with np.errstate(invalid="ignore", divide="ignore"):
        a = np.where(n_col > 0, col / (n_col * max_log_ratio), 0.0).astype(np.float32)
    # Smooth over the footprint so that the pooled plateau peaks at the person's centre.
    kernel = disc.astype(np.float32) / disc.sum()
    a = cv2.filter2D(a, -1, kernel, borderType=cv2.BORDER_CONSTANT)
    agreement = np.where(N[0] >= params.min_cameras, a, -1.0)
    return agreement.astype(np.float32), top + k_min


def ground_detections_from_log_odds(log_odds, views, stack: PlaneStack, time_s: float, max_log_ratio: float,
                                    params: PersonParams = PersonParams(),
                                    source: str = "cameras") -> GroundDetections:
    """Feet positions: non-maximum suppression of :func:`person_score_map`.

    Parameters
    ----------
    log_odds, views : ndarray, shape (L, ny, nx)
        As in :func:`person_score_map`.
    stack : PlaneStack
    time_s : float
    max_log_ratio : float
        ``log(p_d / p_fa)`` of the fusion's sensor model.
    params : PersonParams
    source : str

    Returns
    -------
    GroundDetections
        ``xy_m`` at local maxima of the agreement (centroid of the peak's
        plateau, world XY [m]),
        ``confidence`` = agreement clipped to [0, 1], ``height_m`` = upper band
        edge of the person's top occupied plane (the head lies between that
        plane and the next one up).
    """
    score, top = person_score_map(log_odds, views, stack, max_log_ratio, params)
    r_cells = params.nms_radius_m / stack.cell_size_m
    # ndimage.maximum_filter(score, footprint=disc, mode="constant", cval=-inf), in OpenCV (a dilation's
    # border never wins the maximum)
    peak = cv2.dilate(score, _disc_u8(r_cells), borderType=cv2.BORDER_CONSTANT, borderValue=-np.inf)
    iy, ix = np.nonzero((score >= peak) & (score >= params.min_agreement))
    s = score[iy, ix]
    order = np.argsort(-s, kind="stable")
    iy, ix, s = iy[order], ix[order], s[order]
    # Plateaus give several equal maxima: keep the first of any pair closer than the NMS radius.
    keep = np.ones(len(s), dtype=bool)
    for i in range(len(s)):
        if keep[i]:
            d2 = (iy[i + 1:] - iy[i]) ** 2 + (ix[i + 1:] - ix[i]) ** 2
            keep[i + 1:] &= d2 > r_cells * r_cells
    iy, ix, s = iy[keep], ix[keep], s[keep]
    # Saturated agreement forms plateaus: place each person at the centroid of its plateau (the cells
    # within the NMS radius scoring within `plateau` of the peak), not at an arbitrary tied cell. All peaks at
    # once: (peaks, disc cells) index grids, cells off the grid masked out; the centroids are integer sums
    # divided by the count, the values np.mean gives.
    dy, dx = disc_offsets(r_cells)
    yy, xx = iy[:, None] + dy, ix[:, None] + dx
    inside = (yy >= 0) & (yy < stack.ny) & (xx >= 0) & (xx < stack.nx)
    near = score[np.clip(yy, 0, stack.ny - 1), np.clip(xx, 0, stack.nx - 1)]
    top_cells = inside & (near >= (s - _PLATEAU)[:, None])
    n = np.count_nonzero(top_cells, axis=1)
    fy, fx = (yy * top_cells).sum(axis=1) / n, (xx * top_cells).sum(axis=1) / n
    edges = np.asarray(stack.band_edges_m)
    return GroundDetections(
        float(time_s),
        stack.xy_from_index(fy, fx).reshape(-1, 2),
        np.clip(s, 0.0, 1.0),
        edges[top[iy, ix] + 1],
        source,
    )
