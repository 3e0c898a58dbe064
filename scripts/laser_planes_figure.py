"""Figure docs/figures/laser_planes.png: per-plane evidence of a simulated nodding laser, true cross-sections drawn.

Run: ``PYTHONPATH=src python scripts/laser_planes_figure.py``
"""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from planefuse import laser  # noqa: E402
from planefuse.grid import PlaneStack, probability_from_log_odds  # noqa: E402


def main(out: Path = Path(__file__).resolve().parents[1] / "docs" / "figures" / "laser_planes.png") -> None:
    rng = np.random.default_rng(0)
    unit = laser.TiltingUnit(laser.LaserScannerSpec.hokuyo_utm30lx(0.01), offset_tilt_scanner_m=(0.03, 0.0, 0.05),
                             tilt_min_rad=-0.15, tilt_max_rad=0.5)
    T = laser.T_world_laser_from_pose_2d(0.5, 0.5, np.pi / 4, z_m=1.3)
    cyl = np.array([[3.0, 2.0, 0.25, 0.0, 1.75], [2.0, 4.0, 0.2, 0.0, 1.2], [5.0, 5.0, 0.3, 0.0, 1.6]])
    room, wall_h = (0.0, 7.0, 0.0, 7.0), 2.2
    stack = PlaneStack.from_extent([0.1, 0.5, 0.9, 1.4, 1.7, 2.0], (0, 7), (0, 7), 0.05)
    scans = [laser.simulate_scan(unit, T, tilt, cyl, None, room, wall_h, rng)
             for tilt in np.linspace(unit.tilt_min_rad, unit.tilt_max_rad, 40)]
    m = laser.map_from_scans(scans, stack, unit=unit)
    fig, axes = plt.subplots(2, 3, figsize=(13, 8.5))
    edges = stack.band_edges_m
    for l, ax in enumerate(axes.ravel()):
        ax.imshow(1.0 - probability_from_log_odds(m.log_odds[l]), cmap="gray", vmin=0, vmax=1, origin="lower",
                  extent=stack.extent_m, interpolation="nearest")
        for cx, cy, r, zb, zt in cyl:
            if zb < edges[l + 1] and zt >= edges[l]:
                ax.add_patch(plt.Circle((cx, cy), r, fill=False, color="tab:blue", lw=0.8))
        ax.plot(*T[:2, 3], "^", color="tab:orange")
        ax.set_title(f"plane z = {stack.heights_m[l]:.1f} m (band {edges[l]:.2f}-{edges[l + 1]:.2f} m)")
    fig.suptitle("Nodding laser, 40 scans: occupancy per plane (black occupied, white free, grey unknown); "
                 "blue: true person cross-sections in the band")
    fig.tight_layout()
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=90)
    print(f"wrote {out}")


if __name__ == "__main__":
    main()
