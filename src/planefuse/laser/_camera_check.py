"""Check a laser-to-camera extrinsic on a calibration board seen by both sensors.

A laser scan and a camera image see the same checkerboard, whose pose in the camera frame is known from the
camera calibration. With a good ``T_camera_laser``:

* laser points mapped into the camera and projected (OpenCV ``projectPoints``, with distortion) inside the
  convex hull of the detected corners lie on the board plane (small distance to the plane);
* laser points on the board plane (within ``plane_tolerance_m``, inside the corner grid) project inside the
  corner hull (within ``hull_tolerance_px``).

This is the consistency check of the CMU Laser-Camera Calibration Toolbox sample data (docs/results.md).
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import cv2
import numpy as np

from ..geometry import apply_transform, check_points, check_transform

__all__ = ["BoardCheck", "board_check"]


@dataclass(frozen=True)
class BoardCheck:
    """Result of :func:`board_check` for one scan / image pair.

    Attributes
    ----------
    n_points : int
        Laser points in front of the camera (z_camera > 0).
    n_in_hull : int
        Points projecting inside the corner hull.
    plane_distance_median_m, plane_distance_p90_m : float
        Median and 90th percentile of those points' distance to the board plane [m] (NaN if none).
    n_on_board : int
        Points within ``plane_tolerance_m`` of the board plane and inside the corner grid.
    on_board_in_hull_fraction : float
        Fraction of those projecting inside the hull within ``hull_tolerance_px`` (NaN if none).
    """

    n_points: int
    n_in_hull: int
    plane_distance_median_m: float
    plane_distance_p90_m: float
    n_on_board: int
    on_board_in_hull_fraction: float

    def as_dict(self) -> dict:
        return asdict(self)


def board_check(points_laser, T_camera_laser, K, dist, T_camera_board, corners_px, corners_board_m,
                plane_tolerance_m: float = 0.01, hull_tolerance_px: float = 1.0) -> BoardCheck:
    """Score ``T_camera_laser`` on one board view, see the module docstring.

    Parameters
    ----------
    points_laser : array_like (N, 3)
        Laser points in the laser frame [m]; non-finite points are ignored.
    T_camera_laser : array_like (4, 4)
        Laser frame -> camera frame [m].
    K : array_like (3, 3)
        Camera matrix [px].
    dist : array_like (5,)
        Distortion k1, k2, p1, p2, k3.
    T_camera_board : array_like (4, 4)
        Board frame -> camera frame [m]; the board is the plane z_board = 0.
    corners_px : array_like (K, 2)
        Detected corners in the image [px].
    corners_board_m : array_like (K, 3)
        The same corners in the board frame [m].
    plane_tolerance_m, hull_tolerance_px : float
        On-board test: distance to the plane [m]; hull test margin [px].
    """
    p = check_points(points_laser, 3, "points_laser", allow_nan=True).reshape(-1, 3)
    p = apply_transform(check_transform(T_camera_laser, "T_camera_laser"), p[np.isfinite(p).all(axis=1)])
    p = p[p[:, 2] > 0]
    T_cb = check_transform(T_camera_board, "T_camera_board")
    R, t = T_cb[:3, :3], T_cb[:3, 3]
    hull = cv2.convexHull(check_points(corners_px, 2, "corners_px").astype(np.float32))
    uv = cv2.projectPoints(p, np.zeros(3), np.zeros(3), np.asarray(K, float), np.asarray(dist, float))[0]
    margin_px = np.array([cv2.pointPolygonTest(hull, (float(u), float(v)), True) for u, v in uv.reshape(-1, 2)])
    p_board = (p - t) @ R  # camera -> board frame: R^T (p - t), rows
    inside = margin_px >= 0
    d = np.abs(p_board[inside, 2])
    X = check_points(corners_board_m, 3, "corners_board_m")
    on = (np.abs(p_board[:, 2]) < plane_tolerance_m) & (p_board[:, 0] >= X[:, 0].min()) \
        & (p_board[:, 0] <= X[:, 0].max()) & (p_board[:, 1] >= X[:, 1].min()) & (p_board[:, 1] <= X[:, 1].max())
    nan = float("nan")
    return BoardCheck(
        n_points=int(len(p)), n_in_hull=int(inside.sum()),
        plane_distance_median_m=float(np.median(d)) if d.size else nan,
        plane_distance_p90_m=float(np.percentile(d, 90)) if d.size else nan,
        n_on_board=int(on.sum()),
        on_board_in_hull_fraction=float(np.mean(margin_px[on] >= -hull_tolerance_px)) if on.any() else nan,
    )
