"""Registration of laser beams on the plane stack and the per-plane inverse sensor model.

Seed eq. 5 projects a laser point onto pi_ref:
``x_ref = [[1,0,0,0],[0,1,0,0],[0,0,0,1]] T_world_laser X_L``; on the plane stack a 3-D point is
evidence for the plane whose height band holds it (``PlaneStack.plane_index_from_z``).

Inverse sensor model, per plane ``l`` with band ``[z_l, z_{l+1})``: a beam is the 3-D segment
from the scanner's optical centre to its end. Only the part of the segment *inside band l*
says something about plane l (a tilted beam crosses a band over part of its length; a 2-D
scanner parallel to the ground lies in one band). Along that part, the cells crossed
before the end are free; the cell of the end point is occupied if the beam is a real return
that ends inside band l; cells beyond the end are unknown (log-odds 0). A cell that is
occupied by any beam of the scan is occupied (hits win over pass-throughs).

Beams that did not return (max-range readings, ``inf``) and invalid returns (NaN, 0,
negative, below ``range_min_m``) free space up to ``no_return_free_m`` and occupy nothing
(``invalid_frees=False`` makes invalid returns say nothing instead). Returns below
``ground_clearance_m`` are the floor (a tilting scanner sees it): they free the beam up to
the floor but occupy nothing. Every beam is counted in :class:`ScanRegistration`.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np
from numba import njit

from ..geometry._checks import check_points, check_transform
from ..grid import Evidence, PlaneStack, log_odds_from_probability
from ._scanner import LaserScan, TiltingUnit, _beams_world
from .._params import check_fields, require

__all__ = [
    "P_REF_FROM_WORLD",
    "LaserSensorModel",
    "ScanRegistration",
    "xy_ref_from_points_laser",
    "register_points",
    "register_scan",
    "LaserRegistrar",
    "traverse_beams",
    "CELL_UNKNOWN",
    "CELL_FREE",
    "CELL_OCCUPIED",
]

#: Seed eq. 5: drops z of a homogeneous world point, giving homogeneous pi_ref coordinates.
P_REF_FROM_WORLD = np.array([[1.0, 0, 0, 0], [0, 1.0, 0, 0], [0, 0, 0, 1.0]])
P_REF_FROM_WORLD.setflags(write=False)

#: Indices into :attr:`LaserSensorModel.log_odds_table`.
CELL_UNKNOWN, CELL_FREE, CELL_OCCUPIED = 0, 1, 2


@dataclass(frozen=True)
class LaserSensorModel:
    """Inverse sensor model parameters.

    Attributes
    ----------
    p_occupied_hit : float
        P(occupied | a beam ends in the cell), > 0.5.
    p_occupied_free : float
        P(occupied | a beam crossed the cell), < 0.5.
    ground_clearance_m : float
        End points below this height are floor returns (free space, no occupancy) [m].
    no_return_free_m : float or None
        How far a beam without a return frees space [m]; None: the scan's ``range_max_m``.
    invalid_frees : bool
        Whether invalid returns (NaN, 0, negative) free space like max-range readings.
    """

    p_occupied_hit: float = 0.7
    p_occupied_free: float = 0.35
    ground_clearance_m: float = 0.05
    no_return_free_m: float | None = None
    invalid_frees: bool = True

    def __post_init__(self) -> None:
        check_fields(self, p_occupied_hit="(0,1)", p_occupied_free="(0,1)", ground_clearance_m="finite",
                     no_return_free_m="?>0")
        require(self.p_occupied_hit > 0.5, self, "p_occupied_hit", f"must be above 0.5, got {self.p_occupied_hit}")
        require(self.p_occupied_free < 0.5, self, "p_occupied_free",
                f"must be below 0.5, got {self.p_occupied_free}")

    @cached_property
    def log_odds_table(self) -> np.ndarray:
        """float32 (3,): log-odds of CELL_UNKNOWN, CELL_FREE, CELL_OCCUPIED."""
        lo = log_odds_from_probability([0.5, self.p_occupied_free, self.p_occupied_hit])
        return lo.astype(np.float32)


@dataclass(frozen=True)
class ScanRegistration:
    """One scan registered on the plane stack.

    Attributes
    ----------
    evidence : Evidence
        Log-odds (L, ny, nx) float32 of the inverse sensor model.
    points_world : ndarray (M, 3)
        World points of the real returns (valid, above the ground clearance) [m].
    plane_index : ndarray (M,) int64
        Plane whose band holds each point, -1 for points outside every band.
    n_valid, n_no_return, n_invalid, n_ground, n_outside_bands : int
        Beam counts: real returns, max-range readings, invalid returns (NaN/0/negative),
        floor returns, and real returns above/below every band (they free space only).
    """

    evidence: Evidence
    points_world: np.ndarray
    plane_index: np.ndarray
    n_valid: int
    n_no_return: int
    n_invalid: int
    n_ground: int
    n_outside_bands: int


def xy_ref_from_points_laser(T_world_laser, p_L) -> np.ndarray:
    """Seed eq. 5: project points in the laser frame onto pi_ref.

    Parameters
    ----------
    T_world_laser : array_like (4, 4)
        Laser unit pose in {W}.
    p_L : array_like (N, 3)
        Points in the laser frame [m].

    Returns
    -------
    ndarray (N, 2)
        ``(x, y)`` on pi_ref [m]: ``[[1,0,0,0],[0,1,0,0],[0,0,0,1]] T_world_laser [p_L; 1]``.
    """
    T = check_transform(T_world_laser, "T_world_laser")
    p = check_points(p_L, 3, "p_L", allow_nan=True)
    ph = np.concatenate([p, np.ones(p.shape[:-1] + (1,))], axis=-1)
    x = ph @ (P_REF_FROM_WORLD @ T).T
    return x[..., :2] / x[..., 2:3]


def register_points(p_world, stack: PlaneStack) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Grid cell and plane of every world point (3-D point clouds, or scan end points).

    Parameters
    ----------
    p_world : array_like (N, 3)
        Points in {W} [m] (NaN rows give -1 everywhere).
    stack : PlaneStack

    Returns
    -------
    plane_index, iy, ix : ndarray (N,) int64
        Plane whose band holds the point's z and its cell on the grid (-1 where outside).
    """
    p = check_points(p_world, 3, "p_world", allow_nan=True)
    iy, ix = stack.index_from_xy(p[..., :2])
    return stack.plane_index_from_z(p[..., 2]), iy, ix


@njit(cache=True)
def _clip_to_box(x0, y0, x1, y1, bx, by):
    """Liang-Barsky: parameter interval [ta, tb] of segment p0->p1 inside [0,bx]x[0,by] (ta > tb if none)."""
    ta, tb = 0.0, 1.0
    dx, dy = x1 - x0, y1 - y0
    for p, q in ((-dx, x0), (dx, bx - x0), (-dy, y0), (dy, by - y0)):
        if p == 0.0:
            if q < 0.0:
                return 1.0, 0.0
        else:
            r = q / p
            if p < 0.0:
                if r > ta:
                    ta = r
            elif r < tb:
                tb = r
    return ta, tb


@njit(cache=True)
def _walk(out, l, gx0, gy0, gx1, gy1, mark_end_occupied, nx, ny, v_free, v_occ):
    """Amanatides-Woo 2-D traversal in grid units; writes ``v_free`` into still-unknown (0) cells
    and ``v_occ`` into the last cell if asked (occupied wins over free)."""
    ix, iy = int(np.floor(gx0)), int(np.floor(gy0))
    ex, ey = int(np.floor(gx1)), int(np.floor(gy1))
    ix = min(max(ix, 0), nx - 1)
    iy = min(max(iy, 0), ny - 1)
    ex = min(max(ex, 0), nx - 1)
    ey = min(max(ey, 0), ny - 1)
    dx, dy = gx1 - gx0, gy1 - gy0
    sx = 1 if dx > 0 else -1
    sy = 1 if dy > 0 else -1
    inf = np.inf
    tdx = abs(1.0 / dx) if dx != 0.0 else inf
    tdy = abs(1.0 / dy) if dy != 0.0 else inf
    if dx > 0:
        tmx = (ix + 1 - gx0) / dx
    elif dx < 0:
        tmx = (ix - gx0) / dx
    else:
        tmx = inf
    if dy > 0:
        tmy = (iy + 1 - gy0) / dy
    elif dy < 0:
        tmy = (iy - gy0) / dy
    else:
        tmy = inf
    n = abs(ex - ix) + abs(ey - iy)
    for _ in range(n):
        if out[l, iy, ix] == 0:
            out[l, iy, ix] = v_free
        if tmx < tmy:
            ix += sx
            tmx += tdx
        else:
            iy += sy
            tmy += tdy
        if ix < 0 or ix >= nx or iy < 0 or iy >= ny:
            return
    if mark_end_occupied:
        out[l, iy, ix] = v_occ
    elif out[l, iy, ix] == 0:
        out[l, iy, ix] = v_free


@njit(cache=True)
def _traverse_kernel(origins, ends, is_hit, edges, x_min, y_min, cell, nx, ny, out, v_free, v_occ):
    n_planes = edges.shape[0] - 1
    bx, by = float(nx), float(ny)
    for i in range(origins.shape[0]):
        ox, oy, oz = origins[i, 0], origins[i, 1], origins[i, 2]
        ex_, ey_, ez = ends[i, 0], ends[i, 1], ends[i, 2]
        gx0, gy0 = (ox - x_min) / cell, (oy - y_min) / cell
        gx1, gy1 = (ex_ - x_min) / cell, (ey_ - y_min) / cell
        # part of the segment over the grid
        ta, tb = _clip_to_box(gx0, gy0, gx1, gy1, bx, by)
        if ta > tb:
            continue
        dz = ez - oz
        for l in range(n_planes):
            zl, zh = edges[l], edges[l + 1]
            if dz == 0.0:
                if oz < zl or oz >= zh:
                    continue
                sa, sb = ta, tb
            else:
                s1, s2 = (zl - oz) / dz, (zh - oz) / dz
                if s1 > s2:
                    s1, s2 = s2, s1
                sa, sb = max(ta, s1), min(tb, s2)
                if sa > sb:
                    continue
            end_here = is_hit[i] and sb >= 1.0 and zl <= ez < zh
            _walk(out, l, gx0 + sa * (gx1 - gx0), gy0 + sa * (gy1 - gy0),
                  gx0 + sb * (gx1 - gx0), gy0 + sb * (gy1 - gy0), end_here, nx, ny, v_free, v_occ)


def traverse_beams(origins_world, ends_world, is_hit, stack: PlaneStack,
                   model: LaserSensorModel = LaserSensorModel(), out: np.ndarray | None = None) -> np.ndarray:
    """Per-plane log-odds of 3-D beams (numba Amanatides-Woo traversal, inverse sensor model).

    Parameters
    ----------
    origins_world, ends_world : array_like (N, 3)
        Beam start (optical centre) and end in {W} [m]; all finite.
    is_hit : array_like (N,) bool
        True where the end is a real return (its cell becomes occupied on the plane whose
        band holds it); False frees the whole segment.
    stack : PlaneStack
    model : LaserSensorModel
        Log-odds written into free and occupied cells.
    out : ndarray (L, ny, nx) float32, optional
        Buffer to reuse (zeroed here); saves allocating (and page-faulting) a new grid per scan.

    Returns
    -------
    ndarray (L, ny, nx) float32
        ``log_odds_table[CELL_OCCUPIED]`` where a beam ends, ``[CELL_FREE]`` where beams only
        pass, 0 (unknown) elsewhere.
    """
    o = np.ascontiguousarray(check_points(origins_world, 3, "origins_world"))
    e = np.ascontiguousarray(check_points(ends_world, 3, "ends_world"))
    hit = np.ascontiguousarray(np.asarray(is_hit, dtype=np.bool_).reshape(-1))
    if o.ndim != 2 or e.shape != o.shape or hit.shape != (o.shape[0],):
        raise ValueError(f"origins_world {o.shape}, ends_world {e.shape} and is_hit {hit.shape} must be (N,3),(N,3),(N,)")
    if out is None:
        out = np.zeros(stack.shape, dtype=np.float32)
    elif out.shape != stack.shape or out.dtype != np.float32 or not out.flags.c_contiguous:
        raise ValueError(f"out must be a C-contiguous float32 array of shape {stack.shape}, got {out.dtype} {out.shape}")
    else:
        out.fill(0.0)
    lo = model.log_odds_table
    _traverse_kernel(o, e, hit, np.asarray(stack.band_edges_m), stack.x_min_m, stack.y_min_m,
                     stack.cell_size_m, stack.nx, stack.ny, out, lo[CELL_FREE], lo[CELL_OCCUPIED])
    return out


def register_scan(
    scan: LaserScan,
    stack: PlaneStack,
    *,
    unit: TiltingUnit | None = None,
    T_world_laser=None,
    model: LaserSensorModel = LaserSensorModel(),
    sensor: str = "laser",
) -> ScanRegistration:
    """Register one scan on every plane of the stack with free space (inverse sensor model).

    Parameters
    ----------
    scan : LaserScan
        The scan; beams are classified by ``scan.valid`` / ``scan.no_return`` / ``scan.invalid``.
    stack : PlaneStack
        Planes and grid (the same grid as the cameras').
    unit : TiltingUnit, optional
        Mechanical model of the unit (offsets); default: plain 2-D scanner.
    T_world_laser : array_like (4, 4) or (N, 4, 4), optional
        Unit pose (per scan, or per beam for a moving platform); default ``scan.T_world_laser``.
    model : LaserSensorModel
    sensor : str
        Name put in the Evidence.

    Returns
    -------
    ScanRegistration
        Evidence plus the registered points and the beam counts.
    """
    return LaserRegistrar(stack, unit, model, sensor).register(scan, T_world_laser)


class LaserRegistrar:
    """:func:`register_scan` for a stream of scans: same stack, unit and model, one reused scratch grid.

    Parameters
    ----------
    stack : PlaneStack
    unit : TiltingUnit, optional
    model : LaserSensorModel
    sensor : str

    Notes
    -----
    Each :class:`Evidence` owns its own (clipped) copy of the log-odds, so reusing the
    scratch grid between scans is safe; it avoids allocating and page-faulting a fresh
    (L, ny, nx) grid per scan, which costs as much as the traversal itself.
    """

    def __init__(self, stack: PlaneStack, unit: TiltingUnit | None = None,
                 model: LaserSensorModel = LaserSensorModel(), sensor: str = "laser") -> None:
        self.stack, self.unit, self.model, self.sensor = stack, unit, model, sensor
        self._scratch = np.zeros(stack.shape, dtype=np.float32)

    def register(self, scan: LaserScan, T_world_laser=None) -> ScanRegistration:
        """Register ``scan`` (see :func:`register_scan`); ``T_world_laser`` defaults to ``scan.T_world_laser``."""
        stack, unit, model, sensor = self.stack, self.unit, self.model, self.sensor
        if T_world_laser is None:
            T_world_laser = scan.T_world_laser  # checked when the scan was made
            if T_world_laser is None:
                raise ValueError("register_scan needs T_world_laser (argument or scan.T_world_laser)")
        else:
            T_world_laser = check_transform(T_world_laser, "T_world_laser")
        valid, no_ret, invalid = scan.valid, scan.no_return, scan.invalid
        free_m = scan.range_max_m if model.no_return_free_m is None else model.no_return_free_m
        r = np.where(valid, scan.ranges_m, free_m)
        frees = valid | no_ret | (invalid & model.invalid_frees)
        o_W, d_W = _beams_world(scan.angles_rad, scan.tilt_rad, T_world_laser, unit)
        e_W = o_W + r[:, None] * d_W
        ground = valid & (e_W[..., 2] < model.ground_clearance_m)
        is_hit = valid & ~ground
        log_odds = traverse_beams(o_W[frees], e_W[frees], is_hit[frees], stack, model, self._scratch)
        pts = e_W[is_hit]
        plane = stack.plane_index_from_z(pts[:, 2])
        return ScanRegistration(
            evidence=Evidence(float(scan.time_s), sensor, log_odds),
            points_world=pts,
            plane_index=plane,
            n_valid=int(valid.sum()),
            n_no_return=int(no_ret.sum()),
            n_invalid=int(invalid.sum()),
            n_ground=int(ground.sum()),
            n_outside_bands=int(np.sum(plane < 0)),
        )
