"""Generative multi-view occupancy speed: planefuse's mean-field solver vs POM (Fleuret et al. 2008) on the same input.

POM, the reference program, is built from ``../shared/reference/pom`` in a temporary folder (GPL: nothing of it
enters planefuse; see ``benchmarks/_pom_reference.py``) and run on the same ``.pom`` file and masks as
``planefuse.occupancy.run_pom``. Both run on one core, frame after frame, reading the PNG masks and writing
``proba-f<frame>.dat``; times are CPU seconds (user + system) per frame of the whole run (POM's includes its
start-up): on a machine shared with other jobs CPU time compares the two where wall time does not.

Cases:

* **POM's demo** (``../shared/data/epfl_pom_test``): 2 cameras of 160x120, 1332 locations, 30 real frames.
* **200 x 200 locations, 4 cameras of 360x288**: ``default_camera_ring`` (10 m room), locations on a 5 cm grid,
  silhouettes from ``silhouettes_from_cameras`` (cylinder 0.25 m x 1.8 m), masks = union of the silhouettes of
  6 random people per frame with 3 % of the pixels flipped; PRIOR 2e-4 (0.08 people per m^2).

Agreement: Pearson of the marginals over all locations and frames, and the fraction of POM's detections
(marginal > 0.5) found by planefuse within one location (Chebyshev distance on the location grid).

Run: ``python benchmarks/bench_occupancy.py [--frames-200 3]``.
"""

from __future__ import annotations

import _single_thread  # noqa: F401  (one core; before numpy)

import argparse
import sys
import tempfile
import time
from pathlib import Path

import cv2
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _pom_reference import agreement, build_pom, demo_pom_file, run_pom_program  # noqa: E402

from planefuse.geometry import default_camera_ring  # noqa: E402
from planefuse.grid import PlaneStack  # noqa: E402
from planefuse.occupancy import (  # noqa: E402
    GenerativeParams,
    PersonVolume,
    read_pom,
    run_pom,
    silhouettes_from_cameras,
    write_pom,
)


def _ours(pom_file: Path, frames) -> tuple[np.ndarray, float, float]:
    cfg = read_pom(pom_file)
    list(run_pom(cfg, frames[:1], write=False))  # numba compilation out of the timing
    t0 = time.process_time()
    res = list(run_pom(cfg, frames))
    dt = (time.process_time() - t0) / len(frames)
    return np.array([r.marginals for _, r in res]), dt, float(np.median([r.n_iterations for _, r in res]))


def _row(name, t_pom, t_ours, its, agree) -> None:
    print(f"| {name} | {1e3 * t_pom:.1f} | {1e3 * t_ours:.1f} | {its:.0f} | **{t_pom / t_ours:.1f}x** | "
          f"{agree['found']}/{agree['pom_detections']} ({100 * agree['found_fraction']:.0f} %) | "
          f"{agree['extra']} | {agree['pearson']:.3f} |")


def case_demo(exe: Path, work: Path) -> None:
    pom_file = demo_pom_file(work)
    frames = list(range(160, 190))
    pom, t_pom = run_pom_program(exe, pom_file, 1332, frames, work / "out")
    ours, t_ours, its = _ours(pom_file, frames)
    _row("POM demo: 2 cameras 160x120, 1332 locations (37 x 36), 30 frames", t_pom / len(frames), t_ours, its,
         agreement(ours, pom, (37, 36)))


def case_large(exe: Path, work: Path, n_frames: int) -> None:
    rng = np.random.default_rng(0)
    cams = default_camera_ring(4)
    stack = PlaneStack.from_extent([0.9], (0, 10), (0, 10), 0.05)
    sil = silhouettes_from_cameras(cams, stack, PersonVolume(radius_m=0.25, height_range_m=(0.0, 1.8)))
    (work / "masks").mkdir()
    (work / "out").mkdir()
    for f in range(n_frames):
        people = rng.choice(np.nonzero(sil.visible.all(0))[0], 6, replace=False)
        for c, (h, w) in enumerate(sil.image_sizes):
            img = np.zeros((h, w), np.uint8)
            for k in people:
                x0, y0, x1, y1 = sil.boxes_px[c, k]
                img[y0:y1 + 1, x0:x1 + 1] = 255
            img[rng.random((h, w)) < 0.03] ^= 255
            cv2.imwrite(str(work / "masks" / f"f{f}-c{c}.png"), img)
    pom_file = work / "large.pom"
    write_pom(pom_file, sil, GenerativeParams(prior=2e-4), input_view_format="masks/f%f-c%c.png",
              result_format="out/proba-f%f.dat", process=(0, n_frames))
    frames = list(range(n_frames))
    pom, t_pom = run_pom_program(exe, pom_file, sil.n_locations, frames, work / "out")
    ours, t_ours, its = _ours(pom_file, frames)
    _row(f"4 cameras 360x288, 200 x 200 locations, {n_frames} frames", t_pom / n_frames, t_ours, its,
         agreement(ours, pom, (stack.ny, stack.nx)))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--frames-200", type=int, default=3, help="frames of the 200 x 200 case (POM: ~5 s each)")
    args = ap.parse_args()
    with tempfile.TemporaryDirectory(prefix="bench-occupancy-") as tmp:
        tmp = Path(tmp)
        exe = build_pom(tmp)
        print("| case | POM ms / frame | planefuse ms / frame | planefuse iterations (median) | speed-up | "
              "POM detections found within 1 location | extra | Pearson |")
        print("|---|---|---|---|---|---|---|---|")
        for name, fn in (("demo", lambda d: case_demo(exe, d)), ("large", lambda d: case_large(exe, d, args.frames_200))):
            d = tmp / name
            d.mkdir()
            fn(d)


if __name__ == "__main__":
    main()
