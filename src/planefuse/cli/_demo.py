"""``planefuse demo``: run the main job on the embedded default scene."""

from __future__ import annotations

import numpy as np
import typer
from rich.table import Table

from ..geometry import H_plane_image_calibrated, default_camera_ring, normalize_homography
from ..grid import PlaneStack
from ..registration import ImagePlaneLookup
from ._app import app, console


@app.command()
def demo(
    heights: str = typer.Option("0,0.5,1.0,1.5", help="Comma-separated plane heights [m]."),
) -> None:
    """Run planefuse on the built-in default scene (no downloads needed)."""
    heights_m = [float(h) for h in heights.split(",")]
    stack = PlaneStack.from_extent(heights_m, (0, 10), (0, 10), 0.05)
    cams = default_camera_ring()
    table = Table(title="Image -> plane homographies: IMU route vs calibration route")
    table.add_column("camera")
    table.add_column("plane z [m]", justify="right")
    table.add_column("max rel. diff", justify="right")
    table.add_column("cells seen", justify="right")
    for cam in cams:
        lut = ImagePlaneLookup.from_camera(cam, stack)
        for l, h in enumerate(heights_m):
            a = normalize_homography(H_plane_image_calibrated(cam, h, route="imu"))
            b = normalize_homography(H_plane_image_calibrated(cam, h, route="projection"))
            table.add_row(cam.name, f"{h:.2f}", f"{np.abs(a - b).max():.1e}", f"{lut.visible[l].mean():.0%}")
    console.print(table)
