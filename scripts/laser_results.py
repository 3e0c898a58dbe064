"""Accuracy numbers of planefuse.laser for docs/results.md (## Laser).

Run: ``PYTHONPATH=src python scripts/laser_results.py DATA_ROOT`` (DATA_ROOT holds lrf2d_carmen/,
lrf2d_people_leg_tracker/, lrf3d_camera_lcct/; sections whose files are absent say so). The real-data sections
use the library functions behind ``planefuse laser-map``, ``planefuse laser legs`` and ``planefuse laser
camera-check`` with the same arguments.
"""

from __future__ import annotations

import argparse
import warnings
from pathlib import Path

import numpy as np

from planefuse import laser
from planefuse.calib import load_bouguet_calibration
from planefuse.grid import PlaneStack


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


def _absent(title: str, *paths: Path) -> bool:
    missing = [str(p) for p in paths if not p.exists()]
    if missing:
        print(f"### {title}: skipped, {', '.join(missing)} absent")
    return bool(missing)


def intel_map(log_path: Path) -> None:
    if _absent("Intel Research Lab map", log_path):
        return
    with warnings.catch_warnings(record=True) as w:
        warnings.simplefilter("always")
        log = laser.read_carmen_log(log_path)
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


def legs(bag: Path, labels_topic: str, demo_bag: Path) -> None:
    """As ``planefuse laser legs BAG --labels-topic ...`` (scores) and ``planefuse laser legs DEMO_BAG`` (counts)."""
    if not _absent("Leg detection", bag):
        scans, _ = laser.read_laser_scans(bag)
        _, labels = laser.read_rosbag(bag, labels_topic)
        sc = laser.evaluate_leg_detection(scans, labels, max_distance_m=0.3)
        tp, fp, fn, p, r = sc.tp, sc.fp, sc.fn, sc.precision, sc.recall
        print(f"### Leg detection, {bag.name} ({len(scans)} scans, labels = leg-cluster centroids on {labels_topic}, "
              "evaluated within +-15 deg and 5 m as labelled)")
        print(f"- TP {tp}, FP {fp}, FN {fn}: precision {p:.3f}, recall {r:.3f}, F1 {2 * p * r / (p + r):.3f} at 0.3 m")
    if _absent("People candidates on the unlabelled bag", demo_bag):
        return
    demo, _ = laser.read_laser_scans(demo_bag)
    bg = laser.background_ranges_m(demo)
    n0 = np.array([len(laser.detect_people(s)) for s in demo])
    n1 = np.array([len(laser.detect_people(s, background_ranges_m=bg)) for s in demo])
    print(f"- {demo_bag.name} (unlabelled, {len(demo)} scans): people candidates per scan, median (range): "
          f"{np.median(n0):.0f} ({n0.min()}-{n0.max()}) without background, "
          f"{np.median(n1):.0f} ({n1.min()}-{n1.max()}) with the per-beam median background")


def simulated_people() -> None:
    from planefuse.eval import detection_scores
    from planefuse.sim import Scene, default_scene_config

    rng = np.random.default_rng(0)
    scene = Scene(default_scene_config(duration_s=10))
    T = laser.T_world_laser_from_pose_2d(0.15, 5.0, 0.0, z_m=0.3)
    spec = laser.LaserScannerSpec.hokuyo_utm30lx(0.01)
    scans = []
    for t in np.arange(0.0, 10.0, 0.25):
        cylinders, _, spheres, _ = scene.bodies_at(t)
        scans.append(laser.simulate_scan(spec, T, 0.0, cylinders, spheres, scene.room_xy_m, scene.wall_height_m, rng,
                                         time_s=t))
    bg = laser.background_ranges_m(scans)
    print("### People from a static 2-D laser in the simulated scene (6 people, 40 scans, scanner 0.3 m high)")
    print("| background model | TP | FP | FN | precision | recall | F1 | mean distance (m) |")
    print("| --- | --- | --- | --- | --- | --- | --- | --- |")
    for name, b in (("none", None), ("per-beam median", bg)):
        frames = [(scene.people_at([s.time_s]).xy_m[0], laser.detect_people(s, background_ranges_m=b).xy_m)
                  for s in scans]
        sc = detection_scores(frames, 0.3)
        f1 = 2 * sc.precision * sc.recall / (sc.precision + sc.recall)
        print(f"| {name} | {sc.tp} | {sc.fp} | {sc.fn} | {sc.precision:.3f} | {sc.recall:.3f} | {f1:.3f} | "
              f"{sc.mean_distance_m:.3f} |")


def camera_laser(folder: Path, transform: str, pairs: list[int]) -> None:
    """As ``planefuse laser camera-check FOLDER --transform FOLDER/TRANSFORM --pairs ...``."""
    calib_path, transform_path = folder / "Calib_Results.mat", folder / transform
    if _absent("Camera + 3-D laser", calib_path, transform_path):
        return
    T_camera_laser = laser.read_transform_yaml(transform_path)
    cal = load_bouguet_calibration(calib_path, metres_per_unit=0.001)
    print(f"### Camera + 3-D laser ({folder.name}, {transform})")
    print("| pair | laser pts in board hull | median / 90 % distance to board plane (mm) | "
          "on-board pts projecting inside hull (1 px) |")
    print("| --- | --- | --- | --- |")
    for i in pairs:
        v = cal.views[i]
        r = laser.board_check(laser.read_xyz(folder / f"laser_target{i}.xyz"), T_camera_laser, cal.K, cal.dist,
                              v.T_camera_board, v.corners_px, v.corners_board_m, 0.01, 1.0)
        print(f"| {i} | {r.n_in_hull} | {1e3 * r.plane_distance_median_m:.2f} / {1e3 * r.plane_distance_p90_m:.2f} | "
              f"{100 * r.on_board_in_hull_fraction:.1f} % of {r.n_on_board} |")


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("data_root", type=Path, help="folder holding lrf2d_carmen/, lrf2d_people_leg_tracker/, "
                    "lrf3d_camera_lcct/")
    ap.add_argument("--carmen-log", default="lrf2d_carmen/intel-corrected.log.gz", help="relative to data_root")
    ap.add_argument("--legs-bag", default="lrf2d_people_leg_tracker/positive_1_extracted.bag")
    ap.add_argument("--labels-topic", default="/leg_cluster_positions")
    ap.add_argument("--demo-bag", default="lrf2d_people_leg_tracker/demo_stationary_simple_environment.bag")
    ap.add_argument("--lcct", default="lrf3d_camera_lcct", help="camera-laser folder, relative to data_root")
    ap.add_argument("--transform", default="T_camera_laser_stageII.yaml")
    ap.add_argument("--pairs", default="1,2,3,4", help="comma-separated board image numbers")
    ap.add_argument("--skip-simulated", action="store_true", help="only the real-data sections")
    a = ap.parse_args(argv)
    root = a.data_root
    if not root.is_dir():
        raise SystemExit(f"error: data root {root} is not a folder")
    if not a.skip_simulated:
        simulated_tilting_scanner()
    intel_map(root / a.carmen_log)
    legs(root / a.legs_bag, a.labels_topic, root / a.demo_bag)
    if not a.skip_simulated:
        simulated_people()
    camera_laser(root / a.lcct, a.transform, [int(v) for v in a.pairs.split(",")])


if __name__ == "__main__":
    main()
