"""POM (Fleuret et al. 2008), the reference program, built and run as an external baseline.

POM is GPL: its source (``../shared/reference/pom``) is copied to a temporary folder, patched for libpng >= 1.5
with the patch shipped beside it, built there with ``make`` and run on ``.pom`` files; nothing of it enters
planefuse. Used by ``benchmarks/bench_occupancy.py``, ``scripts/pom_agreement.py`` and the real-data test of
``tests/test_occupancy_pom.py``.
"""

from __future__ import annotations

import resource
import shutil
import subprocess
import tempfile
from pathlib import Path

import numpy as np

POM_SOURCE = Path(__file__).resolve().parents[1].parent / "shared" / "reference" / "pom"
POM_TEST_DATA = Path(__file__).resolve().parents[1].parent / "shared" / "data" / "epfl_pom_test"


def build_pom(workdir: str | Path | None = None) -> Path:
    """Build POM in ``workdir`` (a new temporary folder by default); return the program's path.

    Raises
    ------
    RuntimeError
        The source is absent, or the patch or the build fails (with the tool's last output lines).
    """
    if not (POM_SOURCE / "pom.cc").is_file():
        raise RuntimeError(f"POM source not found at {POM_SOURCE}")
    if shutil.which("make") is None or shutil.which("g++") is None:
        raise RuntimeError("make and g++ are needed to build POM")
    work = Path(workdir) if workdir is not None else Path(tempfile.mkdtemp(prefix="pom-build-"))
    src = work / "pom-src"
    shutil.copytree(POM_SOURCE, src, dirs_exist_ok=True)
    for cmd in (["patch", "-p0", "-N", "-i", "libpng16.patch"], ["make"]):
        r = subprocess.run(cmd, cwd=src, capture_output=True, text=True)
        if r.returncode != 0 and not (cmd[0] == "patch" and "previously applied" in r.stdout):
            raise RuntimeError(f"building POM: {' '.join(cmd)} failed: {(r.stdout + r.stderr)[-600:]}")
    exe = src / "pom"
    if not exe.is_file():
        raise RuntimeError(f"building POM: no program at {exe}")
    return exe


def run_pom_program(exe: Path, pom_file: Path, n_locations: int, frames, result_dir: Path) -> tuple[np.ndarray, float]:
    """Run POM on ``pom_file`` (whose RESULT_FORMAT writes ``result_dir/proba-f%f.dat``).

    Returns
    -------
    marginals : ndarray, shape (F, K)
        POM's ``proba-f<frame>.dat`` of every frame, in order.
    seconds : float
        CPU time (user + system) of the whole run [s] (program start, reading masks and writing results
        included): on a machine shared with other jobs, CPU time compares programs where wall time does not.
    """
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    r = subprocess.run([str(exe), str(pom_file)], cwd=pom_file.parent, capture_output=True, text=True)
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    seconds = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    if r.returncode != 0:
        raise RuntimeError(f"POM failed on {pom_file}: {(r.stdout + r.stderr)[-600:]}")
    out = np.zeros((len(frames), n_locations))
    for i, f in enumerate(frames):
        data = np.loadtxt(result_dir / f"proba-f{f}.dat", ndmin=2)
        out[i, data[:, 0].astype(int)] = data[:, 1]
    return out, seconds


def demo_pom_file(work: Path, frames=(160, 30), extra: tuple[str, ...] = (), data: Path = POM_TEST_DATA,
                  images: Path | None = None) -> Path:
    """POM's own ``test.pom`` (from ``data``) in ``work``, made runnable: sizes through CAMERA lines (this mirror
    refuses a fixed ROOM size, its SOURCE.md), results to ``work/out/proba-f%f.dat``, ``PROCESS`` from ``frames``
    (first, count), ``extra`` keyword lines added, masks from ``images`` (default ``data/images``), linked as
    ``work/images``."""
    src = (data / "test.pom").read_text().replace(
        "ROOM 160 120 2 1332", "ROOM -1 -1 2 1332\nCAMERA 0 160 120\nCAMERA 1 160 120")
    lines = [ln for ln in src.splitlines() if not ln.startswith(("RESULT_VIEW_FORMAT", "RESULT_FORMAT", "PROCESS"))]
    if not (work / "images").exists():
        (work / "images").symlink_to(images or (data / "images"))
    (work / "out").mkdir(exist_ok=True)
    pom_file = work / "demo.pom"
    pom_file.write_text("\n".join(lines + ["RESULT_FORMAT out/proba-f%f.dat", *extra,
                                           f"PROCESS {frames[0]} {frames[1]}"]) + "\n")
    return pom_file


def agreement(ours: np.ndarray, pom: np.ndarray, grid_shape: tuple[int, int], threshold: float = 0.5) -> dict:
    """Agreement of two sets of marginals (F, K) on a location grid ``(rows, cols)`` (K = rows * cols).

    Detections are locations with a marginal above ``threshold``; a POM detection is *found* where planefuse
    has a detection within one location (Chebyshev distance <= 1 on the grid) in the same frame.
    """
    rows, cols = grid_shape
    found = total = extra = 0
    for a, b in zip(ours, pom):
        da = np.argwhere(a.reshape(rows, cols) > threshold)
        db = np.argwhere(b.reshape(rows, cols) > threshold)
        total += len(db)
        if len(db) and len(da):
            d = np.abs(db[:, None, :] - da[None, :, :]).max(-1)
            found += int((d.min(1) <= 1).sum())
            extra += int((d.min(0) > 1).sum())
        else:
            extra += len(da)
    r = float(np.corrcoef(ours.ravel(), pom.ravel())[0, 1])
    return {"pom_detections": total, "found": found, "found_fraction": found / max(total, 1),
            "extra": extra, "pearson": r}
