"""A real ROS 1 bag through planefuse's bag import: the laser-only run's people against the leg detector's.

``../shared/data/lrf2d_people_leg_tracker/demo_stationary_simple_environment.bag`` (a fixed 2-D laser, people
walking past; no /tf, so the laser is placed with ``--tf world,laser,0,0,0.4,0,0,0``: 0.4 m above the floor,
an assumed mounting height) is imported with ``planefuse import-bag`` (library: ``planefuse.io.import_bag``), run
laser-only with the default configuration (``planefuse run``: filter + tracker), and its tracks at every output
step are compared with the people that ``planefuse laser legs`` finds (per-beam median background) in the scan
nearest that step: one-to-one matching within ``--match-m``.

    python scripts/rosbag_legs.py [--out /tmp/rosbag_legs] [--match-m 0.5]
"""

from __future__ import annotations

import argparse
import shutil
import tempfile
from pathlib import Path

import numpy as np
from scipy.optimize import linear_sum_assignment

from planefuse.config import config_from_dict
from planefuse.io import import_bag, read_recording, static_transform
from planefuse.laser import background_ranges_m, detect_people, read_laser_scans
from planefuse.outputs import read_table
from planefuse.pipeline import run_to_folder

BAG = Path(__file__).resolve().parents[1] / ".." / "shared" / "data" / "lrf2d_people_leg_tracker" / \
    "demo_stationary_simple_environment.bag"
HEIGHT_M = 0.4
AREA = (0.0, 6.0, -4.0, 4.0)  # x_min, x_max, y_min, y_max [m]: the laser's half plane up to its 5.6 m range


def _match(a: np.ndarray, b: np.ndarray, max_m: float) -> np.ndarray:
    """Distances [m] of the one-to-one matches (Hungarian) of points a (N, 2) and b (M, 2) within max_m."""
    if not len(a) or not len(b):
        return np.zeros(0)
    d = np.linalg.norm(a[:, None] - b[None], axis=-1)
    r, c = linear_sum_assignment(np.where(d <= max_m, d, 1e6))
    return d[r, c][d[r, c] <= max_m]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--bag", type=Path, default=BAG)
    ap.add_argument("--out", type=Path, default=None, help="work folder (default: a temporary one)")
    ap.add_argument("--match-m", type=float, default=0.5)
    args = ap.parse_args()
    work = args.out or Path(tempfile.mkdtemp(prefix="rosbag_legs_"))
    rec_dir, run_dir = work / "recording", work / "run"
    shutil.rmtree(rec_dir, ignore_errors=True)
    res = import_bag(args.bag, rec_dir, extra_transforms=[static_transform(f"world,laser,0,0,{HEIGHT_M},0,0,0")],
                     planes_heights_m=[HEIGHT_M], room_xy_m=AREA)
    for r in res.topics:
        print(r.line())
    cfg = config_from_dict({
        "recording": str(rec_dir),
        "planes": {"heights_m": [HEIGHT_M], "x_range_m": list(AREA[:2]), "y_range_m": list(AREA[2:])},
        "sensors": {"cameras": {"enabled": False}, "sound": {"enabled": False}},
        "outputs": {"out_dir": str(run_dir), "figures": False, "report": False, "animation": "none"}})
    shutil.rmtree(run_dir, ignore_errors=True)
    run_to_folder(read_recording(rec_dir), cfg.plan(), progress_mode="quiet")
    tracks = read_table(run_dir / "tracks.csv")

    scans, _ = read_laser_scans(args.bag)
    bg = background_ranges_m(scans)
    scan_t = np.array([s.time_s for s in scans]) - res.origin_ns / 1e9  # the recording's clock
    legs = [detect_people(s, background_ranges_m=bg).xy_m for s in scans]

    import zarr

    times = zarr.open_group(run_dir / "occupancy.zarr", mode="r")["time_s"][:]
    xy = np.column_stack([tracks["x_m"], tracks["y_m"]])
    # a track "moves" when it gets farther than 0.5 m from where it started (static clutter never does)
    moved = {int(i): float(np.linalg.norm(xy[tracks["track_id"] == i] - xy[tracks["track_id"] == i][0], axis=1).max())
             > 0.5 for i in np.unique(tracks["track_id"])}
    is_moving = np.array([moved[int(i)] for i in tracks["track_id"]], dtype=bool)
    print(f"\nbag {args.bag.name}: {len(scans)} scans, {len(times)} output steps ({times[0]:.1f}..{times[-1]:.1f} s), "
          f"{len(moved)} tracks of which {sum(moved.values())} move > 0.5 m")
    print(f"| run's people | people per step: run | leg detector (per-beam median background) | matched within "
          f"{args.match_m} m | run's matched | leg detector's matched | median distance of matches |")
    print("|---|---|---|---|---|---|---|")
    for name, keep in (("all tracks", np.ones(len(xy), dtype=bool)), ("tracks that move > 0.5 m", is_moving)):
        n_tr = n_lg = 0
        dists = []
        for k, t in enumerate(times):
            j = int(np.argmin(np.abs(scan_t - t)))
            a, b = xy[(tracks["step"] == k) & keep], legs[j]
            n_tr += len(a)
            n_lg += len(b)
            dists.append(_match(a, b, args.match_m))
        d = np.concatenate(dists)
        print(f"| {name} | {n_tr / len(times):.2f} | {n_lg / len(times):.2f} | {len(d) / len(times):.2f} | "
              f"{len(d) / max(n_tr, 1):.3f} | {len(d) / max(n_lg, 1):.3f} | {np.median(d):.3f} m |")


if __name__ == "__main__":
    main()
