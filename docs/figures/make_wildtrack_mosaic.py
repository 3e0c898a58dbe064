"""Make docs/figures/wildtrack_ground_mosaic.png: the real WILDTRACK frames registered on z = 0 and z = 1 m.

Each camera's distorted 1920x1080 frame is registered on the plane stack with ``ImagePlaneLookup.from_camera``
(cell centres projected through the full camera model, lens distortion included) and the views are averaged
where they overlap. On z = 0 the checkerboards lying on the ground coincide; on z = 1 m they split into one
ghost per camera. The third panel overlays C7 (red) on the C1-C6 ground mosaic: its calibration (IDIAP3)
does not register it with the others.

Run: ``PYTHONPATH=src python docs/figures/make_wildtrack_mosaic.py [../shared/data/wildtrack]``
"""

from __future__ import annotations

import sys
from pathlib import Path

import cv2
import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from planefuse.calib import load_wildtrack_rig  # noqa: E402
from planefuse.grid import PlaneStack  # noqa: E402
from planefuse.registration import ImagePlaneLookup  # noqa: E402

HERE = Path(__file__).resolve().parent


def register_rgb(lut: ImagePlaneLookup, rgb: np.ndarray) -> np.ndarray:
    """(L, ny, nx, 3) float32 in [0, 1], NaN where the camera does not see the cell."""
    return np.stack([lut.gather(rgb[..., ch]) for ch in range(3)], axis=-1) / 255.0


def main(root: Path) -> None:
    stack = PlaneStack.from_extent([0.0, 1.0], (-2.0, 9.0), (-3.0, 19.0), 0.02)
    rig = load_wildtrack_rig(root)
    planes = {}
    for name, cam in rig.items():
        bgr = cv2.imread(str(root / "images_or" / f"{name}.jpg"), cv2.IMREAD_COLOR)  # PNG despite the suffix
        planes[name] = register_rgb(ImagePlaneLookup.from_camera(cam, stack), bgr[..., ::-1].astype(np.float32))
    good = np.stack([planes[n] for n in rig if n != "C7"])
    with np.errstate(invalid="ignore"):
        mosaic = np.nanmean(good, axis=0)  # (L, ny, nx, 3)
    mosaic = np.nan_to_num(mosaic, nan=1.0)
    gray0 = mosaic[0].mean(axis=-1)
    c7 = np.nan_to_num(planes["C7"][0].mean(axis=-1), nan=0.0)
    overlay = np.stack([np.maximum(gray0 * 0.6, c7), gray0 * 0.6, gray0 * 0.6], axis=-1)

    fig, axes = plt.subplots(1, 3, figsize=(15, 10), constrained_layout=True)
    titles = [
        "z = 0 (ground): C1-C6 averaged\ncheckerboards coincide",
        "z = 1.0 m: C1-C6 averaged\none ghost per camera",
        "z = 0: C7 (red) over C1-C6\nIDIAP3 calibration does not register",
    ]
    for ax, img, title in zip(axes, [mosaic[0], mosaic[1], overlay], titles):
        ax.imshow(np.clip(img, 0, 1), origin="lower", extent=stack.extent_m, interpolation="nearest")
        for name, cam in rig.items():
            c = cam.center_world
            if stack.extent_m[0] <= c[0] <= stack.extent_m[1] and stack.extent_m[2] <= c[1] <= stack.extent_m[3]:
                ax.plot(c[0], c[1], "c^")
                ax.annotate(name, c[:2], color="c")
        ax.set_title(title)
        ax.set_xlabel("world X [m]")
        ax.set_ylabel("world Y [m]")
    out = HERE / "wildtrack_ground_mosaic.png"
    fig.savefig(out, dpi=80)
    print(f"wrote {out}")


if __name__ == "__main__":
    main(Path(sys.argv[1]) if len(sys.argv) > 1 else HERE.parents[2] / "shared" / "data" / "wildtrack")
