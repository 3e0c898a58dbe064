"""A screenshot of the live page (docs/figures/live_page.png) by headless Chromium.

The simulated default scene (seed 4) is served as MJPEG streams on 127.0.0.1 at 25 fps; ``LiveRun`` reads them for
``--duration-s`` seconds with the page on, then Chromium renders the page (its last state).

    python scripts/live_page_screenshot.py --out docs/figures/live_page.png
"""

from __future__ import annotations

import argparse
import shutil
import subprocess
import tempfile
from pathlib import Path


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--out", type=Path, default=Path("docs/figures/live_page.png"))
    ap.add_argument("--duration-s", type=float, default=6.0)
    ap.add_argument("--seed", type=int, default=4)
    args = ap.parse_args()
    chromium = shutil.which("chromium") or shutil.which("chromium-browser")
    if chromium is None:
        raise SystemExit("chromium is not installed (apt-get install chromium)")

    from planefuse.live import LiveRun, LiveSettings, MjpegServer, recording_jpeg_frames
    from planefuse.pipeline import SystemParams
    from planefuse.sim import default_scene_config, simulate

    rec = simulate(default_scene_config(duration_s=args.duration_s + 2.0, seed=args.seed))
    frames = recording_jpeg_frames(rec)
    srv = MjpegServer(frames).start()
    live = LiveRun(rec, SystemParams(laser=False, sound=False),
                   LiveSettings(cameras={n: srv.url(n) for n in frames}, port=0), on_event=print)
    try:
        live.run(duration_s=args.duration_s)
        with tempfile.TemporaryDirectory() as profile:
            subprocess.run([chromium, "--headless", "--no-sandbox", "--disable-gpu", "--disable-dev-shm-usage",
                            f"--user-data-dir={profile}", "--hide-scrollbars", "--window-size=1280,1000",
                            "--virtual-time-budget=3000", f"--screenshot={args.out.resolve()}", live.page.url],
                           check=True, capture_output=True, timeout=120)
    finally:
        live.close()
        srv.stop()
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
