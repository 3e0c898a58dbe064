"""``planefuse calib-show``: read a calibration file with planefuse's loaders and print what they understood."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import typer

from ..calib import (
    H_WORLD_TOPVIEW_TERRACE,
    load_bouguet_calibration,
    load_epfl_homography,
    load_json_cameras,
    load_opencv_camera,
    load_opencv_intrinsics,
    load_tsai_xml,
    load_wildtrack_camera,
    pinhole_from_tsai,
)
from ..geometry import roll_pitch_yaw_from_rotation
from ._app import app, console, exit_with_error, units_table


def _camera_rows(cam, intr) -> list[tuple[str, str]]:
    rows = [("image [px]", f"{intr.width_px} x {intr.height_px}"),
            ("K [px]", np.array2string(intr.K, precision=3)),
            ("dist (k1 k2 p1 p2 k3)", np.array2string(intr.dist, precision=5))]
    if cam is None:
        rows.append(("extrinsics", "none (intrinsics only)"))
    else:
        rpy = np.degrees(roll_pitch_yaw_from_rotation(cam.R_world_cam))
        rows.append(("centre in world [m]", np.array2string(cam.center_world, precision=3)))
        rows.append(("R_world_cam roll/pitch/yaw [deg]", np.array2string(rpy, precision=2)))
    return rows


def _epfl_rows(path: Path, terrace: bool | None, metres_per_unit: float) -> list[tuple[str, str]]:
    if terrace is None:  # auto: the terrace's camera folders are named terrace<k>-c<i>
        terrace = path.parent.name.startswith("terrace") and metres_per_unit == 1.0
    if terrace:
        W, units = H_WORLD_TOPVIEW_TERRACE, "world XY [m] (planefuse's terrace map, ~0.0219 m per top-view unit)"
    elif metres_per_unit != 1.0:
        W, units = np.diag([metres_per_unit, metres_per_unit, 1.0]), f"world XY [m] ({metres_per_unit:g} m per unit)"
    else:
        W, units = None, "top-view units (the file's own; --metres-per-unit makes them metres)"
    hom = load_epfl_homography(path, H_world_topview=W)
    return [("H_plane_image", np.array2string(hom.H_plane_image, precision=6)), ("ground units", units)]


def _bouguet_rows(path: Path, metres_per_unit: float) -> list[tuple[str, str]]:
    cal = load_bouguet_calibration(path, metres_per_unit=metres_per_unit)
    rows = [("image [px]", f"{cal.width_px} x {cal.height_px}"), ("K [px]", np.array2string(cal.K, precision=3)),
            ("dist (k1 k2 p1 p2 k3)", np.array2string(cal.dist, precision=5)),
            ("board views", ", ".join(str(i) for i in sorted(cal.views)) or "none")]
    if cal.views:
        d = np.array([np.linalg.norm(v.T_camera_board[:3, 3]) for v in cal.views.values()])
        rows.append(("board origin distance [m]", f"{d.min():.3f} - {d.max():.3f}"))
    return rows


@app.command("calib-show")
def calib_show(
    path: Path = typer.Argument(..., help="OpenCV YAML/XML camera file, WILDTRACK extr_*.xml (with its intr_*.xml), "
                                "EPFL Homography.txt, an EPFL Tsai XML (<Camera> with <Intrinsic focal=...>), a JSON of "
                                "cameras (VoxelPose/Panoptic), or Bouguet toolbox Calib_Results.mat."),
    metres_per_unit: float = typer.Option(1.0, help="Length unit of the file's translations [m] (0.01 for cm, "
                                          "0.001 for mm or a .mat in mm); for an EPFL file, of its top-view units."),
    terrace: bool = typer.Option(None, "--terrace/--topview-units", help="EPFL: convert top-view units with the "
                                 "terrace's metric map, or keep them (default: the map for terrace<k>-c<i> folders)."),
    intrinsics: Path = typer.Option(None, help="Intrinsics file for an extrinsics-only file (default for WILDTRACK "
                                    "extrinsic/extr_<cam>.xml: ../intrinsic/intr_<cam>.xml)."),
    width_px: int = typer.Option(None, help="Image width [px] for files that do not store it."),
    height_px: int = typer.Option(None, help="Image height [px] for files that do not store it."),
) -> None:
    """Print the camera (or ground homography) that planefuse reads from a calibration file."""
    suffix = path.suffix.lower()
    try:
        if not path.is_file():
            raise ValueError(f"{path}: no such file")
        if suffix == ".txt":
            rows = _epfl_rows(path, terrace, metres_per_unit)
        elif suffix == ".mat":
            rows = _bouguet_rows(path, 0.001 if metres_per_unit == 1.0 else metres_per_unit)
        elif suffix == ".json":
            size = (width_px, height_px) if width_px and height_px else None
            rows = []
            for key, cam in load_json_cameras(path, metres_per_unit=metres_per_unit, default_size_px=size).items():
                rows += [(f"{key}: {k}", v) for k, v in _camera_rows(cam, cam.intrinsics)]
        elif suffix == ".xml" and "<Intrinsic" in path.read_text(errors="replace"):
            tsai = load_tsai_xml(path)
            cam, err = pinhole_from_tsai(tsai, metres_per_unit=metres_per_unit, width_px=width_px or None,
                                         height_px=height_px or None)
            rows = [("model", f"Tsai, {tsai.width_px}x{tsai.height_px} px; OpenCV distortion fit within {err:.3f} px")]
            rows += _camera_rows(cam, cam.intrinsics)
        elif suffix in (".xml", ".yaml", ".yml"):
            wild = path.name.startswith("extr_") and path.parent.name == "extrinsic"
            if intrinsics is None and wild:
                intrinsics = path.parent.parent / "intrinsic" / f"intr_{path.name[5:]}"
            if intrinsics is not None:
                cam = load_wildtrack_camera(intrinsics, path, width_px=width_px or 1920, height_px=height_px or 1080)
                rows = _camera_rows(cam, cam.intrinsics)
            else:
                try:
                    cam = load_opencv_camera(path, metres_per_unit=metres_per_unit, width_px=width_px,
                                             height_px=height_px)
                    intr = cam.intrinsics
                except ValueError as exc:
                    if "'rvec': missing" not in str(exc):
                        raise
                    cam, intr = None, load_opencv_intrinsics(path, width_px=width_px, height_px=height_px)
                rows = _camera_rows(cam, intr)
        else:
            raise ValueError(f"{path}: unknown calibration file type {suffix or '(none)'!r}; expected .xml/.yaml "
                             "(OpenCV, Tsai), .json, Homography.txt (EPFL) or .mat (Bouguet)")
    except ValueError as exc:
        hint = "; give --width-px and --height-px" if "'image_width': missing" in str(exc) else ""
        exit_with_error(f"{exc}{hint}", code=1)
    console.print(units_table(str(path), ("quantity", "value"), rows, right=False))
