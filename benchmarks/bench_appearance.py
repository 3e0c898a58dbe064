"""Cost of the tracks' appearance per output step and per track: the Kalman tracker without appearance against the
same tracker with appearance in association and re-identification (the views' extraction from every camera's frame
included), in the same run, on the same clusters and frames.

Run: ``PYTHONPATH=src python benchmarks/bench_appearance.py [--people 6,16] [--cameras 2,4]``

Scene: people walking straight lines at 0.5-1.2 m/s in a 10 m room (reflected at the walls), each a two-colour box
(torso, legs) drawn far to near in every camera's 360 x 288 frame (``default_camera_ring``), position-only clusters
at the people's positions at 5 Hz (the default output rate). Per step it times ``MultiPersonTracker.step`` of both
trackers (the appearance tracker's step asks the views of the clusters: one colour conversion per frame, one
histogram per visible, unhidden view). One thread (``_single_thread``), process CPU time, the median step after a
warm-up; ratios are what to read on a shared machine.
"""

from __future__ import annotations

import _single_thread  # noqa: F401  (first: one thread per library)

import argparse
import time

import numpy as np

from planefuse.geometry import default_camera_ring
from planefuse.occupancy import silhouettes_from_cameras
from planefuse.tracking import AppearanceObserver, AppearanceParams, Clusters, MultiPersonTracker, TrackerParams

DT_S = 0.2
ROOM_M = 10.0


def frames_and_clusters(cameras, n: int, n_steps: int, rng: np.random.Generator):
    start = rng.uniform(1.0, ROOM_M - 1.0, (n, 2))
    heading = rng.uniform(0, 2 * np.pi, n)
    v = rng.uniform(0.5, 1.2, n)[:, None] * np.column_stack([np.cos(heading), np.sin(heading)])
    colours = rng.integers(20, 235, (n, 2, 3))
    person = AppearanceParams().person()
    lo, span = 0.5, ROOM_M - 1.0
    for k in range(n_steps):
        t = k * DT_S
        xy = lo + np.abs((start + v * t - lo + span) % (2 * span) - span)
        boxes = silhouettes_from_cameras(cameras, xy, person).boxes_px
        imgs = []
        for c, cam in enumerate(cameras):
            img = np.full((cam.intrinsics.height_px, cam.intrinsics.width_px, 3), 128, np.uint8)
            for i in np.argsort(-np.hypot(*(xy - cam.center_world[:2]).T)):
                x0, y0, x1, y1 = boxes[c, i]
                if x0 >= 0:
                    ym = (y0 + y1) // 2
                    img[y0:ym, x0:x1 + 1], img[ym:y1 + 1, x0:x1 + 1] = colours[i, 0], colours[i, 1]
            imgs.append(img)
        yield t, imgs, Clusters(t, xy, np.zeros((n, 2)), np.full(n, 1.7), np.ones(n), np.zeros((0, 0)))


def bench(n_cameras: int, n_people: int, n_steps: int, warm: int = 5) -> dict:
    cameras = default_camera_ring(n_cameras, room_size_m=ROOM_M)
    extent = (0.0, ROOM_M, 0.0, ROOM_M)
    plain = MultiPersonTracker(TrackerParams(), extent)
    app = MultiPersonTracker(TrackerParams(appearance_weight=8.0, reid_max_s=5.0), extent)
    app.observer = AppearanceObserver(cameras)
    t_plain, t_app, tracks = [], [], []
    for k, (t, imgs, clusters) in enumerate(frames_and_clusters(cameras, n_people, n_steps,
                                                                 np.random.default_rng(0))):
        app.observer.add_frames(t, imgs)
        t0 = time.process_time()
        plain.step(clusters)
        t1 = time.process_time()
        app.step(clusters)
        t2 = time.process_time()
        if k >= warm:
            t_plain.append(t1 - t0)
            t_app.append(t2 - t1)
            tracks.append(len(app.tracks))
    return {"plain_ms": 1e3 * float(np.median(t_plain)), "app_ms": 1e3 * float(np.median(t_app)),
            "tracks": float(np.mean(tracks))}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--people", default="6,16")
    ap.add_argument("--cameras", default="2,4")
    ap.add_argument("--steps", type=int, default=40)
    args = ap.parse_args()
    print("| cameras | people | tracker [ms/step] | tracker + appearance [ms/step] | ratio | appearance added "
          "[ms per track per step] |")
    print("|---:|---:|---:|---:|---:|---:|")
    for nc in (int(s) for s in args.cameras.split(",")):
        for n in (int(s) for s in args.people.split(",")):
            r = bench(nc, n, args.steps)
            print(f"| {nc} | {n} | {r['plain_ms']:.2f} | {r['app_ms']:.2f} | {r['app_ms'] / r['plain_ms']:.2f} | "
                  f"{(r['app_ms'] - r['plain_ms']) / max(r['tracks'], 1):.3f} |", flush=True)


if __name__ == "__main__":
    main()
