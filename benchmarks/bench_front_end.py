"""The cameras' front end per frame, one core: reading + decoding a frame file, and OpenCV's background subtractors.

Frames: the default scene's ``cam0`` (``planefuse demo``'s, 360x288 BGR), the first ``--frames`` of a ``--duration-s``
simulation (seed 1), written as uncompressed BMP (``planefuse simulate``'s default), stored PNG (zlib level 0), PNG
at level 1 and JPEG 95 by ``cv2.imwrite``, then read back the way a recording is read
(``planefuse.io._streams._read_png``: the file read once, its signature and end checked, ``cv2.imdecode``).

Subtractors: OpenCV's MOG2 and KNN (``cv2.createBackgroundSubtractor*``), contrib's CNT (``cv2.bgsegm``, in
``opencv-contrib-python-headless``, with ``ForegroundParams.method = "cnt"``'s settings) and planefuse's numba
running-average model (``method = "mean"``; :class:`planefuse.vision._mean_background.MeanBackground`,
foreground learnt at 0.2 of the rate), with and without shadow detection, on the full frame, on the frame
reduced by 2 per direction (``cv2.INTER_AREA``, what ``ForegroundParams.downscale = 2`` feeds KNN) and on the grey
frame; each model first learns 10 frames, then ``apply`` is timed at the steady learning rate 1/500. KNN also with
fewer background samples per pixel (``setNSamples``: ``ForegroundParams.knn_samples``, default 7) and with one
matching sample instead of 2 (``setkNNSamples``). Every subtractor once per round, ``--repeats`` rounds, minimum.

CPU time (``time.process_time``), one thread (OpenCV's set to 1), the process pinned to one core.

Usage: ``PYTHONPATH=src python benchmarks/bench_front_end.py [--frames 100] [--duration-s 4] [--repeats 3]``
"""

from __future__ import annotations

import argparse
import os
import tempfile
import time
from pathlib import Path

import cv2
import numpy as np

from planefuse.io._streams import _read_png
from planefuse.sim import default_scene_config, simulate
from planefuse.vision._mean_background import MeanBackground

FORMATS = {  # name -> (suffix, cv2.imwrite parameters)
    "BMP (default)": (".bmp", []),
    "PNG stored (level 0)": (".png", [cv2.IMWRITE_PNG_COMPRESSION, 0]),
    "PNG level 1": (".png", [cv2.IMWRITE_PNG_COMPRESSION, 1]),
    "JPEG 95 (lossy)": (".jpg", [cv2.IMWRITE_JPEG_QUALITY, 95]),
}


def decode_ms(frames: list[np.ndarray], folder: Path) -> dict[str, tuple[int, float, bool]]:
    """Per format: bytes per frame, CPU ms to read + check + decode one, and whether the pixels come back exactly."""
    out = {}
    for k, (name, (suffix, params)) in enumerate(FORMATS.items()):
        paths = [str(folder / f"{k}-{i}{suffix}") for i in range(len(frames))]
        for p, img in zip(paths, frames):
            cv2.imwrite(p, img, params)
        for p in paths:  # the page cache warm, as for a run that reads what was just written
            _read_png(p, cv2.IMREAD_COLOR)
        t0 = time.process_time()
        back = [_read_png(p, cv2.IMREAD_COLOR) for p in paths]
        ms = (time.process_time() - t0) / len(paths) * 1e3
        exact = all(np.array_equal(a, b) for a, b in zip(frames, back))
        out[name] = (os.path.getsize(paths[0]), ms, exact)
    return out


def apply_ms(make, frames: list[np.ndarray]) -> float:
    """CPU ms per ``apply`` of a fresh subtractor from ``make`` (10 frames learnt first)."""
    model = make()
    for f in frames[:10]:
        model.apply(f)
    t0 = time.process_time()
    rate = -1.0 if "CNT" in type(model).__name__ else 1.0 / 500  # CNT's rate scales its stability cap instead
    for f in frames:
        model.apply(f, learningRate=rate)
    return (time.process_time() - t0) / len(frames) * 1e3


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--frames", type=int, default=100)
    ap.add_argument("--duration-s", type=float, default=4.0)
    ap.add_argument("--repeats", type=int, default=3, help="rounds of the subtractors (interleaved), minimum")
    args = ap.parse_args()
    os.sched_setaffinity(0, {min(os.sched_getaffinity(0))})
    cv2.setNumThreads(1)
    rec = simulate(default_scene_config(duration_s=args.duration_s, seed=1))
    stream = rec.camera(rec.cameras[0].name)
    frames = [stream.frame(i) for i in range(min(args.frames, len(stream)))]
    h, w = frames[0].shape[:2]
    print(f"{len(frames)} frames of {stream.name}, {w}x{h} BGR; one core, one OpenCV thread; "
          f"load average {os.getloadavg()[0]:.1f}\n")
    with tempfile.TemporaryDirectory() as tmp:
        rows = decode_ms(frames, Path(tmp))
    print("| frame file | bytes per frame | read + decode [ms per frame] | exact pixels |")
    print("|---|---|---|---|")
    for name, (size, ms, exact) in rows.items():
        print(f"| {name} | {size} | {ms:.3f} | {'yes' if exact else 'no'} |")
    half = [cv2.resize(f, (w // 2, h // 2), interpolation=cv2.INTER_AREA) for f in frames]
    grey = [cv2.cvtColor(f, cv2.COLOR_BGR2GRAY) for f in frames]
    subtractors = {
        "KNN (default), shadows": lambda: cv2.createBackgroundSubtractorKNN(500, 400.0, True),
        "KNN, no shadows": lambda: cv2.createBackgroundSubtractorKNN(500, 400.0, False),
        "KNN, 5 samples per pixel": lambda: _knn(n_samples=5),
        "KNN, 3 samples per pixel (knn_samples: 3)": lambda: _knn(n_samples=3),
        "KNN, 1 matching sample (kNNSamples 1)": lambda: _knn(knn=1),
        "mean (numba running average), shadows": lambda: MeanBackground(400.0, 500, True, 0.2),
        "mean, no shadows": lambda: MeanBackground(400.0, 500, False, 0.2),
        "CNT (contrib; grey inside)": lambda: cv2.bgsegm.createBackgroundSubtractorCNT(15, True, 500, True),
        "MOG2, shadows": lambda: cv2.createBackgroundSubtractorMOG2(500, 16.0, True),
        "MOG2, no shadows": lambda: cv2.createBackgroundSubtractorMOG2(500, 16.0, False),
    }
    others = sorted(a for a in dir(cv2) if a.startswith("createBackgroundSubtractor")) + \
        (sorted(a for a in dir(cv2.bgsegm) if a.startswith("create")) if hasattr(cv2, "bgsegm") else [])
    print(f"\nOpenCV {cv2.__version__}: {', '.join(others)}\n")
    inputs = {"full": frames, "half": half, "grey": grey}
    ms: dict[tuple[str, str], list[float]] = {}
    for _ in range(args.repeats):
        for name, make in subtractors.items():
            for kind, data in inputs.items():
                ms.setdefault((name, kind), []).append(apply_ms(make, data))
    print(f"| subtractor | full {w}x{h} [ms per frame] | 1/2 resolution [ms] | grey [ms] |")
    print("|---|---|---|---|")
    for name in subtractors:
        print(f"| {name} | " + " | ".join(f"{min(ms[name, kind]):.2f}" for kind in inputs) + " |")
    print(f"\nmin of {args.repeats} interleaved rounds; load average at the end {os.getloadavg()[0]:.1f}")


def _knn(n_samples: int = 7, knn: int = 2):
    """OpenCV's default KNN subtractor with ``n_samples`` samples per pixel, ``knn`` of which must match."""
    model = cv2.createBackgroundSubtractorKNN(500, 400.0, True)
    model.setNSamples(n_samples)
    model.setkNNSamples(knn)
    return model

if __name__ == "__main__":
    main()
