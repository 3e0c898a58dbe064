"""Cost of the YOLOX person detector per frame: OpenCV's DNN module (what planefuse runs) at the model's 416 x 416 and
at the terrace frames' own size (384 x 288 canvas), on one thread and on OpenCV's default threads, and onnxruntime on
the same model and canvas as a reference (same outputs to 1e-4; not a dependency unless it is faster here).

Each row is the median of ``--repeats`` timed calls on real terrace frames (detect: letterbox, forward, decoding and
NMS), all rows in the same run, interleaved::

    PYTHONPATH=src python3 benchmarks/bench_detector.py --model ../shared/models/yolox_nano/yolox_nano.onnx
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import cv2
import numpy as np

from planefuse.vision import YoloxDetector, decode_yolox, letterbox


def frames(video: Path, n: int) -> list[np.ndarray]:
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
    default_threads = cv2.getNumThreads()
    rows = []
    try:
        import onnxruntime as ort
    except ImportError:
        ort = None
    variants = []
    for wh in ((416, 416), (384, 288)):
        for threads in (1, default_threads):
            variants.append(("opencv-dnn", wh, threads))
            if ort is not None and wh == (416, 416):
                variants.append(("onnxruntime", wh, threads))
    times = {v: [] for v in variants}
    dets = {wh: YoloxDetector(args.model, wh) for wh in ((416, 416), (384, 288))}
    sessions = {}
    for _ in range(args.repeats):
        for v in variants:
            engine, wh, threads = v
            if engine == "opencv-dnn":
                cv2.setNumThreads(threads)
                det = dets[wh]
                t0 = time.perf_counter()
                for img in imgs:
                    det.detect(img)
            else:
                if threads not in sessions:
                    so = ort.SessionOptions()
                    so.intra_op_num_threads = threads
                    so.inter_op_num_threads = 1
                    sessions[threads] = ort.InferenceSession(str(args.model), so, providers=["CPUExecutionProvider"])
                sess = sessions[threads]
                name = sess.get_inputs()[0].name
                t0 = time.perf_counter()
                for img in imgs:
                    blob, _ = letterbox(img, wh)
                    decode_yolox(sess.run(None, {name: blob})[0], wh)
            times[v].append((time.perf_counter() - t0) / len(imgs) * 1000)
    cv2.setNumThreads(default_threads)
    print(f"{len(imgs)} terrace c0 frames (360 x 288 px), median of {args.repeats} passes, ms per frame")
    print("| engine | canvas (W x H px) | threads | ms / frame |")
    print("|---|---|---|---|")
    for v in variants:
        engine, wh, threads = v
        print(f"| {engine} | {wh[0]} x {wh[1]} | {threads} | {np.median(times[v]):.1f} |")


if __name__ == "__main__":
    main()
