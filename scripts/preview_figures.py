"""The pictures of ``planefuse check --figures`` for the docs: EPFL terrace (c0, c1) and WILDTRACK's 7 calibration
frames, as small PNGs in ``docs/figures/`` (docs/tutorial.md, docs/cameras.md).

The terrace pictures are those ``planefuse check my-terrace/recording --figures DIR`` writes for the tutorial's
recording (a few frames imported here the tutorial's way); WILDTRACK has no video to import, so its cameras
(``planefuse.calib.load_wildtrack_rig``) and frames are drawn by the same library functions
(:func:`planefuse.viz.plot_camera_preview`, :func:`planefuse.viz.plot_coverage`) over the data set's annotation
area (x -3..9 m, y -9..27 m). Example::

    PYTHONPATH=src python3 scripts/preview_figures.py --data ../shared/data --out docs/figures
"""

from __future__ import annotations

import argparse
import io
import sys
import tempfile
from pathlib import Path

import numpy as np

from planefuse.grid import PlaneStack
from planefuse.io import read_recording
from planefuse.pipeline import SystemParams, stack_for_recording
from planefuse.registration import camera_view_findings, cameras_per_cell
from planefuse.viz import installation_preview, plot_camera_preview, plot_coverage, png_bytes

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO / "scripts"))

#: WILDTRACK's annotation grid (its README): 12 m x 36 m from (-3, -9) m.
WILDTRACK_AREA_M = ((-3.0, 9.0), (-9.0, 27.0))
#: The WILDTRACK cameras drawn for the docs (C7: the camera whose shipped calibration does not fit its frame).
WILDTRACK_DOC_CAMERAS = ("C1", "C5", "C7")


def small_png(png: bytes, width_px: int = 480) -> bytes:
    """``png`` scaled to ``width_px`` wide and quantised to 128 colours (a docs-sized file)."""
    from PIL import Image

    im = Image.open(io.BytesIO(png)).convert("RGB")
    im = im.resize((width_px, round(im.height * width_px / im.width)), Image.LANCZOS)
    out = io.BytesIO()
    im.quantize(128, method=Image.Quantize.MEDIANCUT).save(out, format="PNG", optimize=True)
    return out.getvalue()


def terrace(data: Path, out: Path) -> None:
    """The tutorial's recording (frames 1500-1595 every 5th), its check pictures."""
    from terrace import import_terrace

    with tempfile.TemporaryDirectory() as tmp:
        rec = read_recording(import_terrace(Path(tmp), data, np.arange(1500, 1600, 5)))
        stack = stack_for_recording(rec, SystemParams(x_range_m=tuple(rec.room_xy_m[:2]),
                                                      y_range_m=tuple(rec.room_xy_m[2:])))
        for level, subject, message in camera_view_findings(rec.cameras, stack):
            print(f"terrace {level}: {subject}: {message}")
        for stem, png in installation_preview(rec, stack, frame_index=10).items():
            (out / f"check_terrace_{stem}.png").write_bytes(small_png(png))


def wildtrack(data: Path, out: Path) -> None:
    """WILDTRACK's 7 cameras on their calibration frames; the coverage map of the annotation area."""
    import cv2

    from planefuse.calib import load_wildtrack_rig

    root = data / "wildtrack"
    rig = load_wildtrack_rig(root)
    (x0, x1), (y0, y1) = WILDTRACK_AREA_M
    stack = PlaneStack.from_extent(SystemParams().heights_m, (x0, x1), (y0, y1), 0.25)
    for level, subject, message in camera_view_findings(list(rig.values()), stack):
        print(f"wildtrack {level}: {subject}: {message}")
    for name in WILDTRACK_DOC_CAMERAS:
        cam = rig[name]
        img = cv2.imread(str(root / "images_or" / f"{name}.jpg"), cv2.IMREAD_COLOR)[..., ::-1]
        fig = plot_camera_preview(cam, stack, img, title="calibration frame")
        (out / f"check_wildtrack_camera_{name}.png").write_bytes(small_png(png_bytes(fig, 100)))
    ground = PlaneStack(stack.heights_m[:1], stack.x_min_m, stack.y_min_m, stack.cell_size_m, stack.nx, stack.ny)
    counts = cameras_per_cell(list(rig.values()), ground)[0]
    fig = plot_coverage(list(rig.values()), ground, counts, title="WILDTRACK, plane z = 0.1 m")
    (out / "check_wildtrack_coverage.png").write_bytes(small_png(png_bytes(fig, 100)))


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--data", type=Path, default=REPO.parent / "shared" / "data")
    ap.add_argument("--out", type=Path, default=REPO / "docs" / "figures")
    ap.add_argument("--only", choices=("terrace", "wildtrack"), default=None)
    args = ap.parse_args(argv)
    args.out.mkdir(parents=True, exist_ok=True)
    if args.only in (None, "terrace"):
        terrace(args.data, args.out)
    if args.only in (None, "wildtrack"):
        wildtrack(args.data, args.out)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
