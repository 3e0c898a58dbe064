"""The plane stack: horizontal planes z = h_0..h_{L-1}, each carrying a 2-D grid.

Grid convention: every plane shares one XY grid of ``ny x nx`` square cells of
side ``cell_size_m``. Arrays over the stack have shape ``(L, ny, nx)``; index
``[l, iy, ix]`` is the cell whose centre is
``(x_min_m + (ix + 0.5) cell, y_min_m + (iy + 0.5) cell, h_l)``: the row index
grows with world Y and the column index with world X (plot with
``origin="lower"``).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from ..geometry._checks import check_points

__all__ = ["PlaneStack"]


#: Most cells a plane stack may have (all planes): a larger grid is a unit error or exhausts memory.
MAX_CELLS = 50_000_000


@dataclass(frozen=True)
class PlaneStack:
    """Heights and grid of the planes parallel to pi_ref.

    Attributes
    ----------
    heights_m : tuple of float
        Plane heights above pi_ref [m], strictly increasing; pi_ref is 0.
    x_min_m, y_min_m : float
        World coordinates of the grid's lower-left corner [m].
    cell_size_m : float
        Side of a square cell [m].
    nx, ny : int
        Number of cells along world X and Y.
    band_edges_m : tuple of float, optional
        L+1 increasing heights delimiting the height band of each plane (a 3-D
        point with ``band_edges_m[l] <= z < band_edges_m[l+1]`` is evidence for
        plane l). Defaults to mid-points between planes, the first band starting
        at 0 (or below h_0 by half the first gap if h_0 < 0 is impossible) and the
        last ending half a gap above the top plane.
    """

    heights_m: tuple[float, ...]
    x_min_m: float
    y_min_m: float
    cell_size_m: float
    nx: int
    ny: int
    band_edges_m: tuple[float, ...] | None = None

    def __post_init__(self) -> None:
        h = np.asarray(self.heights_m, dtype=float).ravel()
        if h.size == 0:
            raise ValueError("heights_m must hold at least one plane height")
        if not np.isfinite(h).all():
            raise ValueError(f"heights_m must be finite, got {h.tolist()}")
        if np.any(np.diff(h) <= 0):
            raise ValueError(f"heights_m must be strictly increasing, got {h.tolist()}")
        for name in ("x_min_m", "y_min_m", "cell_size_m"):
            if not np.isfinite(getattr(self, name)):
                raise ValueError(f"{name} must be finite, got {getattr(self, name)}")
        if self.cell_size_m <= 0:
            raise ValueError(f"cell_size_m must be > 0, got {self.cell_size_m}")
        if int(self.nx) <= 0 or int(self.ny) <= 0:
            raise ValueError(f"nx and ny must be positive, got nx={self.nx}, ny={self.ny}")
        n_cells = h.size * int(self.nx) * int(self.ny)
        if n_cells > MAX_CELLS:
            raise ValueError(f"the plane stack would have {n_cells:.3g} cells (> {MAX_CELLS:.0e}: "
                             f"{4 * n_cells / 1e9:.2g} GB per float32 grid); increase cell_size_m "
                             f"({self.cell_size_m:g} m) or reduce the extent")
        object.__setattr__(self, "heights_m", tuple(float(x) for x in h))
        object.__setattr__(self, "nx", int(self.nx))
        object.__setattr__(self, "ny", int(self.ny))
        if self.band_edges_m is None:
            if h.size == 1:
                edges = np.array([h[0] - 0.1, h[0] + 0.1])
            else:
                mid = 0.5 * (h[1:] + h[:-1])
                lo = max(0.0, h[0] - 0.5 * (h[1] - h[0])) if h[0] >= 0 else h[0] - 0.5 * (h[1] - h[0])
                hi = h[-1] + 0.5 * (h[-1] - h[-2])
                edges = np.concatenate([[lo], mid, [hi]])
        else:
            edges = np.asarray(self.band_edges_m, dtype=float).ravel()
            if edges.size != h.size + 1 or np.any(np.diff(edges) <= 0) or not np.isfinite(edges).all():
                raise ValueError(
                    f"band_edges_m must be {h.size + 1} finite increasing heights, got {edges.tolist()}"
                )
        object.__setattr__(self, "band_edges_m", tuple(float(x) for x in edges))

    @classmethod
    def from_extent(
        cls,
        heights_m,
        x_range_m: tuple[float, float],
        y_range_m: tuple[float, float],
        cell_size_m: float,
        band_edges_m=None,
    ) -> "PlaneStack":
        """Build a stack covering ``x_range_m`` x ``y_range_m`` [m] with cells of ``cell_size_m``."""
        nx = int(np.ceil((x_range_m[1] - x_range_m[0]) / cell_size_m - 1e-9))
        ny = int(np.ceil((y_range_m[1] - y_range_m[0]) / cell_size_m - 1e-9))
        return cls(tuple(heights_m), float(x_range_m[0]), float(y_range_m[0]), float(cell_size_m), nx, ny,
                   None if band_edges_m is None else tuple(band_edges_m))

    # -- sizes -----------------------------------------------------------------
    @property
    def n_planes(self) -> int:
        """Number of planes L."""
        return len(self.heights_m)

    @property
    def shape(self) -> tuple[int, int, int]:
        """Shape ``(L, ny, nx)`` of arrays over the stack."""
        return (self.n_planes, self.ny, self.nx)

    @property
    def extent_m(self) -> tuple[float, float, float, float]:
        """``(x_min, x_max, y_min, y_max)`` in metres (matplotlib ``extent`` order)."""
        return (
            self.x_min_m,
            self.x_min_m + self.nx * self.cell_size_m,
            self.y_min_m,
            self.y_min_m + self.ny * self.cell_size_m,
        )

    # -- conversions -----------------------------------------------------------
    def cell_centers_xy(self) -> np.ndarray:
        """World XY of every cell centre, shape (ny, nx, 2) [m]."""
        xs = self.x_min_m + (np.arange(self.nx) + 0.5) * self.cell_size_m
        ys = self.y_min_m + (np.arange(self.ny) + 0.5) * self.cell_size_m
        X, Y = np.meshgrid(xs, ys)
        return np.stack([X, Y], axis=-1)

    def cell_centers_world(self) -> np.ndarray:
        """3-D centres of every cell of every plane, shape (L, ny, nx, 3) [m]."""
        xy = self.cell_centers_xy()
        out = np.empty(self.shape + (3,))
        out[..., :2] = xy
        out[..., 2] = np.asarray(self.heights_m)[:, None, None]
        return out

    def index_from_xy(self, xy) -> tuple[np.ndarray, np.ndarray]:
        """Grid indices ``(iy, ix)`` (each (..., N), int64) of world points ``xy`` (..., N, 2) [m].

        Points outside the grid (or NaN) get index -1 in both outputs.
        """
        p = check_points(xy, 2, "xy", allow_nan=True)
        with np.errstate(invalid="ignore"):
            fx = np.floor((p[..., 0] - self.x_min_m) / self.cell_size_m)
            fy = np.floor((p[..., 1] - self.y_min_m) / self.cell_size_m)
            ok = (fx >= 0) & (fx < self.nx) & (fy >= 0) & (fy < self.ny)
        ix = np.where(ok, fx, -1).astype(np.int64)
        iy = np.where(ok, fy, -1).astype(np.int64)
        return iy, ix

    def xy_from_index(self, iy, ix) -> np.ndarray:
        """World XY (..., 2) [m] of cell centres at (possibly fractional) indices ``iy, ix``."""
        iy = np.asarray(iy, dtype=float)
        ix = np.asarray(ix, dtype=float)
        return np.stack(
            [self.x_min_m + (ix + 0.5) * self.cell_size_m, self.y_min_m + (iy + 0.5) * self.cell_size_m],
            axis=-1,
        )

    def fractional_index_from_xy(self, xy_m) -> tuple[np.ndarray, np.ndarray]:
        """Fractional grid indices ``(iy, ix)`` (each (...,) float) of world points ``xy_m`` (..., 2) [m], cell
        centres at whole numbers: the inverse of :meth:`xy_from_index` (no bounds check)."""
        xy, cell = np.asarray(xy_m, dtype=float), self.cell_size_m
        return (xy[..., 1] - self.y_min_m) / cell - 0.5, (xy[..., 0] - self.x_min_m) / cell - 0.5

    def plane_index_from_z(self, z_m) -> np.ndarray:
        """Index (int64, same shape as ``z_m``) of the plane whose band holds each height; -1 outside all bands."""
        z = np.asarray(z_m, dtype=float)
        edges = np.asarray(self.band_edges_m)
        with np.errstate(invalid="ignore"):
            k = np.searchsorted(edges, z, side="right") - 1
            ok = (k >= 0) & (k < self.n_planes) & np.isfinite(z)
        return np.where(ok, k, -1).astype(np.int64)

    def H_grid_plane(self) -> np.ndarray:
        """Affine (3, 3) from world XY [m] to fractional grid coordinates (ix, iy) of cell centres."""
        s = 1.0 / self.cell_size_m
        return np.array([[s, 0.0, -self.x_min_m * s - 0.5], [0.0, s, -self.y_min_m * s - 0.5], [0, 0, 1.0]])


@lru_cache(maxsize=16)
def disc_offsets(radius_cells: float) -> tuple[np.ndarray, np.ndarray]:
    """Row and column offsets (int64, read-only, cached) of the cells within ``radius_cells`` of a centre cell
    (``dy^2 + dx^2 <= radius_cells^2``), in row-major order over the square of side ``2 ceil(radius_cells) + 1``."""
    r = int(np.ceil(radius_cells))
    dy, dx = np.mgrid[-r:r + 1, -r:r + 1]
    within = dy * dy + dx * dx <= radius_cells * radius_cells
    dy, dx = dy[within].astype(np.int64), dx[within].astype(np.int64)
    dy.flags.writeable = dx.flags.writeable = False
    return dy, dx
