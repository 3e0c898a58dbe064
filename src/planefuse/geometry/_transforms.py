"""Rigid transforms between frames, as 4x4 homogeneous matrices.

Naming: ``T_a_b`` maps coordinates expressed in frame ``b`` into frame ``a``
(``p_a = T_a_b @ p_b``); compositions cancel the middle frame:
``T_world_cam = T_world_imu @ T_imu_cam``. Rotations use
:mod:`scipy.spatial.transform`; quaternions are scalar-last ``[x, y, z, w]``
unless ``scalar_first=True`` is given (BROAD, ROS and SOFA differ; see
``docs/conventions.md``).
"""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

from ._checks import check_points, check_rotation, check_transform

__all__ = [
    "transform_from_rotation_translation",
    "rotation_translation_from_transform",
    "invert_transform",
    "apply_transform",
    "transform_from_quaternion",
    "rotation_from_roll_pitch_yaw",
    "roll_pitch_yaw_from_rotation",
    "rotation_aligning",
]


def transform_from_rotation_translation(R_a_b, t_a_b) -> np.ndarray:
    """Build ``T_a_b`` (..., 4, 4) from a rotation (..., 3, 3) and translation (..., 3) in metres."""
    R = check_rotation(R_a_b, "R_a_b")
    t = np.asarray(t_a_b, dtype=float)
    if t.shape[-1:] != (3,):
        raise ValueError(f"t_a_b must have shape (..., 3), got {t.shape}")
    batch = np.broadcast_shapes(R.shape[:-2], t.shape[:-1])
    T = np.zeros(batch + (4, 4))
    T[..., :3, :3] = R
    T[..., :3, 3] = t
    T[..., 3, 3] = 1.0
    return T


def rotation_translation_from_transform(T_a_b) -> tuple[np.ndarray, np.ndarray]:
    """Split ``T_a_b`` (..., 4, 4) into ``R_a_b`` (..., 3, 3) and ``t_a_b`` (..., 3) [m]."""
    T = check_transform(T_a_b, "T_a_b")
    return T[..., :3, :3].copy(), T[..., :3, 3].copy()


def invert_transform(T_a_b) -> np.ndarray:
    """Return ``T_b_a`` = inverse of the rigid transform ``T_a_b`` (..., 4, 4), exactly (R^T, -R^T t)."""
    T = check_transform(T_a_b, "T_a_b")
    R = T[..., :3, :3]
    t = T[..., :3, 3]
    Rt = np.swapaxes(R, -1, -2)
    out = np.zeros_like(T)
    out[..., :3, :3] = Rt
    out[..., :3, 3] = -np.einsum("...ij,...j->...i", Rt, t)
    out[..., 3, 3] = 1.0
    return out


def apply_transform(T_a_b, p_b) -> np.ndarray:
    """Map points ``p_b`` (..., N, 3) [m] in frame b to frame a with ``T_a_b`` (..., 4, 4)."""
    T = check_transform(T_a_b, "T_a_b")
    p = check_points(p_b, 3, "p_b", allow_nan=True)
    R = T[..., None, :3, :3] if p.ndim >= 2 else T[..., :3, :3]
    t = T[..., None, :3, 3] if p.ndim >= 2 else T[..., :3, 3]
    return np.einsum("...ij,...j->...i", R, p) + t


def transform_from_quaternion(q, t=(0.0, 0.0, 0.0), *, scalar_first: bool = False) -> np.ndarray:
    """Build ``T_a_b`` from a unit quaternion of ``R_a_b`` and a translation [m].

    Parameters
    ----------
    q : array_like, shape (..., 4)
        Quaternion, ``[x, y, z, w]`` (default) or ``[w, x, y, z]`` with ``scalar_first=True``.
    t : array_like, shape (..., 3)
        Translation of frame b's origin expressed in frame a [m].
    """
    q = np.asarray(q, dtype=float)
    if q.shape[-1:] != (4,):
        raise ValueError(f"quaternion must have shape (..., 4), got {q.shape}")
    if not np.isfinite(q).all():
        raise ValueError("quaternion has non-finite entries")
    if scalar_first:
        q = np.roll(q, -1, axis=-1)
    R = Rotation.from_quat(q.reshape(-1, 4)).as_matrix().reshape(q.shape[:-1] + (3, 3))
    return transform_from_rotation_translation(R, t)


def rotation_from_roll_pitch_yaw(roll_rad, pitch_rad, yaw_rad) -> np.ndarray:
    """``R_world_body`` (..., 3, 3) from extrinsic x-y-z (roll, pitch, yaw) angles [rad].

    ``R = Rz(yaw) @ Ry(pitch) @ Rx(roll)`` (aerospace/ROS convention, z up).
    """
    angles = np.stack(np.broadcast_arrays(roll_rad, pitch_rad, yaw_rad), axis=-1).astype(float)
    if not np.isfinite(angles).all():
        raise ValueError("roll/pitch/yaw have non-finite entries")
    R = Rotation.from_euler("xyz", angles.reshape(-1, 3)).as_matrix()
    return R.reshape(angles.shape[:-1] + (3, 3))


def roll_pitch_yaw_from_rotation(R_world_body) -> np.ndarray:
    """Inverse of :func:`rotation_from_roll_pitch_yaw`: (..., 3) array of (roll, pitch, yaw) [rad]."""
    R = check_rotation(R_world_body, "R_world_body")
    e = Rotation.from_matrix(R.reshape(-1, 3, 3)).as_euler("xyz")
    return e.reshape(R.shape[:-2] + (3,))


def rotation_aligning(a, b) -> np.ndarray:
    """Smallest rotation ``R`` (3, 3) with ``R @ a/|a| == b/|b|`` (both (3,) vectors)."""
    a = np.asarray(a, dtype=float)
    b = np.asarray(b, dtype=float)
    if a.shape != (3,) or b.shape != (3,):
        raise ValueError(f"a and b must have shape (3,), got {a.shape} and {b.shape}")
    na, nb = np.linalg.norm(a), np.linalg.norm(b)
    if not (np.isfinite(na) and np.isfinite(nb)) or na == 0 or nb == 0:
        raise ValueError("a and b must be finite non-zero vectors")
    rot, _ = Rotation.align_vectors(b[None] / nb, a[None] / na)
    return rot.as_matrix()
