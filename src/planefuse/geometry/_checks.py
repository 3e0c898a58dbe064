"""Input validation shared by the whole library.

Every public function converts its array inputs through one ``check_*`` helper that
returns a float64 array and raises a :class:`ValueError` naming the input, the
expected shape and what actually came.
"""

from __future__ import annotations

import numpy as np

__all__ = [
    "check_finite",
    "check_points",
    "check_homography",
    "check_rotation",
    "check_transform",
    "check_intrinsics_matrix",
]


def check_finite(a: np.ndarray, name: str) -> np.ndarray:
    """Raise ``ValueError`` if ``a`` holds NaN or infinity; return it unchanged."""
    if not np.isfinite(a).all():
        n_bad = int(np.size(a) - np.count_nonzero(np.isfinite(a)))
        raise ValueError(f"{name} has {n_bad} non-finite (NaN/inf) entries")
    return a


def check_points(p, dim: int, name: str = "points", *, allow_nan: bool = False) -> np.ndarray:
    """Convert ``p`` to a float64 array of points of shape ``(..., N, dim)``.

    Parameters
    ----------
    p : array_like, shape (..., N, dim) or (dim,)
        Points as rows. A single point of shape ``(dim,)`` is accepted.
    dim : int
        Number of coordinates per point.
    name : str
        Name used in error messages.
    allow_nan : bool
        If False (default), NaN or infinite coordinates raise ``ValueError``.
    """
    a = np.asarray(p, dtype=float)
    if a.ndim == 0 or a.shape[-1] != dim:
        raise ValueError(f"{name} must have shape (..., N, {dim}) (points as rows), got {a.shape}")
    if not allow_nan:
        check_finite(a, name)
    return a


def check_homography(H, name: str = "homography") -> np.ndarray:
    """Convert ``H`` to float64 of shape ``(..., 3, 3)``; reject non-finite or singular matrices."""
    a = np.asarray(H, dtype=float)
    if a.ndim < 2 or a.shape[-2:] != (3, 3):
        raise ValueError(f"{name} must have shape (..., 3, 3), got {a.shape}")
    check_finite(a, name)
    # Scale-invariant singularity test: condition number of the normalised matrix.
    s = np.linalg.svd(a, compute_uv=False)
    if np.any(s[..., -1] <= 1e-12 * s[..., 0]) or np.any(s[..., 0] == 0):
        raise ValueError(f"{name} is singular (smallest/largest singular value <= 1e-12)")
    return a


def check_rotation(R, name: str = "rotation", atol: float = 1e-6) -> np.ndarray:
    """Convert ``R`` to float64 ``(..., 3, 3)`` and check it is a proper rotation."""
    a = np.asarray(R, dtype=float)
    if a.ndim < 2 or a.shape[-2:] != (3, 3):
        raise ValueError(f"{name} must have shape (..., 3, 3), got {a.shape}")
    check_finite(a, name)
    eye = np.broadcast_to(np.eye(3), a.shape)
    if not np.allclose(a @ np.swapaxes(a, -1, -2), eye, atol=atol):
        raise ValueError(f"{name} is not orthonormal (R R^T != I within {atol})")
    if np.any(np.linalg.det(a) < 0):
        raise ValueError(f"{name} has determinant -1 (a reflection, not a rotation)")
    return a


def check_transform(T, name: str = "transform") -> np.ndarray:
    """Convert ``T`` to float64 ``(..., 4, 4)`` and check it is a rigid transform."""
    a = np.asarray(T, dtype=float)
    if a.ndim < 2 or a.shape[-2:] != (4, 4):
        raise ValueError(f"{name} must have shape (..., 4, 4), got {a.shape}")
    check_finite(a, name)
    if not np.allclose(a[..., 3, :], [0.0, 0.0, 0.0, 1.0]):
        raise ValueError(f"{name} last row must be [0, 0, 0, 1], got {a[..., 3, :]}")
    check_rotation(a[..., :3, :3], name=f"{name} rotation block")
    return a


def check_intrinsics_matrix(K, name: str = "K") -> np.ndarray:
    """Convert ``K`` to float64 ``(3, 3)`` upper-triangular intrinsics with positive focal lengths."""
    a = np.asarray(K, dtype=float)
    if a.shape != (3, 3):
        raise ValueError(f"{name} must have shape (3, 3), got {a.shape}")
    check_finite(a, name)
    if a[0, 0] <= 0 or a[1, 1] <= 0:
        raise ValueError(f"{name} must have positive focal lengths, got fx={a[0, 0]}, fy={a[1, 1]}")
    if not np.allclose(a[2], [0.0, 0.0, 1.0]) or a[1, 0] != 0 or a[2, 0] != 0:
        raise ValueError(f"{name} must be upper triangular with last row [0, 0, 1], got {a.tolist()}")
    return a
