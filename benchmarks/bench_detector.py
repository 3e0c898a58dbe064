"""Cost of the YOLOX person detector per frame, with each engine planefuse runs it by (``person_engine``: OpenCV's
DNN module, ONNX Runtime where installed) at the model's 416 x 416 and at the canvas fitted to the terrace frames
(384 x 288), on one thread and on the machine's default threads.

Each row is the median of ``--repeats`` passes over real terrace frames (the whole ``YoloxDetector.detect``:
letterbox, forward, decoding and NMS), all rows in the same run, interleaved::

    PYTHONPATH=src python3 benchmarks/bench_detector.py --model ../shared/models/yolox_nano/yolox_nano.onnx
"""

from __future__ import annotations

import argparse
import importlib.util
import os
import time
from pathlib import Path

import cv2
import numpy as np

from planefuse.vision import YoloxDetector


def frames(video: Path, n: int) -> list[np.ndarray]:
    """``n`` frames of ``video`` from frame 1500, one a second."""
    cap = cv2.VideoCapture(str(video))
    out = []
    for i in range(0, 25 * n, 25):
        cap.set(cv2.CAP_PROP_POS_FRAMES, 1500 + i)
        ok, f = cap.read()
        if ok:
            out.append(f)
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--model", type=Path, required=True)
    ap.add_argument("--data", type=Path, default=Path(__file__).resolve().parents[1].parent / "shared" / "data")
    ap.add_argument("--repeats", type=int, default=5)
    args = ap.parse_args()
    imgs = frames(args.data / "epfl_video" / "terrace1-c0.mp4", 10)
    default_threads = os.cpu_count() or 1
    engines = ["opencv"] + (["onnxruntime"] if importlib.util.find_spec("onnxruntime") else [])
    variants = [(e, wh, t) for wh in ((416, 416), (384, 288)) for e in engines for t in sorted({1, default_threads})]
    dets = {v: YoloxDetector(args.model, v[1], engine=v[0], threads=v[2]) for v in variants}
    times = {v: [] for v in variants}
    for _ in range(args.repeats):
        for v in variants:
            cv2.setNumThreads(v[2])  # OpenCV's DNN module: process-wide; ONNX Runtime: its session's own
            det = dets[v]
            t0 = time.perf_counter()
            for img in imgs:
                det.detect(img)
            times[v].append((time.perf_counter() - t0) / len(imgs) * 1000)
    print(f"{len(imgs)} terrace c0 frames (360 x 288 px), median of {args.repeats} passes, ms per frame; "
          f"load average {os.getloadavg()[0]:.1f}")
    print("| engine | canvas (W x H px) | threads | ms / frame |")
    print("|---|---|---|---|")
    for v in variants:
        engine, wh, threads = v
        print(f"| {engine} | {wh[0]} x {wh[1]} | {threads} | {np.median(times[v]):.1f} |")


if __name__ == "__main__":
    main()
