"""Mutation testing of planefuse's core: plant one bug at a time in a temporary copy of the repository, run the
test files that should notice it, and report which mutations the tests kill and which survive.

Usage::

    PYTHONPATH=src python3 scripts/mutate.py                  # every mutation, Markdown table on stdout
    PYTHONPATH=src python3 scripts/mutate.py --only BOF-1,EVAL-1 --timeout-s 300
    PYTHONPATH=src python3 scripts/mutate.py --list

The working tree is never modified: the tracked and untracked (not ignored) files are copied to a temporary
folder, each mutation edits the copy's file, the tests run there (``PYTHONPATH`` = the copy's ``src``; the
copy sees ``../shared`` through a link, so the real-data tests run too) and the file is restored. A mutation
whose original text is not found exactly once is an error (the code moved on: update the mutation).

The unmutated test files must pass first (``--no-baseline`` skips that check). A mutation is *killed* when
its tests fail or time out, *survived* when they pass. docs/testing.md holds the table and the reason why
each survivor is harmless.
"""

from __future__ import annotations

import argparse
import os
import re
import shutil
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

GEOMETRY = ("tests/test_geometry_core.py", "tests/test_lookup_gather.py", "tests/test_vision.py")
BOF = ("tests/test_tracking_bof.py", "tests/test_tracking_bof_oracles.py", "tests/test_tracking_tracker.py",
       "tests/test_system_accuracy.py")
EVAL = ("tests/test_eval_detection.py", "tests/test_eval_tracking.py")
AUDIO = ("tests/test_audio_localize.py", "tests/test_audio_simulate.py", "tests/test_system_accuracy.py")
VISION = ("tests/test_vision.py", "tests/test_system_accuracy.py")
PIPELINE = ("tests/test_tracking_async.py", "tests/test_pipeline.py", "tests/test_system_accuracy.py")
PINNED = ("tests/test_tracking_pinned_rules.py",)  # the tracker's documented rules as exact cases (issue 39)


@dataclass(frozen=True)
class Mutation:
    """One planted bug: ``old`` (found exactly once in ``path``) replaced by ``new``."""

    id: str
    module: str
    path: str
    old: str
    new: str
    what: str
    tests: tuple[str, ...]


M = Mutation
MUTATIONS = [
    # -- geometry ------------------------------------------------------------------------------------------------
    M("GEO-1", "geometry", "src/planefuse/geometry/_transforms.py",
      'out[..., :3, 3] = -np.einsum("...ij,...j->...i", Rt, t)', 'out[..., :3, 3] = np.einsum("...ij,...j->...i", Rt, t)',
      "invert_transform: translation sign flipped", GEOMETRY),
    M("GEO-2", "geometry", "src/planefuse/geometry/_transforms.py",
      "Rt = np.swapaxes(R, -1, -2)", "Rt = R", "invert_transform: rotation not transposed", GEOMETRY),
    M("GEO-3", "geometry", "src/planefuse/geometry/_camera.py",
      "radial = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3))", "radial = 1.0 + r2 * (k1 + r2 * (k2 - r2 * k3))",
      "distortion: k3 term sign flipped", GEOMETRY),
    M("GEO-4", "geometry", "src/planefuse/geometry/_camera.py",
      "K[0, 0] * xy[..., 0] + K[0, 1] * xy[..., 1] + K[0, 2]", "K[0, 0] * xy[..., 0] + K[0, 2]",
      "pixels_from_normalized: skew K[0, 1] dropped", GEOMETRY),
    M("GEO-5", "geometry", "src/planefuse/geometry/_camera.py",
      "uv[z <= 0] = np.nan", "pass", "project: points behind the camera get an image", GEOMETRY),
    M("GEO-6", "geometry", "src/planefuse/geometry/_camera.py",
      "s = (height_m - c[2]) / d[..., 2]", "s = (c[2] - height_m) / d[..., 2]",
      "backproject_to_height: ray parameter sign flipped", GEOMETRY),
    M("GEO-7", "geometry", "src/planefuse/geometry/_homography.py",
      "out = ph[..., :2] / w", "out = ph[..., :2] / 1.0", "apply_homography: no division by w", GEOMETRY),
    M("GEO-8", "geometry", "src/planefuse/geometry/_homography.py",
      "H[..., :, 2] = h[..., None] * P[:, 2] + P[:, 3]", "H[..., :, 2] = h[..., None] * P[:, 2] - P[:, 3]",
      "H_image_plane_from_projection: translation column sign flipped", GEOMETRY),
    M("GEO-9", "geometry", "src/planefuse/geometry/_homography.py",
      "return d0 / dh", "return dh / d0", "mu_from_heights: cross-ratio inverted", GEOMETRY),
    M("GEO-10", "geometry", "src/planefuse/geometry/_homography.py",
      "flip = np.array([[1.0, 0.0, c[0]], [0.0, -1.0, c[1]]", "flip = np.array([[1.0, 0.0, c[0]], [0.0, 1.0, c[1]]",
      "H_world_refview: Y axis not flipped", GEOMETRY),
    # -- Bayesian occupancy filter -------------------------------------------------------------------------------
    M("BOF-1", "BOF", "src/planefuse/tracking/_bof.py",
      "p_mix / np.maximum(n_nb[np.maximum(nbr, 0)], 1)", "p_mix / 4.0",
      "velocity mixing leaks mass from edge/corner hypotheses (issue 21)", BOF),
    M("BOF-2", "BOF", "src/planefuse/tracking/_bof.py",
      "lam = min(max(lam, min(-max_posterior - prior, 0.0)), max(max_posterior - prior, 0.0))", "pass",
      "posterior log-odds clip dropped (issue 21)", BOF),
    M("BOF-3", "BOF", "src/planefuse/tracking/_bof.py",
      "lam = min(max(log_odds[l, iy, ix], -max_log_odds), max_log_odds)", "lam = log_odds[l, iy, ix]",
      "per-update log-odds clip dropped", BOF),
    M("BOF-4", "BOF", "src/planefuse/tracking/_bof.py",
      "x0 + 1])\n                        hat[k, iy, ix] = s_occ * a + s_app * b",
      "x0 + 1])\n                        hat[k, iy, ix] = s_occ * a + s_dis * b",
      "bilinear prediction: appearance uses p_dis", BOF),
    M("BOF-5", "BOF", "src/planefuse/tracking/_bof.py",
      "return params.prior_occupancy * q, (1.0 - params.prior_occupancy) * q, p_mix",
      "return params.prior_occupancy * q, params.prior_occupancy * q, p_mix",
      "transition: p_dis = p_app (wrong stationary law)", BOF),
    M("BOF-6", "BOF", "src/planefuse/tracking/_bof.py",
      "back = -d", "back = d", "prediction: antecedent on the wrong side (motion reversed)", BOF),
    M("BOF-7", "BOF", "src/planefuse/tracking/_bof.py",
      "free[l, iy, ix] = f * e * z", "free[l, iy, ix] = f * z", "update (lam >= 0): free not scaled", BOF),
    M("BOF-8", "BOF", "src/planefuse/tracking/_bof.py",
      "fsrc[pad:pad + ny, pad:pad + nx] = free[l] * invK", "fsrc[pad:pad + ny, pad:pad + nx] = free[l]",
      "prediction: free mass not split over the K hypotheses", BOF),
    M("BOF-9", "BOF", "src/planefuse/tracking/_bof.py",
      "a_out = np.float32(prior / K)", "a_out = np.float32(prior)",
      "prediction: outside-the-grid antecedents hold K times the prior", BOF),
    M("BOF-10", "BOF", "src/planefuse/tracking/_bof.py",
      "vel[l, iy, ix, 1] += m * vy", "vel[l, iy, ix, 1] += m * vx", "moments: vy from vx", BOF),
    M("BOF-11", "BOF", "src/planefuse/tracking/_bof.py",
      "w01 = (1 - wy1) * wx1", "w01 = wy1 * (1 - wx1)", "bilinear read: weights of two corners swapped", BOF),
    # -- matcher and metrics -------------------------------------------------------------------------------------
    M("EVAL-1", "eval", "src/planefuse/eval/_detection.py",
      "big = match_distance_m * (min(len(g), len(d)) + 1)", "big = match_distance_m",
      "Hungarian matching no longer maximal (issue 21)", EVAL),
    M("EVAL-2", "eval", "src/planefuse/eval/_detection.py",
      "allowed = dist <= match_distance_m", "allowed = dist < match_distance_m",
      "inclusive threshold made strict (issue 21)", EVAL),
    M("EVAL-3", "eval", "src/planefuse/eval/_detection.py",
      "1.0 - (self.fn + self.fp) / self.n_gt", "1.0 - self.fn / self.n_gt", "MODA ignores false positives", EVAL),
    M("EVAL-4", "eval", "src/planefuse/eval/_detection.py",
      "sim += float(np.sum(1.0 - d / match_distance_m))", "sim += float(np.sum(d / match_distance_m))",
      "MODP: distance instead of similarity", EVAL),
    M("EVAL-5", "eval", "src/planefuse/eval/_detection.py",
      "n_fp -= len(ui)", "n_fp -= 0", "ignore regions have no effect", EVAL),
    M("EVAL-6", "eval", "src/planefuse/eval/_detection.py",
      "self.tp / (self.tp + self.fp) if", "self.tp / (self.tp + self.fn) if", "precision uses FN", EVAL),
    M("EVAL-7", "eval", "src/planefuse/eval/_tracking.py",
      "d = np.where(d <= match_distance_m, d, np.nan)", "d = np.where(d <= 2 * match_distance_m, d, np.nan)",
      "tracking metrics: match gate doubled", EVAL),
    M("EVAL-8", "eval", "src/planefuse/eval/_tracking.py",
      "if abs(hyp_t[j] - t) <= time_tolerance_s:", "if True:",
      "tracking metrics: frames paired whatever their time difference", EVAL),
    # -- audio Bayes -----------------------------------------------------------------------------------------------
    M("AUD-1", "audio", "src/planefuse/audio/_bayes.py",
      "0.5 * (y[i - 1] - y[i + 1]) / den", "0.5 * (y[i + 1] - y[i - 1]) / den",
      "peak refinement: sign error (issue 21)", AUDIO),
    M("AUD-2", "audio", "src/planefuse/audio/_bayes.py",
      "d = float(np.clip(0.5 * (y[i - 1] - y[i + 1]) / den, -0.5, 0.5))",
      "d = float(0.5 * (y[i - 1] - y[i + 1]) / den)", "peak refinement: clip to +-half a step dropped", AUDIO),
    M("AUD-3", "audio", "src/planefuse/audio/_bayes.py",
      "r -= np.round(r / Pb) * Pb", "pass", "ITD residual not wrapped to the band period", AUDIO),
    M("AUD-4", "audio", "src/planefuse/audio/_bayes.py",
      "g = np.exp(-0.5 * z * z)", "g = np.exp(-0.5 * np.abs(z))", "likelihood: Laplace-like instead of normal", AUDIO),
    M("AUD-5", "audio", "src/planefuse/audio/_bayes.py",
      "peaks = peaks[np.argsort(sal[peaks])[::-1]]", "peaks = peaks[np.argsort(sal[peaks])]",
      "sources sorted least salient first", AUDIO),
    M("AUD-6", "audio", "src/planefuse/audio/_register.py",
      "az = np.arctan2(p[:, 1], p[:, 0])", "az = np.arctan2(p[:, 0], p[:, 1])",
      "sound on the planes: head-frame axes swapped", AUDIO),
    M("AUD-7", "audio", "src/planefuse/audio/_register.py",
      "p = apply_transform(invert_transform(T), stack.cell_centers_world().reshape(-1, 3))",
      "p = apply_transform(T, stack.cell_centers_world().reshape(-1, 3))",
      "sound on the planes: T_world_head used as T_head_world", AUDIO),
    # -- camera fusion ---------------------------------------------------------------------------------------------
    M("VIS-1", "vision", "src/planefuse/vision/_fusion.py",
      "np.log(f * pfa + (1 - f) * (1 - pfa))", "np.log(f * pfa + (1 - f) * pfa)",
      "sensor model: P(background given free) wrong", VISION),
    M("VIS-2", "vision", "src/planefuse/vision/_fusion.py",
      "            if k >= 0:\n                out[n]", "            if k > 0:\n                out[n]",
      "fusion kernel: off by one (pixel 0 of camera 0 ignored)", VISION),
    M("VIS-3", "vision", "src/planefuse/vision/_fusion.py",
      "        if not active[c]:\n            continue\n", "",
      "fusion kernel: a camera without a frame still contributes its last image", VISION),
    M("VIS-4", "vision", "src/planefuse/vision/_fusion.py",
      "seen = (self._lut[np.asarray(key)] >= 0).sum(axis=0)", "seen = (self._lut >= 0).sum(axis=0)",
      "cameras_seeing ignores which cameras delivered a frame", VISION),
    # -- pipeline merge --------------------------------------------------------------------------------------------
    M("PIPE-1", "pipeline", "src/planefuse/pipeline/_streams.py",
      "            report.camera_detections.append(det)\n            yield ev\n",
      "            report.camera_detections.append(det)\n"
      "            yield Evidence(ev.time_s, ev.sensor, np.zeros_like(ev.log_odds))\n",
      "all camera evidence replaced by zeros (issue 21)", PIPELINE),
    M("PIPE-2", "pipeline", "src/planefuse/tracking/_async.py",
      "log_odds = np.sum([e.log_odds for e in group], axis=0, dtype=np.float32)", "log_odds = group[-1].log_odds",
      "merge: only the last message of a batch is fused", PIPELINE),
    M("PIPE-3", "pipeline", "src/planefuse/tracking/_async.py",
      "while self._heap and self._heap[0][0] <= t0 + self.merge_tolerance_s:",
      "while self._heap and self._heap[0][0] <= t0:", "merge tolerance ignored", PIPELINE),
    M("PIPE-4", "pipeline", "src/planefuse/pipeline/_streams.py",
      "heapq.heappush(heap, (float(item[0]), i, item[1]))", "heapq.heappush(heap, (float(i), i, item[1]))",
      "sources not interleaved by time (one source after the other)", PIPELINE),
    # -- the tracker's documented rules (issue 39: each passed the whole suite before) ------------------------------
    M("TRK-1", "tracker", "src/planefuse/tracking/_tracker.py",
      "(np.linalg.norm(y[..., :2], axis=-1) <= cap[:, None])",
      "(np.linalg.norm(y[..., :2], axis=-1) <= 1.5 * cap[:, None])", "gate distance cap x 1.5", PINNED),
    M("TRK-2", "tracker", "src/planefuse/tracking/_tracker.py",
      "gated = (d2_pos <= p.gate_chi2) &", "gated = (d2_pos <= 1.5 * p.gate_chi2) &",
      "gate chi-square bound x 1.5", PINNED),
    M("TRK-3", "tracker", "src/planefuse/tracking/_tracker.py",
      "tr.misses > p.max_misses or", "tr.misses > p.max_misses + 1 or",
      "a lost track deleted one step later", PINNED),
    M("TRK-4", "tracker", "src/planefuse/tracking/_tracker.py",
      "tr.misses > p.max_misses or", "tr.misses >= p.max_misses or",
      "a lost track deleted one step earlier", PINNED),
    M("TRK-5", "tracker", "src/planefuse/tracking/_tracker.py",
      "if not tr.confirmed or tr.misses > p.max_misses", "if tr.misses > p.max_misses",
      "a tentative track kept after its first miss", PINNED),
    M("TRK-6", "tracker", "src/planefuse/tracking/_tracker.py",
      "tr.misses > p.max_misses or not self._inside(tr.x[:2])", "tr.misses > p.max_misses",
      "a track whose prediction left the grid kept", PINNED),
    M("ASYNC-1", "tracker", "src/planefuse/tracking/_async.py",
      "heapq.heappush(self._heap, (t, self._next_seq, evidence))", "self._heap.append((t, self._next_seq, evidence))",
      "the buffer releases in arrival order, not time order", PINNED),
    M("ASYNC-2", "tracker", "src/planefuse/tracking/_async.py",
      "until = np.inf if final else self._newest_s - self.window_s", "until = np.inf",
      "the buffer holds nothing back: each message fused on arrival (arrival order)", PINNED),
]


def _files(root: Path) -> list[str]:
    out = subprocess.run(["git", "ls-files", "-co", "--exclude-standard"], cwd=root, check=True,
                         capture_output=True, text=True).stdout
    return [f for f in out.splitlines() if f and (root / f).is_file()]


def make_copy(root: Path, dest: Path) -> Path:
    """Copy the repository's files (tracked and untracked, not ignored) to ``dest/repo``; link ``dest/shared``
    to the real ``../shared`` so that the real-data tests run."""
    repo = dest / "repo"
    for f in _files(root):
        target = repo / f
        target.parent.mkdir(parents=True, exist_ok=True)
        shutil.copy2(root / f, target)
    shared = root.parent / "shared"
    if shared.exists():
        (dest / "shared").symlink_to(shared)
    return repo


def run_tests(repo: Path, tests: tuple[str, ...], timeout_s: float) -> tuple[str, str, float]:
    """``("pass" | "fail" | "timeout", first failing test or '', seconds)``."""
    env = dict(os.environ, PYTHONPATH=str(repo / "src"), MPLBACKEND="Agg", PYTHONDONTWRITEBYTECODE="1")
    cmd = [sys.executable, "-m", "pytest", "-x", "-q", "-p", "no:cacheprovider", "-p", "no:randomly", *tests]
    t0 = time.perf_counter()
    try:
        r = subprocess.run(cmd, cwd=repo, env=env, capture_output=True, text=True, timeout=timeout_s)
    except subprocess.TimeoutExpired:
        return "timeout", "", time.perf_counter() - t0
    dt = time.perf_counter() - t0
    if r.returncode == 0:
        return "pass", "", dt
    m = re.search(r"^(?:FAILED|ERROR) (\S+)", r.stdout, re.M)
    return "fail", (m.group(1) if m else f"exit {r.returncode}: {r.stdout.strip().splitlines()[-1:]}"), dt


def apply(repo: Path, mut: Mutation) -> str:
    """Plant ``mut`` in the copy; return the original text of the file."""
    p = repo / mut.path
    text = p.read_text()
    n = text.count(mut.old)
    if n != 1:
        raise SystemExit(f"{mut.id}: the original text occurs {n} times in {mut.path} (expected once): "
                         f"{mut.old!r}")
    p.write_text(text.replace(mut.old, mut.new))
    return text


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--only", default="", help="comma-separated mutation ids (default: all)")
    ap.add_argument("--timeout-s", type=float, default=600.0, help="time limit of one mutation's tests [s]")
    ap.add_argument("--list", action="store_true", help="list the mutations and exit")
    ap.add_argument("--no-baseline", action="store_true", help="do not check that the unmutated tests pass")
    args = ap.parse_args()
    muts = MUTATIONS
    if args.only:
        ids = set(args.only.split(","))
        unknown = ids - {m.id for m in MUTATIONS}
        if unknown:
            raise SystemExit(f"unknown mutation ids: {sorted(unknown)}")
        muts = [m for m in MUTATIONS if m.id in ids]
    if args.list:
        for m in muts:
            print(f"{m.id:8s} {m.module:9s} {m.path}: {m.what}")
        return
    with tempfile.TemporaryDirectory(prefix="planefuse-mutate-") as tmp:
        repo = make_copy(ROOT, Path(tmp))
        for m in muts:  # every mutation must apply before anything runs
            (repo / m.path).write_text(apply(repo, m))
        if not args.no_baseline:
            for tests in sorted({m.tests for m in muts}):
                status, first, dt = run_tests(repo, tests, args.timeout_s)
                print(f"baseline {' '.join(tests)}: {status} {first} ({dt:.0f} s)", file=sys.stderr, flush=True)
                if status != "pass":
                    raise SystemExit("the unmutated tests do not pass: a kill would mean nothing")
        print("| id | module | mutation | result | killed by | time [s] |")
        print("|---|---|---|---|---|---|")
        killed = 0
        for m in muts:
            original = apply(repo, m)
            try:
                status, first, dt = run_tests(repo, m.tests, args.timeout_s)
            finally:
                (repo / m.path).write_text(original)
            result = {"pass": "SURVIVED", "fail": "killed", "timeout": "killed (timeout)"}[status]
            killed += status != "pass"
            print(f"| {m.id} | {m.module} | {m.what} (`{m.path.split('/')[-1]}`) | {result} | "
                  f"{first.replace('tests/', '') if first else '-'} | {dt:.0f} |", flush=True)
        print(f"\n{killed} of {len(muts)} mutations killed.")


if __name__ == "__main__":
    main()
