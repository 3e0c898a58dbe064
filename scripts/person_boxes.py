"""Per-camera person detection on the EPFL terrace video against the EPFL boxes (recall, precision at IoU 0.5).

Runs a YOLOX ONNX model (:class:`planefuse.vision.YoloxDetector`) on cameras c0 and c1, frames ``--first`` to
``--last`` every ``--step``-th, and matches its boxes to the visible ground-truth boxes of the same frame (greedy by
score, IoU >= 0.5; Hungarian matching gives the same counts to within a box here). Ground-truth boxes are never the
detector's input. Hold-out: choose on frames 0-1499, report 1500-2999::

    PYTHONPATH=src python3 scripts/person_boxes.py --model ../shared/models/yolox_nano/yolox_nano.onnx \\
        --first 0 --last 1500 --step 25 --scores 0.2,0.3,0.4,0.5 --sizes 416x416,384x288
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import cv2
import numpy as np

from planefuse.calib import load_epfl_boxes
from planefuse.vision import YoloxDetector


def iou(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """IoU of (N, 4) and (M, 4) ``x0 y0 x1 y1`` boxes, (N, M)."""
    lt = np.maximum(a[:, None, :2], b[None, :, :2])
    rb = np.minimum(a[:, None, 2:], b[None, :, 2:])
    inter = np.prod(np.clip(rb - lt, 0, None), axis=2)
    area = lambda x: np.prod(x[:, 2:] - x[:, :2], axis=1)  # noqa: E731
    return inter / (area(a)[:, None] + area(b)[None, :] - inter)


def match_counts(det_xyxy: np.ndarray, gt_xyxy: np.ndarray, threshold: float = 0.5) -> int:
    """True positives of a greedy one-to-one matching of detections (in score order) to ground truth."""
    if not len(det_xyxy) or not len(gt_xyxy):
        return 0
    m = iou(det_xyxy, gt_xyxy)
    used = np.zeros(len(gt_xyxy), bool)
    tp = 0
    for i in range(len(det_xyxy)):
        cand = np.where(~used, m[i], -1.0)
        j = int(np.argmax(cand))
        if cand[j] >= threshold:
            used[j], tp = True, tp + 1
    return tp


def frames_of(video: Path, wanted: list[int]):
    cap = cv2.VideoCapture(str(video))
    want, f = set(wanted), 0
    while want:
        ok = cap.grab()
        if not ok:
            break
        if f in want:
            yield f, cap.retrieve()[1]
            want.discard(f)
        f += 1


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--data", type=Path, default=Path(__file__).resolve().parents[1].parent / "shared" / "data")
    ap.add_argument("--model", type=Path, required=True)
    ap.add_argument("--first", type=int, default=1500)
    ap.add_argument("--last", type=int, default=3000)
    ap.add_argument("--step", type=int, default=25)
    ap.add_argument("--scores", default="0.3")
    ap.add_argument("--sizes", default="416x416")
    ap.add_argument("--nms-iou", type=float, default=0.45)
    args = ap.parse_args()
    cv2.setNumThreads(1)
    frames = list(range(args.first, args.last, args.step))
    scores = [float(s) for s in args.scores.split(",")]
    print(f"frames {args.first}-{args.last - 1} every {args.step} ({len(frames)}), cameras c0 c1, IoU 0.5")
    print("| input (W x H px) | min score | recall | precision | GT boxes | ms / frame (1 core) |")
    print("|---|---|---|---|---|---|")
    for size in args.sizes.split(","):
        wh = tuple(int(v) for v in size.split("x"))
        det = YoloxDetector(args.model, wh, min_score=min(scores), nms_iou=args.nms_iou)
        tp = {s: 0 for s in scores}
        n_det = {s: 0 for s in scores}
        n_gt, secs, n_frames = 0, 0.0, 0
        for cam in ("c0", "c1"):
            gt = load_epfl_boxes(args.data / "epfl_pom" / "EPFL-Terrace" / f"terrace1-{cam}" / "gt" / "gt.txt")
            for f, img in frames_of(args.data / "epfl_video" / f"terrace1-{cam}.mp4", frames):
                sel = (gt.frame == f) & ~gt.lost
                g = gt.box_xyxy_px[sel]
                t0 = time.perf_counter()
                boxes = det.detect(img)
                secs += time.perf_counter() - t0
                n_frames += 1
                n_gt += len(g)
                xyxy = np.c_[boxes.ltwh_px[:, :2], boxes.ltwh_px[:, :2] + boxes.ltwh_px[:, 2:]]
                for s in scores:
                    k = boxes.score >= s
                    tp[s] += match_counts(xyxy[k], g)
                    n_det[s] += int(k.sum())
        for s in scores:
            print(f"| {wh[0]} x {wh[1]} | {s:.2f} | {tp[s] / max(n_gt, 1):.3f} | {tp[s] / max(n_det[s], 1):.3f} | "
                  f"{n_gt} | {1000 * secs / max(n_frames, 1):.1f} |")


if __name__ == "__main__":
    main()
