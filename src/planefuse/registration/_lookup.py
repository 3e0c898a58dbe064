"""Precomputed image -> plane-stack lookup: registering a frame is one gather.

For every camera and every cell of every plane, the lookup stores the flat index
of the image pixel that sees the cell centre (through the full camera model,
lens distortion included, or through given plane homographies), or a sentinel
for cells the camera does not see (outside the image, behind the camera).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numba import njit

from ..geometry._camera import PinholeCamera
from ..geometry._checks import check_homography
from ..geometry._homography import apply_homography
from ..grid._stack import PlaneStack

__all__ = ["ImagePlaneLookup"]


@njit(cache=True)
def _gather_kernel(padded_image, pixel_index, out):  # pragma: no cover - compiled
    # out[i] = padded_image[pixel_index[i]]; the sentinel indexes the fill value appended after the last pixel.
    # Branch-free and without np.take's int32 -> intp index copy: ~1.4x faster than np.take here.
    for i in range(pixel_index.size):
        out[i] = padded_image[pixel_index[i]]


@dataclass(frozen=True)
class ImagePlaneLookup:
    """Per-camera map from plane-stack cells to image pixels.

    Attributes
    ----------
    pixel_index : ndarray, shape (L, ny, nx), int32
        Flat index ``v * width + u`` of the pixel seeing each cell centre, or
        ``width * height`` (a sentinel one past the last pixel) where unseen.
    width_px, height_px : int
        Image size the lookup was built for.
    stack : PlaneStack
    """

    pixel_index: np.ndarray
    width_px: int
    height_px: int
    stack: PlaneStack

    @property
    def visible(self) -> np.ndarray:
        """Boolean (L, ny, nx): the camera sees the cell."""
        return self.pixel_index < self.width_px * self.height_px

    @property
    def sentinel(self) -> int:
        """Index used for unseen cells."""
        return self.width_px * self.height_px

    @classmethod
    def _from_pixels(cls, uv: np.ndarray, width: int, height: int, stack: PlaneStack) -> "ImagePlaneLookup":
        with np.errstate(invalid="ignore"):
            u = np.rint(uv[..., 0])
            v = np.rint(uv[..., 1])
            ok = np.isfinite(u) & np.isfinite(v) & (u >= 0) & (u < width) & (v >= 0) & (v < height)
        idx = np.full(uv.shape[:-1], width * height, dtype=np.int64)
        idx[ok] = v[ok].astype(np.int64) * width + u[ok].astype(np.int64)
        if width * height >= np.iinfo(np.int32).max:
            raise ValueError(f"image {width}x{height} too large for an int32 lookup")
        return cls(idx.astype(np.int32), int(width), int(height), stack)

    @classmethod
    def from_camera(cls, camera: PinholeCamera, stack: PlaneStack) -> "ImagePlaneLookup":
        """Project every cell centre (with lens distortion) into ``camera``."""
        uv = camera.project(stack.cell_centers_world().reshape(stack.n_planes, -1, 3))
        uv = uv.reshape(stack.shape + (2,))
        return cls._from_pixels(uv, camera.intrinsics.width_px, camera.intrinsics.height_px, stack)

    @classmethod
    def from_homographies(
        cls, H_image_plane, width_px: int, height_px: int, stack: PlaneStack
    ) -> "ImagePlaneLookup":
        """Build from plane -> image homographies (L, 3, 3) (world XY [m] -> pixels).

        Cells mapped through a negative homogeneous scale are behind the camera
        only if the homographies come from a projection matrix with the sign of
        ``P`` preserved; callers without that guarantee should pass
        homographies normalised so that visible points have positive scale.
        """
        H = check_homography(H_image_plane, "H_image_plane")
        if H.shape != (stack.n_planes, 3, 3):
            raise ValueError(f"H_image_plane must have shape ({stack.n_planes}, 3, 3), got {H.shape}")
        xy = stack.cell_centers_xy().reshape(-1, 2)
        uv = apply_homography(H, np.broadcast_to(xy, (stack.n_planes,) + xy.shape))
        w = np.einsum("lj,nj->ln", H[:, 2, :2], xy) + H[:, 2, 2][:, None]
        uv[w <= 0] = np.nan
        return cls._from_pixels(uv.reshape(stack.shape + (2,)), width_px, height_px, stack)

    def without_pixels(self, ignore_mask) -> "ImagePlaneLookup":
        """This lookup with the cells seen through ignored pixels made unseen (sentinel).

        Parameters
        ----------
        ignore_mask : ndarray, shape (height_px, width_px), bool
            Pixels that are not scene evidence (watermark, privacy zone...).

        Returns
        -------
        ImagePlaneLookup
            Cells whose pixel is ignored are unobserved: a sensor model built on it says nothing about them.
        """
        mask = np.asarray(ignore_mask)
        if mask.shape != (self.height_px, self.width_px):
            raise ValueError(f"ignore_mask must have shape ({self.height_px}, {self.width_px}), got {mask.shape}")
        padded = np.append(mask.reshape(-1).astype(bool), False)  # the sentinel stays the sentinel
        return self.without_cells(padded[self.pixel_index])

    def without_cells(self, unobserved) -> "ImagePlaneLookup":
        """This lookup with the given cells made unseen (sentinel), e.g. cells a known static occluder hides
        from the camera (:func:`planefuse.grid.cells_hidden_by_occluders`).

        Parameters
        ----------
        unobserved : ndarray, shape (L, ny, nx), bool

        Returns
        -------
        ImagePlaneLookup
            A sensor model built on it says nothing about those cells.
        """
        mask = np.asarray(unobserved, dtype=bool)
        if mask.shape != self.pixel_index.shape:
            raise ValueError(f"unobserved must have shape {self.pixel_index.shape}, got {mask.shape}")
        idx = np.where(mask, np.int32(self.sentinel), self.pixel_index)
        return ImagePlaneLookup(idx.astype(np.int32), self.width_px, self.height_px, self.stack)

    def gather(self, image, fill: float = np.nan, out=None) -> np.ndarray:
        """Register one image on every plane: ``out[l, iy, ix] = image[pixel seeing the cell]``.

        Parameters
        ----------
        image : ndarray, shape (height_px, width_px)
            A per-pixel quantity (e.g. foreground likelihood in [0, 1]).
        fill : float
            Value for cells the camera does not see (NaN = unknown by default).
        out : ndarray, shape (L, ny, nx), optional
            Output buffer (float32 or float64).

        Returns
        -------
        ndarray, shape (L, ny, nx)
        """
        img = np.asarray(image)
        if img.shape != (self.height_px, self.width_px):
            raise ValueError(
                f"image must have shape ({self.height_px}, {self.width_px}) for this lookup, got {img.shape}"
            )
        if out is None:
            out = np.empty(self.pixel_index.shape, dtype=np.float32)
        elif out.shape != self.pixel_index.shape or out.dtype not in (np.float32, np.float64):
            raise ValueError(
                f"out must be a float32/float64 array of shape {self.pixel_index.shape}, got {out.dtype} {out.shape}"
            )
        padded = np.empty(img.size + 1, dtype=out.dtype)
        padded[:-1] = img.ravel()
        padded[-1] = fill
        target = out if out.flags.c_contiguous else np.empty_like(out)
        _gather_kernel(padded, self.pixel_index.ravel(), target.ravel())
        if target is not out:
            out[...] = target
        return out
