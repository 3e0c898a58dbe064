"""Why planefuse's marginals differ from POM's on POM's test data (docs/results.md, "Generative multi-view occupancy").

POM (Fleuret et al. 2008) is built from ``../shared/reference/pom`` in a temporary folder and run as a black box
on ``../shared/data/epfl_pom_test`` (2 real cameras, 1332 locations; nothing of its source is read or enters
planefuse). Frames 160-174 are the tuning frames, 175-189 the held-out ones.

1. **First iterates.** POM with ``MAX_NB_SOLVER_ITERATIONS n`` (n = 1, 2, 5, 10, 20, 40) against planefuse's
   solver stopped after n iterations, on the tuning frames: does the update follow the same path from the
   prior? The damping is read off the first iterate (a location whose target is 1 ends at
   ``damping eps + (1 - damping)``).
2. **Image area.** The tuning frames' masks padded with 160 columns of background (rectangles unchanged): the
   paper's pseudo-distance ``|B (1 - A) + (1 - B) A| / |A|`` does not see pixels where ``A = B = 0``; does POM's?
3. **Held-out frames.** Per frame: Pearson of the marginals, POM's and planefuse's locations above 0.5, and
   planefuse started from POM's final marginals (if it stays there, POM's answer is also a fixed point of the
   paper's update and the two differ only in which fixed point their iterations reach).

Run: ``python scripts/pom_agreement.py``.
"""

from __future__ import annotations

import dataclasses
import sys
import tempfile
from pathlib import Path

import cv2
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
from _pom_reference import POM_TEST_DATA, build_pom, demo_pom_file, run_pom_program  # noqa: E402

from planefuse.occupancy import MeanFieldSolver, read_pom, read_pom_masks  # noqa: E402

TUNE = list(range(160, 175))
HELD_OUT = list(range(175, 190))


def _pom(exe: Path, work: Path, frames, extra=(), images: Path | None = None) -> np.ndarray:
    work.mkdir()
    pom_file = demo_pom_file(work, (frames[0], len(frames)), extra, images=images)
    return run_pom_program(exe, pom_file, 1332, frames, work / "out")[0]


def _ours(cfg, frames, params=None, initial=None) -> np.ndarray:
    solver = MeanFieldSolver(cfg.silhouettes, params or cfg.params)
    return np.array([solver.solve(read_pom_masks(cfg, f), initial=None if initial is None else initial[i]).marginals
                     for i, f in enumerate(frames)])


def first_iterates(exe: Path, tmp: Path, cfg) -> None:
    print("\n## 1. First iterates from the prior (tuning frames 160-174)\n")
    print("| iterations n | POM: largest marginal | max abs difference | Pearson |")
    print("|---|---|---|---|")
    for n in (1, 2, 5, 10, 20, 40):
        pom = _pom(exe, tmp / f"it{n}", TUNE, (f"MAX_NB_SOLVER_ITERATIONS {n}",))
        ours = _ours(cfg, TUNE, dataclasses.replace(cfg.params, max_iterations=n, tolerance=0.0))
        print(f"| {n} | {pom.max():.4f} | {np.abs(ours - pom).max():.4f} | "
              f"{np.corrcoef(ours.ravel(), pom.ravel())[0, 1]:.4f} |")


def image_area(exe: Path, tmp: Path, cfg) -> None:
    print("\n## 2. Masks padded with 160 columns of background (tuning frames, first iterate)\n")
    padded = tmp / "padded_images"
    padded.mkdir()
    for f in TUNE:
        for c in (0, 1):
            name = f"view-f{f}-c{c}.png"
            img = cv2.imread(str(POM_TEST_DATA / "images" / name), cv2.IMREAD_COLOR)
            cv2.imwrite(str(padded / name), np.pad(img, ((0, 0), (0, 160), (0, 0))))
    one = ("MAX_NB_SOLVER_ITERATIONS 1",)
    plain = _pom(exe, tmp / "area_plain", TUNE, one)
    wide = tmp / "area_wide"
    wide.mkdir()
    pom_file = demo_pom_file(wide, (TUNE[0], len(TUNE)), one, images=padded)
    text = pom_file.read_text().replace("CAMERA 0 160 120", "CAMERA 0 320 120").replace("CAMERA 1 160 120",
                                                                                       "CAMERA 1 320 120")
    pom_file.write_text(text)
    pom_wide = run_pom_program(exe, pom_file, 1332, TUNE, wide / "out")[0]
    cfg_wide = read_pom(pom_file)
    p1 = dataclasses.replace(cfg.params, max_iterations=1, tolerance=0.0)
    ours = _ours(cfg, TUNE, p1)
    ours_wide = _ours(cfg_wide, TUNE, p1)
    print("| program | max abs change of the first iterate, 160x120 -> 320x120 masks |")
    print("|---|---|")
    print(f"| POM | {np.abs(pom_wide - plain).max():.4f} |")
    print(f"| planefuse | {np.abs(ours_wide - ours).max():.4f} |")


def held_out(exe: Path, tmp: Path, cfg) -> None:
    print("\n## 3. Held-out frames 175-189, frame by frame\n")
    pom = _pom(exe, tmp / "held_out", HELD_OUT)
    ours = _ours(cfg, HELD_OUT)
    restarted = _ours(cfg, HELD_OUT, initial=pom)
    print("| frame | Pearson | POM > 0.5 | planefuse > 0.5 | planefuse started from POM's marginals: Pearson |")
    print("|---|---|---|---|---|")
    for i, f in enumerate(HELD_OUT):
        print(f"| {f} | {np.corrcoef(ours[i], pom[i])[0, 1]:.3f} | {np.nonzero(pom[i] > 0.5)[0].tolist()} | "
              f"{np.nonzero(ours[i] > 0.5)[0].tolist()} | {np.corrcoef(restarted[i], pom[i])[0, 1]:.3f} |")
    print(f"\nAll held-out frames: Pearson {np.corrcoef(ours.ravel(), pom.ravel())[0, 1]:.3f}; planefuse started "
          f"from POM's marginals: {np.corrcoef(restarted.ravel(), pom.ravel())[0, 1]:.3f}")


def main() -> None:
    with tempfile.TemporaryDirectory(prefix="pom-agreement-") as tmp:
        tmp = Path(tmp)
        try:
            exe = build_pom(tmp)
        except RuntimeError as exc:
            print(f"POM could not be built: {exc}")
            return
        (tmp / "cfg").mkdir()
        cfg = read_pom(demo_pom_file(tmp / "cfg"))
        first_iterates(exe, tmp, cfg)
        image_area(exe, tmp, cfg)
        held_out(exe, tmp, cfg)


if __name__ == "__main__":
    main()
