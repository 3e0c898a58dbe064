"""Hostile inputs, round two (issue 39): ``check`` and ``run`` give one verdict, one writer per output folder,
write errors name the path, a failed or interrupted run says so, the memory check counts the writer's buffers
against the process's limits."""

from __future__ import annotations

import errno
import json
import os
import re
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
import yaml
from typer.testing import CliRunner

from planefuse.cli import app
from planefuse.config import example_yaml
from planefuse.grid import PlaneStack
from planefuse.outputs import OutputWriter
from planefuse.outputs._lock import LOCK_FILE, OutputLock, lock_holder
from planefuse.pipeline import SystemParams, _system, check_memory, filter_memory_bytes, writer_buffered_steps

SRC = Path(__file__).resolve().parents[1] / "src"


def _config(tmp: Path, rec: Path, **outputs) -> Path:
    cfg = yaml.safe_load(example_yaml(str(rec)))
    cfg["outputs"].update(out_dir=str(tmp / "out"), figures=False, report=False, animation="none", **outputs)
    p = tmp / "run.yaml"
    p.write_text(yaml.safe_dump(cfg))
    return p


def _manifest(rec: Path, edit) -> None:
    m = yaml.safe_load((rec / "scene.yaml").read_text())
    edit(m)
    (rec / "scene.yaml").write_text(yaml.safe_dump(m))


def _verdicts(cfg: Path):
    """(exit code, message) of ``check --log-json`` and of ``run``: the first error of each."""
    c = CliRunner().invoke(app, ["check", str(cfg), "--log-json"])
    r = CliRunner().invoke(app, ["run", str(cfg), "--quiet"])
    for res in (c, r):
        assert res.exception is None or isinstance(res.exception, SystemExit), res.exception
    errors = [i for i in json.loads(c.output.strip().splitlines()[-1])["issues"] if i["level"] == "error"]
    return c.exit_code, errors, r.exit_code, " ".join(r.output.split())


def _imu_csv(rec: Path) -> Path:
    return next((rec / "imu").glob("*.csv"))


def _imu_nan(rec: Path) -> None:
    p = _imu_csv(rec)
    lines = p.read_text().splitlines()
    lines[5] = ",".join(["nan"] + lines[5].split(",")[1:])
    p.write_text("\n".join(lines) + "\n")


def _imu_backwards(rec: Path) -> None:
    p = _imu_csv(rec)
    lines = p.read_text().splitlines()
    lines[5] = ",".join(["0.0"] + lines[5].split(",")[1:])
    p.write_text("\n".join(lines) + "\n")


def _audio_late(rec: Path) -> None:
    _manifest(rec, lambda m: [s.update(start_time_s=100.0) for s in m["sensors"] if s["type"] == "binaural"])


@pytest.mark.parametrize("corrupt, words", [
    (_imu_nan, r"imu\.csv: line 6: time_s is not finite"),
    (_imu_backwards, r"imu\.csv: line 6: time_s 0\.0 goes backwards"),
    (_audio_late, r"streams: streams do not overlap in time \(latest start 100\.000 s"),
])
def test_check_and_run_give_the_same_verdict(rec_copy, tmp_path, corrupt, words):
    """Inputs ``check`` refused and ``run`` ran (the IMU is not used with the default attitude source; a sound
    stream 97 s after the recording added output steps at 100-103 s): both refuse, with the same words."""
    corrupt(rec_copy)
    code, errors, run_code, run_out = _verdicts(_config(tmp_path, rec_copy))
    assert code == 1 and any(re.search(words, f"{e['subject']}: {e['message']}") for e in errors), errors
    assert run_code == 1 and re.search(words, run_out) and "nothing was run" in run_out
    assert not (tmp_path / "out").exists()  # refused before the output folder was made


def test_an_implausible_lens_distortion_is_refused_by_check_and_run(rec_copy, tmp_path):
    def k1(m):
        cam = next(s for s in m["sensors"] if s["type"] == "camera")
        cam["dist"] = [50.0, 0.0, 0.0, 0.0, 0.0]

    _manifest(rec_copy, k1)
    code, errors, run_code, run_out = _verdicts(_config(tmp_path, rec_copy))
    assert code == 1 and "not a plausible calibration" in errors[0]["message"] and "'cam0'" in errors[0]["message"]
    assert run_code == 1 and "not a plausible calibration" in run_out


# -- one writer per output folder -----------------------------------------------------------------------------------
def _stack():
    return PlaneStack.from_extent((0.1, 1.0), (0.0, 1.0), (0.0, 1.0), 0.1)


def test_a_second_writer_of_a_folder_is_refused_until_the_first_ends(tmp_path):
    out = tmp_path / "out"
    w = OutputWriter(out, _stack(), config_hash="a")
    assert (out / LOCK_FILE).read_text().split()[0] == str(os.getpid())
    assert f"PID {os.getpid()}" in lock_holder(out)
    with pytest.raises(ValueError, match=f"being written by another planefuse run \\(PID {os.getpid()} on "):
        OutputWriter(out, _stack(), config_hash="a")
    w.finish()
    assert not (out / LOCK_FILE).exists() and lock_holder(out) is None
    with OutputWriter(out, _stack(), config_hash="a"):
        pass
    assert not (out / LOCK_FILE).exists()  # released at the end of the with block


def test_a_lock_left_by_a_dead_process_is_taken_over_with_a_warning(tmp_path):
    out = tmp_path / "out"
    out.mkdir()
    dead = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"], capture_output=True, text=True)
    (out / LOCK_FILE).write_text(f"{dead.stdout.strip()} {os.uname().nodename} 2026-12-07 08:00:00\n")
    assert lock_holder(out) is None  # nobody holds it
    with pytest.warns(UserWarning, match=f"took over the lock of a planefuse run that is no longer running \\(PID {dead.stdout.strip()} "):
        lock = OutputLock(out)
        lock.acquire()
    lock.release()
    assert not (out / LOCK_FILE).exists()


HOLD = """
import sys, time
from planefuse.outputs._lock import OutputLock
lock = OutputLock(sys.argv[1]); lock.acquire(); print("held", flush=True); time.sleep(60)
"""


def test_a_lock_held_by_another_process_refuses_check_and_run_and_dies_with_it(recording_dir, tmp_path):
    out = tmp_path / "out"
    out.mkdir()
    env = {**os.environ, "PYTHONPATH": str(SRC)}
    proc = subprocess.Popen([sys.executable, "-c", HOLD, str(out)], env=env, stdout=subprocess.PIPE, text=True)
    try:
        assert proc.stdout.readline().strip() == "held"
        cfg = _config(tmp_path, recording_dir)
        code, errors, run_code, run_out = _verdicts(cfg)
        assert code == 1 and f"PID {proc.pid}" in errors[0]["message"] and "being written" in errors[0]["message"]
        assert run_code == 1 and f"another planefuse run (PID {proc.pid}" in run_out
        with pytest.raises(ValueError, match=f"PID {proc.pid}"):
            OutputLock(out).acquire()
    finally:
        proc.kill()
        proc.wait()
    assert lock_holder(out) is None  # the kernel released the lock with the process
    with pytest.warns(UserWarning, match="took over the lock"):
        r = CliRunner().invoke(app, ["run", str(cfg), "--quiet"])
    assert r.exit_code == 0, r.output
    assert json.loads((out / "run_state.json").read_text())["status"] == "finished"


WAITING = """
import sys, time
from pathlib import Path
from planefuse.outputs import OutputWriter
o = OutputWriter.write_occupancy
def w(self, *a, **k):
    go = Path(sys.argv[2])
    while not go.exists():  # hold the folder until the test says go
        time.sleep(0.02)
    return o(self, *a, **k)
OutputWriter.write_occupancy = w
from planefuse.cli import app
app(["run", sys.argv[1], "--quiet"])
"""


def test_two_concurrent_runs_on_one_folder_one_is_refused(recording_dir, tmp_path):
    """Two ``planefuse run`` processes on one output folder at once: the second exits 1 naming the first, which
    finishes; the folder holds one finished run."""
    cfg = _config(tmp_path, recording_dir, chunk_steps=2)
    go = tmp_path / "go"
    env = {**os.environ, "PYTHONPATH": str(SRC), "NUMBA_NUM_THREADS": "1"}
    first = subprocess.Popen([sys.executable, "-c", WAITING, str(cfg), str(go)], env=env, stdout=subprocess.PIPE,
                             stderr=subprocess.STDOUT, text=True)
    try:
        deadline = time.monotonic() + 120
        while not (tmp_path / "out" / LOCK_FILE).exists() and time.monotonic() < deadline:
            assert first.poll() is None, first.stdout.read()[-2000:]
            time.sleep(0.02)
        second = subprocess.run([sys.executable, "-m", "planefuse", "run", str(cfg), "--quiet"], env=env,
                                capture_output=True, text=True, timeout=300)
    finally:
        go.write_text("go")
    out1, _ = first.communicate(timeout=300)
    assert first.returncode == 0, out1[-2000:]
    assert second.returncode == 1, second.stdout[-2000:] + second.stderr[-2000:]
    assert f"being written by another planefuse run (PID {first.pid} on " in " ".join(second.stdout.split())
    assert json.loads((tmp_path / "out" / "run_state.json").read_text())["status"] == "finished"


# -- write errors and the state of a run that did not finish ------------------------------------------------------
def test_a_full_disk_names_the_file_and_the_state_says_failed(recording_dir, tmp_path, monkeypatch):
    cfg = _config(tmp_path, recording_dir, chunk_steps=2)
    calls = {"n": 0}
    real_fsync = os.fsync

    def fsync(fd):  # the disk fills up after the first few files
        calls["n"] += 1
        if calls["n"] > 6:
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
        return real_fsync(fd)

    monkeypatch.setattr(os, "fsync", fsync)
    r = CliRunner().invoke(app, ["run", str(cfg), "--quiet"])
    assert r.exit_code == 1 and isinstance(r.exception, SystemExit), r.output
    line = " ".join(r.output.split())
    assert "[Errno 28] cannot write " in line and str(tmp_path / "out") in line and "No space left" in line
    state = json.loads((tmp_path / "out" / "run_state.json").read_text())
    assert state["status"] == "failed" and "No space left on device" in state["error"]
    assert not (tmp_path / "out" / LOCK_FILE).exists()


def test_sigterm_leaves_the_state_interrupted_and_the_run_resumes(recording_dir, tmp_path):
    cfg = _config(tmp_path, recording_dir, chunk_steps=2)
    slow = ("import sys, time\nfrom planefuse.outputs import OutputWriter\no = OutputWriter.write_occupancy\n"
            "def w(self, *a, **k):\n    time.sleep(0.2)\n    return o(self, *a, **k)\nOutputWriter.write_occupancy = w\n"
            "from planefuse.cli import app\napp(['run', sys.argv[1], '--quiet'])\n")
    env = {**os.environ, "PYTHONPATH": str(SRC), "NUMBA_NUM_THREADS": "1"}
    proc = subprocess.Popen([sys.executable, "-c", slow, str(cfg)], env=env, stdout=subprocess.PIPE,
                            stderr=subprocess.STDOUT, text=True)
    state_file = tmp_path / "out" / "run_state.json"
    deadline = time.monotonic() + 120
    while time.monotonic() < deadline:
        try:
            if json.loads(state_file.read_text()).get("n_chunks_done", 0) >= 1:
                break
        except (OSError, ValueError):
            pass
        assert proc.poll() is None, proc.stdout.read()[-2000:]
        time.sleep(0.02)
    proc.send_signal(signal.SIGTERM)
    out, _ = proc.communicate(timeout=120)
    assert proc.returncode == 143, out[-2000:]
    assert json.loads(state_file.read_text())["status"] == "interrupted"
    assert not (tmp_path / "out" / LOCK_FILE).exists()
    r = CliRunner().invoke(app, ["run", str(cfg), "--quiet"])
    assert r.exit_code == 0 and json.loads(state_file.read_text())["status"] == "finished"


# -- memory ------------------------------------------------------------------------------------------------------
def test_the_memory_check_counts_the_writers_chunk_buffers(monkeypatch):
    stack = PlaneStack.from_extent((0.1, 0.5, 1.0, 1.5), (0.0, 40.0), (0.0, 40.0), 0.1)
    params = SystemParams()
    cells = 4 * 400 * 400
    base = filter_memory_bytes(stack, params)
    assert filter_memory_bytes(stack, params, buffered_steps=writer_buffered_steps(10_000)) == base + cells * 4 * 20_000
    assert writer_buffered_steps(50, zarr=False, n_steps=1000) == 1100  # without zarr every step stays in memory
    monkeypatch.setattr(_system, "available_memory_bytes", lambda: 8 * 2**30)
    check_memory(stack, params, buffered_steps=writer_buffered_steps(50))  # 0.6 GiB: fits
    with pytest.raises(ValueError, match=r"and 20000 buffered output steps \(outputs.chunk_steps\) needs about 47.\d "
                                         r"GiB, more than 80 % of the 8 GiB available .*outputs.chunk_steps"):
        check_memory(stack, params, buffered_steps=writer_buffered_steps(10_000))


def test_chunk_steps_too_large_for_memory_is_refused_by_check_and_run(recording_dir, tmp_path, monkeypatch):
    monkeypatch.setattr(_system, "available_memory_bytes", lambda: 2 * 2**30)
    code, errors, run_code, run_out = _verdicts(_config(tmp_path, recording_dir, chunk_steps=10_000))
    assert code == 1 and "buffered output steps" in errors[0]["message"]
    assert run_code == 1 and "buffered output steps" in run_out


LIMITED = """
import resource, sys
from planefuse.pipeline import available_memory_bytes, memory_limits_bytes, check_memory, SystemParams
from planefuse.grid import PlaneStack
resource.setrlimit(resource.RLIMIT_AS, (int(sys.argv[1]), resource.RLIM_INFINITY))
limits = memory_limits_bytes()
stack = PlaneStack.from_extent((0.1, 0.5, 1.0, 1.5), (0.0, 40.0), (0.0, 40.0), 0.02)
try:
    check_memory(stack, SystemParams())
    print("accepted", limits)
except ValueError as err:
    print("refused", limits["RLIMIT_AS"], str(err))
"""


def test_the_memory_check_compares_with_the_process_address_space_limit():
    """A 40 m grid of 2 cm cells (4 x 2000 x 2000 x 49: 3.2 GiB of filter state) under ``ulimit -v`` of 3 GiB
    beyond what the interpreter holds is refused before allocating, whatever the machine's free memory."""
    probe = subprocess.run([sys.executable, "-c", "import planefuse.pipeline, re; print(re.search(r'VmSize:\\s+(\\d+)',"
                            " open('/proc/self/status').read()).group(1))"],
                           env={**os.environ, "PYTHONPATH": str(SRC)}, capture_output=True, text=True)
    if probe.returncode != 0:
        pytest.skip(f"no /proc/self/status here: {probe.stderr[-200:]}")
    limit = int(probe.stdout) * 1024 + 3 * 2**30
    r = subprocess.run([sys.executable, "-c", LIMITED, str(limit)], env={**os.environ, "PYTHONPATH": str(SRC)},
                       capture_output=True, text=True, timeout=120)
    assert r.stdout.startswith("refused"), r.stdout + r.stderr[-2000:]
    left = int(r.stdout.split()[1])
    assert 2 * 2**30 < left < 3.5 * 2**30  # what the limit leaves, not the machine's free memory
    assert "4 planes x 2000 x 2000 cells" in r.stdout and "RLIMIT_AS" in r.stdout


def test_a_memory_error_beyond_the_estimate_is_one_line(recording_dir, tmp_path, monkeypatch):
    import planefuse.pipeline

    def boom(*a, **kw):
        raise MemoryError("Unable to allocate 2.92 GiB for an array")

    monkeypatch.setattr(planefuse.pipeline, "run_plan", boom)
    r = CliRunner().invoke(app, ["run", str(_config(tmp_path, recording_dir)), "--quiet"])
    assert r.exit_code == 1 and isinstance(r.exception, SystemExit)
    assert "out of memory during the run (Unable to allocate 2.92 GiB" in " ".join(r.output.split())


# -- calibration plausibility -------------------------------------------------------------------------------------
@pytest.mark.parametrize("K, dist, match", [
    ([[300, 0, 180], [0, 300, 144], [0, 0, 1]], [0, 0, 0, 0, 0], None),
    ([[300, 0, 180], [0, 300, 144], [0, 0, 1]], [-0.3, 0.1, 0.001, -0.002, 0], None),  # a typical lens
    ([[300, 0, 180], [0, 300, 144], [0, 0, 1]], [50, 0, 0, 0, 0], "moves the image's edges by 200% of their radius"),
    ([[300, 0, 180], [0, 300, 144], [0, 0, 1]], [5, 0, 0, 0, 0], "by 66% of their radius"),
    ([[300, 0, 180], [0, 300, 144], [0, 0, 1]], [-0.5, 0, 0, 0, 0], "folds back inside the image"),
    ([[300, 0, 180], [0, 300, 144], [0, 0, 1]], [0, 0, 0.5, 0, 0], "by 90% of their radius"),
    ([[300, 0, 500], [0, 300, 144], [0, 0, 1]], [0, 0, 0, 0, 0], r"principal point \(500, 144\) px lies outside"),
    ([[300, 0, 180], [0, 1000, 144], [0, 0, 1]], [0, 0, 0, 0, 0], "fy / fx = 3.33"),
    ([[4.2, 0, 180], [0, 4.2, 144], [0, 0, 1]], [0, 0, 0, 0, 0], "177 degree horizontal field of view"),
    ([[60000, 0, 180], [0, 60000, 144], [0, 0, 1]], [0, 0, 0, 0, 0], "0.344 degree horizontal field of view"),
])
def test_implausible_intrinsics_are_named(K, dist, match):
    from planefuse.geometry import CameraIntrinsics, intrinsics_problem

    problem = intrinsics_problem(CameraIntrinsics(np.array(K, float), 360, 288, np.array(dist, float)))
    assert (problem is None) if match is None else re.search(match, problem), problem


def test_real_calibrations_are_plausible():
    from planefuse.calib import EPFL_TERRACE_TSAI, pinhole_from_tsai
    from planefuse.geometry import intrinsics_problem

    cams = [pinhole_from_tsai(EPFL_TERRACE_TSAI[f"c{i}"], metres_per_unit=1e-3, width_px=360, height_px=288)[0]
            for i in range(4)]
    wildtrack = Path(__file__).resolve().parents[2] / "shared" / "data" / "wildtrack"
    if wildtrack.is_dir():
        from planefuse.calib._wildtrack import load_wildtrack_rig

        cams += list(load_wildtrack_rig(wildtrack).values())  # C1 and C6 fold back beyond the edges, in the corners
    assert [intrinsics_problem(c.intrinsics) for c in cams] == [None] * len(cams)


def test_the_cgroup_memory_limit_is_read_from_v2_and_v1(tmp_path):
    from planefuse.pipeline._system import _cgroup_memory_left_bytes

    root = tmp_path / "cgroup"
    (root / "user" / "job").mkdir(parents=True)
    (tmp_path / "self").write_text("0::/user/job\n")
    for d, limit, used in ((root / "user" / "job", "max", 1), (root / "user", str(3 * 2**30), 2**30), (root, "max", 5)):
        (d / "memory.max").write_text(limit + "\n")
        (d / "memory.current").write_text(f"{used}\n")
    assert _cgroup_memory_left_bytes(tmp_path / "self", root) == 2 * 2**30  # the parent's limit binds
    (root / "user" / "job" / "memory.max").write_text(f"{2**30 + 100}\n")
    assert _cgroup_memory_left_bytes(tmp_path / "self", root) == 2**30 + 99  # now the group's own
    (tmp_path / "v1").write_text("4:memory:/docker/abc\n0::/\n")
    (root / "memory" / "docker" / "abc").mkdir(parents=True)
    (root / "memory" / "docker" / "abc" / "memory.limit_in_bytes").write_text(f"{4 * 2**30}\n")
    (root / "memory" / "docker" / "abc" / "memory.usage_in_bytes").write_text(f"{2**30}\n")
    for f in ("memory.max", "memory.current"):
        (root / f).unlink()
    assert _cgroup_memory_left_bytes(tmp_path / "v1", root) == 3 * 2**30
    (root / "memory" / "docker" / "abc" / "memory.limit_in_bytes").write_text("9223372036854771712\n")
    assert _cgroup_memory_left_bytes(tmp_path / "v1", root) is None  # v1's "no limit"
    assert _cgroup_memory_left_bytes(tmp_path / "absent", root) is None
