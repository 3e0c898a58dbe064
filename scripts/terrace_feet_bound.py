"""A labelled upper bound on terrace (cameras c0 + c1): the annotators' own boxes, each box's foot point on the ground
(:func:`planefuse.vision.box_feet` through the Tsai models), the two views' points merged, scored against the ground
truth as ``scripts/terrace.py`` scores (median of the four cameras' feet, 0.5 and 1.0 m).

Ground-truth boxes are the *input* here: this is not a detection result but the best a per-view detector with perfect
boxes could do through foot points on these two cameras and their calibration. Merging: greedily, points closer than
``--merge`` metres become one (their mean). Per camera alone and both::

    PYTHONPATH=src python3 scripts/terrace_feet_bound.py --first 1500 --last 3000

With ``--person-model FILE`` the same geometry takes that YOLOX model's boxes instead (the library's settings, no
ground truth in the input): what a detector's foot points alone give, beside the bound; the rows with merge radius 0
keep every view's every point (no merging), so their recall at 1.0 m is the most any fusion of these foot points
could find::

    PYTHONPATH=src python3 scripts/terrace_feet_bound.py --first 1500 --last 3000 --merge 0,0.6,1.0 \
        --person-model ../shared/models/yolox_nano/yolox_nano.onnx
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import terrace as T  # noqa: E402
from person_boxes import frames_of  # noqa: E402

from planefuse.calib import load_epfl_boxes  # noqa: E402
from planefuse.vision import ForegroundParams, PersonBoxes, box_feet  # noqa: E402
from planefuse.vision._foreground import PersonDetector  # noqa: E402


def detector_boxes(video: Path, model: Path, frames: np.ndarray) -> dict[int, PersonBoxes]:
    """The boxes a YOLOX model finds in ``frames`` of ``video`` at the library's settings, by frame."""
    det = PersonDetector(ForegroundParams(person_detector="yolox", person_model=str(model)))
    out = {f: det.detect(frame) for f, frame in frames_of(video, [int(x) for x in frames])}
    if len(out) < len(frames):
        raise ValueError(f"{video}: ends before frame {max(frames)}")
    return out


def merged_points(pts: np.ndarray, radius_m: float) -> np.ndarray:
    """Greedy merge: each point with every later one within ``radius_m`` [m] becomes their mean, (K, 2)."""
    out, used = [], np.zeros(len(pts), bool)
    for i in range(len(pts)):
        if used[i]:
            continue
        near = ~used & (np.linalg.norm(pts - pts[i], axis=1) < radius_m)
        out.append(pts[near].mean(axis=0))
        used |= near
    return np.asarray(out).reshape(-1, 2)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--data", type=Path, default=T.REPO.parent / "shared" / "data")
    ap.add_argument("--first", type=int, default=1500)
    ap.add_argument("--last", type=int, default=3000)
    ap.add_argument("--step", type=int, default=5)
    ap.add_argument("--merge", default="0.3,0.6,1.0", help="merge radii [m] (0: no merging)")
    ap.add_argument("--person-model", type=Path, default=None,
                    help="a YOLOX ONNX file: its boxes instead of the annotators' (a detection result, not a bound)")
    args = ap.parse_args()
    pom = args.data / "epfl_pom" / "EPFL-Terrace"
    frames = np.arange(args.first, args.last, args.step)
    truth = T.terrace_truth(pom, frames)
    cams = T.terrace_cameras((0, 1))
    gts = [load_epfl_boxes(pom / f"terrace1-c{c}" / "gt" / "gt.txt") for c in (0, 1)]
    if args.person_model is None:
        print(f"frames {args.first}-{args.last - 1} every {args.step}: the annotators' boxes' foot points (an upper "
              "bound)")

        def boxes_of(c, f):
            sel = (gts[c].frame == f) & ~gts[c].lost
            b = gts[c].box_xyxy_px[sel]
            return PersonBoxes(np.c_[b[:, :2], b[:, 2:] - b[:, :2]], np.ones(len(b)))
    else:
        found = [detector_boxes(args.data / "epfl_video" / f"terrace1-c{c}.mp4", args.person_model, frames)
                 for c in (0, 1)]
        print(f"frames {args.first}-{args.last - 1} every {args.step}: {args.person_model.name}'s boxes' foot points "
              "(a detection result)")

        def boxes_of(c, f):
            return found[c][int(f)]
    print("| views | merge radius (m) | MODA 0.5 m | MODA 1.0 m | precision 0.5 / 1.0 m | recall 0.5 / 1.0 m |")
    print("|---|---|---|---|---|---|")
    for radius in (float(r) for r in args.merge.split(",")):
        for views in ((0,), (1,), (0, 1)):
            dets = []
            for f in frames:
                pts = []
                for c in views:
                    pts += list(box_feet(cams[c], boxes_of(c, f), edge_px=-1.0)[0])
                pts = np.asarray(pts).reshape(-1, 2)
                dets.append(merged_points(pts, radius) if radius > 0 else pts)
            s = T.score(truth, frames, dets)
            print(f"| {' + '.join(f'c{c}' for c in views)} | {radius:g} | {s['moda@0.5']:.3f} | {s['moda@1.0']:.3f} | "
                  f"{s['precision@0.5']:.2f} / {s['precision@1.0']:.2f} | {s['recall@0.5']:.2f} / "
                  f"{s['recall@1.0']:.2f} |")


if __name__ == "__main__":
    main()
