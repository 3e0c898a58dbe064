"""How well the simulator's outputs agree with its own 3-D ground truth (numbers for docs/results.md).

    python examples/sim_groundtruth_check.py [--duration-s 20] [--seed 0]

* masks: for 10 instants and every camera, points sampled uniformly inside every body volume are projected
  with ``PinholeCamera.project``; we report the share landing on foreground pixels of the rendered mask and
  the IoU of the mask with an independent rasterisation (pixels hit by the samples, 3x3 closing).
* walking: speed while moving, share of time standing, turning, closest approach of two people.
* IMU: angle between gravity measured by each accelerometer (mean over the run) and the true vertical.
"""

from __future__ import annotations

import argparse

import cv2
import numpy as np

from planefuse.sim import default_scene_config, sample_points_in_bodies, simulate


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--duration-s", type=float, default=20.0)
    ap.add_argument("--seed", type=int, default=0)
    args = ap.parse_args()
    rec = simulate(default_scene_config(duration_s=args.duration_s, seed=args.seed, laser=None, head=None))
    scene = rec.scene
    rng = np.random.default_rng(0)
    on_mask, ious = [], []
    cs0 = next(iter(rec.camera_streams.values()))
    for k in np.linspace(0, len(cs0) - 1, 10).astype(int):
        t = float(cs0.times_s[k])
        cyl, _, sph, _ = scene.bodies_at(t)
        pts, _ = sample_points_in_bodies(cyl, sph, 20000, rng)
        for cs in rec.camera_streams.values():
            fg = cs.mask(k) > 0
            uv = cs.camera.project(pts)
            px = np.round(uv[cs.camera.intrinsics.contains(uv)]).astype(int)
            on_mask.append(fg[px[:, 1], px[:, 0]].mean())
            dense = np.zeros(fg.shape, np.uint8)
            dense[px[:, 1], px[:, 0]] = 1
            dense = cv2.morphologyEx(dense, cv2.MORPH_CLOSE, np.ones((3, 3), np.uint8)) > 0
            ious.append((dense & fg).sum() / (dense | fg).sum())
    st = scene.people_at(np.arange(0, args.duration_s, 0.04))
    moving = st.speed_m_s > 0.3
    d = np.linalg.norm(st.xy_m[:, :, None] - st.xy_m[:, None], axis=-1) + 99 * np.eye(scene.n_people)
    turn = np.degrees(np.abs(np.diff(np.unwrap(st.heading_rad, axis=0), axis=0))).sum(axis=0) / args.duration_s
    ang = []
    for cs in rec.camera_streams.values():
        imu = rec.imu_for(cs.name)
        f = imu.read().accel_m_s2.mean(axis=0)
        g = (cs.camera.R_world_cam @ imu.T_cam_imu[:3, :3]).T @ np.array([0.0, 0.0, 1.0])
        ang.append(np.degrees(np.arccos(f @ g / np.linalg.norm(f))))
    print(f"default scene, seed {args.seed}, {args.duration_s:g} s, {scene.n_people} people")
    print(f"masks: inside-volume samples on the mask: mean {np.mean(on_mask):.5f}, min {np.min(on_mask):.5f} "
          f"({len(on_mask)} camera-frames)")
    print(f"masks: IoU with dense-sample rasterisation: mean {np.mean(ious):.3f}, min {np.min(ious):.3f}")
    print(f"walking: median speed while moving {np.median(st.speed_m_s[moving]):.2f} m/s, "
          f"standing (< 0.3 m/s) {1 - moving.mean():.0%} of the time, mean turning {turn.mean():.0f} deg/s, "
          f"closest approach {d.min():.2f} m")
    print(f"IMU: gravity direction error per camera [deg]: {', '.join(f'{a:.2f}' for a in ang)}")


if __name__ == "__main__":
    main()
