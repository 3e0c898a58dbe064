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

Timing (whole runs, CPU seconds of user + system, one core each): each repeat runs POM and planefuse on all the
case's frames, one right after the other, the order alternating between repeats, so each repeat gives one
*paired* ratio of two runs minutes apart at most. Reported: the median over repeats of each program's time per
frame, the median and the range of the paired ratio, and each program's spread (max / min over its repeats: what
the machine's noise does to one program's time). Both runs include reading their configuration (POM: its whole
process; planefuse: ``read_pom``, the solver's set-up and the frames), not numba's one-off compilation (done
before timing). The start-up alone (POM on ``PROCESS <first> 0``, planefuse's ``read_pom`` + set-up) is printed
too. ``--breakdown`` adds planefuse's fixed per-frame costs at the demo size (reading the masks, the solver,
writing the result file), measured frame by frame.

Agreement: Pearson of the marginals over all locations and frames, and the fraction of POM's detections
(marginal > 0.5) found by planefuse within one location (Chebyshev distance on the location grid).

Run: ``python benchmarks/bench_occupancy.py [--frames-200 3] [--repeats 5] [--breakdown]``.
"""

from __future__ import annotations

import _single_thread  # noqa: F401  (one core; before numpy)

import argparse
import os
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
    MeanFieldSolver,
    PersonVolume,
    pom_frame_path,
    read_pom,
    run_pom,
    silhouettes_from_cameras,
    write_pom,
    write_pom_result,
)


def _ours(pom_file: Path, frames) -> tuple[np.ndarray, float, float]:
    """planefuse's whole run on ``frames``: CPU seconds (configuration read and solver set-up included)."""
    t0 = time.process_time()
    res = list(run_pom(read_pom(pom_file), frames))
    dt = time.process_time() - t0
    return np.array([r.marginals for _, r in res]), dt, float(np.median([r.n_iterations for _, r in res]))


def _startup(exe: Path, pom_file: Path) -> tuple[float, float]:
    """CPU seconds of the start-up alone: POM on ``PROCESS <first> 0``; planefuse's ``read_pom`` + solver."""
    empty = pom_file.with_name("startup.pom")
    text = pom_file.read_text().splitlines()
    empty.write_text("\n".join(ln if not ln.startswith("PROCESS") else ln.rsplit(" ", 1)[0] + " 0"
                               for ln in text) + "\n")
    _, t_pom = run_pom_program(exe, empty, 0, [], empty.parent)
    t0 = time.process_time()
    MeanFieldSolver(read_pom(pom_file).silhouettes)
    return t_pom, time.process_time() - t0


def compare(exe: Path, name: str, pom_file: Path, frames, grid_shape, repeats: int) -> None:
    """Interleaved repeats of both programs on the same input; one table row."""
    cfg = read_pom(pom_file)
    list(run_pom(cfg, frames[:1], write=False))  # numba compilation out of the timing
    t_pom, t_ours = [], []
    for rep in range(repeats):
        for prog in (("pom", "ours") if rep % 2 == 0 else ("ours", "pom")):
            if prog == "pom":
                pom, t = run_pom_program(exe, pom_file, cfg.silhouettes.n_locations, frames, pom_file.parent / "out")
                t_pom.append(t / len(frames))
            else:
                ours, t, its = _ours(pom_file, frames)
                t_ours.append(t / len(frames))
    t_pom, t_ours = np.array(t_pom), np.array(t_ours)
    ratio = t_pom / t_ours
    agree = agreement(ours, pom, grid_shape)
    s_pom, s_ours = _startup(exe, pom_file)
    print(f"<!-- {name}: paired ratios {' '.join(f'{r:.2f}' for r in ratio)}; load average "
          f"{os.getloadavg()[0]:.1f} -->", file=sys.stderr)
    print(f"| {name} | {repeats} | {1e3 * np.median(t_pom):.1f} ({t_pom.max() / t_pom.min():.2f}) | "
          f"{1e3 * np.median(t_ours):.1f} ({t_ours.max() / t_ours.min():.2f}) | {its:.0f} | "
          f"**{np.median(ratio):.1f}x** ({ratio.min():.1f}-{ratio.max():.1f}) | {1e3 * s_pom:.0f} / {1e3 * s_ours:.0f} | "
          f"{agree['found']}/{agree['pom_detections']} ({100 * agree['found_fraction']:.0f} %) | "
          f"{agree['extra']} | {agree['pearson']:.3f} |", flush=True)


def demo_case(work: Path) -> tuple[Path, list[int], tuple[int, int]]:
    return demo_pom_file(work), list(range(160, 190)), (37, 36)


def large_case(work: Path, n_frames: int) -> tuple[Path, list[int], tuple[int, int]]:
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
    return pom_file, list(range(n_frames)), (stack.ny, stack.nx)


def breakdown(pom_file: Path, frames, repeats: int) -> None:
    """planefuse's per-frame costs, each summed over the frames, fastest of the repeats [ms per frame]."""
    from planefuse.occupancy._pom import _read_grey_masks  # run_pom's reading of the masks

    cfg = read_pom(pom_file)
    solver = MeanFieldSolver(cfg.silhouettes, cfg.params)
    best = {}
    for _ in range(repeats):
        t = {"read masks": 0.0, "solve": 0.0, "write result": 0.0}
        for f in frames:
            t0 = time.process_time()
            masks = _read_grey_masks(cfg, f)
            t1 = time.process_time()
            q = solver.solve(masks).marginals
            t2 = time.process_time()
            write_pom_result(pom_frame_path(cfg, "RESULT_FORMAT", f), q)
            t3 = time.process_time()
            t["read masks"] += t1 - t0
            t["solve"] += t2 - t1
            t["write result"] += t3 - t2
        best = {k: min(v, best.get(k, np.inf)) for k, v in t.items()}
    print("planefuse per frame at this size (fastest of", repeats, "repeats): " +
          ", ".join(f"{k} {1e3 * v / len(frames):.2f} ms" for k, v in best.items()), flush=True)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--frames-200", type=int, default=3, help="frames of the 200 x 200 case (POM: ~6 s each)")
    ap.add_argument("--repeats", type=int, default=5, help="interleaved repeats of both programs per case")
    ap.add_argument("--cases", default="demo,large", help="comma-separated: demo, large")
    ap.add_argument("--breakdown", action="store_true", help="planefuse's per-frame costs at the demo size")
    args = ap.parse_args()
    if args.repeats < 1 or args.frames_200 < 1:
        raise SystemExit("--repeats and --frames-200 must be >= 1")
    print(f"<!-- load average at start {os.getloadavg()[0]:.1f} (other jobs on the machine inflate both programs' "
          f"times; the paired ratios are the numbers to read) -->", file=sys.stderr)
    with tempfile.TemporaryDirectory(prefix="bench-occupancy-") as tmp:
        tmp = Path(tmp)
        exe = build_pom(tmp)
        print("| case | repeats | POM ms / frame, median (max / min) | planefuse ms / frame, median (max / min) | "
              "planefuse iterations (median) | speed-up, median of paired ratios (range) | start-up POM / planefuse "
              "[ms] | POM detections found within 1 location | extra | Pearson |")
        print("|---|---|---|---|---|---|---|---|---|---|")
        for case in args.cases.split(","):
            d = tmp / case
            d.mkdir()
            if case == "demo":
                pom_file, frames, shape = demo_case(d)
                compare(exe, f"POM demo: 2 cameras 160x120, 1332 locations (37 x 36), {len(frames)} real frames",
                        pom_file, frames, shape, args.repeats)
                if args.breakdown:
                    breakdown(pom_file, frames, args.repeats)
            elif case == "large":
                pom_file, frames, shape = large_case(d, args.frames_200)
                compare(exe, f"4 cameras 360x288, 200 x 200 locations, {len(frames)} frames", pom_file, frames,
                        shape, args.repeats)
            else:
                raise SystemExit(f"--cases: unknown case {case!r} (demo, large)")


if __name__ == "__main__":
    main()
