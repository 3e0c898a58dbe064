"""Person boxes registered on every plane: each box's foot point on the ground, its body up the planes.

A person detector's box in camera c is the person's silhouette in that view. Its bottom centre ``u_f`` is where
the feet touch the ground, so its ray meets the ground plane z = 0 at the person's position ``x_f``; its top
centre's ray passes over ``x_f`` at the head's height ``z_h`` (the point of that ray nearest the vertical line
through ``x_f``). One view is enough to place a person (no triangulation), which is what a person hidden from the
other cameras needs.

The foot pixel is uncertain by ``sigma_px = foot_std_frac * h_px`` in each direction (``h_px`` the box's height:
a bigger box has a less certain bottom in pixels -- feet, shadow, the box's own slack), mapped to the ground
through the Jacobian ``J`` of the pixel -> ground map at ``u_f``, so the uncertainty grows with distance (the
ground's scale in the image shrinks) and along the viewing ray::

    Sigma_f = sigma_px^2 J J^T + min_std_m^2 I                    [m^2]

Each box adds, on every plane whose height lies between the ground and the head (``z_l <= z_h``), a Gaussian
bump of log-odds around ``x_f``::

    L_l(X) += log_odds * exp(-0.5 (X - x_f)^T Sigma_f^-1 (X - x_f))

(per camera the largest bump of its boxes at each cell; the cameras' bumps add, as independent views do). Boxes
whose foot pixel lies on the image's bottom edge (the feet are cut off) or in an ignore region, and boxes whose
foot ray does not reach the ground in front of the camera, give nothing.

A detector that finds nobody at a place it sees says something too (``free_log_odds`` < 0): a cell of the
ground plane whose pixel in camera c (its lookup on the lowest plane) lies outside every box of c gets
``free_log_odds`` on every plane -- the detector's miss rate against its rate of boxes on empty ground, about
``log(1 - recall)``. A cell whose pixel lies inside a box gets nothing from that view: it is the detected person, or
behind him (hidden: a person there may be missed), so people in groups keep what the other views and the
background subtraction say. Ghosts of the background subtraction -- light, shadows, a moved object -- are not
people to a detector, and so lose.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Sequence

import numpy as np

from .._params import check_fields
from ..geometry import PinholeCamera
from ..grid import PlaneStack
from ._yolox import PersonBoxes

__all__ = ["BoxEvidenceParams", "box_evidence", "box_feet", "combine_box_evidence"]

#: The bump is cut where it falls below this share of its peak (3 standard deviations: exp(-4.5)).
_CUT_MAHALANOBIS2 = 9.0


@dataclass(frozen=True)
class BoxEvidenceParams:
    """How person boxes become evidence on the plane stack (module doc).

    Attributes
    ----------
    log_odds : float or None
        Peak log-odds one box adds at its foot point on each plane of the body; 0 = no foot points. None: the
        detector's default (:meth:`for_detector`): YOLOX 1, chosen on the EPFL terrace's tuning frames with the
        free space -3 and the fitted canvas (cold starts at 0 and 1000, frames up to 995 / 1000-1495 every 5th,
        filtered MODA 0.5 / 1.0 m, MOTA, IDF1): 0.805 / 0.890, 0.788, 0.895 and 0.747 / 0.909, 0.731, 0.861 against
        0.803 / 0.893, 0.788, 0.895 and 0.739 / 0.897, 0.731, 0.808 without (2: 0.810 / 0.890, 0.788, 0.895 and
        0.737 / 0.911, 0.733, 0.862; 3: 0.808 / 0.888, 0.778, 0.890 and 0.741 / 0.911, 0.715, 0.805 -- 1 and 2 tie,
        and a detector that sees less well on another installation is trusted less); HOG 0.
    foot_std_frac : float
        Standard deviation of the foot pixel in each image direction, as a share of the box's height.
    min_std_m : float
        Standard deviation [m] added in every ground direction (the person's own width: a foot point is somewhere
        under a body).
    edge_px : float
        A box whose bottom lies within this many pixels of the image's bottom edge has its feet cut off: no foot
        point [px].
    free_log_odds : float or None
        Log-odds (<= 0) a camera gives a ground cell it sees outside every one of its boxes, on every plane (module
        doc); 0 = none. None: the detector's default (:meth:`for_detector`): YOLOX -3, chosen on the EPFL terrace's
        tuning frames (cold starts at 0 and 1000, frames up to 999 / 1000-1499 every 5th, filtered MODA 0.5 / 1.0 m,
        MOTA, IDF1): 0.800 / 0.890, 0.788, 0.895 and 0.735 / 0.893, 0.723, 0.811 against 0.783 / 0.873, 0.758,
        0.881 and 0.696 / 0.895, 0.719, 0.804 without (-1: 0.791 / 0.875, 0.773, 0.888 and 0.717 / 0.901, 0.715,
        0.772; -2: 0.798 / 0.883, 0.788, 0.895 and 0.733 / 0.891, 0.715, 0.755; -4: 0.823 / 0.913, 0.810, 0.905
        and 0.731 / 0.881, 0.694, 0.837 -- -3 keeps the busiest range's MOTA, and a detector that sees less well
        on another installation is trusted less); HOG 0 (it finds 60 % of the terrace's people: its misses are
        no evidence of free space).
    override : bool
        Where the boxes' bumps lie, the sensor model's evidence *against* a person is dropped before the bumps are
        added (:func:`combine_box_evidence`): a detected person who stands still has faded from the background
        model, and the subtraction then calls him background. False: the two are added as they are.
    """

    log_odds: float | None = None
    foot_std_frac: float = 0.05
    min_std_m: float = 0.1
    edge_px: float = 2.0
    free_log_odds: float | None = None
    override: bool = False

    def __post_init__(self) -> None:
        check_fields(self, log_odds="?>=0", foot_std_frac=">0", min_std_m=">0", edge_px=">=0",
                     free_log_odds="?finite")
        if self.free_log_odds is not None and self.free_log_odds > 0:
            raise ValueError(f"BoxEvidenceParams.free_log_odds must be <= 0 (evidence against a person), got "
                             f"{self.free_log_odds}")

    def for_detector(self, detector: str | None) -> "BoxEvidenceParams":
        """These parameters with ``log_odds`` and ``free_log_odds`` resolved for ``detector`` where None: ``"yolox"``
        1 and -3, else 0 and 0."""
        yolox = detector == "yolox"
        return replace(self, log_odds=(1.0 if yolox else 0.0) if self.log_odds is None else self.log_odds,
                       free_log_odds=(-3.0 if yolox else 0.0) if self.free_log_odds is None else self.free_log_odds)

    @property
    def active(self) -> bool:
        """True where boxes give any evidence (a bump or a free-space term); both must be resolved."""
        return (self.log_odds or 0.0) > 0 or (self.free_log_odds or 0.0) < 0


def box_feet(camera: PinholeCamera, boxes: PersonBoxes, foot_std_frac: float = 0.05, min_std_m: float = 0.1,
             ignore_mask: np.ndarray | None = None, edge_px: float = 2.0
             ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Foot points, their covariances and head heights of one camera's boxes.

    Parameters
    ----------
    camera : PinholeCamera
        The camera the boxes were found in (frame pixels, lens distortion included).
    boxes : PersonBoxes
    foot_std_frac, min_std_m, edge_px : float
        As in :class:`BoxEvidenceParams`.
    ignore_mask : ndarray, shape (height_px, width_px), bool, optional
        Pixels that are not scene evidence: a box whose foot pixel lies there gives no foot point.

    Returns
    -------
    xy_m : ndarray, shape (K, 2)
        Foot points on the ground [m, world].
    cov_m2 : ndarray, shape (K, 2, 2)
        Their covariances [m^2].
    head_m : ndarray, shape (K,)
        Height of the head above the ground [m] (the top centre's ray over the foot point).
    used : ndarray, shape (K,), bool
        Boxes that gave a foot point (the others: feet cut by the image's bottom edge, foot pixel ignored, or a
        ray that does not reach the ground in front of the camera); the arrays above hold only these.
    """
    b = np.asarray(boxes.ltwh_px, float).reshape(-1, 4)
    w_px, h_px = camera.intrinsics.width_px, camera.intrinsics.height_px
    u = b[:, 0] + b[:, 2] / 2
    foot = np.c_[u, b[:, 1] + b[:, 3]]
    used = foot[:, 1] < h_px - edge_px
    if ignore_mask is not None and len(b):
        r = np.clip(np.floor(foot[:, 1]).astype(int), 0, h_px - 1)
        c = np.clip(np.floor(foot[:, 0]).astype(int), 0, w_px - 1)
        used &= ~np.asarray(ignore_mask, bool)[r, c]
    # the foot pixel and its neighbours one pixel to the right and down: the pixel -> ground Jacobian
    probe = np.concatenate([foot, foot + [1.0, 0.0], foot + [0.0, 1.0]])
    ground = camera.backproject_to_height(probe, 0.0)[:, :2].reshape(3, -1, 2)
    xy, J = ground[0], np.stack([ground[1] - ground[0], ground[2] - ground[0]], axis=-1)  # (K, 2, 2)
    used &= np.isfinite(xy).all(axis=1) & np.isfinite(J).all(axis=(1, 2))
    xy, J, b, u = xy[used], J[used], b[used], u[used]
    sigma_px = foot_std_frac * b[:, 3]
    cov = (sigma_px ** 2)[:, None, None] * (J @ J.transpose(0, 2, 1)) + min_std_m ** 2 * np.eye(2)
    # the head: the point of the top centre's ray nearest the vertical line through the foot point
    d = camera.rays(np.c_[u, b[:, 1]])
    c = camera.center_world
    dxy = d[:, :2]
    s = np.einsum("ij,ij->i", dxy, xy - c[:2]) / np.maximum(np.einsum("ij,ij->i", dxy, dxy), 1e-12)
    head = c[2] + s * d[:, 2]
    return xy, cov, head, used


def box_evidence(cameras: Sequence[PinholeCamera], boxes: Sequence[PersonBoxes | None], stack: PlaneStack,
                 params: BoxEvidenceParams, ignore_masks: Sequence[np.ndarray | None] | None = None,
                 lookups: Sequence | None = None) -> np.ndarray:
    """Log-odds ``(L, ny, nx)`` float32 the cameras' person boxes add on the stack (module doc).

    Parameters
    ----------
    cameras : sequence of PinholeCamera, or None
        The calibrated cameras; needed by ``params.log_odds`` > 0 (the foot points), else may be None.
    boxes : sequence of (PersonBoxes or None)
        One entry per camera (None: no frame, or no detector).
    stack : PlaneStack
    params : BoxEvidenceParams
    ignore_masks : sequence of (bool ndarray or None), optional
        Per camera, pixels that are not scene evidence.
    lookups : sequence of ImagePlaneLookup, optional
        Per camera, the stack's cells -> pixels (ignore regions already left out); needed by
        ``params.free_log_odds``.
    """
    if params.log_odds is None or params.free_log_odds is None:
        raise ValueError("box_evidence: resolve log_odds and free_log_odds first (BoxEvidenceParams.for_detector)")
    if cameras is None and params.log_odds > 0:
        raise ValueError("box_evidence: log_odds > 0 places the boxes' foot points: it needs the cameras")
    n = len(cameras) if cameras is not None else len(lookups or ())
    if len(boxes) != n:
        raise ValueError(f"boxes: expected {n} entries (None where absent), got {len(boxes)}")
    out = np.zeros(stack.shape, np.float32)
    if params.free_log_odds < 0:
        if lookups is None or len(lookups) != n:
            raise ValueError("box_evidence: free_log_odds needs one lookup per camera")
        for lk, found in zip(lookups, boxes):
            if found is not None:
                out += params.free_log_odds * _seen_outside_boxes(lk, found)[None]
    if params.log_odds == 0:
        return out
    heights = np.asarray(stack.heights_m)
    cell = stack.cell_size_m
    for c, (cam, found) in enumerate(zip(cameras, boxes)):
        if found is None or not len(found):
            continue
        mask = None if ignore_masks is None else ignore_masks[c]
        xy, cov, head, _ = box_feet(cam, found, params.foot_std_frac, params.min_std_m, mask, params.edge_px)
        bump = np.zeros(stack.shape, np.float32)
        for k in range(len(xy)):
            planes = np.flatnonzero(heights <= head[k])
            if not planes.size:
                continue
            inv = np.linalg.inv(cov[k])
            reach = np.sqrt(_CUT_MAHALANOBIS2 * np.diag(cov[k]))  # half-widths of the box holding the 3-sigma ellipse
            fy, fx = stack.fractional_index_from_xy(xy[k])
            x0, x1 = int(np.floor(fx - reach[0] / cell)), int(np.ceil(fx + reach[0] / cell)) + 1
            y0, y1 = int(np.floor(fy - reach[1] / cell)), int(np.ceil(fy + reach[1] / cell)) + 1
            x0, x1, y0, y1 = max(x0, 0), min(x1, stack.nx), max(y0, 0), min(y1, stack.ny)
            if x0 >= x1 or y0 >= y1:
                continue
            gy, gx = np.mgrid[y0:y1, x0:x1]
            dxy = stack.xy_from_index(gy, gx) - xy[k]
            m2 = np.einsum("...i,ij,...j->...", dxy, inv, dxy)
            g = np.where(m2 <= _CUT_MAHALANOBIS2, params.log_odds * np.exp(-0.5 * m2), 0.0).astype(np.float32)
            view = bump[planes[0]:planes[-1] + 1, y0:y1, x0:x1]
            np.maximum(view, g, out=view)
        out += bump
    return out


def combine_box_evidence(log_odds: np.ndarray, boxes_log_odds: np.ndarray, params: BoxEvidenceParams) -> np.ndarray:
    """The sensor model's per-plane ``log_odds`` with the boxes' ``boxes_log_odds`` (:func:`box_evidence`), both
    ``(L, ny, nx)``: their sum, where ``params.override`` first lifts the sensor model's negative log-odds to 0
    wherever a bump lies (float32, a new array)."""
    base = np.asarray(log_odds, np.float32)
    if params.override and (params.log_odds or 0.0) > 0:
        base = np.where(boxes_log_odds > 0, np.maximum(base, 0.0), base)
    return (base + boxes_log_odds).astype(np.float32, copy=False)


def _seen_outside_boxes(lookup, found: PersonBoxes) -> np.ndarray:
    """Cells ``(ny, nx)`` float32 (1 or 0) of the ground whose pixel in the camera (``lookup`` on the lowest plane)
    lies outside every box of ``found``."""
    w, h = lookup.width_px, lookup.height_px
    inside = np.zeros((h, w), bool)
    for x, y, bw, bh in np.asarray(found.ltwh_px, float).reshape(-1, 4):
        c0, c1 = max(0, int(np.floor(x))), min(w, int(np.ceil(x + bw)))
        r0, r1 = max(0, int(np.floor(y))), min(h, int(np.ceil(y + bh)))
        inside[r0:r1, c0:c1] = True
    flat = np.append(inside.ravel(), True)  # the lookup's sentinel (unseen) counts as inside: no evidence
    return (~flat[lookup.pixel_index[0]]).astype(np.float32)
