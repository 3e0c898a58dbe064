"""Latency and drops of ``planefuse live`` on one core; a soak with RSS and latency over time.

The simulated default scene (seed 4, 20 s, 4 cameras at 25 fps, 360x288) is served as MJPEG streams on 127.0.0.1 at
the frames' own rate (:class:`planefuse.live.MjpegServer`, looping), and a :class:`planefuse.live.LiveRun` (cameras
only, arrival clock, no page) reads 2 or 4 of them at 5 Hz (the default ``max_rate_hz``) or at their full rate.
Everything (server, stream decoding, system) runs in one process pinned to one core, with OpenCV and numba on one
thread. Latency: an output step's emission less the arrival of the newest frame of the instant it fused
(after the 1 s warm-up).

    python scripts/bench_live.py --duration-s 40                   # the table: 2 and 4 cameras, 5 Hz and full rate
    python scripts/bench_live.py --soak-s 600 --cameras 4 --rate 5  # the soak (RSS, latency per minute)
    python scripts/bench_live.py --source rtsp --cameras 4         # RTSP streams (tests/_rtsp_server.py, RTP/JPEG
                                                                   # over TCP) read through OpenCV's FFmpeg
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np


def one(n_cameras: int, rate: str, duration_s: float, seed: int, scene_s: float, page: bool = False,
        source: str = "mjpeg") -> dict:
    from planefuse.cli._run import set_threads
    from planefuse.io import Recording
    from planefuse.live import LiveRun, LiveSettings, MjpegServer, recording_jpeg_frames
    from planefuse.pipeline import SystemParams
    from planefuse.sim import default_scene_config, simulate
    from planefuse.vision import CameraParams

    os.sched_setaffinity(0, {sorted(os.sched_getaffinity(0))[0]})
    set_threads(1)
    rec = simulate(default_scene_config(duration_s=scene_s, seed=seed))
    names = [c.name for c in rec.cameras][:n_cameras]
    rec = Recording(rec.duration_s, camera_streams={n: rec.camera(n) for n in names},
                    planes_heights_m=rec.planes_heights_m, room_xy_m=rec.room_xy_m)
    frames = recording_jpeg_frames(rec)
    if source == "rtsp":  # the loopback RTSP server of the tests (test-only code, not a runtime dependency)
        sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
        from _rtsp_server import RtspServer

        srv = RtspServer(frames, loop=True).start()
    else:
        srv = MjpegServer(frames, loop=True).start()
    params = SystemParams(laser=False, sound=False,
                          camera_params=replace(CameraParams(), max_rate_hz=5.0 if rate == "5" else None))
    live = LiveRun(rec, params, LiveSettings(cameras={n: srv.url(n) for n in names}, serve=page, port=0))
    import resource
    import time

    cpu0, wall0 = resource.getrusage(resource.RUSAGE_SELF), time.perf_counter()
    try:
        summary = live.run(duration_s=duration_s)
    finally:
        live.close()
        srv.stop()
    cpu1, wall = resource.getrusage(resource.RUSAGE_SELF), time.perf_counter() - wall0
    cpu_s = (cpu1.ru_utime + cpu1.ru_stime) - (cpu0.ru_utime + cpu0.ru_stime)
    lat = summary.latencies_s
    t_start = lat[0][0] if lat else 0.0
    minutes = []
    for m in range(int(np.ceil(duration_s / 60.0))):
        w = [v for t, v, warm in lat if warm and m * 60 <= t - t_start < (m + 1) * 60]
        if w:
            minutes.append({"minute": m, "n": len(w), "p50_ms": float(np.percentile(w, 50) * 1e3),
                            "p95_ms": float(np.percentile(w, 95) * 1e3)})
    return {"source": source, "load_avg_1min_end": os.getloadavg()[0], "cpu_s": cpu_s, "wall_s": wall,
            "cpu_share": cpu_s / wall,
            "cameras": n_cameras, "rate": rate, "duration_s": duration_s, "outputs": summary.outputs,
            "instants": summary.instants, "p50_ms": summary.latency_ms(50), "p95_ms": summary.latency_ms(95),
            "max_ms": summary.latency_ms(100), "step_p50_ms": summary.step_latency_ms(50),
            "step_p95_ms": summary.step_latency_ms(95), "health": summary.health, "rss_mib": list(summary.rss_mib),
            "latency_per_minute": minutes}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--duration-s", type=float, default=40.0)
    ap.add_argument("--soak-s", type=float, default=None, help="one long run instead of the table")
    ap.add_argument("--cameras", type=int, nargs="*", default=[2, 4])
    ap.add_argument("--rate", nargs="*", default=["5", "full"], choices=["5", "full"])
    ap.add_argument("--seed", type=int, default=4)
    ap.add_argument("--scene-s", type=float, default=20.0)
    ap.add_argument("--json", type=Path, default=None, help="write the results here")
    ap.add_argument("--page", action="store_true", help="serve the live page (no browser connected)")
    ap.add_argument("--figure", type=Path, default=None, help="soak: RSS and latency over time (PNG)")
    ap.add_argument("--source", choices=["mjpeg", "rtsp"], default="mjpeg", help="how the frames are streamed")
    ap.add_argument("--_one", nargs=2, default=None, help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args._one is not None:  # a child process: one configuration
        res = one(int(args._one[0]), args._one[1], args.soak_s or args.duration_s, args.seed, args.scene_s, args.page,
                  args.source)
        print("RESULT " + json.dumps(res))
        return
    results = []
    for n in args.cameras:
        for rate in args.rate:
            cmd = [sys.executable, __file__, "--_one", str(n), rate, "--duration-s", str(args.duration_s),
                   "--seed", str(args.seed), "--scene-s", str(args.scene_s), "--source", args.source]
            if args.soak_s:
                cmd += ["--soak-s", str(args.soak_s)]
            if args.page:
                cmd += ["--page"]
            out = subprocess.run(cmd, capture_output=True, text=True, check=True).stdout
            res = json.loads(next(line for line in out.splitlines() if line.startswith("RESULT "))[7:])
            results.append(res)
            used = [h["used"] for h in res["health"]]
            dropped = [h["dropped"] for h in res["health"]]
            print(f"{args.source}: {n} cameras, {rate:>4} Hz: p50 {res['p50_ms']:.0f} ms, p95 {res['p95_ms']:.0f} ms, "
                  f"max {res['max_ms']:.0f} ms; instants {res['instants']}, outputs {res['outputs']}; used per camera "
                  f"{used}, dropped {dropped}; RSS {res['rss_mib'][0][1]:.0f} -> {res['rss_mib'][-1][1]:.0f} MiB",
                  flush=True)
            for m in res["latency_per_minute"] if args.soak_s else ():
                print(f"   minute {m['minute']}: n {m['n']}, p50 {m['p50_ms']:.0f} ms, p95 {m['p95_ms']:.0f} ms")
    if args.json is not None:
        args.json.write_text(json.dumps(results, indent=1))
    if args.figure is not None and args.soak_s:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        res = results[0]
        fig, (a, b) = plt.subplots(2, 1, figsize=(7, 4.5), sharex=True)
        t, r = np.array(res["rss_mib"]).T
        a.plot(t / 60, r)
        a.set_ylabel("RSS [MiB]")
        m = res["latency_per_minute"]
        b.plot([x["minute"] + 0.5 for x in m], [x["p50_ms"] for x in m], "o-", label="p50")
        b.plot([x["minute"] + 0.5 for x in m], [x["p95_ms"] for x in m], "s-", label="p95")
        b.set_ylabel("latency [ms]")
        b.set_xlabel("time [min]")
        b.legend()
        a.set_title(f"planefuse live soak: {res['cameras']} cameras at {res['rate']} Hz, one core")
        fig.tight_layout()
        fig.savefig(args.figure, dpi=100)


if __name__ == "__main__":
    main()
