"""Silhouettes of a standing person projected from calibrated cameras.

A person standing at ground location ``(x, y)`` is modelled as a vertical cylinder of radius ``radius_m`` spanning
the heights ``height_range_m = (z_bottom, z_top)`` -- for a plane stack, the stack's height bands
(``(band_edges_m[0], band_edges_m[-1])``), so that the person is the same volume whose slices the stack's
planes cut. Its silhouette in a camera is the bounding box, in pixels, of the projections of points on the
cylinder's surface (``n_sides`` around each of ``n_rings`` horizontal circles from bottom to top), through the
full camera model (lens distortion included, so boxes fit raw frames). The box is clipped to the image: a
person partly out of view keeps the visible part of its box (partial views at the image border), and has no
silhouette (``-1``) only where nothing of it is inside the image, or where less than ``min_visible_fraction`` of
its unclipped box is.

A volume not wholly in front of a camera (a point at or behind its principal plane) or reaching past the radius
where the lens model folds back (:attr:`CameraIntrinsics.max_radius`) has no defined box in that camera; it is
marked not visible there.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

import numpy as np

from ..geometry import PinholeCamera, check_points
from ..grid import PlaneStack
from ._meanfield import Silhouettes

__all__ = ["PersonVolume", "locations_from_stack", "silhouettes_from_cameras"]


@dataclass(frozen=True)
class PersonVolume:
    """The volume of a standing person, for silhouettes.

    Attributes
    ----------
    radius_m : float
        Radius of the vertical cylinder [m] (0.25: shoulders about 0.5 m wide).
    height_range_m : tuple of (float, float)
        Bottom and top heights of the cylinder above the ground [m] (default 0 to 1.8 m).
    n_sides : int
        Points per horizontal circle.
    n_rings : int
        Horizontal circles from bottom to top (>= 2; more only matter with strong lens distortion).
    min_visible_fraction : float
        A clipped box smaller than this fraction of its unclipped area is dropped (0 keeps every sliver).
    """

    radius_m: float = 0.25
    height_range_m: tuple[float, float] = (0.0, 1.8)
    n_sides: int = 16
    n_rings: int = 3
    min_visible_fraction: float = 0.0

    def __post_init__(self) -> None:
        lo, hi = (float(v) for v in self.height_range_m)
        if not (np.isfinite(lo) and np.isfinite(hi) and lo < hi):
            raise ValueError(f"PersonVolume.height_range_m must be finite with bottom < top, got {(lo, hi)}")
        if not (np.isfinite(self.radius_m) and self.radius_m >= 0.0):
            raise ValueError(f"PersonVolume.radius_m must be finite and >= 0, got {self.radius_m}")
        if int(self.n_sides) < 3 or int(self.n_rings) < 2:
            raise ValueError(f"PersonVolume needs n_sides >= 3 and n_rings >= 2, got {self.n_sides}, {self.n_rings}")
        if not 0.0 <= self.min_visible_fraction <= 1.0:
            raise ValueError(f"PersonVolume.min_visible_fraction must be in [0, 1], got {self.min_visible_fraction}")
        object.__setattr__(self, "height_range_m", (lo, hi))

    @classmethod
    def from_stack(cls, stack: PlaneStack, radius_m: float = 0.25, **kwargs) -> "PersonVolume":
        """The cylinder across the stack's height bands ``(band_edges_m[0], band_edges_m[-1])``."""
        return cls(radius_m=radius_m, height_range_m=(stack.band_edges_m[0], stack.band_edges_m[-1]), **kwargs)

    def surface_points(self, locations_xy_m) -> np.ndarray:
        """Points on the cylinder of every location, shape (K, n_rings * n_sides, 3) [m, world]."""
        xy = check_points(locations_xy_m, 2, "locations_xy_m")
        a = np.linspace(0.0, 2.0 * np.pi, int(self.n_sides), endpoint=False)
        z = np.linspace(self.height_range_m[0], self.height_range_m[1], int(self.n_rings))
        ring = np.stack([self.radius_m * np.cos(a), self.radius_m * np.sin(a)], axis=-1)      # (S, 2)
        offsets = np.concatenate([np.concatenate([ring, np.full((len(a), 1), zi)], axis=1) for zi in z])  # (R S, 3)
        pts = np.empty((xy.shape[0], offsets.shape[0], 3))
        pts[..., :2] = xy[:, None, :] + offsets[None, :, :2]
        pts[..., 2] = offsets[None, :, 2]
        return pts


def locations_from_stack(stack: PlaneStack) -> np.ndarray:
    """Ground locations of a plane stack's grid: cell centres, shape (ny * nx, 2) [m, world XY].

    Location ``k`` is cell ``(iy, ix) = divmod(k, nx)``: marginals reshape to ``(ny, nx)`` like any stack plane.
    """
    return stack.cell_centers_xy().reshape(-1, 2)


def silhouettes_from_cameras(cameras: Sequence[PinholeCamera], locations: PlaneStack | np.ndarray,
                             person: PersonVolume | None = None) -> Silhouettes:
    """One silhouette box per camera and ground location, projected from calibrated cameras.

    Parameters
    ----------
    cameras : sequence of C PinholeCamera
        Calibrated cameras (image sizes from their intrinsics; lens distortion applied).
    locations : PlaneStack or array_like, shape (K, 2)
        Ground locations [m, world XY]: a stack's cell centres (``K = ny * nx``, row-major, see
        :func:`locations_from_stack`) or explicit points.
    person : PersonVolume, optional
        The person's volume; default: :meth:`PersonVolume.from_stack` for a stack, ``PersonVolume()`` otherwise.

    Returns
    -------
    Silhouettes
        ``boxes_px`` (C, K, 4) inclusive pixel boxes clipped to each image, -1 where not visible.
    """
    if isinstance(locations, PlaneStack):
        person = person or PersonVolume.from_stack(locations)
        xy = locations_from_stack(locations)
    else:
        person = person or PersonVolume()
        xy = check_points(locations, 2, "locations")
        if xy.ndim != 2:
            raise ValueError(f"locations must have shape (K, 2), got {xy.shape}")
    if len(cameras) == 0:
        raise ValueError("silhouettes_from_cameras needs at least one camera")
    pts = person.surface_points(xy)                     # (K, P, 3)
    boxes = np.full((len(cameras), xy.shape[0], 4), -1, dtype=np.int32)
    sizes = []
    for c, cam in enumerate(cameras):
        w, h = cam.intrinsics.width_px, cam.intrinsics.height_px
        sizes.append((h, w))
        uv = cam.project(pts)                           # (K, P, 2), NaN behind the camera / past the lens model
        defined = np.isfinite(uv).all(axis=(1, 2))
        with np.errstate(invalid="ignore"):
            lo = np.nanmin(np.where(defined[:, None, None], uv, 0.0), axis=1)
            hi = np.nanmax(np.where(defined[:, None, None], uv, 0.0), axis=1)
        # pixel i covers [i - 0.5, i + 0.5): the box holds every pixel the projected volume's hull touches
        x0, y0 = np.floor(lo[:, 0] + 0.5), np.floor(lo[:, 1] + 0.5)
        x1, y1 = np.floor(hi[:, 0] + 0.5), np.floor(hi[:, 1] + 0.5)
        full = (x1 - x0 + 1.0) * (y1 - y0 + 1.0)
        cx0, cy0 = np.clip(x0, 0, w - 1), np.clip(y0, 0, h - 1)
        cx1, cy1 = np.clip(x1, 0, w - 1), np.clip(y1, 0, h - 1)
        inside = defined & (x1 >= 0) & (x0 <= w - 1) & (y1 >= 0) & (y0 <= h - 1)
        clipped = (cx1 - cx0 + 1.0) * (cy1 - cy0 + 1.0)
        keep = inside & (clipped >= person.min_visible_fraction * full)
        boxes[c, keep] = np.stack([cx0, cy0, cx1, cy1], axis=-1)[keep].astype(np.int32)
    return Silhouettes(boxes, tuple(sizes))
