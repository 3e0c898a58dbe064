"""Bad inputs through ``planefuse check`` and ``planefuse run``: prints a Markdown table of what happened.

Usage: ``PYTHONPATH=src python scripts/bad_inputs.py [--duration-s 1.0] [--only NAME ...] [--no-run]``

A short simulated recording (seed 2) is written once; every case copies it and its configuration, corrupts
one thing (a frame file, a time stamp, a manifest entry, a configuration field, the output folder, ...) and
runs ``check`` (and ``run`` where the case says so) in-process through typer's ``CliRunner``. An outcome is

- *clear error*: exit code 1 or 2 and no exception escaped;
- *repair reported*: exit code 0 and the case expects a repair, reported (a warning or a check finding);
- *traceback*: an exception other than ``SystemExit`` escaped (goal 0);
- *silent acceptance*: exit code 0 where an error (or a reported repair) was expected (goal 0).

NumPy runtime warnings (NaN, division by zero, overflow; NumPy's default error state) leaking from a case are
counted too.
"""

from __future__ import annotations

import argparse
import json
import shutil
import sys
import tempfile
import warnings
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import yaml
from typer.testing import CliRunner

from planefuse.cli import app
from planefuse.config import example_yaml
from planefuse.sim import default_scene_config, simulate


@dataclass(frozen=True)
class Case:
    """One bad input: ``corrupt(rec_dir, cfg, tmp)`` edits the recording copy / configuration dict in place."""

    name: str
    corrupt: Callable[[Path, dict, Path], None]
    run: bool = False  # also run it (check alone otherwise)
    expect: str = "error"  # "error" or "repair"
    args: tuple[str, ...] = ()  # extra arguments of ``run``


def _manifest(rec: Path, edit: Callable[[dict], None]) -> None:
    m = yaml.safe_load((rec / "scene.yaml").read_text())
    edit(m)
    (rec / "scene.yaml").write_text(yaml.safe_dump(m))


def _camera(rec: Path, i: int, key: str, value) -> None:
    def edit(m):
        cams = [s for s in m["sensors"] if s["type"] == "camera"]
        cams[i][key] = value(cams[i][key]) if callable(value) else value
    _manifest(rec, edit)


def _times(rec: Path, cam: str, row: int, value: str) -> None:
    p = rec / "cameras" / cam / "times.csv"
    lines = p.read_text().splitlines()
    parts = lines[row + 1].split(",")
    parts[0] = value
    lines[row + 1] = ",".join(parts)
    p.write_text("\n".join(lines) + "\n")


def _drop_rows(rec: Path, cam: str, row: int, n: int) -> None:
    p = rec / "cameras" / cam / "times.csv"
    lines = p.read_text().splitlines()
    kept = lines[: row + 1] + lines[row + 1 + n:]
    p.write_text("\n".join(kept) + "\n")
    _camera(rec, int(cam[-1]), "n_frames", len(kept) - 1)


def _frame(rec: Path, i: int = 10) -> Path:
    return rec / "cameras" / "cam1" / "frames" / f"{i:06d}.jpg"


def _laser_npz(rec: Path, edit: Callable[[dict], None]) -> None:
    p = next((rec / "laser").rglob("*.npz"))
    with np.load(p) as z:
        arrays = {k: z[k] for k in z.files}
    edit(arrays)
    np.savez(p, **arrays)


def _mm(m: dict) -> None:
    for s in m["sensors"]:
        if s["type"] == "camera":
            for r in range(3):
                s["T_world_cam"][r][3] *= 1000.0


def _set(cfg: dict, dotted: str, value) -> None:
    *path, last = dotted.split(".")
    d = cfg
    for k in path:
        d = d.setdefault(k, {})
    d[last] = value


def _out_holds_other_run(rec: Path, cfg: dict, tmp: Path) -> None:
    out = Path(cfg["outputs"]["out_dir"])
    out.mkdir(parents=True)
    (out / "run_state.json").write_text('{"status": "finished", "config_hash": "0123456789abcdef", '
                                        '"chunk_steps": 50, "n_chunks_done": 1}')
    (out / "tracks.csv").write_text("step,time_s,track_id,x_m,y_m,vx_m_s,vy_m_s\n")


def _out_holds_foreign_files(rec: Path, cfg: dict, tmp: Path) -> None:
    out = Path(cfg["outputs"]["out_dir"])
    (out / "figures").mkdir(parents=True)
    (out / "figures" / "my_plot.png").write_bytes(b"mine")
    (out / "notes.txt").write_text("mine")


def _no_rerun(rec: Path, cfg: dict, tmp: Path) -> None:
    sys.modules["rerun"] = None  # import rerun -> ImportError, as without rerun-sdk (restored by the caller)
    cfg["outputs"]["rerun"] = True


CASES = [
    # -- camera frames and their time stamps
    Case("frame file missing", lambda r, c, t: _frame(r).unlink(), run=True),
    Case("frame file truncated", lambda r, c, t: _frame(r).write_bytes(_frame(r).read_bytes()[:500]), run=True),
    Case("frame file garbage", lambda r, c, t: _frame(r).write_bytes(b"\x00garbage" * 100), run=True),
    Case("frame file empty", lambda r, c, t: _frame(r).write_bytes(b"")),
    Case("frames dropped (a gap in the time stamps)", lambda r, c, t: _drop_rows(r, "cam1", 8, 5), run=True,
         expect="repair"),
    Case("camera time stamp NaN", lambda r, c, t: _times(r, "cam1", 5, "nan")),
    Case("camera time stamps backwards", lambda r, c, t: _times(r, "cam1", 5, "0.0")),
    Case("camera rate_hz in millihertz", lambda r, c, t: _camera(r, 1, "rate_hz", 25000.0e3)),
    Case("camera times_file outside the recording",
         lambda r, c, t: _camera(r, 0, "times_file", "../../../../etc/passwd")),
    Case("camera name with a slash", lambda r, c, t: _camera(r, 0, "name", "x/../../somewhere")),
    Case("camera translations in millimetres", lambda r, c, t: _manifest(r, _mm), run=True),
    Case("camera K not 3x3", lambda r, c, t: _camera(r, 0, "K", [[1, 0], [0, 1]])),
    Case("camera pose not a rotation", lambda r, c, t: _camera(
        r, 1, "T_world_cam", lambda T: [[2 * v for v in row[:3]] + [row[3]] for row in T[:3]] + [T[3]])),
    # -- laser
    Case("laser chunk with no scans", lambda r, c, t: _laser_npz(
        r, lambda a: a.update({k: v[:0] for k, v in a.items() if k not in ("angles_rad",)})), run=True),
    Case("laser time stamps NaN", lambda r, c, t: _laser_npz(
        r, lambda a: a["time_s"].__setitem__(slice(3, 5), np.nan)), run=True),
    Case("laser enabled, the recording has none", lambda r, c, t: _manifest(
        r, lambda m: m.update(sensors=[s for s in m["sensors"] if s["type"] != "laser"])), run=True),
    Case("laser file garbage", lambda r, c, t: next((r / "laser").rglob("*.npz")).write_bytes(b"PK\x03\x04junk")),
    # -- other streams and the manifest
    Case("audio file truncated", lambda r, c, t: (r / "audio" / "head.wav").write_bytes(
        (r / "audio" / "head.wav").read_bytes()[:1000])),
    Case("imu file garbage", lambda r, c, t: next((r / "imu").glob("*.csv")).write_text("a,b\n1,2\n")),
    Case("manifest garbage", lambda r, c, t: (r / "scene.yaml").write_text("{{{ not yaml")),
    Case("manifest missing", lambda r, c, t: (r / "scene.yaml").unlink()),
    Case("ground truth garbage", lambda r, c, t: (r / "groundtruth" / "people.csv").write_text("x\n1\n")),
    # -- configuration
    Case("plane above every camera", lambda r, c, t: _set(c, "planes.heights_m", [0.1, 1.0, 5.0])),
    Case("plane at a camera's height", lambda r, c, t: _set(c, "planes.heights_m", [0.1, 1.0, 3.0])),
    Case("grid of 4 x 3500 x 3500 cells", lambda r, c, t: (
        _set(c, "planes.x_range_m", [0.0, 350.0]), _set(c, "planes.y_range_m", [0.0, 350.0])), run=True),
    Case("cell size negative", lambda r, c, t: _set(c, "planes.cell_size_m", -0.1)),
    Case("unknown configuration field", lambda r, c, t: _set(c, "planes.cell_size", 0.1)),
    Case("occluder box inside out", lambda r, c, t: _set(c, "scene.occluder_boxes_m", [[2.0, 1.0, 0, 1, 0, 2]])),
    Case("occluder box with NaN", lambda r, c, t: _set(c, "scene.occluder_boxes_m", [[0, 1, 0, float("nan"), 0, 2]])),
    Case("occluder box in millimetres", lambda r, c, t: _set(c, "scene.occluder_boxes_m",
                                                             [[1000.0, 1500.0, 1000.0, 1500.0, 0.0, 2000.0]])),
    Case("background subtraction downscale 0", lambda r, c, t: _set(c, "sensors.cameras.subtraction_downscale", 0)),
    Case("track support threshold NaN", lambda r, c, t: _set(c, "models.detection.support_threshold", float("nan"))),
    Case("selective update frames 0", lambda r, c, t: (_set(c, "sensors.cameras.selective_update", True),
                                                       _set(c, "sensors.cameras.selective_max_frames", 0))),
    Case("selective update with MOG2", lambda r, c, t: (_set(c, "sensors.cameras.selective_update", True),
                                                        _set(c, "sensors.cameras.foreground_method", "mog2"))),
    Case("tracker clutter density 0", lambda r, c, t: _set(c, "models.detection.clutter_density_per_m2", 0.0)),
    Case("tracker clutter density NaN",
         lambda r, c, t: _set(c, "models.detection.clutter_density_per_m2", float("nan"))),
    Case("generative evidence prior unknown word",
         lambda r, c, t: _set(c, "sensors.cameras.generative_evidence_prior", "detections")),
    Case("sound model missing", lambda r, c, t: _set(c, "sensors.sound.model_path", str(t / "none.npz")),
         run=True),
    Case("sound model garbage", lambda r, c, t: (
        (t / "model.npz").write_bytes(b"garbage"), _set(c, "sensors.sound.model_path", str(t / "model.npz"))),
        run=True),
    # -- the output folder
    Case("out_dir is the recording folder", lambda r, c, t: _set(c, "outputs.out_dir", str(r)), run=True),
    Case("out_dir inside the recording folder", lambda r, c, t: _set(c, "outputs.out_dir", str(r / "out")),
         run=True),
    Case("out_dir is a file", lambda r, c, t: ((t / "f").write_text("x"), _set(c, "outputs.out_dir", str(t / "f"))),
         run=True),
    Case("out_dir below a file", lambda r, c, t: (
        (t / "f").write_text("x"), _set(c, "outputs.out_dir", str(t / "f" / "out"))), run=True),
    Case("out_dir not writable", lambda r, c, t: _set(c, "outputs.out_dir", "/proc/planefuse-out"), run=True),
    Case("out_dir holds another run's results", _out_holds_other_run, run=True),
    Case("out_dir holds the user's files", _out_holds_foreign_files, run=True),
    Case("outputs.rerun without rerun-sdk", _no_rerun, run=True),
]


def _classify(result, expect: str, reported: bool) -> str:
    if result.exception is not None and not isinstance(result.exception, SystemExit):
        return "traceback"
    if result.exit_code in (1, 2):
        return "clear error"
    if result.exit_code == 0 and expect == "repair" and reported:
        return "repair reported"
    return "silent acceptance" if result.exit_code == 0 else f"exit {result.exit_code}"


def _invoke(args: list[str], expect: str):
    runner = CliRunner()
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        result = runner.invoke(app, args)
    leaks = [w for w in caught if issubclass(w.category, RuntimeWarning)]
    reported = any(not issubclass(w.category, RuntimeWarning) for w in caught) or "warning" in result.output
    return result, _classify(result, expect, reported), len(leaks)


def _last_line(result) -> str:
    """The first error (``check --log-json``: its first error finding), else the output's last line."""
    if result.exception is not None and not isinstance(result.exception, SystemExit):
        return f"{type(result.exception).__name__}: {result.exception}".splitlines()[0][:140]
    lines = result.output.strip().splitlines() or [""]
    try:
        issues = json.loads(lines[-1])["issues"]
        errors = [f"{i['subject']}: {i['message']}" for i in issues if i["level"] == "error"]
        warns = [f"{i['subject']}: {i['message']}" for i in issues if i["level"] == "warning"]
        return (errors or warns or ["OK"])[0][:140]
    except (ValueError, KeyError, TypeError):
        return " ".join(lines[-1].split())[:140]


def run_cases(cases, rec_dir: Path, work: Path, with_run: bool = True):
    """Run every case; returns rows ``(case, command, outcome, runtime warnings, first error line)``."""
    rows = []
    base = yaml.safe_load(example_yaml(str(rec_dir)))
    for k, case in enumerate(cases):
        tmp = work / f"case{k:02d}"
        tmp.mkdir()
        rec = tmp / "rec"
        shutil.copytree(rec_dir, rec)
        cfg = yaml.safe_load(yaml.safe_dump(base))
        cfg["recording"] = str(rec)
        cfg["outputs"].update(out_dir=str(tmp / "out"), figures=False, report=False, animation="none")
        saved = dict(sys.modules)
        try:
            case.corrupt(rec, cfg, tmp)
            (tmp / "run.yaml").write_text(yaml.safe_dump(cfg))
            commands = [["check", str(tmp / "run.yaml"), "--log-json"]]
            if with_run and case.run:
                commands.append(["run", str(tmp / "run.yaml"), "--quiet", *case.args])
            for cmd in commands:
                result, outcome, leaks = _invoke(cmd, case.expect)
                rows.append((case.name, cmd[0], outcome, leaks, _last_line(result).replace(str(work), "<tmp>")))
        finally:
            sys.modules.clear()
            sys.modules.update(saved)
    return rows


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--duration-s", type=float, default=1.0)
    ap.add_argument("--only", nargs="*", default=None, help="Run only the cases whose name contains one of these.")
    ap.add_argument("--no-run", action="store_true", help="Only planefuse check.")
    args = ap.parse_args()
    cases = [c for c in CASES if args.only is None or any(s in c.name for s in args.only)]
    with tempfile.TemporaryDirectory() as d:
        work = Path(d)
        rec_dir = work / "recording"
        simulate(default_scene_config(duration_s=args.duration_s, seed=2)).write(rec_dir, image_format="jpg")
        rows = run_cases(cases, rec_dir, work, with_run=not args.no_run)
    print("| bad input | command | outcome | NumPy warnings | message (first error line) |")
    print("|---|---|---|---|---|")
    for name, cmd, outcome, leaks, msg in rows:
        print(f"| {name} | {cmd} | {outcome} | {leaks} | {msg.replace('|', '/')} |")
    tally = {o: sum(r[2] == o for r in rows) for o in ("clear error", "repair reported", "traceback",
                                                        "silent acceptance")}
    print(f"\n{len(rows)} inputs tried ({len(cases)} bad inputs): " + ", ".join(f"{v} {k}" for k, v in tally.items())
          + f", {sum(r[3] > 0 for r in rows)} with NumPy runtime warnings")


if __name__ == "__main__":
    main()
