"""How well the tracks' colour descriptor tells people apart on the EPFL terrace: the appearance distance of the same
person and of two different people, at the ground-truth positions, cameras c0 + c1.

For every scored frame (``--first``..``--last``, every ``--step``-th) each ground-truth person is described in each
camera (:func:`planefuse.tracking.describe_positions`, the library's default :class:`AppearanceParams`; the other
people, the ignored ones included, as occluders; the watermark as an ignore region). Every pair of descriptions at
most ``--within-s`` apart is compared over the cameras where both have a view: same person or not. Prints the
quantiles of both distributions and, per bin of distance, ``-2 ln (p(d | same) / p(d | other))``, the likelihood
ratio the tracker's appearance term ``w (d - d0)`` approximates (``appearance_reference_distance`` d0 where it
crosses 0, ``appearance_weight`` w its slope). Tuning: frames 0-1499. Example::

    PYTHONPATH=src python3 scripts/terrace_appearance.py --first 0 --last 1500
"""

from __future__ import annotations

import argparse
import shutil
import sys
import tempfile
from pathlib import Path

import numpy as np
from scipy.stats import mannwhitneyu

sys.path.insert(0, str(Path(__file__).resolve().parent))
import terrace as T  # noqa: E402

from planefuse.io import read_recording  # noqa: E402
from planefuse.tracking import AppearanceParams, describe_positions, descriptor_distance  # noqa: E402
from planefuse.vision import recording_frames  # noqa: E402


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--data", type=Path, default=T.REPO.parent / "shared" / "data")
    ap.add_argument("--first", type=int, default=0)
    ap.add_argument("--last", type=int, default=1500)
    ap.add_argument("--step", type=int, default=5)
    ap.add_argument("--within-s", type=float, default=5.0, help="largest time between two compared descriptions")
    ap.add_argument("--near-m", type=float, default=None,
                    help="compare only descriptions at most this far apart on the ground [m] (same person or not): "
                         "what the tracker must tell apart, with the background behind both alike; default: all")
    ap.add_argument("--set", action="append", default=[], metavar="FIELD=VALUE",
                    help="an AppearanceParams field changed, e.g. value_bins=8 (tuning; repeatable)")
    args = ap.parse_args(argv)
    pom_root = args.data / "epfl_pom" / "EPFL-Terrace"
    if not (args.data / "epfl_video" / "terrace1-c0.mp4").is_file() or not pom_root.is_dir():
        print(f"skipped: the terrace data is absent under {args.data}", file=sys.stderr)
        return 0
    frames = np.arange(args.first, args.last, args.step)
    truth = T.terrace_truth(pom_root, frames)
    tmp = Path(tempfile.mkdtemp(prefix="terrace-appearance-"))
    params = AppearanceParams(**T.with_sets({}, args.set))
    desc = {}
    try:
        rec = read_recording(T.import_terrace(tmp, args.data, frames, None))
        cams = list(rec.cameras)
        masks = [rec.camera(c.name).ignore_mask for c in cams]
        for t, imgs in recording_frames(rec):
            f = T._frame_of(t)
            if f not in truth.xy_m:
                continue
            v = describe_positions(imgs, cams, truth.xy_m[f], params, masks, truth.ignore_xy_m[f])
            for i, pid in enumerate(truth.ids[f]):
                desc[(f, int(pid))] = (v.hist[i], v.valid[i], truth.xy_m[f][i])
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    keys = sorted(desc)
    same, other = [], []
    for a, (f, p) in enumerate(keys):
        for g, q in keys[a + 1:]:
            if not 0 < g - f <= args.within_s * T.FPS:
                continue
            (hf, vf, xf), (hg, vg, xg) = desc[(f, p)], desc[(g, q)]
            if args.near_m is not None and np.hypot(*(xf - xg)) > args.near_m:
                continue
            both = vf & vg
            if both.any():
                (same if p == q else other).append(float(np.mean(descriptor_distance(hf[both], hg[both]))))
    same, other = np.array(same), np.array(other)
    taken = np.mean([v.mean() for _, v, _ in desc.values()])
    print(f"frames {args.first}-{args.last - 1} every {args.step}: views taken {taken:.2f} of the people's views in "
          "c0 and c1")
    q = (10, 25, 50, 75, 90)
    print(f"same person   ({len(same)} pairs): distance quantiles {q}: {np.percentile(same, q).round(3).tolist()}")
    print(f"other person  ({len(other)} pairs): distance quantiles {q}: {np.percentile(other, q).round(3).tolist()}")
    # the chance that another person's description is farther than the same person's (area under the ROC curve)
    auc = mannwhitneyu(other, same).statistic / (len(same) * len(other))
    print(f"AUC (other person farther than the same person): {auc:.3f}")
    bins = np.linspace(0, 1, 21)
    hs, _ = np.histogram(same, bins, density=True)
    ho, _ = np.histogram(other, bins, density=True)
    print("| distance | p(d, same) | p(d, other) | -2 ln LR |\n|---|---:|---:|---:|")
    for b0, b1, a, b in zip(bins, bins[1:], hs, ho):
        if a > 0 or b > 0:
            print(f"| {b0:.2f}-{b1:.2f} | {a:.2f} | {b:.2f} | {-2 * np.log((a + 1e-3) / (b + 1e-3)):+.1f} |")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
