"""Figures of the terrace experiment on real video (docs/results.md, real-video section).

* ``terrace_views.png``: both views at one frame, the ground-truth boxes (green), the detections of the
  generative camera model projected back as their silhouette boxes (red) and feet (red dot), the ignored
  watermark (hatched);
* ``terrace_fig4.png``: the seed's Fig. 4 on real video: each view's foreground registered on the ground plane
  and on the plane at 1 m, side by side, and their intersection (the product of the two views' likelihoods),
  where the feet (ground plane) and the bodies (1 m) are; ground-truth positions as circles.

The front end runs from ``--first`` up to ``--frame`` (every ``--step``-th frame), as in ``scripts/terrace.py``::

    PYTHONPATH=src python3 scripts/terrace_figures.py --frame 2000 --out docs/figures
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import cv2
import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib.patches import Rectangle  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent))
from terrace import (AREA_X_M, AREA_Y_M, FPS, WATERMARK_PX, ignore_mask, load_base_config,  # noqa: E402
                     merged, terrace_cameras)

from planefuse.calib import load_epfl_boxes  # noqa: E402
from planefuse.config import config_from_dict  # noqa: E402
from planefuse.grid import PlaneStack  # noqa: E402
from planefuse.occupancy import silhouettes_from_cameras  # noqa: E402
from planefuse.vision import (  # noqa: E402
    BackgroundSubtractor,
    GenerativeCameraSensor,
    epfl_ground_truth_from_cameras,
    load_epfl_sequence,
    lookups_from_cameras,
)


def _camera_params():
    """The camera parameters of scripts/terrace.yaml (front end, generative sensor model)."""
    return config_from_dict(merged(load_base_config(), {"recording": "."})).system_params().camera_params


def _frames_and_masks(video_root: Path, first: int, frame: int, step: int):
    cams = terrace_cameras((0, 1))
    fg = _camera_params().foreground
    subs = [BackgroundSubtractor(360, 288, fg, c.name) for c in cams]
    images, masks = [], []
    for c, sub in enumerate(subs):
        cap = cv2.VideoCapture(str(video_root / f"terrace1-c{c}.mp4"))
        like = img = None
        for k in range(frame + 1):
            ok, im = cap.read()
            if not ok:
                raise ValueError(f"terrace1-c{c}.mp4: frame {k} could not be decoded")
            if k >= first and (k - first) % step == 0:
                img, like = im, sub.apply(im)
        cap.release()
        images.append(img)
        masks.append(like)
    return cams, images, masks


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--data", type=Path, default=Path(__file__).resolve().parents[2] / "shared" / "data")
    ap.add_argument("--first", type=int, default=1500)
    ap.add_argument("--frame", type=int, default=2000)
    ap.add_argument("--step", type=int, default=5)
    ap.add_argument("--out", type=Path, default=Path("docs/figures"))
    args = ap.parse_args(argv)
    if (args.frame - args.first) % args.step:
        raise SystemExit("--frame must be --first plus a multiple of --step")
    video_root, pom_root = args.data / "epfl_video", args.data / "epfl_pom" / "EPFL-Terrace"
    cams, images, masks = _frames_and_masks(video_root, args.first, args.frame, args.step)
    ignore = [ignore_mask(c) for c in cams]
    seq = load_epfl_sequence(pom_root, "terrace1")
    _, gt_xy, ign_xy = epfl_ground_truth_from_cameras(seq, terrace_cameras((0, 1, 2, 3)), (0, 1), [args.frame])[
        args.frame]
    # detections of the generative model at this frame (per frame, no filter)
    stack = PlaneStack.from_extent((0.1, 0.5, 1.0, 1.5), AREA_X_M, AREA_Y_M, 0.1)
    sensor = GenerativeCameraSensor(cams, stack, _camera_params().generative, ignore, ["c0", "c1"])
    det = sensor.detections(sensor.marginals(masks), args.frame / FPS, 0.45)
    sil = silhouettes_from_cameras(cams, det.xy_m, sensor.person) if len(det.xy_m) else None
    args.out.mkdir(parents=True, exist_ok=True)

    fig, axes = plt.subplots(1, 2, figsize=(10, 4.2))
    for c, ax in enumerate(axes):
        ax.imshow(cv2.cvtColor(images[c], cv2.COLOR_BGR2RGB))
        b = load_epfl_boxes(pom_root / f"terrace1-c{c}" / "gt" / "gt.txt")
        sel = (b.frame == args.frame) & ~b.lost
        for x0, y0, x1, y1 in b.box_xyxy_px[sel]:
            ax.add_patch(Rectangle((x0, y0), x1 - x0, y1 - y0, fill=False, ec="lime", lw=1.2))
        if sil is not None:
            for x0, y0, x1, y1 in sil.boxes_px[c]:
                if x0 >= 0:
                    ax.add_patch(Rectangle((x0, y0), x1 - x0, y1 - y0, fill=False, ec="red", lw=1.2, ls="--"))
            feet = cams[c].project(np.c_[det.xy_m, np.zeros(len(det.xy_m))])
            ax.plot(feet[:, 0], feet[:, 1], "o", color="red", ms=4)
        u0, v0, u1, v1 = WATERMARK_PX
        ax.add_patch(Rectangle((u0, v0), u1 - u0, v1 - v0, fill=False, ec="white", hatch="//", lw=0.8))
        ax.set_xlim(0, 360)
        ax.set_ylim(288, 0)
        ax.set_title(f"c{c}, frame {args.frame}: ground truth (green), detections (red)", fontsize=9)
        ax.axis("off")
    fig.tight_layout()
    fig.savefig(args.out / "terrace_views.png", dpi=110)
    plt.close(fig)

    # Fig. 4: foreground registered on the ground and on the 1 m plane, per view and intersected
    st = PlaneStack.from_extent((0.0, 1.0), AREA_X_M, AREA_Y_M, 0.05)
    lks = lookups_from_cameras(cams, st, ignore_masks=ignore)
    reg = [lk.gather(m, fill=np.nan) for lk, m in zip(lks, masks)]           # (2, ny, nx) per camera
    both = np.where(np.isfinite(reg[0]) & np.isfinite(reg[1]), np.nan_to_num(reg[0]) * np.nan_to_num(reg[1]), np.nan)
    fig, axes = plt.subplots(2, 3, figsize=(9.5, 8.5))
    extent = (st.x_min_m, st.x_min_m + st.nx * st.cell_size_m, st.y_min_m, st.y_min_m + st.ny * st.cell_size_m)
    for li, name in enumerate(("ground plane (z = 0)", "plane at z = 1 m")):
        for j, (img, title) in enumerate(((reg[0][li], "c0"), (reg[1][li], "c1"), (both[li], "c0 x c1"))):
            ax = axes[li, j]
            ax.imshow(img, origin="lower", extent=extent, cmap="magma", vmin=0, vmax=1)
            ax.plot(gt_xy[:, 0], gt_xy[:, 1], "o", mfc="none", mec="cyan", ms=9, mew=1.2)
            if len(ign_xy):
                ax.plot(ign_xy[:, 0], ign_xy[:, 1], "x", color="grey", ms=7)
            for cam in cams:
                ax.plot(*cam.center_world[:2], "^", color="white", ms=7)
            ax.set_title(f"{title}: {name}", fontsize=9)
            ax.set_xlabel("x [m]", fontsize=8)
            ax.set_ylabel("y [m]", fontsize=8)
            ax.tick_params(labelsize=7)
    fig.suptitle(f"EPFL terrace frame {args.frame}: foreground registered on two planes; "
                 "ground truth (cyan circles), cameras (triangles)", fontsize=9)
    fig.tight_layout()
    fig.savefig(args.out / "terrace_fig4.png", dpi=100)
    plt.close(fig)
    print(f"written {args.out / 'terrace_views.png'} and {args.out / 'terrace_fig4.png'}; "
          f"{len(det.xy_m)} detections, {len(gt_xy)} people")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
