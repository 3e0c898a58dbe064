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
4. **Uniform views.** One 20x20 camera, two locations whose silhouette is the whole image, location 1 at the
   prior eps, the top rows of the mask foreground (fraction beta). Every image sum is then a fraction of the
   area, and the paper's evidence for location 0, ``Psi(B, A^{0,1}) - Psi(B, A^{0,0})`` with ``A^{0,1} = 1`` and
   ``A^{0,0} = eps``, is ``(1 - beta) - (1 + beta (1 - 2 eps) / eps) = -beta (1 - eps) / eps``: linear in beta.
   POM's, read off its first iterate (``q_1 = 0.8 eps + 0.2 target``, part 1), is compared with it.

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

from planefuse.occupancy import (  # noqa: E402
    GenerativeParams,
    MeanFieldSolver,
    Silhouettes,
    read_pom,
    read_pom_masks,
    write_pom,
)

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


def _evidence(q1: float, prior: float, sigma: float) -> float:
    """The evidence ``sum_c [Psi(B, A^{k,1}) - Psi(B, A^{k,0})]`` behind a first iterate ``q1`` from the prior."""
    target = (q1 - 0.8 * prior) / 0.2
    return sigma * (np.log((1.0 - target) / target) - np.log((1.0 - prior) / prior))


def uniform_views(exe: Path, tmp: Path) -> None:
    print("\n## 4. Uniform views: evidence for a location against the foreground fraction beta\n")
    print("| prior eps | paper's evidence | planefuse's, max abs difference to the paper's | POM's: least-squares "
          "a beta + b beta^2 over beta = 0.1 .. 1 | its largest residual |")
    print("|---|---|---|---|---|")
    n = 20
    sil = Silhouettes(np.array([[[0, 0, n - 1, n - 1]] * 2], np.int32), ((n, n),))
    betas = np.array([0.1, 0.25, 0.5, 0.75, 1.0])
    for prior in (0.05, 0.1, 0.3, 0.5):
        work = tmp / f"uniform-{prior}"
        (work / "masks").mkdir(parents=True)
        (work / "out").mkdir()
        ours, pom = [], []
        for beta in betas:
            # sigma of the order of the evidence: the first iterate stays far from 0 and 1 (POM prints 6 digits)
            sigma = float(2.0 * beta * (1.0 - prior) / prior + 0.2)
            mask = np.zeros((n, n), np.uint8)
            mask[:round(beta * n)] = 255
            cv2.imwrite(str(work / "masks" / "f0-c0.png"), cv2.merge([mask] * 3))  # POM reads RGB
            params = GenerativeParams(prior=prior, sigma=sigma, max_iterations=1, tolerance=0.0)
            pom_file = work / "u.pom"
            write_pom(pom_file, sil, params, input_view_format="masks/f%f-c%c.png", result_format="out/proba-f%f.dat",
                      process=(0, 1))
            pom.append(_evidence(run_pom_program(exe, pom_file, 2, [0], work / "out")[0][0, 0], prior, sigma))
            ours.append(_evidence(MeanFieldSolver(sil, params).solve([mask]).marginals[0], prior, sigma))
        slope = -(1.0 - prior) / prior
        design = np.stack([betas, betas ** 2], 1)
        fit = np.linalg.lstsq(design, np.array(pom), rcond=None)[0]
        print(f"| {prior} | {slope:.3f} beta | {np.abs(np.array(ours) - slope * betas).max():.1e} | "
              f"{fit[0]:.3f} beta {fit[1]:+.3f} beta^2 | {np.abs(design @ fit - pom).max():.1e} |")


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
        uniform_views(exe, tmp)


if __name__ == "__main__":
    main()
