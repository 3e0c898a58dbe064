"""Reader for the ``Calib_Results.mat`` of J.-Y. Bouguet's Camera Calibration Toolbox for MATLAB.

The toolbox stores the intrinsics (``KK``, ``kc`` = k1, k2, p1, p2, k3 as in OpenCV), the image size
(``nx``, ``ny``) and, per calibration image ``i``, the board pose ``Rc_i`` (3x3), ``Tc_i`` (3,) with
``X_cam = Rc_i X_board + Tc_i``, the detected corners ``x_i`` (2, K) [px] and the board corners ``X_i``
(3, K), all lengths in the unit of the board squares (``dX``; millimetres in most files).
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..geometry._transforms import transform_from_rotation_translation

__all__ = ["BouguetBoardView", "BouguetCalibration", "load_bouguet_calibration"]


@dataclass(frozen=True)
class BouguetBoardView:
    """One calibration image's board.

    Attributes
    ----------
    index : int
        Image number ``i`` of the toolbox (1-based).
    T_camera_board : ndarray (4, 4)
        Board frame -> camera frame, translation [m].
    corners_px : ndarray (K, 2)
        Detected corners in the image [px].
    corners_board_m : ndarray (K, 3)
        The same corners in the board frame [m] (z = 0 on the board).
    """

    index: int
    T_camera_board: np.ndarray
    corners_px: np.ndarray
    corners_board_m: np.ndarray


@dataclass(frozen=True)
class BouguetCalibration:
    """Intrinsics and board views of a ``Calib_Results.mat``.

    Attributes
    ----------
    K : ndarray (3, 3)
        Camera matrix [px].
    dist : ndarray (5,)
        Distortion k1, k2, p1, p2, k3 (OpenCV order).
    width_px, height_px : int
        Image size [px].
    views : dict[int, BouguetBoardView]
        Board views by image number.
    source : str
        File read.
    """

    K: np.ndarray
    dist: np.ndarray
    width_px: int
    height_px: int
    views: dict
    source: str = ""


def load_bouguet_calibration(path, metres_per_unit: float = 0.001) -> BouguetCalibration:
    """Read a Bouguet toolbox ``Calib_Results.mat`` (MATLAB v5, via ``scipy.io.loadmat``).

    Parameters
    ----------
    path : path-like
    metres_per_unit : float
        Length of the file's unit (the board squares' unit) [m]; 0.001 for millimetres.

    Raises
    ------
    ValueError
        Not a MATLAB file, no ``KK``/``kc``, or a view whose ``Rc_i``, ``Tc_i``, ``x_i``, ``X_i`` are missing
        or malformed (the error names the file and the variable).
    """
    import scipy.io

    path = Path(path)
    if not path.is_file():
        raise ValueError(f"calibration file {path} does not exist")
    if not metres_per_unit > 0:
        raise ValueError(f"metres_per_unit must be > 0, got {metres_per_unit}")
    try:
        mat = scipy.io.loadmat(path)
    except Exception as err:  # scipy raises several error types for non-MATLAB files
        raise ValueError(f"{path} is not a MATLAB .mat file ({type(err).__name__}: {err})") from err
    missing = [k for k in ("KK", "kc") if k not in mat]
    if missing:
        names = sorted(k for k in mat if not k.startswith("__"))
        raise ValueError(f"{path} is not a Bouguet Calib_Results.mat: no {missing}; variables: {names[:12]}")
    K = np.asarray(mat["KK"], dtype=float)
    dist = np.zeros(5)
    kc = np.asarray(mat["kc"], dtype=float).ravel()[:5]
    dist[: kc.size] = kc
    if K.shape != (3, 3):
        raise ValueError(f"{path}: KK must be 3x3, got {K.shape}")
    size = [int(np.ravel(mat[k])[0]) if k in mat else 0 for k in ("nx", "ny")]
    views = {}
    for i in sorted(int(m.group(1)) for m in map(re.compile(r"Rc_(\d+)$").match, mat) if m):
        try:
            R = np.asarray(mat[f"Rc_{i}"], dtype=float)
            t = np.asarray(mat[f"Tc_{i}"], dtype=float).ravel() * metres_per_unit
            x = np.asarray(mat[f"x_{i}"], dtype=float)
            X = np.asarray(mat[f"X_{i}"], dtype=float) * metres_per_unit
        except KeyError as err:
            raise ValueError(f"{path}: view {i} has no variable {err}") from None
        if R.shape != (3, 3) or t.shape != (3,) or x.ndim != 2 or x.shape[0] != 2 or X.shape != (3, x.shape[1]):
            raise ValueError(f"{path}: view {i} has Rc {R.shape}, Tc {t.shape}, x {x.shape}, X {X.shape}; "
                             "expected (3, 3), (3,), (2, K), (3, K)")
        views[i] = BouguetBoardView(i, transform_from_rotation_translation(R, t), x.T.copy(), X.T.copy())
    return BouguetCalibration(K, dist, size[0], size[1], views, str(path))
