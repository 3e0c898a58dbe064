"""Speed of binaural localisation: real-time factor on one core, 2 channels at 16 kHz, 32 bands.

Baseline in the same run: pyroomacoustics SRP-PHAT (STFT + locate_sources) on the same input, same
frames (20 ms, no overlap), same azimuth grid (-90..90 deg, 1 deg). Run: python benchmarks/bench_audio.py
"""

from __future__ import annotations

import os

import _single_thread  # noqa: F401  (before numpy)

import dataclasses
import time

import numpy as np
import pyroomacoustics as pra

from planefuse.audio import (
    HEAD_RADIUS_M,
    SphericalHead,
    default_sensor_model,
    localize,
    speech_like_signal,
)
from planefuse.audio._evaluate import SweepScene, sweep_recordings

FS = 16000.0
DURATION_S = 10.0
REPEATS = 5


def best_of(fn, repeats=REPEATS) -> tuple[float, float]:
    """Best wall-clock and best CPU time of this process [s] (CPU time is less sensitive to other load)."""
    wall, cpu = [], []
    for _ in range(repeats):
        t, c = time.perf_counter(), time.process_time()
        fn()
        wall.append(time.perf_counter() - t)
        cpu.append(time.process_time() - c)
    return min(wall), min(cpu)


def main() -> None:
    model = default_sensor_model(FS)  # 32 bands, 100-4000 Hz, front_end="time"
    fast = dataclasses.replace(model, front_end="fft")
    x = sweep_recordings(speech_like_signal(DURATION_S, FS, seed=3), [np.deg2rad(40.0)], SweepScene(),
                         SphericalHead(), FS)[0][: int(DURATION_S * FS)]
    localize(x[:4000], FS, model)  # compile / warm up
    localize(x[:4000], FS, fast)
    frame = int(round(model.frame_s * FS))
    L = np.array([[0.0, 0.0], [HEAD_RADIUS_M, -HEAD_RADIUS_M]])
    srp = pra.doa.algorithms["SRP"](L, FS, frame, num_src=1, azimuth=model.azimuth_rad)

    def run_srp():
        X = pra.transform.stft.analysis(x, frame, frame).transpose(2, 1, 0)
        srp.locate_sources(X, num_src=1, freq_range=[100.0, 4000.0])

    stages = {
        "planefuse: gammatone filterbank (32 bands x 2 ears)": lambda: model.filterbank.process(x),
        "planefuse: binaural unit (filterbank + ITD/ILD + gating)": lambda: model.cues(x, FS),
        "planefuse: localize (all of it, + Bayes + saliency)": lambda: localize(x, FS, model),
        "planefuse: localize, front_end='fft'": lambda: localize(x, FS, fast),
        "pyroomacoustics SRP-PHAT (STFT + grid search)": run_srp,
    }
    print(f"input: {DURATION_S:.0f} s, 2 channels, {FS:.0f} Hz; best of {REPEATS}; one thread")
    print(f"{'stage':60s} {'wall [s]':>9s} {'x real time':>12s} {'CPU [s]':>8s} {'x real time (CPU)':>18s}")
    res = {}
    for name, fn in stages.items():
        t, c = best_of(fn)
        res[name] = t
        print(f"{name:60s} {t:9.3f} {DURATION_S / t:12.1f} {c:8.3f} {DURATION_S / c:18.1f}")
    full = res["planefuse: localize (all of it, + Bayes + saliency)"]
    base = res["pyroomacoustics SRP-PHAT (STFT + grid search)"]
    fft = res["planefuse: localize, front_end='fft'"]
    print(f"ratio of wall times, planefuse localize / SRP-PHAT: {full / base:.2f}; "
          f"with front_end='fft': {fft / base:.2f}")
    print(f"load average while running: {os.getloadavg()[0]:.1f}")


if __name__ == "__main__":
    main()
