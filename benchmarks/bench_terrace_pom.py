"""POM beside planefuse on the real terrace video: same foreground masks, same silhouettes, same scorer.

POM (Fleuret et al. 2008), the reference program, is built from ``../shared/reference/pom`` in a temporary
folder (GPL: nothing of it enters planefuse; ``benchmarks/_pom_reference.py``). It is fed

* planefuse's own foreground masks of the same frames (the front end of ``scripts/terrace.py``): its likelihoods
  written as grey PNG (POM reads a pixel's grey level / 255 as its foreground probability, as planefuse's solver
  does); the watermark, which POM cannot ignore, is painted background (``pom_row``'s ``ignored_level``),
* one rectangle per ground location (POM's terrace grid, 30 x 44 locations of 25 cm) projected from the same
  Tsai cameras (:func:`planefuse.occupancy.silhouettes_from_cameras`, written by :func:`planefuse.occupancy.write_pom`),
* the same PRIOR and SIGMA_IMAGE_DENSITY as planefuse's mean-field row,

and its ``proba-f<frame>.dat`` marginals become detections exactly as planefuse's (local maxima >= 0.5), scored by
the caller's scorer. POM's time per frame: wall-clock and CPU (its process's user + system time) over the whole
program run (start-up, reading the PNGs and writing the results included), on one core.

Run alone (skips cleanly without g++/make or the POM source)::

    PYTHONPATH=src python3 benchmarks/bench_terrace_pom.py --first 1500 --last 3000 --step 5

or as the POM row of ``scripts/terrace.py --pom``.
"""

from __future__ import annotations

import resource
import shutil
import sys
import tempfile
import time
from pathlib import Path

import cv2
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _pom_reference import build_pom, run_pom_program  # noqa: E402

from planefuse.grid import PlaneStack  # noqa: E402
from planefuse.occupancy import silhouettes_from_cameras, write_pom  # noqa: E402


def pom_row(rec, masks, frames, scorer, out: Path, area_x_m=(-0.5, 7.0), area_y_m=(-1.5, 9.5), cell_m=0.25,
            params=None, person=None, ignored_level: int = 0) -> dict | None:
    """Build and run POM on ``masks`` ((F, H, W) uint8 per camera of ``rec``); ``scorer(detections)`` scores the
    per-frame detections; ``person`` (PersonVolume) shapes the silhouettes; ``ignored_level`` (0-255) is painted
    where the camera's ignore region is (POM has no ignore mask): background (0), chosen on tuning frames 750-1499
    (POM's MODA 0.619 / 0.799 at 0.5 / 1.0 m against -0.180 / -0.121 with 128, which POM's program reads as half a
    person and explains by the locations in front of the cameras, whose clipped boxes cover the watermark). Returns the scores with ``seconds_per_frame``, or
    None (with the reason printed) where POM cannot be built here."""
    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "scripts"))
    from terrace import GENERATIVE, ignore_mask, peaks_from_marginals

    params = params or GENERATIVE
    work = Path(tempfile.mkdtemp(prefix="pom-terrace-"))
    try:
        exe = build_pom(work)
    except RuntimeError as exc:
        shutil.rmtree(work, ignore_errors=True)
        print(f"POM row skipped: {exc}", file=sys.stderr)
        return None
    stack = PlaneStack.from_extent((0.0,), area_x_m, area_y_m, cell_m)
    xy = stack.cell_centers_xy().reshape(-1, 2)
    sil = silhouettes_from_cameras(list(rec.cameras), xy, person)
    (work / "masks").mkdir()
    (work / "result").mkdir()
    for c, cam in enumerate(rec.cameras):
        ign = ignore_mask(cam)
        for k in range(len(frames)):
            m = np.where(ign, np.uint8(ignored_level), masks[c][k])
            cv2.imwrite(str(work / "masks" / f"c{c}-f{k}.png"), m)
    pom_file = work / "terrace.pom"
    write_pom(pom_file, sil, params, input_view_format=str(work / "masks" / "c%c-f%f.png"),
              result_format=str(work / "result" / "proba-f%f.dat"), process=(0, len(frames)),
              comment="EPFL terrace1 c0+c1, planefuse masks (benchmarks/bench_terrace_pom.py)")
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    try:
        q, seconds = run_pom_program(exe, pom_file, sil.n_locations, range(len(frames)), work / "result")
        after = resource.getrusage(resource.RUSAGE_CHILDREN)
    finally:
        shutil.rmtree(work, ignore_errors=True)
    dets = [peaks_from_marginals(qk.reshape(stack.ny, stack.nx), xy) for qk in q]
    scores = scorer(dets)
    cpu_s = (after.ru_utime + after.ru_stime) - (before.ru_utime + before.ru_stime)
    scores.update(seconds_per_frame=seconds / len(frames), pom_wall_s=seconds, cpu_s_per_frame=cpu_s / len(frames))
    np.save(out / "pom_marginals.npy", q)
    return scores


def main(argv=None) -> int:
    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "scripts"))
    import terrace

    args = list(sys.argv[1:] if argv is None else argv)
    return terrace.main(args + ["--rows", "generative", "--pom"])


if __name__ == "__main__":
    raise SystemExit(main())
