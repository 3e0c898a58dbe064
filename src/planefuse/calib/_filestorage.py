"""OpenCV ``FileStorage`` camera files (YAML or XML): read and write :class:`PinholeCamera`.

Fields (OpenCV's calibration-sample names):

* ``camera_matrix``: 3x3 K [px];
* ``distortion_coefficients``: 4 or 5 values ``(k1, k2, p1, p2[, k3])``;
* ``image_width``, ``image_height``: integers [px];
* extrinsics, optional, in the file's length unit: ``rvec`` + ``tvec`` (OpenCV's
  world -> camera: ``X_cam = R(rvec) X_world + tvec``, as ``cv2.projectPoints`` takes them),
  ``R`` (3x3) + ``T`` (3) in the same convention (``X_cam = R X_world + T``, as ``cv2.stereoCalibrate``
  writes them), or a 4x4 ``T_world_cam`` or ``T_cam_world``.

Every malformed file raises ``ValueError("<file>: field '<field>': <what is wrong>")``.
"""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np

from ..geometry._camera import CameraIntrinsics, PinholeCamera
from ..geometry._checks import check_transform
from ..geometry._transforms import invert_transform, transform_from_rotation_translation

__all__ = ["load_opencv_intrinsics", "load_opencv_camera", "save_opencv_camera"]


def calib_error(path, field: str, what: str) -> ValueError:
    """The loaders' error: names the file and the field."""
    return ValueError(f"{path}: field '{field}': {what}")


def rotation_from_file(R, path, field: str, atol: float = 1e-3) -> np.ndarray:
    """A rotation matrix read from a file, made exactly orthonormal (nearest rotation, SVD) when it is one to
    ``atol`` (files print 6-10 digits); ``ValueError`` naming the file and field otherwise (a reflection, a
    scaled or a non-finite matrix)."""
    R = np.asarray(R, dtype=float).reshape(3, 3)
    if not np.isfinite(R).all():
        raise calib_error(path, field, "non-finite values")
    if not np.allclose(R @ R.T, np.eye(3), atol=atol):
        raise calib_error(path, field, f"not a rotation: R R^T differs from I by {np.abs(R @ R.T - np.eye(3)).max():.3g}")
    if np.linalg.det(R) < 0:
        raise calib_error(path, field, "determinant -1 (a reflection, not a rotation: left-handed world?)")
    U, _, Vt = np.linalg.svd(R)
    return U @ Vt


def open_filestorage(path) -> cv2.FileStorage:
    """Open an OpenCV YAML/XML file for reading; ``ValueError`` naming the file if it is absent, empty or unparsable."""
    p = Path(path)
    if not p.is_file():
        raise calib_error(p, "<file>", "no such file")
    if p.stat().st_size == 0:
        raise calib_error(p, "<file>", "file is empty")
    try:
        fs = cv2.FileStorage(str(p), cv2.FILE_STORAGE_READ)
    except (cv2.error, SystemError) as exc:  # OpenCV surfaces parse errors as SystemError from the constructor
        raise calib_error(p, "<file>", f"not a valid OpenCV FileStorage YAML/XML file ({exc})") from None
    if not fs.isOpened():
        raise calib_error(p, "<file>", "OpenCV could not open it as FileStorage YAML/XML")
    return fs


def read_array(fs: cv2.FileStorage, path, field: str, size=None, *, required: bool = True) -> np.ndarray | None:
    """Numeric node ``field`` as a float64 array: an ``opencv-matrix``, a plain sequence or whitespace-separated text.

    Parameters
    ----------
    size : int or tuple of int, optional
        Accepted element counts; the array is returned flat (callers reshape).
    required : bool
        If False, a missing field returns None.
    """
    node = fs.getNode(field)
    if node.empty() or node.isNone():
        if required:
            raise calib_error(path, field, "missing")
        return None
    if node.isMap():
        try:
            a = np.asarray(node.mat(), dtype=float)
        except cv2.error as exc:
            raise calib_error(path, field, f"malformed opencv-matrix ({str(exc).splitlines()[-1]})") from None
    elif node.isSeq():
        items = [node.at(i) for i in range(node.size())]
        if not all(it.isReal() or it.isInt() for it in items):
            bad = [i for i, it in enumerate(items) if not (it.isReal() or it.isInt())]
            raise calib_error(path, field, f"non-numeric entries at positions {bad}")
        a = np.array([it.real() for it in items], dtype=float)
    elif node.isReal() or node.isInt():
        a = np.array([node.real()])
    elif node.isString():
        try:
            a = np.array([float(x) for x in node.string().split()])
        except ValueError:
            raise calib_error(path, field, f"non-numeric text {node.string()!r}") from None
    else:
        raise calib_error(path, field, "not a number, a sequence or a matrix")
    a = a.ravel()
    sizes = (size,) if isinstance(size, int) else size
    if sizes is not None and a.size not in sizes:
        raise calib_error(path, field, f"expected {' or '.join(map(str, sizes))} values, got {a.size}")
    if not np.isfinite(a).all():
        raise calib_error(path, field, "non-finite values")
    return a


def read_int(fs: cv2.FileStorage, path, field: str, default: int | None = None) -> int:
    """Positive integer node ``field`` (e.g. ``image_width``); ``default`` if absent and given."""
    a = read_array(fs, path, field, 1, required=default is None)
    if a is None:
        return int(default)
    if a[0] != np.round(a[0]) or a[0] <= 0:
        raise calib_error(path, field, f"expected a positive integer, got {a[0]}")
    return int(a[0])


def intrinsics_from_filestorage(fs, path, width_px: int | None, height_px: int | None) -> CameraIntrinsics:
    """Build :class:`CameraIntrinsics` from the opened file; sizes given here override the file's."""
    K = read_array(fs, path, "camera_matrix", 9).reshape(3, 3)
    dist_node = fs.getNode("distortion_coefficients")
    dist = np.zeros(5) if dist_node.empty() else read_array(fs, path, "distortion_coefficients", (4, 5))
    w = width_px if width_px is not None else read_int(fs, path, "image_width")
    h = height_px if height_px is not None else read_int(fs, path, "image_height")
    try:
        return CameraIntrinsics(K, w, h, dist)
    except ValueError as exc:
        raise calib_error(path, "camera_matrix", str(exc)) from None


def load_opencv_intrinsics(path, *, width_px: int | None = None, height_px: int | None = None) -> CameraIntrinsics:
    """Intrinsics from an OpenCV YAML/XML file.

    Parameters
    ----------
    path : str or Path
        File with ``camera_matrix``, optional ``distortion_coefficients`` (zeros if absent)
        and ``image_width``/``image_height`` (unless given here).
    width_px, height_px : int, optional
        Image size [px] for files that do not store it.

    Raises
    ------
    ValueError
        Naming the file and the field: missing, wrong number of values, non-numeric,
        not a valid K, or an empty/unparsable file.
    """
    fs = open_filestorage(path)
    try:
        return intrinsics_from_filestorage(fs, path, width_px, height_px)
    finally:
        fs.release()


def T_world_cam_from_filestorage(fs, path, metres_per_unit: float) -> np.ndarray | None:
    """``T_world_cam`` (4, 4) [m] from ``rvec``/``tvec``, ``R``/``T`` or ``T_world_cam``/``T_cam_world``; None if
    none is given."""
    rvec = read_array(fs, path, "rvec", 3, required=False)
    R = read_array(fs, path, "R", 9, required=False)
    if rvec is not None or R is not None:
        if rvec is not None:
            R_cam_world, t_field = cv2.Rodrigues(rvec)[0], "tvec"
        else:
            R_cam_world, t_field = rotation_from_file(R.reshape(3, 3), path, "R"), "T"
        tvec = read_array(fs, path, t_field, 3)
        try:
            T_cam_world = transform_from_rotation_translation(R_cam_world, tvec * metres_per_unit)
        except ValueError as exc:
            raise calib_error(path, "R", str(exc)) from None
        return invert_transform(T_cam_world)
    for field in ("T_world_cam", "T_cam_world"):
        T = read_array(fs, path, field, 16, required=False)
        if T is None:
            continue
        T = T.reshape(4, 4).copy()
        T[:3, 3] *= metres_per_unit
        try:
            T = check_transform(T, field)
        except ValueError as exc:
            raise calib_error(path, field, str(exc)) from None
        return invert_transform(T) if field == "T_cam_world" else T
    return None


def load_opencv_camera(
    path,
    *,
    name: str | None = None,
    metres_per_unit: float = 1.0,
    width_px: int | None = None,
    height_px: int | None = None,
) -> PinholeCamera:
    """A placed camera from an OpenCV YAML/XML file with intrinsics and extrinsics.

    Parameters
    ----------
    path : str or Path
        See the module docstring for the fields.
    name : str, optional
        Camera name (defaults to the file stem).
    metres_per_unit : float
        Length unit of the file's translations in metres (0.01 for centimetres).
    width_px, height_px : int, optional
        Image size for files that do not store it.

    Raises
    ------
    ValueError
        Naming the file and the field (see :func:`load_opencv_intrinsics`); also when
        no extrinsics (``rvec``/``tvec``, ``R``/``T``, ``T_world_cam`` or ``T_cam_world``) are present.
    """
    if not (np.isfinite(metres_per_unit) and metres_per_unit > 0):
        raise ValueError(f"metres_per_unit must be a positive number, got {metres_per_unit}")
    fs = open_filestorage(path)
    try:
        intr = intrinsics_from_filestorage(fs, path, width_px, height_px)
        T = T_world_cam_from_filestorage(fs, path, metres_per_unit)
    finally:
        fs.release()
    if T is None:
        raise calib_error(path, "rvec", "missing (no rvec/tvec, R/T, T_world_cam or T_cam_world extrinsics)")
    return PinholeCamera(intr, T, name or Path(path).stem)


def save_opencv_camera(path, camera: PinholeCamera | CameraIntrinsics, *, metres_per_unit: float = 1.0) -> None:
    """Write a camera (or intrinsics only) as an OpenCV YAML/XML file (format from the suffix).

    Extrinsics are written as OpenCV ``rvec``/``tvec`` (world -> camera) in the file unit
    ``metres_per_unit``; :func:`load_opencv_camera` reads them back.
    """
    intr = camera.intrinsics if isinstance(camera, PinholeCamera) else camera
    fs = cv2.FileStorage(str(path), cv2.FILE_STORAGE_WRITE)
    try:
        fs.write("image_width", intr.width_px)
        fs.write("image_height", intr.height_px)
        fs.write("camera_matrix", np.asarray(intr.K))
        fs.write("distortion_coefficients", np.asarray(intr.dist).reshape(5, 1))
        if isinstance(camera, PinholeCamera):
            T = camera.T_cam_world
            fs.write("rvec", cv2.Rodrigues(T[:3, :3])[0])
            fs.write("tvec", (T[:3, 3] / metres_per_unit).reshape(3, 1))
    finally:
        fs.release()
