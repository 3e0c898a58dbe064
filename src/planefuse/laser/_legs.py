"""People from a 2-D laser alone: leg clusters in a scan, paired into people.

1. The scan's valid returns, in beam order, are cut into segments wherever consecutive
   points are farther apart than ``jump_m`` (0.13 m, the clustering threshold of the
   leg-tracker labels of Leigh et al., ICRA 2015).
2. A segment is a leg when it has at least ``min_points`` points and its chord (first to
   last point) is between ``min_width_m`` and ``max_width_m``; a wider segment up to
   ``max_pair_width_m`` is two legs side by side (one person).
   With a background model of a static scanner (``background_ranges_m``, e.g. the per-beam
   median over a recording), a segment must also be foreground: most of its points at least
   ``background_margin_m`` closer than the background. This removes leg-sized pieces of wall
   seen between the shadows of people, which geometry alone cannot tell from legs.
3. Legs closer than ``pair_distance_m`` are paired greedily (closest first); a person is
   at the midpoint of a pair, at a merged two-leg segment, or at a lone leg (lower
   confidence, the other leg occluded).
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass

import numpy as np
from scipy.spatial.distance import cdist

from .._params import check_fields, require
from ..eval import DetectionScores, detection_scores
from ..grid import GroundDetections
from ._scanner import LaserScan, points_world_from_scan

__all__ = ["LegDetectorParams", "LegClusters", "segment_scan", "detect_legs", "people_from_legs",
           "detect_people", "evaluate_leg_detection", "background_ranges_m"]


@dataclass(frozen=True)
class LegDetectorParams:
    """Thresholds of the leg detector (metres)."""

    jump_m: float = 0.13
    min_points: int = 3
    min_width_m: float = 0.03
    max_width_m: float = 0.30
    max_pair_width_m: float = 0.55
    pair_distance_m: float = 0.6
    background_margin_m: float = 0.1

    def __post_init__(self) -> None:
        check_fields(self, jump_m=">0", min_points="int>=1", min_width_m=">0", pair_distance_m=">0",
                     background_margin_m=">=0")
        require(self.min_width_m < self.max_width_m <= self.max_pair_width_m, self, "min_width_m",
                f"need min_width_m < max_width_m <= max_pair_width_m, got {self.min_width_m}, {self.max_width_m}, "
                f"{self.max_pair_width_m}")


@dataclass(frozen=True)
class LegClusters:
    """Leg candidates of one scan.

    Attributes
    ----------
    xy_m : ndarray (K, 2)
        Centroid of each leg segment [m] (frame of the input points).
    width_m : ndarray (K,)
        Chord of the segment [m].
    n_points : ndarray (K,) int
        Points in the segment.
    double : ndarray (K,) bool
        Segment wide enough to be two legs side by side.
    """

    xy_m: np.ndarray
    width_m: np.ndarray
    n_points: np.ndarray
    double: np.ndarray

    def __len__(self) -> int:
        return len(self.xy_m)


def segment_scan(xy, jump_m: float = 0.13) -> np.ndarray:
    """Segment labels (N,) int of points ordered by beam: a new segment where a jump exceeds ``jump_m``.

    Parameters
    ----------
    xy : array_like (N, 2)
        Valid returns in beam order [m].
    jump_m : float
        Break distance [m].
    """
    p = np.asarray(xy, dtype=float)
    if p.ndim != 2 or p.shape[1] != 2 or not np.isfinite(p).all():
        raise ValueError(f"xy must be finite points (N, 2) in beam order, got shape {p.shape}")
    if len(p) == 0:
        return np.zeros(0, dtype=np.int64)
    jump = np.linalg.norm(np.diff(p, axis=0), axis=1) > jump_m
    return np.concatenate([[0], np.cumsum(jump)]).astype(np.int64)


def detect_legs(xy, params: LegDetectorParams = LegDetectorParams(), foreground=None) -> LegClusters:
    """Leg-sized segments of one scan's valid returns, see the module docstring.

    Parameters
    ----------
    xy : array_like (N, 2)
        Valid returns in beam order [m].
    params : LegDetectorParams
    foreground : array_like (N,) bool, optional
        Points in front of the static background; segments that are mostly background are
        dropped. None: no background model (every segment may be a leg).

    Notes
    -----
    Purely geometric: a leg-sized piece of background (a stretch of wall seen between the
    shadows of two legs) is also a leg candidate. A foreground test (neighbours across
    the jumps farther away) would remove those, but it rejects half of the labelled legs of
    the leg-tracker recordings, which are seen through a gap between closer objects.
    """
    p = np.asarray(xy, dtype=float)
    lab = segment_scan(p, params.jump_m)
    if lab.size == 0:
        z = np.zeros(0)
        return LegClusters(np.zeros((0, 2)), z, z.astype(np.int64), z.astype(bool))
    n_seg = lab[-1] + 1
    counts = np.bincount(lab, minlength=n_seg)
    first = np.concatenate([[0], np.cumsum(counts)[:-1]])
    last = first + counts - 1
    width = np.linalg.norm(p[last] - p[first], axis=1)
    cx = np.bincount(lab, p[:, 0], n_seg) / counts
    cy = np.bincount(lab, p[:, 1], n_seg) / counts
    keep = (counts >= params.min_points) & (width >= params.min_width_m) & (width <= params.max_pair_width_m)
    if foreground is not None:
        fg = np.asarray(foreground, dtype=bool).reshape(-1)
        if fg.shape != (len(p),):
            raise ValueError(f"foreground must have one flag per point ({len(p)}), got {fg.shape}")
        keep &= np.bincount(lab, fg.astype(float), n_seg) > 0.5 * counts
    return LegClusters(np.column_stack([cx, cy])[keep], width[keep], counts[keep],
                       width[keep] > params.max_width_m)


def people_from_legs(legs: LegClusters, params: LegDetectorParams = LegDetectorParams()) -> tuple[np.ndarray, np.ndarray]:
    """People positions (M, 2) [m] and confidences (M,) from leg clusters.

    Pairs of single legs closer than ``pair_distance_m`` (greedy, closest first) give a person
    at their midpoint (confidence 0.9); a double-leg segment gives one person (0.8); a lone leg
    gives a person at the leg (0.5).
    """
    single = np.flatnonzero(~legs.double)
    xy = legs.xy_m
    people, conf = [], []
    used = np.zeros(len(xy), bool)
    if single.size >= 2:
        d = cdist(xy[single], xy[single])
        iu, ju = np.triu_indices(single.size, 1)
        order = np.argsort(d[iu, ju])
        for k in order:  # greedy matching over candidate pairs (few legs per scan)
            a, b = single[iu[k]], single[ju[k]]
            if d[iu[k], ju[k]] > params.pair_distance_m:
                break
            if not (used[a] or used[b]):
                used[a] = used[b] = True
                people.append(0.5 * (xy[a] + xy[b]))
                conf.append(0.9)
    for i in np.flatnonzero(legs.double):
        people.append(xy[i])
        conf.append(0.8)
        used[i] = True
    for i in np.flatnonzero(~used):
        people.append(xy[i])
        conf.append(0.5)
    if not people:
        return np.zeros((0, 2)), np.zeros(0)
    return np.array(people), np.array(conf)


def background_ranges_m(scans) -> np.ndarray:
    """Per-beam background range (N,) [m] of a static scanner: the median of the valid ranges over ``scans``.

    People move, so the median over a recording is the static scene. Beams that never
    returned get ``inf`` (anything they see is foreground).
    """
    r = np.array([np.where(s.valid, s.ranges_m, np.nan) for s in scans])
    if r.ndim != 2:
        raise ValueError("scans must all have the same number of beams")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # all-NaN beams: handled below
        med = np.nanmedian(r, axis=0)
    return np.where(np.isnan(med), np.inf, med)


def detect_people(scan: LaserScan, T_world_laser=None, params: LegDetectorParams = LegDetectorParams(),
                  source: str = "laser", background_ranges_m=None) -> GroundDetections:
    """People in one 2-D scan, in world XY, as :class:`GroundDetections` (height unknown: NaN).

    Parameters
    ----------
    scan : LaserScan
        A scan roughly parallel to the ground at leg height; only ``scan.valid`` returns are used
        (max-range and invalid beams cannot hold legs).
    T_world_laser : array_like (4, 4), optional
        Laser pose; default ``scan.T_world_laser``, or the laser frame itself if neither is set.
    params : LegDetectorParams
    source : str
    background_ranges_m : array_like (N,), optional
        Static background range per beam (:func:`background_ranges_m`) for a fixed scanner;
        returns not ``params.background_margin_m`` closer than it are background.
    """
    T = scan.T_world_laser if T_world_laser is None else T_world_laser
    T = np.eye(4) if T is None else T
    ok = scan.valid
    p = points_world_from_scan(scan.angles_rad[ok], scan.ranges_m[ok], scan.tilt_rad[ok], T)
    fg = None
    if background_ranges_m is not None:
        bg = np.asarray(background_ranges_m, dtype=float).reshape(-1)
        if bg.shape != scan.ranges_m.shape:
            raise ValueError(f"background_ranges_m has {bg.size} beams, the scan {scan.ranges_m.size}")
        fg = scan.ranges_m[ok] < bg[ok] - params.background_margin_m
    xy, conf = people_from_legs(detect_legs(p[:, :2], params, fg), params)
    return GroundDetections(float(scan.time_s), xy, conf, None, source)


def evaluate_leg_detection(scans, labels, *, max_distance_m: float = 0.3, window_deg: float = 15.0,
                           max_range_m: float = 5.0, params: LegDetectorParams = LegDetectorParams(),
                           ) -> DetectionScores:
    """Leg detection scored against labelled leg centroids in the laser frame (leg-tracker bags).

    The labels of ``angusleigh/leg_tracker``'s extracted bags only cover legs within
    ``+-window_deg`` of the scanner's axis and ``max_range_m``; detections are scored in the same
    window.

    Parameters
    ----------
    scans : sequence of LaserScan
    labels : sequence of ndarray (P_i, 2 or 3)
        Labelled leg centroids per scan, laser frame [m] (paired with ``scans`` by order).

    Returns
    -------
    DetectionScores
        :func:`planefuse.eval.detection_scores` (one-to-one Hungarian matching within
        ``max_distance_m``) over the scans.
    """
    if len(scans) != len(labels):
        raise ValueError(f"{len(scans)} scans but {len(labels)} label sets")

    def frames():
        for scan, truth in zip(scans, labels):  # one detector call per scan
            ok = scan.valid
            xy = points_world_from_scan(scan.angles_rad[ok], scan.ranges_m[ok], scan.tilt_rad[ok], np.eye(4))[:, :2]
            d = detect_legs(xy, params).xy_m
            win = (np.abs(np.arctan2(d[:, 1], d[:, 0])) <= np.deg2rad(window_deg)) \
                & (np.hypot(d[:, 0], d[:, 1]) <= max_range_m)
            yield np.asarray(truth, dtype=float)[:, :2], d[win]

    return detection_scores(frames(), max_distance_m)
