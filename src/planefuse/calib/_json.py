"""Camera calibrations in JSON, as multi-view pose code keeps them (VoxelPose, CMU Panoptic and their kin).

One file holds every camera: either a mapping ``name -> camera`` (VoxelPose's ``calibration_*.json``) or
``{"cameras": [{"name": ..., ...}, ...]}`` (CMU Panoptic's ``calibration_<seq>.json``). A camera gives

* intrinsics: ``K`` (3x3 px) or ``fx, fy, cx, cy`` [px];
* distortion (optional, zeros if absent): ``dist`` / ``distCoef`` / ``distortion`` (OpenCV ``k1 k2 p1 p2 [k3]``)
  or ``k`` (``k1 k2 [k3]``) with ``p`` (``p1 p2``);
* rotation ``R`` (3x3, world -> camera) and a translation, in the file's length unit, either
  ``t`` / ``tvec`` (OpenCV: ``X_cam = R X_world + t``; Panoptic) or ``T`` (the camera **centre**:
  ``X_cam = R (X_world - T)``; VoxelPose). ``rvec`` (Rodrigues) may replace ``R``;
* image size (optional): ``resolution`` ``[width, height]`` or ``width``/``height``.

Errors name the file, the camera and the field.
"""

from __future__ import annotations

import json
from pathlib import Path

import cv2
import numpy as np

from ..geometry._camera import CameraIntrinsics, PinholeCamera
from ..geometry._transforms import invert_transform, transform_from_rotation_translation
from ._filestorage import calib_error, rotation_from_file

__all__ = ["load_json_cameras"]


def _cameras_in(data, path: Path) -> dict[str, dict]:
    if isinstance(data, dict) and isinstance(data.get("cameras"), list):
        out = {}
        for i, c in enumerate(data["cameras"]):
            if not isinstance(c, dict) or "name" not in c:
                raise calib_error(path, f"cameras[{i}]", "expected an object with a 'name'")
            out[str(c["name"])] = c
        return out
    if isinstance(data, dict) and data and all(isinstance(v, dict) for v in data.values()):
        return {str(k): v for k, v in data.items()}
    raise calib_error(path, "<file>", "expected an object name -> camera, or {'cameras': [...]}")


def _array(cam: dict, path: Path, where: str, field: str, sizes: tuple[int, ...]) -> np.ndarray:
    try:
        a = np.asarray(cam[field], dtype=float).ravel()
    except (TypeError, ValueError):
        raise calib_error(path, f"{where}.{field}", "non-numeric entries") from None
    if a.size not in sizes:
        raise calib_error(path, f"{where}.{field}", f"expected {' or '.join(map(str, sizes))} values, got {a.size}")
    if not np.isfinite(a).all():
        raise calib_error(path, f"{where}.{field}", "non-finite values")
    return a


def _camera(cam: dict, path: Path, where: str, name: str, metres_per_unit: float,
            size: tuple[int, int] | None, default_size: tuple[int, int] | None = None) -> PinholeCamera:
    if "K" in cam:
        K = _array(cam, path, where, "K", (9,)).reshape(3, 3)
    elif all(k in cam for k in ("fx", "fy", "cx", "cy")):
        fx, fy, cx, cy = (float(_array(cam, path, where, k, (1,))[0]) for k in ("fx", "fy", "cx", "cy"))
        K = np.array([[fx, 0.0, cx], [0.0, fy, cy], [0.0, 0.0, 1.0]])
    else:
        raise calib_error(path, f"{where}.K", "missing (give K, or fx, fy, cx, cy)")
    dist = np.zeros(5)
    for key in ("dist", "distCoef", "distortion"):
        if key in cam:
            d = _array(cam, path, where, key, (4, 5))
            dist[: d.size] = d
            break
    else:
        if "k" in cam:
            k = _array(cam, path, where, "k", (2, 3))
            dist[0], dist[1] = k[0], k[1]
            dist[4] = k[2] if k.size == 3 else 0.0
        if "p" in cam:
            dist[2:4] = _array(cam, path, where, "p", (2,))
    if "R" in cam:
        R = rotation_from_file(_array(cam, path, where, "R", (9,)), path, f"{where}.R")
    elif "rvec" in cam:
        R = cv2.Rodrigues(_array(cam, path, where, "rvec", (3,)))[0]
    else:
        raise calib_error(path, f"{where}.R", "missing (give R or rvec)")
    if "t" in cam or "tvec" in cam:
        t = _array(cam, path, where, "t" if "t" in cam else "tvec", (3,)) * metres_per_unit
    elif "T" in cam:  # the camera centre in the world (VoxelPose)
        t = -R @ (_array(cam, path, where, "T", (3,)) * metres_per_unit)
    else:
        raise calib_error(path, f"{where}.t", "missing (give t/tvec, OpenCV's world -> camera translation, or T, "
                          "the camera centre)")
    if size is None:
        if "resolution" in cam:
            w, h = (int(x) for x in _array(cam, path, where, "resolution", (2,)))
        elif "width" in cam and "height" in cam:
            w, h = int(cam["width"]), int(cam["height"])
        elif default_size is not None:
            w, h = default_size
        else:
            raise calib_error(path, f"{where}.resolution", "missing (the image size is not in the file: give it)")
        size = (w, h)
    try:
        intr = CameraIntrinsics(K, size[0], size[1], dist)
    except ValueError as exc:
        raise calib_error(path, f"{where}.K", str(exc)) from None
    return PinholeCamera(intr, invert_transform(transform_from_rotation_translation(R, t)), name)


def load_json_cameras(path, *, metres_per_unit: float, sizes_px: dict[str, tuple[int, int]] | None = None,
                      names: dict[str, str] | None = None, keys=None,
                      default_size_px: tuple[int, int] | None = None) -> dict[str, PinholeCamera]:
    """Every camera of a JSON calibration (module docstring), placed in the world in metres.

    Parameters
    ----------
    path : str or Path
    metres_per_unit : float
        Length unit of the file's translations in metres (VoxelPose: 0.001, Panoptic: 0.01).
    sizes_px : dict, optional
        Camera key -> ``(width_px, height_px)`` for files without the image size (or to override it).
    names : dict, optional
        Camera key in the file -> planefuse camera name (default: the key itself).
    keys : collection of str, optional
        Load only these cameras of the file (default: all).
    default_size_px : (width_px, height_px), optional
        Image size of the cameras ``sizes_px`` does not name and the file does not size.

    Returns
    -------
    dict of str -> PinholeCamera
        Keyed by the file's camera keys.

    Raises
    ------
    ValueError
        ``<file>: field '<camera>.<field>': ...`` for a missing, malformed or non-finite field, not a JSON file,
        or a rotation that is not one.
    """
    p = Path(path)
    if not (np.isfinite(metres_per_unit) and metres_per_unit > 0):
        raise ValueError(f"metres_per_unit must be a positive number, got {metres_per_unit}")
    if not p.is_file():
        raise calib_error(p, "<file>", "no such file")
    try:
        data = json.loads(p.read_text())
    except (json.JSONDecodeError, UnicodeDecodeError) as exc:
        raise calib_error(p, "<file>", f"not valid JSON ({exc})") from None
    sizes_px = sizes_px or {}
    names = names or {}
    found = _cameras_in(data, p)
    for key in keys or ():
        if key not in found:
            raise calib_error(p, key, f"no such camera (the file has {', '.join(sorted(found))})")
    return {key: _camera(c, p, key, names.get(key, key), metres_per_unit, sizes_px.get(key), default_size_px)
            for key, c in found.items() if keys is None or key in keys}
