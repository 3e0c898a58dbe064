"""Known static occluders (pillars, shelves, counters): what they hide from a sensor and what they fill.

An installation's static objects are declared as axis-aligned boxes in the world frame,
``[x_min, x_max, y_min, y_max, z_min, z_max]`` [m] (the format of :func:`planefuse.laser.raycast`'s
``boxes``). Two facts follow from them, each a boolean grid over the plane stack ``(L, ny, nx)``:

* **hidden from a viewpoint** (:func:`cells_hidden_by_occluders`): the line of sight from a sensor's centre
  ``o`` to the centre ``p`` of cell ``(l, iy, ix)`` passes through a box. With the segment
  ``x(t) = o + t (p - o)``, ``t`` in ``[0, 1]``, and per axis ``a`` the parameters where it crosses the box's
  two faces, ``t_a^- = min((lo_a - o_a) / d_a, (hi_a - o_a) / d_a)`` and ``t_a^+ = max(...)``
  (slab method; an axis with ``d_a = 0`` is crossed everywhere or nowhere), the cell is hidden by the box iff::

      t_in = max(0, max_a t_a^-)  <  t_out = min(1, min_a t_a^+)

  i.e. the segment enters the box before it reaches the cell. What a camera records through such a pixel is
  the occluder, whatever the cell holds: the cell is **unobserved** by that camera (its evidence about the
  cell is 0, neither occupied nor free; :meth:`planefuse.registration.ImagePlaneLookup.without_cells`).
  A cell inside a box is hidden from every viewpoint outside it.
* **filled** (:func:`cells_filled_by_occluders`): the cell's square footprint overlaps the box and the
  plane's height is within ``[z_min, z_max]``. No person stands there; what a laser returns from the box's
  surface in such a cell, and any other sensor's evidence there, is about the occluder, not a person, so
  the system replaces the evidence there by certain free space for people (:class:`planefuse.tracking.
  EvidenceTracker` ``static_cells``).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from ._stack import PlaneStack

__all__ = ["check_occluder_boxes", "cells_filled_by_occluders", "cells_hidden_by_occluders"]


def check_occluder_boxes(boxes, name: str = "occluder_boxes_m") -> np.ndarray:
    """Static occluder boxes as a ``(B, 6)`` float64 array ``[x_min, x_max, y_min, y_max, z_min, z_max]`` [m].

    Raises
    ------
    ValueError
        Not ``(B, 6)``, non-finite entries, or a box whose minimum is not below its maximum on some axis; the
        message names ``name`` and the box.
    """
    b = np.asarray(boxes if boxes is not None and len(boxes) else np.zeros((0, 6)), dtype=float)
    if b.ndim != 2 or b.shape[1] != 6:
        raise ValueError(f"{name} must be boxes [x_min, x_max, y_min, y_max, z_min, z_max] (shape (B, 6)) [m], "
                         f"got shape {b.shape}")
    if not np.isfinite(b).all():
        raise ValueError(f"{name} has non-finite entries")
    for i, box in enumerate(b):
        if not (box[0] < box[1] and box[2] < box[3] and box[4] < box[5]):
            raise ValueError(f"{name}[{i}] = {box.tolist()}: each minimum must be below its maximum "
                             "([x_min, x_max, y_min, y_max, z_min, z_max] [m])")
    return b


def _inside(point: np.ndarray, box: np.ndarray) -> bool:
    return bool(np.all(point >= box[0::2]) and np.all(point <= box[1::2]))


def cells_hidden_by_occluders(center_world: Sequence[float], stack: PlaneStack, boxes) -> np.ndarray:
    """Cells whose line of sight from ``center_world`` passes through an occluder (module docstring).

    Parameters
    ----------
    center_world : (3,) float
        The sensor's centre (a camera's optical centre) in the world frame [m].
    stack : PlaneStack
    boxes : array_like, shape (B, 6)
        Occluders ``[x_min, x_max, y_min, y_max, z_min, z_max]`` [m] (:func:`check_occluder_boxes`).

    Returns
    -------
    ndarray, shape (L, ny, nx), bool
        True where the segment from ``center_world`` to the cell centre enters a box before the cell.

    Raises
    ------
    ValueError
        Bad boxes, or a centre inside a box (a sensor cannot see out of a solid occluder).
    """
    boxes = check_occluder_boxes(boxes)
    o = np.asarray(center_world, dtype=float).reshape(3)
    if not np.isfinite(o).all():
        raise ValueError(f"center_world must be 3 finite coordinates [m], got {o.tolist()}")
    hidden = np.zeros(stack.shape, dtype=bool)
    if not len(boxes):
        return hidden
    d = stack.cell_centers_world().reshape(-1, 3) - o  # (N, 3): x(t) = o + t d, t in [0, 1]
    flat = hidden.reshape(-1)
    with np.errstate(divide="ignore", invalid="ignore"):
        inv = 1.0 / d  # +-inf on an axis the segment is parallel to
    for i, box in enumerate(boxes):
        if _inside(o, box):
            raise ValueError(f"center_world {o.tolist()} m is inside occluder box {i} {box.tolist()}")
        t_in = np.zeros(len(d))
        t_out = np.ones(len(d))
        for a in range(3):
            with np.errstate(invalid="ignore"):
                t1 = (box[2 * a] - o[a]) * inv[:, a]
                t2 = (box[2 * a + 1] - o[a]) * inv[:, a]
            # parallel to this axis (d_a = 0): within the slab for every t, or for none
            in_slab = box[2 * a] <= o[a] <= box[2 * a + 1]
            parallel = d[:, a] == 0.0
            lo = np.where(parallel, -np.inf if in_slab else np.inf, np.minimum(t1, t2))
            hi = np.where(parallel, np.inf if in_slab else -np.inf, np.maximum(t1, t2))
            np.maximum(t_in, lo, out=t_in)
            np.minimum(t_out, hi, out=t_out)
        flat |= t_in < t_out
    return hidden


def cells_filled_by_occluders(stack: PlaneStack, boxes) -> np.ndarray:
    """Cells an occluder fills: footprint overlapping a box, plane height within the box's (module docstring).

    Parameters
    ----------
    stack : PlaneStack
    boxes : array_like, shape (B, 6)
        Occluders ``[x_min, x_max, y_min, y_max, z_min, z_max]`` [m].

    Returns
    -------
    ndarray, shape (L, ny, nx), bool
        True where cell ``[l, iy, ix]``'s square (side ``stack.cell_size_m``, around its centre) overlaps a box
        and ``z_min <= heights_m[l] <= z_max``.
    """
    boxes = check_occluder_boxes(boxes)
    filled = np.zeros(stack.shape, dtype=bool)
    xy = stack.cell_centers_xy()  # (ny, nx, 2)
    h = 0.5 * stack.cell_size_m
    z = np.asarray(stack.heights_m, dtype=float)
    for box in boxes:
        foot = ((xy[..., 0] + h > box[0]) & (xy[..., 0] - h < box[1])
                & (xy[..., 1] + h > box[2]) & (xy[..., 1] - h < box[3]))
        planes = (z >= box[4]) & (z <= box[5])
        filled[planes] |= foot
    return filled
