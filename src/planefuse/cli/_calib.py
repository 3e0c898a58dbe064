"""``planefuse calib-show``: read a calibration file with planefuse's loaders and print what they understood."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import typer
from rich.markup import escape
from rich.table import Table

from ..calib import (
    H_WORLD_TOPVIEW_TERRACE,
    load_epfl_homography,
    load_json_cameras,
    load_opencv_camera,
    load_opencv_intrinsics,
    load_tsai_xml,
    pinhole_from_tsai,
)
from ..geometry import roll_pitch_yaw_from_rotation
from ._app import app, console


def _camera_rows(cam, intr) -> list[tuple[str, str]]:
    rows = [("image [px]", f"{intr.width_px} x {intr.height_px}"), ("K [px]", np.array2string(intr.K, precision=3)),
            ("dist (k1 k2 p1 p2 k3)", np.array2string(intr.dist, precision=5))]
    if cam is None:
        rows.append(("extrinsics", "none (intrinsics only)"))
    else:
        rpy = np.degrees(roll_pitch_yaw_from_rotation(cam.R_world_cam))
        rows.append(("centre in world [m]", np.array2string(cam.center_world, precision=3)))
        rows.append(("R_world_cam roll/pitch/yaw [deg]", np.array2string(rpy, precision=2)))
    return rows


@app.command("calib-show")
def calib_show(
    path: Path = typer.Argument(..., help="OpenCV YAML/XML camera file, an EPFL Homography.txt, an EPFL Tsai XML "
                                "(<Camera> with <Intrinsic focal=...>) or a JSON of cameras (VoxelPose/Panoptic)."),
    metres_per_unit: float = typer.Option(1.0, help="Length unit of the file's translations [m] (0.01 for cm, 0.001 "
                                          "for mm)."),
    terrace: bool = typer.Option(False, help="EPFL: convert top-view units with the terrace's metric map."),
    width_px: int = typer.Option(None, help="Image width [px] for files that do not store it."),
    height_px: int = typer.Option(None, help="Image height [px] for files that do not store it."),
) -> None:
    """Print the camera (or ground homography) that planefuse reads from a calibration file."""
    rows: list[tuple[str, str]] = []
    size = (width_px, height_px) if width_px and height_px else None
    try:
        if path.suffix.lower() == ".txt":
            hom = load_epfl_homography(path, H_world_topview=H_WORLD_TOPVIEW_TERRACE if terrace else None)
            rows.append(("H_plane_image", np.array2string(hom.H_plane_image, precision=6)))
            rows.append(("units", "world XY [m] (terrace map)" if terrace else "top-view units (file's own)"))
        elif path.suffix.lower() == ".json":
            cams = load_json_cameras(path, metres_per_unit=metres_per_unit, default_size_px=size)
            for key, cam in cams.items():
                rows += [(f"{key}: {k}", v) for k, v in _camera_rows(cam, cam.intrinsics)]
        elif path.suffix.lower() == ".xml" and "<Intrinsic" in path.read_text(errors="replace"):
            tsai = load_tsai_xml(path)
            cam, err = pinhole_from_tsai(tsai, metres_per_unit=metres_per_unit, width_px=width_px or None,
                                         height_px=height_px or None)
            rows.append(("model", f"Tsai, {tsai.width_px}x{tsai.height_px} px; OpenCV distortion fit within "
                         f"{err:.3f} px"))
            rows += _camera_rows(cam, cam.intrinsics)
        else:
            try:
                cam = load_opencv_camera(path, metres_per_unit=metres_per_unit, width_px=width_px, height_px=height_px)
                intr = cam.intrinsics
            except ValueError as exc:
                if "'rvec': missing" not in str(exc):
                    raise
                cam, intr = None, load_opencv_intrinsics(path, width_px=width_px, height_px=height_px)
            rows += _camera_rows(cam, intr)
    except ValueError as exc:
        console.print(f"[red]error:[/red] {escape(str(exc))}")
        raise typer.Exit(code=1) from None
    table = Table(title=escape(str(path)), show_header=False)
    for key, value in rows:
        table.add_row(escape(key), escape(value))
    console.print(table)

