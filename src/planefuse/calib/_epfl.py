"""EPFL POM data set: ground-plane ``Homography.txt`` and the per-view box ground truth (``gt.txt``).

``Homography.txt`` maps image pixels (u right, v down, origin top-left, 360x288 views) to ground
points in "top-view" units: ``[x y w]^T = H [u v 1]^T``. The files carry no unit; for the terrace
sequence a fit against EPFL's Tsai calibration (world in mm, ground Z = 0, Z up) gives
``u_top = 0.0457 X_mm + 19.0`` and ``v_top = -0.0459 Y_mm + 402.8`` (about 2.19 cm per unit, v
flipped against Y; rms 1.6-2.1 units per camera). :data:`H_WORLD_TOPVIEW_TERRACE` is that map's
inverse, taking top-view units to the Tsai world in metres, so that planefuse's ``H_plane_image``
for the terrace is metric (approximately) and right-handed with z up.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..geometry._checks import check_homography
from ..grid._stack import PlaneStack
from ._filestorage import calib_error

__all__ = [
    "H_WORLD_TOPVIEW_TERRACE",
    "EpflGroundHomography",
    "EpflBoxes",
    "load_epfl_homography",
    "load_epfl_boxes",
    "epfl_terrace_pom_stack",
]


def _topview_to_world(metres_per_unit_x: float, metres_per_unit_y: float, u0: float, v0: float) -> np.ndarray:
    """Affine (3, 3): top-view (u_top, v_top) -> world XY [m], X = (u - u0) s_x, Y = (v0 - v) s_y."""
    return np.array([[metres_per_unit_x, 0.0, -u0 * metres_per_unit_x], [0.0, -metres_per_unit_y, v0 * metres_per_unit_y],
                     [0.0, 0.0, 1.0]])


#: Terrace top-view units -> Tsai world XY [m] (see the module docstring; approximate, ~2 units rms).
H_WORLD_TOPVIEW_TERRACE = _topview_to_world(1e-3 / 0.0457, 1e-3 / 0.0459, 19.0, 402.8)
H_WORLD_TOPVIEW_TERRACE.setflags(write=False)


@dataclass(frozen=True)
class EpflGroundHomography:
    """One EPFL camera's ground-plane homography.

    Attributes
    ----------
    H_topview_image : ndarray, shape (3, 3)
        Image pixels -> top-view units, as in the file.
    H_world_topview : ndarray, shape (3, 3)
        Top-view units -> world XY [m] (identity if the unit is unknown).
    path : Path
        The file read.
    """

    H_topview_image: np.ndarray
    H_world_topview: np.ndarray
    path: Path

    @property
    def H_plane_image(self) -> np.ndarray:
        """Image pixels -> ground plane z = 0, world XY (metres when ``H_world_topview`` is metric), (3, 3)."""
        return self.H_world_topview @ self.H_topview_image

    @property
    def H_image_plane(self) -> np.ndarray:
        """Ground plane (world XY) -> image pixels (3, 3), for drawing ground points into the image."""
        return np.linalg.inv(self.H_plane_image)


def load_epfl_homography(path, *, H_world_topview=None) -> EpflGroundHomography:
    """Read an EPFL ``Homography.txt`` (3x3, whitespace-separated, image -> top-view ground).

    Parameters
    ----------
    path : str or Path
    H_world_topview : array_like, shape (3, 3), optional
        Top-view units -> world XY [m]; :data:`H_WORLD_TOPVIEW_TERRACE` for the terrace
        sequence. Identity (keep top-view units) if not given.

    Raises
    ------
    ValueError
        Naming the file: missing/empty, non-numeric entries, not 3x3, or a singular matrix.
    """
    p = Path(path)
    if not p.is_file():
        raise calib_error(p, "<file>", "no such file")
    text = p.read_text()
    if not text.strip():
        raise calib_error(p, "H", "file is empty")
    rows = [line.split() for line in text.strip().splitlines() if line.strip()]
    try:
        H = np.array([[float(x) for x in r] for r in rows], dtype=float) if all(len(r) == 3 for r in rows) else None
    except ValueError as exc:
        raise calib_error(p, "H", f"non-numeric entry ({exc})") from None
    if H is None or H.shape != (3, 3):
        raise calib_error(p, "H", f"expected 3 rows of 3 numbers, got rows of {[len(r) for r in rows]} values")
    try:
        check_homography(H, "H")
    except ValueError as exc:
        raise calib_error(p, "H", str(exc)) from None
    W = np.eye(3) if H_world_topview is None else check_homography(H_world_topview, "H_world_topview")
    return EpflGroundHomography(H, np.array(W), p)


@dataclass(frozen=True)
class EpflBoxes:
    """Rows of an EPFL ``gt.txt`` (Xu et al., Vatic): one per (identity, frame).

    Attributes
    ----------
    track_id, frame : ndarray, shape (N,), int64
        Identity (shared by all cameras of a sequence) and 0-based synchronised frame.
    box_xyxy_px : ndarray, shape (N, 4), float64
        ``(xmin, ymin, xmax, ymax)`` in pixels of the 360x288 view.
    lost, occluded, generated : ndarray, shape (N,), bool
        ``lost``: outside the view (coordinates are stale); ``generated``: interpolated.
    """

    track_id: np.ndarray
    frame: np.ndarray
    box_xyxy_px: np.ndarray
    lost: np.ndarray
    occluded: np.ndarray
    generated: np.ndarray

    def foot_uv(self) -> np.ndarray:
        """Bottom centre ``((xmin + xmax) / 2, ymax)`` of each box, (N, 2) [px]."""
        b = self.box_xyxy_px
        return np.stack([0.5 * (b[:, 0] + b[:, 2]), b[:, 3]], axis=-1)


def load_epfl_boxes(path) -> EpflBoxes:
    """Read an EPFL ``gt.txt``: ``track_id xmin ymin xmax ymax frame lost occluded generated "label"`` per line.

    All rows are kept (``lost`` rows included: filter with the ``lost`` field).

    Raises
    ------
    ValueError
        Naming the file and line for a row without 10 fields or with non-integer values.
    """
    p = Path(path)
    if not p.is_file():
        raise calib_error(p, "<file>", "no such file")
    lines = [ln for ln in p.read_text().splitlines() if ln.strip()]
    if not lines:
        raise calib_error(p, "rows", "file is empty")
    vals = np.empty((len(lines), 9), dtype=np.int64)
    for i, ln in enumerate(lines):
        parts = ln.split()
        if len(parts) != 10:
            raise calib_error(p, f"line {i + 1}", f"expected 10 fields, got {len(parts)}")
        try:
            vals[i] = [int(x) for x in parts[:9]]
        except ValueError:
            raise calib_error(p, f"line {i + 1}", f"non-integer value in {parts[:9]}") from None
    return EpflBoxes(
        track_id=vals[:, 0],
        frame=vals[:, 5],
        box_xyxy_px=vals[:, 1:5].astype(float),
        lost=vals[:, 6] != 0,
        occluded=vals[:, 7] != 0,
        generated=vals[:, 8] != 0,
    )


def epfl_terrace_pom_stack(heights_m=(0.0,)) -> PlaneStack:
    """POM's terrace occupancy grid in the Tsai world [m]: 30 x 44 cells of 25 cm from (-0.5, -1.5) m."""
    return PlaneStack(tuple(heights_m), -0.5, -1.5, 0.25, 30, 44)
