"""Ray casting against the simulator's scene: vertical cylinders, spheres, boxes, floor and room walls.

Scene contract (the one ``planefuse.sim``'s ``scene.bodies_at(time_s)`` returns):

* ``cylinders`` (P, 5): ``[x, y, radius, z_bottom, z_top]`` [m] -- finite vertical
  cylinders, closed by horizontal caps at ``z_bottom`` and ``z_top``;
* ``spheres`` (S, 4): ``[x, y, z, radius]`` [m];
* ``boxes`` (B, 6), optional: ``[x_min, x_max, y_min, y_max, z_min, z_max]`` [m] -- axis-aligned static
  occluders (slab intersection);
* the floor: the infinite plane z = 0;
* the room's walls: the four vertical rectangles ``x = x0``, ``x = x1`` (for
  ``y0 <= y <= y1``) and ``y = y0``, ``y = y1`` (for ``x0 <= x <= x1``), each from
  z = 0 to ``wall_height_m``, with ``room_xy_m = (x0, x1, y0, y1)``. There is no ceiling.

Every surface is two-sided; a ray starting inside a body hits its far side.
"""

from __future__ import annotations

import numpy as np
from numba import njit

__all__ = ["raycast", "HIT_NONE", "HIT_FLOOR", "HIT_WALL", "HIT_CYLINDER", "HIT_SPHERE", "HIT_BOX"]

#: Hit kinds returned by ``raycast(..., return_hits=True)``.
HIT_NONE, HIT_FLOOR, HIT_WALL, HIT_CYLINDER, HIT_SPHERE, HIT_BOX = 0, 1, 2, 3, 4, 5

_EPS = 1e-9


@njit(cache=True)
def _raycast_kernel(origins, directions, cylinders, spheres, boxes, room, wall_h, max_range, out_t, out_kind,
                    out_idx):
    n = origins.shape[0]
    x0, x1, y0, y1 = room[0], room[1], room[2], room[3]
    for i in range(n):
        ox, oy, oz = origins[i, 0], origins[i, 1], origins[i, 2]
        dx, dy, dz = directions[i, 0], directions[i, 1], directions[i, 2]
        best = max_range
        kind = 0
        idx = -1
        # floor z = 0
        if dz != 0.0:
            t = -oz / dz
            if _EPS < t <= best:
                best, kind, idx = t, 1, -1
        # walls x = const
        if dx != 0.0:
            for wx in (x0, x1):
                t = (wx - ox) / dx
                if _EPS < t <= best:
                    y = oy + t * dy
                    z = oz + t * dz
                    if y0 <= y <= y1 and 0.0 <= z <= wall_h:
                        best, kind, idx = t, 2, -1
        if dy != 0.0:
            for wy in (y0, y1):
                t = (wy - oy) / dy
                if _EPS < t <= best:
                    x = ox + t * dx
                    z = oz + t * dz
                    if x0 <= x <= x1 and 0.0 <= z <= wall_h:
                        best, kind, idx = t, 2, -1
        # vertical cylinders: side + caps
        a = dx * dx + dy * dy
        for k in range(cylinders.shape[0]):
            cx, cy, r, zb, zt = cylinders[k, 0], cylinders[k, 1], cylinders[k, 2], cylinders[k, 3], cylinders[k, 4]
            px, py = ox - cx, oy - cy
            if a > 0.0:
                b = px * dx + py * dy
                c = px * px + py * py - r * r
                disc = b * b - a * c
                if disc >= 0.0:
                    sq = np.sqrt(disc)
                    for t in ((-b - sq) / a, (-b + sq) / a):
                        if _EPS < t <= best:
                            z = oz + t * dz
                            if zb <= z <= zt:
                                best, kind, idx = t, 3, k
            if dz != 0.0:
                for zc in (zb, zt):
                    t = (zc - oz) / dz
                    if _EPS < t <= best:
                        qx = px + t * dx
                        qy = py + t * dy
                        if qx * qx + qy * qy <= r * r:
                            best, kind, idx = t, 3, k
        # spheres
        for k in range(spheres.shape[0]):
            px = ox - spheres[k, 0]
            py = oy - spheres[k, 1]
            pz = oz - spheres[k, 2]
            r = spheres[k, 3]
            aa = dx * dx + dy * dy + dz * dz
            b = px * dx + py * dy + pz * dz
            c = px * px + py * py + pz * pz - r * r
            disc = b * b - aa * c
            if disc >= 0.0 and aa > 0.0:
                sq = np.sqrt(disc)
                for t in ((-b - sq) / aa, (-b + sq) / aa):
                    if _EPS < t <= best:
                        best, kind, idx = t, 4, k
        # axis-aligned boxes (slabs): entry point, or exit point from inside
        for k in range(boxes.shape[0]):
            t_in = -np.inf
            t_out = np.inf
            o3 = (ox, oy, oz)
            d3 = (dx, dy, dz)
            for ax in range(3):
                lo = boxes[k, 2 * ax]
                hi = boxes[k, 2 * ax + 1]
                if d3[ax] == 0.0:
                    if o3[ax] < lo or o3[ax] > hi:
                        t_in = np.inf
                else:
                    ta = (lo - o3[ax]) / d3[ax]
                    tb = (hi - o3[ax]) / d3[ax]
                    t_in = max(t_in, min(ta, tb))
                    t_out = min(t_out, max(ta, tb))
            if t_in <= t_out:
                t = t_in if t_in > _EPS else t_out
                if _EPS < t <= best:
                    best, kind, idx = t, 5, k
        if kind == 0:
            out_t[i] = np.inf
        else:
            out_t[i] = best
        out_kind[i] = kind
        out_idx[i] = idx


def _as_table(a, cols: int, name: str) -> np.ndarray:
    arr = np.asarray(a if a is not None else np.zeros((0, cols)), dtype=np.float64)
    if arr.size == 0:
        return np.zeros((0, cols))
    if arr.ndim != 2 or arr.shape[1] != cols:
        raise ValueError(f"{name} must have shape (K, {cols}), got {arr.shape}")
    if not np.isfinite(arr).all():
        raise ValueError(f"{name} has non-finite entries")
    return np.ascontiguousarray(arr)


def raycast(
    origins,
    directions,
    cylinders,
    spheres,
    room_xy_m,
    wall_height_m: float,
    max_range_m: float,
    *,
    boxes=None,
    return_hits: bool = False,
):
    """Distance along each ray to the first surface of the scene (numba).

    Parameters
    ----------
    origins : array_like (N, 3)
        Ray origins in {W} [m].
    directions : array_like (N, 3)
        Ray directions in {W}; normalised here, so the result is a metric range.
    cylinders : array_like (P, 5)
        ``[x, y, radius, z_bottom, z_top]`` [m] per vertical cylinder (P may be 0).
    spheres : array_like (S, 4)
        ``[x, y, z, radius]`` [m] per sphere (S may be 0).
    room_xy_m : (x0, x1, y0, y1)
        Room walls [m].
    wall_height_m : float
        Height of the walls [m].
    max_range_m : float
        Surfaces farther than this are ignored [m].
    boxes : array_like (B, 6), optional
        ``[x_min, x_max, y_min, y_max, z_min, z_max]`` [m] per axis-aligned box (static occluders).
    return_hits : bool
        Also return what each ray hit.

    Returns
    -------
    ranges_m : ndarray (N,)
        Distance to the first hit [m]; ``inf`` where nothing lies within ``max_range_m``.
    hit_kind : ndarray (N,) int8, only with ``return_hits``
        ``HIT_NONE``, ``HIT_FLOOR``, ``HIT_WALL``, ``HIT_CYLINDER``, ``HIT_SPHERE`` or ``HIT_BOX``.
    hit_index : ndarray (N,) int64, only with ``return_hits``
        Row of the hit cylinder / sphere / box, -1 otherwise.
    """
    o = np.asarray(origins, dtype=np.float64)
    d = np.asarray(directions, dtype=np.float64)
    if o.ndim != 2 or o.shape[1] != 3 or d.shape != o.shape:
        raise ValueError(f"origins and directions must both have shape (N, 3), got {o.shape} and {d.shape}")
    if not (np.isfinite(o).all() and np.isfinite(d).all()):
        raise ValueError("origins/directions have non-finite entries")
    norm = np.linalg.norm(d, axis=1)
    if np.any(norm == 0):
        raise ValueError(f"directions has {int(np.sum(norm == 0))} zero-length rows")
    d = np.ascontiguousarray(d / norm[:, None])
    room = np.asarray(room_xy_m, dtype=np.float64).reshape(-1)
    if room.shape != (4,) or not np.isfinite(room).all() or room[0] >= room[1] or room[2] >= room[3]:
        raise ValueError(f"room_xy_m must be (x0, x1, y0, y1) with x0 < x1, y0 < y1, got {room_xy_m}")
    if not (np.isfinite(wall_height_m) and wall_height_m >= 0):
        raise ValueError(f"wall_height_m must be finite and >= 0, got {wall_height_m}")
    if not max_range_m > 0:
        raise ValueError(f"max_range_m must be > 0, got {max_range_m}")
    cyl = _as_table(cylinders, 5, "cylinders")
    sph = _as_table(spheres, 4, "spheres")
    if np.any(cyl[:, 2] <= 0) or np.any(cyl[:, 3] > cyl[:, 4]):
        raise ValueError("cylinders need radius > 0 and z_bottom <= z_top")
    if np.any(sph[:, 3] <= 0):
        raise ValueError("spheres need radius > 0")
    box = _as_table(boxes, 6, "boxes")
    if np.any(box[:, 0::2] > box[:, 1::2]):
        raise ValueError("boxes need x_min <= x_max, y_min <= y_max, z_min <= z_max")
    n = o.shape[0]
    out_t = np.empty(n)
    out_kind = np.empty(n, dtype=np.int8)
    out_idx = np.empty(n, dtype=np.int64)
    _raycast_kernel(np.ascontiguousarray(o), d, cyl, sph, box, room, float(wall_height_m), float(max_range_m),
                    out_t, out_kind, out_idx)
    if return_hits:
        return out_t, out_kind, out_idx
    return out_t
