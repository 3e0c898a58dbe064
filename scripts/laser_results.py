"""Accuracy numbers of planefuse.laser for docs/results.md (## Laser).

Run: ``PYTHONPATH=src python scripts/laser_results.py`` (needs ../shared/data beside the checkout).
"""

from __future__ import annotations

import warnings
from pathlib import Path

import cv2
import numpy as np
import scipy.io

from planefuse.geometry import apply_transform
from planefuse.grid import PlaneStack
from planefuse import laser

DATA = Path(__file__).resolve().parents[1].parent / "shared" / "data"


def simulated_tilting_scanner() -> None:
    rng = np.random.default_rng(0)
    unit = laser.TiltingUnit(laser.LaserScannerSpec.hokuyo_utm30lx(0.01), offset_tilt_scanner_m=(0.03, 0.0, 0.05),
                       tilt_min_rad=-0.15, tilt_max_rad=0.5)
    T = laser.T_world_laser_from_pose_2d(0.5, 0.5, np.pi / 4, z_m=1.3)  # looking diagonally into the room
    cyl = np.array([[3.0, 2.0, 0.25, 0.0, 1.75], [2.0, 4.0, 0.2, 0.0, 1.2], [5.0, 5.0, 0.3, 0.0, 1.6]])
    room, wall_h = (0.0, 7.0, 0.0, 7.0), 2.2
    stack = PlaneStack.from_extent([0.1, 0.5, 0.9, 1.4, 1.7, 2.0], (0, 7), (0, 7), 0.05)
    d_cyl, d_wall, r_err = [], [], []
    acc = np.zeros(stack.shape, np.float32)
    for tilt in np.linspace(unit.tilt_min_rad, unit.tilt_max_rad, 40):
        scan, truth = laser.simulate_scan(unit, T, tilt, cyl, None, room, wall_h, rng, return_truth=True)
        ok = scan.valid
        p = laser.points_world_from_scan(scan.angles_rad[ok], scan.ranges_m[ok], scan.tilt_rad[ok], T, unit)
        kind, idx = truth.hit_kind[ok], truth.hit_index[ok]
        side = (kind == laser.HIT_CYLINDER) & (p[:, 2] < cyl[idx, 4] - 0.02)
        d_cyl.append(np.hypot(p[side, 0] - cyl[idx[side], 0], p[side, 1] - cyl[idx[side], 1]) - cyl[idx[side], 2])
        w = kind == laser.HIT_WALL
        d_wall.append(np.min(np.abs(np.stack([p[w, 0] - room[0], p[w, 0] - room[1], p[w, 1] - room[2],
                                               p[w, 1] - room[3]])), axis=0))
        r_err.append(scan.ranges_m[ok] - truth.range_m[ok])
        acc += laser.register_scan(scan, stack, unit=unit).evidence.log_odds
    d_cyl, d_wall, r_err = map(np.concatenate, (d_cyl, d_wall, r_err))
    print("### Simulated tilting scanner (Hokuyo UTM-30LX model, sigma 10 mm, 40 tilts -0.15..0.5 rad)")
    print(f"- range error vs analytic ray casting: RMS {1e3 * np.sqrt(np.mean(r_err ** 2)):.2f} mm over {r_err.size} beams")
    print(f"- registered points on people (cylinder sides): RMS distance to the surface "
          f"{1e3 * np.sqrt(np.mean(d_cyl ** 2)):.2f} mm, max {1e3 * np.abs(d_cyl).max():.1f} mm ({d_cyl.size} points)")
    print(f"- registered points on walls: RMS {1e3 * np.sqrt(np.mean(d_wall ** 2)):.2f} mm, "
          f"max {1e3 * d_wall.max():.1f} mm ({d_wall.size} points)")
    xy = stack.cell_centers_xy()
    edges = stack.band_edges_m
    print("- per-plane occupancy (sum of 40 scans), occupied cells within 0.75 cell + 4 cm of a true surface, "
          "and rim cells of each person cross-section marked:")
    print("  | plane z (m) | occupied cells | on a true surface | people seen (>= 15 cm of the body in the band) |")
    print("  | --- | --- | --- | --- |")
    for l, h in enumerate(stack.heights_m):
        occ = acc[l] > 0
        d = np.full(xy.shape[:2], np.inf)
        seen, present = 0, 0
        for cx, cy, r, zb, zt in cyl:
            if zb < edges[l + 1] and zt >= edges[l]:
                rho = np.hypot(xy[..., 0] - cx, xy[..., 1] - cy)
                cap = edges[l] <= zt < edges[l + 1]
                d = np.minimum(d, np.maximum(rho - r, 0) if cap else np.abs(rho - r))
                if min(zt, edges[l + 1]) - edges[l] >= 0.15:  # enough of the body inside the band
                    present += 1
                    seen += int((occ & (np.abs(rho - r) < 1.5 * stack.cell_size_m)).sum() >= 3)
        if edges[l] < wall_h:
            dw = np.min(np.abs(np.stack([xy[..., 0] - room[0], xy[..., 0] - room[1], xy[..., 1] - room[2],
                                         xy[..., 1] - room[3]])), 0)
            d = np.minimum(d, dw)
        good = d[occ] < 0.75 * stack.cell_size_m + 0.04
        print(f"  | {h:.1f} | {occ.sum()} | {100 * good.mean():.1f} % | {seen} of {present} |")


def intel_map() -> None:
    with warnings.catch_warnings(record=True) as w:
        warnings.simplefilter("always")
        log = laser.read_carmen_log(DATA / "lrf2d_carmen" / "intel-corrected.log.gz")
    m, pts = laser.map_from_carmen_log(log)
    rng = np.random.default_rng(0)
    pose = log.pose_xy_theta + rng.normal(0, [0.05, 0.05, np.deg2rad(1.0)], log.pose_xy_theta.shape)
    bad = log.returns_world_xy(pose)
    print("### Intel Research Lab map (910 scans, corrected poses, 5 cm cells)")
    print(f"- warnings: {[str(x.message)[:80] for x in w]}")
    print(f"- beams: {m.n_valid} real returns, {m.n_no_return} max-range, {m.n_invalid} invalid; "
          f"time stamps backwards {log.n_time_backwards} times")
    print(f"- map entropy of observed cells: {laser.map_entropy_bits(m.log_odds):.3f} bit")
    print(f"- median wall spread (RMS distance of 20 neighbours to their local line): corrected poses "
          f"{1e3 * np.median(laser.wall_spread_m(pts)):.1f} mm, poses perturbed by 5 cm / 1 deg "
          f"{1e3 * np.median(laser.wall_spread_m(bad)):.1f} mm")


def legs() -> None:
    bag = DATA / "lrf2d_people_leg_tracker" / "positive_1_extracted.bag"
    _, scans = laser.read_rosbag(bag, "/training_scan")
    _, labels = laser.read_rosbag(bag, "/leg_cluster_positions")
    sc = laser.evaluate_leg_detection(scans, labels, max_distance_m=0.3)
    tp, fp, fn, p, r = sc.tp, sc.fp, sc.fn, sc.precision, sc.recall
    print("### Leg detection, positive_1_extracted.bag (197 scans, labels = leg-cluster centroids, "
          "evaluated within +-15 deg and 5 m as labelled)")
    print(f"- TP {tp}, FP {fp}, FN {fn}: precision {p:.3f}, recall {r:.3f}, F1 {2 * p * r / (p + r):.3f} at 0.3 m")
    _, demo = laser.read_rosbag(DATA / "lrf2d_people_leg_tracker" / "demo_stationary_simple_environment.bag", "/scan")
    n = np.array([len(laser.detect_people(s)) for s in demo])
    print(f"- demo bag (unlabelled, 1265 scans): people candidates per scan median {np.median(n):.0f}, "
          f"range {n.min()}-{n.max()}")


def camera_laser() -> None:
    d = DATA / "lrf3d_camera_lcct"
    T_camera_laser = laser.read_transform_yaml(d / "T_camera_laser_stageII.yaml")
    calib = scipy.io.loadmat(d / "Calib_Results.mat")
    K, kc = calib["KK"], calib["kc"].ravel()
    print("### Camera + 3-D laser (LCCT, stage-II T_camera_laser)")
    print("| pair | laser pts in board hull | median / 90 % distance to board plane (mm) | "
          "on-board pts projecting inside hull (1 px) |")
    print("| --- | --- | --- | --- |")
    for i in range(1, 5):
        R, t = calib[f"Rc_{i}"], calib[f"Tc_{i}"].ravel() / 1000.0
        hull = cv2.convexHull(calib[f"x_{i}"].T.astype(np.float32))
        p = apply_transform(T_camera_laser, laser.read_xyz(d / f"laser_target{i}.xyz"))
        p = p[p[:, 2] > 0]
        uv = cv2.projectPoints(p, np.zeros(3), np.zeros(3), K, kc)[0].reshape(-1, 2)
        margin = np.array([cv2.pointPolygonTest(hull, (float(u), float(v)), True) for u, v in uv])
        dist = np.abs((p[margin >= 0] - t) @ R[:, 2])
        pb = (p - t) @ R
        X = calib[f"X_{i}"] / 1000.0
        on = (np.abs(pb[:, 2]) < 0.01) & (pb[:, 0] >= X[0].min()) & (pb[:, 0] <= X[0].max()) \
            & (pb[:, 1] >= X[1].min()) & (pb[:, 1] <= X[1].max())
        print(f"| {i} | {(margin >= 0).sum()} | {1e3 * np.median(dist):.2f} / {1e3 * np.percentile(dist, 90):.2f} | "
              f"{100 * np.mean(margin[on] >= -1):.1f} % of {on.sum()} |")


if __name__ == "__main__":
    simulated_tilting_scanner()
    intel_map()
    legs()
    camera_laser()
