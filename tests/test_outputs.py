"""Run outputs: atomic writes survive SIGKILL, Ctrl-C leaves valid files, a re-run resumes; progress modes."""

from __future__ import annotations

import io
import json
import os
import signal
import subprocess
import sys
import time
import warnings
from pathlib import Path

import motmetrics as mm
import numpy as np
import pytest
import zarr

from planefuse.config import example_yaml, load_config
from planefuse.grid import GroundDetections, PlaneStack
from planefuse.outputs import (
    OutputWriter,
    atomic_write_json,
    mot_rows,
    progress_steps,
    read_table,
)

SRC = Path(__file__).resolve().parents[1] / "src"

# A long fake run through the writer: occupancy of step k is a known function of k; the "filter state" is
# the running sum of the steps, saved as a checkpoint, so a resumed run ends with the same sum only if it
# restarted exactly at the last finished chunk with the saved state.
JOB = '''
import signal, sys, time
import numpy as np
# Ctrl-C as a shell's foreground job gets it: the test runner's process may have SIGINT ignored (a pytest-xdist
# worker did in CI, after earlier tests), and an ignored signal is inherited by the child, which then never stops
signal.signal(signal.SIGINT, signal.default_int_handler)
from planefuse.config import load_config
from planefuse.grid import GroundDetections
from planefuse.outputs import OutputWriter, progress_steps

def occ(stack, k):
    return ((np.arange(np.prod(stack.shape)).reshape(stack.shape) + k) % 101 / 100.0).astype(np.float32)

from planefuse.grid import PlaneStack

cfg = load_config(sys.argv[1])
plan = cfg.plan()
n, delay = int(sys.argv[2]), float(sys.argv[3])
stack = PlaneStack.from_extent(cfg.planes.heights_m, (0, 10), (0, 10), cfg.planes.cell_size_m)
try:
    with progress_steps("json") as progress, OutputWriter(plan.out_dir, stack, config_hash=plan.config_key,
                                                          chunk_steps=plan.outputs.chunk_steps) as out:
        state = out.load_checkpoint()
        acc = 0 if state is None else int(state["acc"])
        with progress.step("filter", total=n, completed=out.resume_step) as advance:
            for k in range(out.resume_step, n):
                acc += k
                out.write_detections(k, GroundDetections(0.1 * k, [[1 + 0.01 * k, 2.0]], [0.9]))
                out.write_tracks(k, 0.1 * k, [7, 8], [[1 + 0.01 * k, 2.0], [3.0, 4.0]])
                out.write_occupancy(k, 0.1 * k, occ(stack, k), checkpoint=lambda: {"acc": np.array(acc)})
                advance(1)
                time.sleep(delay)
        out.write_metrics({"acc": acc})
        out.finish()
except KeyboardInterrupt:
    sys.exit(130)
'''


def _stack(cfg) -> PlaneStack:
    return PlaneStack.from_extent(cfg.planes.heights_m, (0, 10), (0, 10), cfg.planes.cell_size_m)


def _writer(cfg, resume: bool = True) -> OutputWriter:
    plan = cfg.plan()
    return OutputWriter(plan.out_dir, _stack(cfg), config_hash=plan.config_key, chunk_steps=plan.outputs.chunk_steps,
                        resume=resume)


def _occ(stack: PlaneStack, k: int) -> np.ndarray:
    return ((np.arange(np.prod(stack.shape)).reshape(stack.shape) + k) % 101 / 100.0).astype(np.float32)


@pytest.fixture
def job(tmp_path):
    script = tmp_path / "job.py"
    script.write_text(JOB)
    text = (example_yaml("rec").replace("cell_size_m: 0.1", "cell_size_m: 0.5")
            .replace("chunk_steps: 50", "chunk_steps: 5").replace("figures: true", "figures: false")
            .replace("report: true", "report: false").replace("animation: gif", "animation: none"))
    cfg_path = tmp_path / "run.yaml"
    cfg_path.write_text(text)
    env = dict(os.environ, PYTHONPATH=str(SRC), PYTHONUNBUFFERED="1")

    def start(n: int, delay: float, config: Path = cfg_path) -> subprocess.Popen:
        return subprocess.Popen([sys.executable, str(script), str(config), str(n), str(delay)], env=env,
                                stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)

    return start, cfg_path


def _wait_state(out_dir: Path, chunks: int, proc: subprocess.Popen, timeout_s: float = 30.0) -> dict:
    t0 = time.monotonic()
    while time.monotonic() - t0 < timeout_s:
        try:
            state = json.loads((out_dir / "run_state.json").read_text())
            if state["n_chunks_done"] >= chunks:
                return state
        except (OSError, ValueError):  # pragma: no cover - not yet written
            pass
        assert proc.poll() is None, proc.communicate()
        time.sleep(0.02)
    raise AssertionError("the job did not reach the expected chunk in time")


def _events(stderr: str) -> list[dict]:
    return [json.loads(l) for l in stderr.splitlines() if l.startswith("{")]


def _assert_outputs_consistent(out_dir: Path, stack: PlaneStack, n_steps: int) -> None:
    g = zarr.open_group(out_dir / "occupancy.zarr", mode="r")
    occ, t = g["occupancy"][:], g["time_s"][:]
    assert occ.shape == (n_steps,) + stack.shape and t.shape == (n_steps,)
    np.testing.assert_array_equal(occ, np.stack([_occ(stack, k) for k in range(n_steps)]))
    np.testing.assert_allclose(t, 0.1 * np.arange(n_steps))
    tracks = read_table(out_dir / "tracks.csv")
    raw_ids = [l.split(",")[2] for l in (out_dir / "tracks.csv").read_text().splitlines()[1:]]
    assert all(i.isdigit() for i in raw_ids), "track ids must stay integers across a resume"
    np.testing.assert_array_equal(np.sort(tracks["step"]), np.repeat(np.arange(n_steps), 2))
    dets = read_table(out_dir / "detections.csv")
    np.testing.assert_array_equal(dets["step"], np.arange(n_steps))
    mot = mm.io.loadtxt(str(out_dir / "tracks_mot.txt"), fmt="mot15-2D")  # an independent MOT reader
    assert len(mot) == 2 * n_steps and set(mot.index.get_level_values("Id")) == {7, 8}


def test_ctrl_c_leaves_valid_outputs_and_rerun_resumes(job, tmp_path):
    start, cfg_path = job
    cfg = load_config(cfg_path)
    out_dir, stack = cfg.outputs.out_dir, _stack(cfg)
    proc = start(10_000, 0.01)
    _wait_state(out_dir, 2, proc)
    proc.send_signal(signal.SIGINT)
    _, err = proc.communicate(timeout=30)
    assert proc.returncode == 130, err
    assert any(e["event"] == "interrupted" for e in _events(err))
    state = json.loads((out_dir / "run_state.json").read_text())
    assert state["status"] == "interrupted" and state["n_chunks_done"] >= 2
    assert state["n_steps_written"] >= 5 * state["n_chunks_done"]
    _assert_outputs_consistent(out_dir, stack, state["n_steps_written"])  # partial chunk flushed, all valid

    proc = start(43, 0.0)
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == 0, err
    first = _events(err)[0]
    assert first["event"] == "start" and first["completed"] == 5 * state["n_chunks_done"]  # skipped finished chunks
    _assert_outputs_consistent(out_dir, stack, 43)
    assert json.loads((out_dir / "metrics.json").read_text())["acc"] == sum(range(43))  # checkpoint restored
    final = json.loads((out_dir / "run_state.json").read_text())
    assert final["status"] == "finished" and final["n_chunks_done"] == 8

    same = _writer(cfg)
    assert same.resumed and same.resume_step == 40  # only full chunks count: the short tail is recomputed
    with pytest.raises(ValueError, match="being written by another planefuse run"):
        _writer(cfg)  # one writer per folder, in one process too
    same.close()
    changed = cfg.model_copy(update={"planes": cfg.planes.model_copy(update={"heights_m": [0.0, 0.7]})})
    with pytest.raises(ValueError, match="results of another run"):
        _writer(changed)  # another configuration's results are not replaced silently
    fresh = _writer(changed, resume=False)  # --fresh
    assert not fresh.resumed and fresh.resume_step == 0 and fresh.n_steps == 0
    assert not (out_dir / "tracks.csv").exists() or read_table(out_dir / "tracks.csv")["step"].size == 0


def test_sigkill_mid_run_leaves_no_partial_file_and_resumes(job):
    start, cfg_path = job
    cfg = load_config(cfg_path)
    out_dir, stack = cfg.outputs.out_dir, _stack(cfg)
    proc = start(10_000, 0.0)
    _wait_state(out_dir, 2, proc)
    proc.kill()
    proc.communicate(timeout=30)
    state = json.loads((out_dir / "run_state.json").read_text())
    # every final file parses; the committed chunks are intact (files may hold more steps than committed)
    g = zarr.open_group(out_dir / "occupancy.zarr", mode="r")
    done = 5 * state["n_chunks_done"]
    np.testing.assert_array_equal(g["occupancy"][:done], np.stack([_occ(stack, k) for k in range(done)]))
    read_table(out_dir / "tracks.csv")
    read_table(out_dir / "detections.csv")
    proc = start(done + 7, 0.0)
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == 0, err
    _assert_outputs_consistent(out_dir, stack, done + 7)
    assert not list(out_dir.glob(".*pf-tmp*")), "stale temporary files were not cleaned"


KILL_WRITER = '''
import hashlib, sys
from planefuse.outputs import atomic_write_bytes
path = sys.argv[1]
v = 0
while True:
    payload = bytes([v % 251]) * 4_000_000
    atomic_write_bytes(path, payload + hashlib.sha256(payload).digest())
    v += 1
'''


def test_sigkill_during_atomic_write_never_exposes_partial_file(tmp_path):
    import hashlib

    script = tmp_path / "w.py"
    script.write_text(KILL_WRITER)
    target = tmp_path / "big.bin"
    env = dict(os.environ, PYTHONPATH=str(SRC))
    rng = np.random.default_rng(0)
    for _ in range(3):
        proc = subprocess.Popen([sys.executable, str(script), str(target)], env=env)
        t0 = time.monotonic()
        while not target.exists() and time.monotonic() - t0 < 30:  # the first version is complete
            time.sleep(0.01)
        time.sleep(0.05 + 0.2 * rng.random())  # then kill it at some point of a later write
        proc.kill()
        proc.wait()
        data = target.read_bytes()
        assert len(data) == 4_000_032 and hashlib.sha256(data[:-32]).digest() == data[-32:]


def test_atomic_write_keeps_old_content_on_error(tmp_path):
    p = tmp_path / "m.json"
    atomic_write_json(p, {"a": np.float32(1.5), "b": np.arange(3), "c": float("nan")})
    assert json.loads(p.read_text()) == {"a": 1.5, "b": [0, 1, 2], "c": None}
    with pytest.raises(TypeError):
        atomic_write_json(p, {"x": object()})
    assert json.loads(p.read_text())["a"] == 1.5
    assert [q.name for q in tmp_path.iterdir()] == ["m.json"]
    assert (p.stat().st_mode & 0o777) == (0o666 & ~_umask())


def _umask() -> int:
    m = os.umask(0)
    os.umask(m)
    return m


def test_writer_input_errors_and_mot_layout(tmp_path):
    stack = PlaneStack.from_extent([0.0, 1.0], (0, 4), (0, 3), 0.5)
    w = OutputWriter(tmp_path, stack, config_hash="h", chunk_steps=4)
    with pytest.raises(ValueError, match="shape"):
        w.write_occupancy(0, 0.0, np.zeros((2, 3, 3)))
    with pytest.raises(ValueError, match="out of order"):
        w.write_occupancy(1, 0.0, np.zeros(stack.shape))
    with pytest.raises(ValueError, match="disagree"):
        w.write_tracks(0, 0.0, [1, 2], [[0, 0]])
    with pytest.raises(ValueError, match="chunk_steps"):
        OutputWriter(tmp_path, stack, config_hash="h", chunk_steps=0)
    rows = mot_rows([0, 4], [3, 5], [[1.0, 2.0], [2.0, 1.0]], 0.8, person_radius_m=0.25)
    np.testing.assert_allclose(rows[0], [1, 3, 0.75, 1.75, 0.5, 0.5, 0.8, 1.0, 2.0, -1])
    assert rows[1, 0] == 5
    w.write_detections(0, GroundDetections(0.0, [[1.0, 1.0]], [0.5], source="bof"))
    w.write_occupancy(0, 0.0, np.zeros(stack.shape))
    for k in range(1, 4):
        w.write_occupancy(k, 0.1 * k, np.zeros(stack.shape))  # step 3 commits the chunk 0..3
    with pytest.raises(ValueError, match="before its occupancy"):
        w.write_tracks(3, 0.3, [1], [[0.0, 0.0]])
    w.finish()
    assert not (tmp_path / "figures").exists() and not (tmp_path / "report.html").exists()  # the pipeline's job
    assert read_table(tmp_path / "detections.csv")["source"].tolist() == ["bof"]
    assert zarr.open_group(tmp_path / "occupancy.zarr", mode="r")["occupancy"].shape == (4,) + stack.shape


def test_interruption_between_a_steps_tables_and_its_occupancy_leaves_them_in_step(tmp_path):
    """Regression (seen once in CI): Ctrl-C after a step's tracks were recorded but before its occupancy left
    tracks.csv one step ahead of occupancy.zarr and run_state.json."""
    stack = PlaneStack.from_extent([0.0, 1.0], (0, 4), (0, 3), 0.5)
    with pytest.raises(KeyboardInterrupt):
        with OutputWriter(tmp_path, stack, config_hash="h", chunk_steps=4) as w:
            for k in range(6):
                w.write_tracks(k, 0.1 * k, [1], [[0.5 * k, 1.0]])
                w.write_detections(k, GroundDetections(0.1 * k, [[0.5 * k, 1.0]], [0.5], source="bof"))
                if k == 5:
                    raise KeyboardInterrupt  # step 5's occupancy never written
                w.write_occupancy(k, 0.1 * k, np.zeros(stack.shape))
    assert zarr.open_group(tmp_path / "occupancy.zarr", mode="r")["occupancy"].shape[0] == 5
    assert read_table(tmp_path / "tracks.csv")["step"].tolist() == [0, 1, 2, 3, 4]
    assert read_table(tmp_path / "detections.csv")["step"].tolist() == [0, 1, 2, 3, 4]
    assert np.loadtxt(tmp_path / "tracks_mot.txt", delimiter=",", ndmin=2)[:, 0].tolist() == [1, 2, 3, 4, 5]
    assert json.loads((tmp_path / "run_state.json").read_text())["status"] == "interrupted"
    # rows held back are written with their step
    w = OutputWriter(tmp_path / "b", stack, config_hash="h", chunk_steps=4)
    w.write_tracks(0, 0.0, [1], [[0.5, 1.0]])
    w.flush("running")
    assert read_table(tmp_path / "b" / "tracks.csv")["step"].size == 0
    w.write_occupancy(0, 0.0, np.zeros(stack.shape))
    w.finish()
    assert read_table(tmp_path / "b" / "tracks.csv")["step"].tolist() == [0]


def test_progress_modes():
    buf = io.StringIO()
    with progress_steps("json", stream=buf, json_interval_s=0.0) as p:
        with p.step("register", total=4, unit="frames") as advance:
            for _ in range(4):
                advance(1)
    ev = [json.loads(l) for l in buf.getvalue().splitlines()]
    assert [e["event"] for e in ev] == ["start"] + ["progress"] * 4 + ["end"]
    assert ev[-2]["done"] == 4 and ev[-2]["eta_s"] == 0 and ev[-2]["rate_per_s"] > 0
    # a warning raised inside is an event of the stream (every line JSON), and the usual display comes back after
    buf = io.StringIO()
    with progress_steps("json", stream=buf) as p:
        warnings.warn("frames dropped\n  at t=2.96 s", UserWarning, stacklevel=1)
    (w,) = [json.loads(l) for l in buf.getvalue().splitlines()]
    assert w["event"] == "warning" and w["category"] == "UserWarning" and w["message"] == "frames dropped at t=2.96 s"
    with pytest.warns(UserWarning, match="after"):
        warnings.warn("after", UserWarning, stacklevel=1)
    assert buf.getvalue().count("\n") == 1
    # a total that was an estimate (rich mode): the finished bar shows the items done
    buf = io.StringIO()
    with progress_steps("rich", stream=buf) as p, p.step("track", total=5, unit="steps") as advance:
        advance(4)
    assert "4/4" in buf.getvalue()
    buf = io.StringIO()
    with progress_steps("quiet", stream=buf) as p, p.step("x", total=3) as advance:
        advance(3)
    assert buf.getvalue() == ""
    buf = io.StringIO()
    with progress_steps("rich", stream=buf) as p, p.step("filter", total=3, unit="frames") as advance:
        for _ in range(3):
            time.sleep(0.02)
            advance(1)
    assert "filter" in buf.getvalue() and "3/3" in buf.getvalue() and "frames/s" in buf.getvalue()
    with pytest.raises(ValueError, match="progress mode"):
        progress_steps("loud").__enter__()


def test_a_run_reads_its_zarr_store_in_one_codec_thread_unless_the_user_chose():
    """run_to_folder asks zarr for one codec thread (each pool thread kept its own C-heap arena of decoded
    chunks: ~50 MB more resident at the end of a 300 s run); a pool size the user configured is kept."""
    from planefuse.pipeline._outputs import one_zarr_codec_thread

    with zarr.config.set({"threading.max_workers": None}):
        one_zarr_codec_thread()
        assert zarr.config.get("threading.max_workers") == 1
    with zarr.config.set({"threading.max_workers": 3}):
        one_zarr_codec_thread()
        assert zarr.config.get("threading.max_workers") == 3
