"""One entry point for the calibration formats ``planefuse import`` reads, and the check that the units are right.

Formats (``CALIBRATION_FORMATS``):

* ``opencv`` -- one OpenCV ``FileStorage`` YAML/XML per camera (:func:`load_opencv_camera`);
* ``json`` -- one JSON for all cameras, VoxelPose / Panoptic layouts (:func:`load_json_cameras`);
* ``tsai`` -- one EPFL Tsai XML per camera (:func:`load_tsai_xml`, :func:`pinhole_from_tsai`);
* ``homography`` -- one 3x3 image -> ground homography per camera (text, EPFL's ``Homography.txt`` layout), with
  the ground unit in metres (:func:`camera_from_ground_homography`).

Lengths are converted to metres with an explicit unit; :func:`check_metric_scale` refuses cameras whose heights
say the unit is wrong (a calibration in millimetres read as metres puts cameras kilometres up).
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path

import numpy as np

from ..geometry._camera import PinholeCamera
from ._epfl import load_epfl_homography
from ._filestorage import load_opencv_camera, open_filestorage, read_array
from ._ground import camera_from_ground_homography
from ._json import load_json_cameras
from ._tsai import load_tsai_xml, pinhole_from_tsai

__all__ = ["CALIBRATION_FORMATS", "LENGTH_UNITS_M", "load_cameras", "load_ground_homographies", "check_metric_scale"]

CALIBRATION_FORMATS = ("opencv", "json", "tsai", "homography")

#: Length unit name -> metres.
LENGTH_UNITS_M = {"mm": 1e-3, "cm": 1e-2, "m": 1.0}

#: A pinhole model reproducing a ground homography worse than this [px] is reported as a warning.
HOMOGRAPHY_MODEL_WARN_PX = 2.0

#: Camera heights above the ground outside this range [m] mean the length unit is wrong.
PLAUSIBLE_CAMERA_HEIGHT_M = (0.05, 300.0)


def _opencv(path: Path, name: str, metres_per_unit: float, size: tuple[int, int] | None) -> PinholeCamera:
    fs = open_filestorage(path)
    try:
        has_size = read_array(fs, path, "image_width", 1, required=False) is not None
    finally:
        fs.release()
    if has_size or size is None:
        cam = load_opencv_camera(path, name=name, metres_per_unit=metres_per_unit)
    else:
        cam = load_opencv_camera(path, name=name, metres_per_unit=metres_per_unit, width_px=size[0], height_px=size[1])
    got = (cam.intrinsics.width_px, cam.intrinsics.height_px)
    if size is not None and got != tuple(size):
        raise ValueError(f"{path}: field 'image_width': the calibration is {got[0]}x{got[1]} px, the images of camera "
                         f"{name!r} {size[0]}x{size[1]} px")
    return cam


def load_ground_homographies(files: Mapping[str, str | Path], *, ground_unit_m: float | None,
                             ground_flip_y: bool = False) -> dict[str, np.ndarray]:
    """``H_ground_image`` (3, 3) per camera, pixels -> ground XY [m], from 3x3 text files in ground units.

    Raises
    ------
    ValueError
        A missing or non-positive ``ground_unit_m``, or a malformed file (file and field named).
    """
    out = {}
    for name, spec in files.items():
        if ground_unit_m is None or not (np.isfinite(ground_unit_m) and ground_unit_m > 0):
            raise ValueError(f"{spec}: a ground homography needs its ground unit in metres (ground_unit_m / "
                             f"--ground-unit-m), got {ground_unit_m}")
        W = np.diag([ground_unit_m, -ground_unit_m if ground_flip_y else ground_unit_m, 1.0])
        out[name] = load_epfl_homography(spec, H_world_topview=W).H_plane_image
    return out


def load_cameras(fmt: str, files: Mapping[str, str | Path], *, unit: str,
                 sizes_px: Mapping[str, tuple[int, int]] | None = None, ground_unit_m: float | None = None,
                 ground_flip_y: bool = False) -> tuple[dict[str, PinholeCamera], list[str]]:
    """Cameras in metres from calibration files of one format.

    Parameters
    ----------
    fmt : {"opencv", "json", "tsai", "homography"}
    files : mapping of str -> path
        Camera name -> its file. For ``json`` the path may end in ``#KEY`` to pick the camera ``KEY`` of the file
        (default: the camera's name).
    unit : {"mm", "cm", "m"}
        Length unit of the files' translations (``homography``: of the control lengths only; see
        ``ground_unit_m``).
    sizes_px : mapping of str -> (width_px, height_px), optional
        Image size of each camera's frames: calibrations of another size are refused (``opencv``), scaled
        (``tsai``, uniform scaling only) or completed (files without a size).
    ground_unit_m : float, optional
        ``homography`` only (required there): metres per ground unit of the homographies.
    ground_flip_y : bool
        ``homography`` only: the ground frame's y axis points the other way (EPFL's top-view v), flip it to get a
        right-handed world with z up.

    Returns
    -------
    (dict of str -> PinholeCamera, list of (level, message))
        The cameras, and notes worth printing (fit errors of converted models; ``"warning"`` for a pinhole model
        that reproduces its ground homography worse than 2 px).

    Raises
    ------
    ValueError
        Unknown format or unit, a missing size, or any file error (the loaders name the file and field).
    """
    if fmt not in CALIBRATION_FORMATS:
        raise ValueError(f"calibration format {fmt!r} is unknown; use one of {', '.join(CALIBRATION_FORMATS)}")
    if unit not in LENGTH_UNITS_M:
        raise ValueError(f"length unit {unit!r} is unknown; use one of {', '.join(LENGTH_UNITS_M)}")
    m = LENGTH_UNITS_M[unit]
    sizes_px = dict(sizes_px or {})
    cams: dict[str, PinholeCamera] = {}
    notes: list[tuple[str, str]] = []
    for name, spec in files.items():
        size = sizes_px.get(name)
        if fmt == "opencv":
            cams[name] = _opencv(Path(spec), name, m, size)
        elif fmt == "json":
            path, _, key = str(spec).partition("#")
            key = key or name
            cams[name] = load_json_cameras(path, metres_per_unit=m, names={key: name}, keys=[key],
                                           sizes_px={key: size} if size else None)[key]
        elif fmt == "tsai":
            tsai = load_tsai_xml(spec, name=name)
            w, h = size if size is not None else (tsai.width_px, tsai.height_px)
            try:
                cams[name], err = pinhole_from_tsai(tsai, metres_per_unit=m, width_px=w, height_px=h, name=name)
            except ValueError as exc:
                raise ValueError(f"{spec}: {exc}") from None
            notes.append(("info", f"{name}: Tsai model {tsai.width_px}x{tsai.height_px} px -> {w}x{h} px, OpenCV "
                                  f"distortion fit within {err:.3f} px"))
        else:
            if size is None:
                raise ValueError(f"{spec}: camera {name!r} needs an image size for its homography")
            H = load_ground_homographies({name: spec}, ground_unit_m=ground_unit_m, ground_flip_y=ground_flip_y)[name]
            try:
                cams[name], err = camera_from_ground_homography(H, size[0], size[1], name=name)
            except ValueError as exc:
                raise ValueError(f"{spec}: {exc}") from None
            notes.append(("warning" if err > HOMOGRAPHY_MODEL_WARN_PX else "info",
                          f"{name}: pinhole model from the ground homography (centred principal point, square "
                          f"pixels): reproduces it within {err:.2f} px"))
    return cams, notes


def check_metric_scale(cameras: Mapping[str, PinholeCamera], unit: str, *, source: str = "calibration",
                       room_xy_m=None) -> None:
    """Refuse cameras whose height above the ground (z = 0, z up) shows a wrong length unit.

    Heights outside :data:`PLAUSIBLE_CAMERA_HEIGHT_M` (5 cm .. 300 m) are about 1000x off for a person-scale
    installation: millimetres read as metres put a 2 m camera 2 km up, metres read as millimetres 2 mm up.
    A camera below the ground means the world's z axis points down. With a monitored area ``room_xy_m``
    ``(x_min, x_max, y_min, y_max)`` [m], a camera farther from it than 100 times its size (and 100 m) means the area
    and the calibration use different units.

    Raises
    ------
    ValueError
        One line naming the camera, its height, and the unit that would make it plausible.
    """
    lo, hi = PLAUSIBLE_CAMERA_HEIGHT_M
    for name, cam in cameras.items():
        z = float(cam.center_world[2])
        if z <= 0:
            raise ValueError(f"{source}: camera {name!r} is {-z:.3g} m below the ground plane z = 0: the world's z "
                             "axis must point up (against gravity) with the ground at z = 0")
        if lo <= z <= hi:
            if room_xy_m is not None:
                x0, x1, y0, y1 = room_xy_m
                size = max(x1 - x0, y1 - y0, 1.0)
                d = float(np.hypot(cam.center_world[0] - np.clip(cam.center_world[0], x0, x1),
                                   cam.center_world[1] - np.clip(cam.center_world[1], y0, y1)))
                if d > max(100.0 * size, 100.0):
                    raise ValueError(f"{source}: camera {name!r} is {d:.4g} m from the monitored area {list(room_xy_m)} m "
                                     f"({size:g} m across): the area and the calibration use different length units")
            continue
        better = [u for u, f in LENGTH_UNITS_M.items() if lo <= z * f / LENGTH_UNITS_M[unit] <= hi]
        hint = f"; with --units {better[0]} it would be {z * LENGTH_UNITS_M[better[0]] / LENGTH_UNITS_M[unit]:.3g} m" \
            if better else ""
        raise ValueError(f"{source}: camera {name!r} is {z:.4g} m above the ground with --units {unit}: implausible "
                         f"(expected {lo:g}..{hi:g} m), the length unit looks wrong{hint}")
