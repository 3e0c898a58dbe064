"""Bad inputs through ``planefuse check`` and ``planefuse run``: prints a Markdown table of what happened.

Usage: ``PYTHONPATH=src python scripts/bad_inputs.py [--duration-s 1.0] [--only NAME ...] [--no-run]``

A short simulated recording (seed 2) is written once; every case copies it and its configuration, corrupts
one thing (a frame file, a time stamp, a manifest entry, a configuration field or the configuration file's
bytes, the output folder, the process's memory limit, the disk, ...) and runs ``check`` (and ``run`` where the
case says so; ``import`` for image folders) in-process through typer's ``CliRunner``. An outcome is

- *clear error*: exit code 1 or 2 and no exception escaped;
- *repair reported*: exit code 0 and the case expects a repair, reported (a warning or a check finding);
- *accepted (legitimate)*: exit code 0 on an input that is legitimate (a UTF-16 configuration with a byte-order
  mark is read as the same configuration);
- *traceback*: an exception other than ``SystemExit`` escaped (goal 0);
- *silent acceptance*: exit code 0 where an error (or a reported repair) was expected (goal 0);
- *hang*: the command ran past ``--limit-s`` (default 120 s; stopped by SIGALRM) (goal 0).

NumPy runtime warnings (NaN, division by zero, overflow; NumPy's default error state) leaking from a case are
counted too, and each command's wall time is given.
"""

from __future__ import annotations

import argparse
import errno
import json
import os
import resource
import shutil
import signal
import subprocess
import sys
import tempfile
import time
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
    """One bad input: ``corrupt(rec_dir, cfg, tmp)`` edits the recording copy / configuration dict in place (it may
    return a function that undoes what it did to the process: a memory limit, a patched ``os.fsync``, a process
    holding the output folder's lock); ``text(yaml_text)`` gives the configuration file's bytes (default UTF-8);
    ``command(rec, tmp)`` replaces ``check``/``run`` (``planefuse import`` cases)."""

    name: str
    corrupt: Callable[[Path, dict, Path], Callable[[], None] | None]
    run: bool = False  # also run it (check alone otherwise)
    check: bool = True  # check it (False: a condition of the run alone, a full disk)
    expect: str = "error"  # "error", "repair" or "accept" (a legitimate input)
    args: tuple[str, ...] = ()  # extra arguments of ``run``
    text: Callable[[str], bytes] | None = None
    command: Callable[[Path, Path], list[str]] | None = None


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


# -- round two (issue 39) ----------------------------------------------------------------------------------------
def _bomb(levels: int, key: str = "lol") -> str:
    """The "billion laughs": ``levels`` anchors of 10 aliases each, 10^levels values once expanded."""
    lines = [f"{key}0: &a0 [" + ", ".join(['"lol"'] * 10) + "]"]
    lines += [f"{key}{i}: &a{i} [" + ", ".join([f"*a{i - 1}"] * 10) + "]" for i in range(1, levels)]
    return "\n".join(lines) + "\n"


def _bomb_under(field: str, levels: int) -> Callable[[str], bytes]:
    """The bomb as the value of ``field`` (an existing section's field, or an unknown one)."""
    def text(t: str) -> bytes:
        body = _bomb(levels).splitlines()
        anchors, value = "\n".join(f"x_{line}" for line in body[:-1]), body[-1].split(": ", 1)[1]
        return (t + anchors + f"\n{field}: {value}\n").encode()
    return text


def _duplicate_key(t: str) -> bytes:
    lines = t.splitlines()
    i = next(k for k, line in enumerate(lines) if line.strip().startswith("cell_size_m:"))
    lines.insert(i + 1, lines[i].replace(lines[i].split(":")[1], " 0.3"))
    return ("\n".join(lines) + "\n").encode()


def _imu_row(rec: Path, value: str) -> None:
    p = next((rec / "imu").glob("*.csv"))
    lines = p.read_text().splitlines()
    lines[5] = ",".join([value] + lines[5].split(",")[1:])
    p.write_text("\n".join(lines) + "\n")


def _audio_start(rec: Path, start_s: float) -> None:
    _manifest(rec, lambda m: [s.update(start_time_s=start_s) for s in m["sensors"] if s["type"] == "binaural"])


def _address_space_limit(extra_bytes: int):
    """Limit the process's address space (``ulimit -v``) to what it uses plus ``extra_bytes``; returns the undo."""
    soft, hard = resource.getrlimit(resource.RLIMIT_AS)
    used = next(int(line.split()[1]) * 1024 for line in Path("/proc/self/status").read_text().splitlines()
                if line.startswith("VmSize:"))
    resource.setrlimit(resource.RLIMIT_AS, (used + extra_bytes, hard))
    return lambda: resource.setrlimit(resource.RLIMIT_AS, (soft, hard))


def _fine_grid_under_a_limit(rec: Path, cfg: dict, tmp: Path):
    """A 20 m grid of 2 cm cells (about 3.5 GiB: fits the machine's free memory, not the limit) under ``ulimit -v``
    of 2 GiB beyond what the process holds."""
    _set(cfg, "planes.x_range_m", [0.0, 20.0])
    _set(cfg, "planes.y_range_m", [0.0, 20.0])
    _set(cfg, "planes.cell_size_m", 0.02)
    return _address_space_limit(2 * 2**30)


def _disk_full(rec: Path, cfg: dict, tmp: Path):
    """The disk fills up after the run's first 6 files: every fsync then fails with ENOSPC."""
    real, calls = os.fsync, [0]

    def fsync(fd):
        calls[0] += 1
        if calls[0] > 6:
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
        return real(fd)

    _set(cfg, "outputs.chunk_steps", 2)
    os.fsync = fsync

    def undo():
        os.fsync = real
    return undo


_HOLD_LOCK = "import sys, time\nfrom planefuse.outputs._lock import OutputLock\nlock = OutputLock(sys.argv[1])\n" \
             "lock.acquire()\nprint('held', flush=True)\ntime.sleep(600)\n"


def _folder_in_use(rec: Path, cfg: dict, tmp: Path):
    """Another ``planefuse run`` (a process holding the output folder's lock) is writing into out_dir."""
    out = Path(cfg["outputs"]["out_dir"])
    out.mkdir(parents=True)
    proc = subprocess.Popen([sys.executable, "-c", _HOLD_LOCK, str(out)], stdout=subprocess.PIPE, text=True,
                            env={**os.environ, "PYTHONPATH": str(Path(__file__).resolve().parents[1] / "src")})
    proc.stdout.readline()

    def undo():
        proc.kill()
        proc.wait()
    return undo


def _images(rec: Path, tmp: Path, edit: Callable[[Path], None]) -> list[str]:
    """``planefuse import`` of camera cam0's frames as an image folder (25 Hz, its calibration as OpenCV YAML),
    after ``edit(folder)``."""
    from planefuse.calib import save_opencv_camera
    from planefuse.io import read_recording

    folder = tmp / "images"
    shutil.copytree(rec / "cameras" / "cam0" / "frames", folder)
    edit(folder)
    save_opencv_camera(tmp / "cam0.yaml", read_recording(rec).cameras[0])
    return ["import", str(tmp / "imported"), "--camera", f"cam0={folder}", "--rate", "cam0=25", "--calib-format",
            "opencv", "--units", "m", "--calib", f"cam0={tmp / 'cam0.yaml'}"]


def _odd_size(folder: Path) -> None:
    import cv2

    cv2.imwrite(str(folder / "000012.jpg"), np.zeros((240, 320, 3), np.uint8))


def _numbering_gap(folder: Path) -> None:
    (folder / "000012.jpg").unlink()
    (folder / "000013.jpg").unlink()


def _nothing(rec: Path, cfg: dict, tmp: Path) -> None:
    return None


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
    # -- round two (issue 39): configuration files
    Case("YAML alias bomb, 10^9 values", _nothing, run=True, text=_bomb_under("scene.occluder_boxes_m", 9)),
    Case("YAML alias bomb, 10^9 values under an unknown key", _nothing, run=True,
         text=_bomb_under("not_a_field", 9)),
    Case("YAML alias bomb, 10^6 values", _nothing, run=True, text=_bomb_under("scene.occluder_boxes_m", 6)),
    Case("YAML recursive alias", _nothing, text=lambda t: (t + "loop: &l [1, *l]\n").encode()),
    Case("duplicate key (cell_size_m twice)", _nothing, run=True, text=_duplicate_key),
    Case("configuration in UTF-16 with a byte-order mark", _nothing, expect="accept",
         text=lambda t: t.encode("utf-16")),
    Case("configuration in UTF-8 with a byte-order mark", _nothing, expect="accept",
         text=lambda t: t.encode("utf-8-sig")),
    Case("configuration in UTF-16 without a byte-order mark", _nothing, text=lambda t: t.encode("utf-16-le")),
    Case("configuration in Latin-1 (not UTF-8)", _nothing, text=lambda t: (t + "# caf\xe9\n").encode("latin-1")),
    Case("configuration nested 100000 levels deep", _nothing, text=lambda t: (t + "deep: " + "[" * 100_000
                                                                              + "]" * 100_000 + "\n").encode()),
    Case("configuration with a 5000-digit number", _nothing, text=lambda t: t.replace(
        "cell_size_m: 0.1", "cell_size_m: " + "9" * 5000).encode()),
    Case("configuration with a 1 MB string value", _nothing, text=lambda t: t.replace(
        "cell_size_m: 0.1", "cell_size_m: '" + "x" * 1_000_000 + "'").encode()),
    Case("configuration that is a list", _nothing, text=lambda t: b"- 1\n- 2\n"),
    Case("configuration with a Python object tag", _nothing, text=lambda t: (
        t + "evil: !!python/object/apply:os.system ['echo pwned']\n").encode()),
    # -- round two: calibration and streams (check and run, one verdict)
    Case("lens distortion k1 = 50", lambda r, c, t: _camera(r, 0, "dist", [50.0, 0.0, 0.0, 0.0, 0.0]), run=True),
    Case("lens distortion folding inside the image (k1 = -0.5)",
         lambda r, c, t: _camera(r, 1, "dist", [-0.5, 0.0, 0.0, 0.0, 0.0]), run=True),
    Case("focal length in millimetres (fx = fy = 4.2)", lambda r, c, t: _camera(
        r, 0, "K", lambda K: [[4.2, 0.0, K[0][2]], [0.0, 4.2, K[1][2]], [0.0, 0.0, 1.0]]), run=True),
    Case("principal point outside the image", lambda r, c, t: _camera(
        r, 0, "K", lambda K: [[K[0][0], 0.0, 3 * K[0][2]], [0.0, K[1][1], K[1][2]], [0.0, 0.0, 1.0]]), run=True),
    Case("audio stream starting at 100 s in a 1 s recording", lambda r, c, t: _audio_start(r, 100.0), run=True),
    Case("imu time stamp NaN", lambda r, c, t: _imu_row(r, "nan"), run=True),
    Case("imu time stamps backwards", lambda r, c, t: _imu_row(r, "0.0"), run=True),
    # -- round two: import of image folders
    Case("import: one 320x240 image among 360x288 ones", _nothing,
         command=lambda r, t: _images(r, t, _odd_size)),
    Case("import: a gap in the image numbering (2 frames)", _nothing, expect="repair",
         command=lambda r, t: _images(r, t, _numbering_gap)),
    # -- round two: memory, the output folder, the disk
    Case("chunk_steps 10000 with a fine grid (2 cm, 20 m)", lambda r, c, t: (
        _set(c, "outputs.chunk_steps", 10_000), _set(c, "planes.cell_size_m", 0.02),
        _set(c, "planes.x_range_m", [0.0, 20.0]), _set(c, "planes.y_range_m", [0.0, 20.0])) and None, run=True),
    Case("20 m grid of 2 cm cells under a 2 GiB address-space limit", _fine_grid_under_a_limit, run=True),
    Case("out_dir being written by another run", _folder_in_use, run=True),
    Case("disk full during the run", _disk_full, run=True, check=False),
]


class _Hang(BaseException):
    """Raised by SIGALRM in a command that ran past the limit (not an Exception: nothing in planefuse catches it)."""


def _classify(result, expect: str, reported: bool) -> str:
    if isinstance(result.exception, _Hang):
        return "hang"
    if result.exception is not None and not isinstance(result.exception, SystemExit):
        return "traceback"
    if result.exit_code in (1, 2):
        return "clear error" if expect != "accept" else "refused (legitimate input)"
    if result.exit_code == 0 and expect == "repair" and reported:
        return "repair reported"
    if result.exit_code == 0 and expect == "accept":
        return "accepted (legitimate)"
    return "silent acceptance" if result.exit_code == 0 else f"exit {result.exit_code}"


def _alarm(signum, frame):
    raise _Hang()


def _invoke(args: list[str], expect: str, limit_s: float = 120.0):
    runner = CliRunner()
    previous = signal.signal(signal.SIGALRM, _alarm)
    signal.setitimer(signal.ITIMER_REAL, limit_s)
    t0 = time.perf_counter()
    try:
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            result = runner.invoke(app, args)
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, previous)
    wall_s = time.perf_counter() - t0
    leaks = [w for w in caught if issubclass(w.category, RuntimeWarning)]
    reported = any(not issubclass(w.category, RuntimeWarning) for w in caught) or "warning" in result.output
    return result, _classify(result, expect, reported), len(leaks), wall_s


def _last_line(result) -> str:
    """The first error (``check --log-json``: its first error finding), else the output's last line."""
    if result.exception is not None and not isinstance(result.exception, SystemExit):
        return f"{type(result.exception).__name__}: {result.exception}".splitlines()[0][:140]
    lines = result.output.strip().splitlines() or [""]
    try:
        issues = json.loads(lines[-1])["issues"]
        errors = [f"{i['subject'] or '<file>'}: {i['message']}" for i in issues if i["level"] == "error"]
        warns = [f"{i['subject'] or '<file>'}: {i['message']}" for i in issues if i["level"] == "warning"]
        return (errors or warns or ["OK"])[0][:140]
    except (ValueError, KeyError, TypeError):
        text = " ".join(result.output.split())
        if result.exit_code == 0 and "warning" in text:  # a repair: what it said
            return text[text.index("warning"):][:140]
        return " ".join(lines[-1].split())[:140]


def run_cases(cases, rec_dir: Path, work: Path, with_run: bool = True, limit_s: float = 120.0):
    """Run every case; returns rows ``(case, command, outcome, runtime warnings, first error line, wall s)``."""
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
        undo = None
        try:
            undo = case.corrupt(rec, cfg, tmp)
            text = yaml.safe_dump(cfg)
            (tmp / "run.yaml").write_bytes(case.text(text) if case.text is not None else text.encode())
            if case.command is not None:
                commands = [case.command(rec, tmp)]
            else:
                commands = [["check", str(tmp / "run.yaml"), "--log-json"]] if case.check else []
                if with_run and case.run:
                    commands.append(["run", str(tmp / "run.yaml"), "--quiet", *case.args])
            for cmd in commands:
                result, outcome, leaks, wall_s = _invoke(cmd, case.expect, limit_s)
                rows.append((case.name, cmd[0], outcome, leaks, _last_line(result).replace(str(work), "<tmp>"),
                             wall_s))
        finally:
            if callable(undo):
                undo()
            sys.modules.clear()
            sys.modules.update(saved)
    return rows


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--duration-s", type=float, default=1.0)
    ap.add_argument("--only", nargs="*", default=None, help="Run only the cases whose name contains one of these.")
    ap.add_argument("--no-run", action="store_true", help="Only planefuse check.")
    ap.add_argument("--limit-s", type=float, default=120.0, help="A command running longer is a hang [s].")
    args = ap.parse_args()
    cases = [c for c in CASES if args.only is None or any(s in c.name for s in args.only)]
    with tempfile.TemporaryDirectory() as d:
        work = Path(d)
        rec_dir = work / "recording"
        simulate(default_scene_config(duration_s=args.duration_s, seed=2)).write(rec_dir, image_format="jpg")
        rows = run_cases(cases, rec_dir, work, with_run=not args.no_run, limit_s=args.limit_s)
    print("| bad input | command | outcome | NumPy warnings | s | message (first error line) |")
    print("|---|---|---|---|---|---|")
    for name, cmd, outcome, leaks, msg, wall_s in rows:
        print(f"| {name} | {cmd} | {outcome} | {leaks} | {wall_s:.1f} | {msg.replace('|', '/')} |")
    tally = {o: sum(r[2] == o for r in rows) for o in ("clear error", "repair reported", "accepted (legitimate)",
                                                        "traceback", "silent acceptance", "hang")}
    print(f"\n{len(rows)} inputs tried ({len(cases)} bad inputs): " + ", ".join(f"{v} {k}" for k, v in tally.items())
          + f", {sum(r[3] > 0 for r in rows)} with NumPy runtime warnings")


if __name__ == "__main__":
    main()
