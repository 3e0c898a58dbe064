"""Peak memory and CPU time per output step of ``planefuse run`` over the length of a recording.

Run: ``python benchmarks/bench_memory.py [--durations-s 10 60 300] [--seed 4] [--work DIR]``

For each duration the default scene is simulated to disk (``planefuse simulate --image-format jpg``), and
``planefuse run`` is started as a child process on it with the demo's configuration (every field at its
default: figures, animation and report on). The child's peak resident set size (``getrusage`` of that one
process, through ``os.wait4``) and its CPU time (user + system) are read when it ends; CPU time is divided
by the run's output steps. In the same run, for each duration, the baseline: the same ``planefuse run`` with
the end-of-run figures reading the whole occupancy array into memory (``--baseline-up-to-s`` limits it to
the shorter recordings) (what they did before they read it a
block of steps at a time; the occupancy grows ~9 MB per recorded second on the demo grid).
The shortest recording is run once first, unmeasured, so that numba's kernels are compiled and cached
before any measured run. Goal (issue 16): peak RSS flat within 10 % from 10 s to 300 s.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

from planefuse.cli._demo import demo_config
from planefuse.config import config_yaml

#: The child process of the baseline: figures and animation get the whole occupancy array in memory.
_WHOLE_ARRAY = ("import planefuse.outputs._writer as w; w.OutputWriter.occupancy_array = w.OutputWriter.occupancy; "
                "from planefuse.cli import main; main()")


def _child(argv: list[str]) -> tuple[float, float]:
    """Run ``argv``; return (peak RSS [MiB], CPU time [s]) of that process alone."""
    p = subprocess.Popen(argv, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    _, status, usage = os.wait4(p.pid, 0)
    err = p.stderr.read().decode(errors="replace") if p.stderr else ""
    p.returncode = os.waitstatus_to_exitcode(status)
    if p.returncode:
        raise RuntimeError(f"{' '.join(argv[:4])} ... failed ({p.returncode}): {err.strip()[-500:]}")
    return usage.ru_maxrss / 1024.0, usage.ru_utime + usage.ru_stime  # ru_maxrss is in KiB on Linux


def measure(work: Path, duration_s: float, seed: int, baseline: bool, warm_up: bool = False) -> list[dict]:
    """Simulate ``duration_s`` seconds, run it (and the baseline if ``baseline``); one row per way.
    ``warm_up``: run it once first, unmeasured (numba compiles its kernels into its cache on a first run;
    the compiler's memory and time are not the run's)."""
    rec = work / f"rec{duration_s:g}"
    if not (rec / "scene.yaml").exists():
        subprocess.run([sys.executable, "-m", "planefuse", "simulate", "--out", str(rec), "--duration-s",
                        str(duration_s), "--seed", str(seed), "--image-format", "jpg", "--overwrite"],
                       check=True, stdout=subprocess.DEVNULL)
    rows = []
    ways = [("streamed (current)", [sys.executable, "-m", "planefuse"])]
    if baseline:
        ways.append(("whole array (before)", [sys.executable, "-c", _WHOLE_ARRAY]))
    if warm_up:
        ways.insert(0, ("warm-up", [sys.executable, "-m", "planefuse"]))
    for way, prefix in ways:
        out = work / f"out{duration_s:g}-{'before' if 'before' in way else 'now'}"
        cfg = demo_config(out, seed=seed, duration_s=duration_s).model_copy(update={"recording": rec})
        cfg_path = work / f"cfg{duration_s:g}.yaml"
        cfg_path.write_text(config_yaml(cfg))
        rss_mib, cpu_s = _child(prefix + ["run", str(cfg_path), "--quiet", "--fresh"])
        steps = json.loads((out / "run_state.json").read_text()).get("n_steps_written")
        if way == "warm-up":
            continue
        rows.append({"duration_s": duration_s, "way": way, "peak_rss_mib": rss_mib, "cpu_s": cpu_s,
                     "steps": steps, "cpu_ms_per_step": 1e3 * cpu_s / steps if steps else float("nan")})
        print(rows[-1], flush=True)
    return rows


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--durations-s", type=float, nargs="+", default=[10.0, 60.0, 300.0],
                    help="recording lengths [s]")
    ap.add_argument("--seed", type=int, default=4, help="simulation seed")
    ap.add_argument("--baseline-up-to-s", type=float, default=float("inf"),
                    help="run the baseline only for recordings up to this length [s] (it costs a second run)")
    ap.add_argument("--work", type=Path, default=None, help="folder for recordings and outputs (default: temp)")
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        work = args.work or Path(tmp)
        work.mkdir(parents=True, exist_ok=True)
        rows = [r for i, d in enumerate(args.durations_s)
                for r in measure(work, d, args.seed, d <= args.baseline_up_to_s, warm_up=i == 0)]
    print("\n| recording [s] | output steps | figures read occupancy | peak RSS [MiB] | vs shortest | "
          "CPU [s] | CPU per step [ms] |")
    print("|---:|---:|---|---:|---:|---:|---:|")
    first = {r["way"]: r["peak_rss_mib"] for r in rows if r["duration_s"] == rows[0]["duration_s"]}
    for r in rows:
        print(f"| {r['duration_s']:g} | {r['steps']} | {r['way']} | {r['peak_rss_mib']:.0f} | "
              f"{r['peak_rss_mib'] / first[r['way']]:.2f} | {r['cpu_s']:.1f} | {r['cpu_ms_per_step']:.1f} |")


if __name__ == "__main__":
    main()
