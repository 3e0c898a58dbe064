"""``planefuse calib-show``: read a calibration file with planefuse's loaders and print what they understood."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import typer
from rich.markup import escape
from rich.table import Table

from ..calib import H_WORLD_TOPVIEW_TERRACE, load_epfl_homography, load_opencv_camera, load_opencv_intrinsics
from ..geometry import roll_pitch_yaw_from_rotation
from ._app import app, console


@app.command("calib-show")
def calib_show(
    path: Path = typer.Argument(..., help="OpenCV YAML/XML camera file, or an EPFL Homography.txt."),
    metres_per_unit: float = typer.Option(1.0, help="Length unit of the file's translations [m] (0.01 for cm)."),
    terrace: bool = typer.Option(False, help="EPFL: convert top-view units with the terrace's metric map."),
    width_px: int = typer.Option(None, help="Image width [px] for files that do not store it."),
    height_px: int = typer.Option(None, help="Image height [px] for files that do not store it."),
) -> None:
    """Print the camera (or ground homography) that planefuse reads from a calibration file."""
    rows: list[tuple[str, str]] = []
    try:
        if path.suffix.lower() == ".txt":
            hom = load_epfl_homography(path, H_world_topview=H_WORLD_TOPVIEW_TERRACE if terrace else None)
            rows.append(("H_plane_image", np.array2string(hom.H_plane_image, precision=6)))
            rows.append(("units", "world XY [m] (terrace map)" if terrace else "top-view units (file's own)"))
        else:
            try:
                cam = load_opencv_camera(path, metres_per_unit=metres_per_unit, width_px=width_px, height_px=height_px)
                intr = cam.intrinsics
            except ValueError as exc:
                if "'rvec': missing" not in str(exc):
                    raise
                cam, intr = None, load_opencv_intrinsics(path, width_px=width_px, height_px=height_px)
            rows.append(("image [px]", f"{intr.width_px} x {intr.height_px}"))
            rows.append(("K [px]", np.array2string(intr.K, precision=3)))
            rows.append(("dist (k1 k2 p1 p2 k3)", np.array2string(intr.dist, precision=5)))
            if cam is None:
                rows.append(("extrinsics", "none (intrinsics only)"))
            else:
                rpy = np.degrees(roll_pitch_yaw_from_rotation(cam.R_world_cam))
                rows.append(("centre in world [m]", np.array2string(cam.center_world, precision=3)))
                rows.append(("R_world_cam roll/pitch/yaw [deg]", np.array2string(rpy, precision=2)))
    except ValueError as exc:
        console.print(f"[red]error:[/red] {escape(str(exc))}")
        raise typer.Exit(code=1) from None
    table = Table(title=escape(str(path)), show_header=False)
    for key, value in rows:
        table.add_row(escape(key), escape(value))
    console.print(table)
