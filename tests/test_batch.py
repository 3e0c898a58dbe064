"""planefuse.batch: runs as dask.distributed tasks give exactly the serial runs' metrics, on a LocalCluster and
on a real scheduler with its workers started as separate processes on localhost."""

from __future__ import annotations

import os
import socket
import subprocess
import sys
import time
from pathlib import Path

import pytest

pytest.importorskip("distributed")

from planefuse.batch import BatchJob, SceneSpec, run_batch, run_job  # noqa: E402
from planefuse.pipeline import RunPlan, SystemParams  # noqa: E402

SRC = str(Path(__file__).resolve().parents[1] / "src")
TIMING = {"elapsed_s"}  # measured computing time: the only metric that may differ between two runs


def _jobs() -> list[BatchJob]:
    params = SystemParams(laser=False, sound=False)
    return [BatchJob(f"seed{s}", SceneSpec(seed=s, duration_s=1.5), RunPlan(params), tags={"seed": s}) for s in (1, 2)]


def _same(a: dict, b: dict) -> bool:
    return {k: v for k, v in a.items() if k not in TIMING} == {k: v for k, v in b.items() if k not in TIMING}


@pytest.fixture
def workers_see_checkout(monkeypatch):
    """Spawned worker processes import this checkout's planefuse."""
    monkeypatch.setenv("PYTHONPATH", SRC + os.pathsep + os.environ.get("PYTHONPATH", ""))


def test_local_cluster_gives_the_serial_metrics(workers_see_checkout):
    jobs = _jobs()
    serial = [run_job(j) for j in jobs]
    assert all(r.ok for r in serial), [r.error for r in serial]
    batch = run_batch(jobs, n_workers=2, progress_mode="quiet")
    assert [r.name for r in batch] == ["seed1", "seed2"]
    for s, b in zip(serial, batch):
        assert b.ok and b.tags == s.tags
        assert s.metrics["n_camera_frames"] > 0
        assert _same(s.metrics, b.metrics), (s.metrics, b.metrics)


def test_failed_job_is_reported_and_the_others_finish(workers_see_checkout, tmp_path):
    jobs = [BatchJob("missing", str(tmp_path / "no-such-recording")), _jobs()[0]]
    res = run_batch(jobs, n_workers=1, progress_mode="quiet")
    assert not res[0].ok and res[0].error.startswith("missing: ") and "no-such-recording" in res[0].error
    assert "\n" not in res[0].error
    assert res[1].ok and res[1].metrics["moda"] > 0.5


def test_a_runs_warnings_come_back_from_its_worker(workers_see_checkout):
    """What a run warns of on a worker (here: a recording too short to score) comes back with its result, each
    message once, where a remote worker's own output would not be seen."""
    job = BatchJob("short", SceneSpec(seed=1, duration_s=0.8), RunPlan(SystemParams(laser=False, sound=False)))
    here = run_job(job)
    assert here.ok and len(here.warnings) == 1
    assert ("ends within the first 1 s skipped by the evaluation: no scores computed, the run's counts only"
            in here.warnings[0])
    assert "moda" not in here.metrics and here.metrics["n_steps"] >= 1  # the counts of a run without scores
    (remote,) = run_batch([job], n_workers=1, progress_mode="quiet")
    assert remote.warnings == here.warnings


def test_bad_batches_are_refused():
    with pytest.raises(ValueError, match="repeated: a"):
        run_batch([BatchJob("a", SceneSpec()), BatchJob("a", SceneSpec(seed=2))])
    with pytest.raises(ValueError, match="n_workers is for a local cluster"):
        run_batch(_jobs(), scheduler="tcp://127.0.0.1:1", n_workers=2)


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def test_unreachable_scheduler_is_one_clear_error():
    port = _free_port()  # nothing listens there once closed
    with pytest.raises(OSError, match=f"dask scheduler tcp://127.0.0.1:{port}: cannot connect"):
        run_batch(_jobs(), scheduler=f"tcp://127.0.0.1:{port}")


def test_real_scheduler_and_workers_on_localhost(tmp_path):
    """A ``dask scheduler`` and two ``dask worker`` processes, as a user starts them on their machines."""
    port = _free_port()
    address = f"tcp://127.0.0.1:{port}"
    env = {**os.environ, "PYTHONPATH": SRC + os.pathsep + os.environ.get("PYTHONPATH", "")}
    dask = [sys.executable, "-m", "distributed.cli.dask_scheduler"]
    procs = [subprocess.Popen(dask + ["--host", "127.0.0.1", "--port", str(port), "--no-dashboard"], env=env,
                              stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)]
    try:
        time.sleep(2.0)
        for _ in range(2):
            procs.append(subprocess.Popen([sys.executable, "-m", "distributed.cli.dask_worker", address,
                                           "--nthreads", "1", "--no-dashboard"], env=env, cwd=tmp_path,
                                          stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL))
        jobs = _jobs()
        batch = run_batch(jobs, scheduler=address, progress_mode="quiet")
        serial = [run_job(j) for j in jobs]
        for s, b in zip(serial, batch):
            assert b.ok, b.error
            assert _same(s.metrics, b.metrics)
    finally:
        for p in reversed(procs):
            p.terminate()
        for p in procs:
            try:
                p.wait(timeout=20)
            except subprocess.TimeoutExpired:
                p.kill()


def test_cli_batch_writes_what_planefuse_run_writes(tmp_path, workers_see_checkout):
    """``planefuse batch`` of a configuration writes the same tracks, detections and metrics as ``planefuse run``
    of it (byte for byte, the measured run time aside)."""
    import json

    from typer.testing import CliRunner

    from planefuse.cli import app
    from planefuse.config import example_yaml
    from planefuse.sim import default_scene_config, simulate

    simulate(default_scene_config(duration_s=1.5, seed=2)).write(tmp_path / "rec")
    text = (example_yaml("rec").replace("figures: true", "figures: false").replace("animation: gif", "animation: none")
            .replace("report: true", "report: false"))
    for name in ("a", "b"):
        (tmp_path / f"{name}.yaml").write_text(text.replace("out_dir: planefuse-out", f"out_dir: out-{name}"))
    runner = CliRunner()
    r = runner.invoke(app, ["run", str(tmp_path / "a.yaml"), "--quiet"], terminal_width=200)
    assert r.exit_code == 0, r.output
    r = runner.invoke(app, ["batch", str(tmp_path / "b.yaml"), "--workers", "1", "--quiet", "--json-out",
                            str(tmp_path / "batch.json")], terminal_width=200)
    assert r.exit_code == 0, r.output
    for f in ("tracks.csv", "detections.csv"):
        assert (tmp_path / "out-a" / f).read_bytes() == (tmp_path / "out-b" / f).read_bytes(), f
    ma, mb = (json.loads((tmp_path / f"out-{n}" / "metrics.json").read_text()) for n in ("a", "b"))
    assert _same(ma, mb)
    rows = json.loads((tmp_path / "batch.json").read_text())
    assert rows[0]["name"] == "b" and rows[0]["error"] is None and _same(rows[0]["metrics"], mb)
    # a configuration that does not load is refused before any task starts
    (tmp_path / "bad.yaml").write_text(text.replace("cell_size_m: 0.1", "cell_size_m: -1"))
    r = runner.invoke(app, ["batch", str(tmp_path / "bad.yaml"), "--workers", "1"], terminal_width=200)
    assert r.exit_code == 2 and "cell_size_m" in r.output


@pytest.mark.parametrize("cameras", ["cell", "generative, tracks' prior", "person detector"])
def test_run_with_camera_streams_on_workers_is_the_serial_run(tmp_path, workers_see_checkout, cameras):
    """``planefuse run --workers 2``: each camera's front end on a worker gives the serial single-threaded run's
    (``--threads 1``) tables, occupancy and metrics byte for byte, with missing and black frames; also with the
    generative model taking the tracked people as its prior (the workers' foregrounds, the tracks in this process),
    and with a person detector on the workers (its boxes come back with the foregrounds: the same camera boxes)."""
    import json

    import numpy as np
    import zarr
    from typer.testing import CliRunner

    from planefuse.cli import app
    from planefuse.cli._run import set_threads
    from planefuse.config import example_yaml
    from planefuse.sim import scenario_config, simulate

    # cam0 black from 2 s, 5 % of the frames dropped
    simulate(scenario_config("camera_dropout", seed=3, duration_s=3.0)).write(tmp_path / "rec", image_format="jpg")
    text = (example_yaml("rec").replace("figures: true", "figures: false").replace("animation: gif", "animation: none")
            .replace("report: true", "report: false").replace("chunk_steps: 50", "chunk_steps: 4"))
    if cameras == "generative, tracks' prior":
        text = text.replace("sensor_model: cell", "sensor_model: generative").replace(
            "generative_track_prior_ratio: 1.0", "generative_track_prior_ratio: 2.0")
    if cameras == "person detector":
        pytest.importorskip("onnx", reason="the onnx package (dev extra) builds the test model")
        from test_vision_yolox import SIDE, constant_model, raw_rows, set_row

        rows = raw_rows()
        set_row(rows, 8, 3, 3, (0.5, 0.5, 0.7, 1.4), 0.9, 1.0)  # one box in every frame
        model = constant_model(tmp_path / "one_box.onnx", rows)
        text = text.replace("person_detector: null", "person_detector: yolox").replace(
            "person_model: null", f"person_model: {model}").replace(
            "person_input_px: null", f"person_input_px: [{SIDE}, {SIDE}]")
    for name in ("serial", "workers"):
        (tmp_path / f"{name}.yaml").write_text(text.replace("out_dir: planefuse-out", f"out_dir: out-{name}"))
    runner = CliRunner()
    r = runner.invoke(app, ["run", str(tmp_path / "serial.yaml"), "--quiet", "--threads", "1"], terminal_width=200)
    assert r.exit_code == 0, r.output
    set_threads(os.cpu_count() or 1)  # back to the default: the run below is multi-threaded
    r = runner.invoke(app, ["run", str(tmp_path / "workers.yaml"), "--quiet", "--workers", "2"], terminal_width=200)
    assert r.exit_code == 0, r.output
    a, b = tmp_path / "out-serial", tmp_path / "out-workers"
    for f in ("tracks.csv", "detections.csv") + (("camera_boxes.csv",) if cameras == "person detector" else ()):
        assert (a / f).read_bytes() == (b / f).read_bytes(), f
    occ = [zarr.open_group(d / "occupancy.zarr", mode="r")["occupancy"][:] for d in (a, b)]
    assert np.array_equal(*occ)
    ma, mb = (json.loads((d / "metrics.json").read_text()) for d in (a, b))
    # cameras at the default 5 Hz: cam0 black at the 5 instants from 2 s, and frames dropped (9 measured)
    assert ma["n_missing_camera_frames"] > 5 and _same(ma, mb)
    r = runner.invoke(app, ["run", str(tmp_path / "workers.yaml"), "--workers", "1", "--scheduler", "tcp://x:1"])
    assert r.exit_code == 2


@pytest.mark.parametrize("select", [{"stride": 2}, {"max_rate_hz": 10.0}])
def test_camera_stream_on_a_worker_follows_the_frame_stride(tmp_path, select):
    """The per-camera stream a dask worker runs (called here in this process) reads every ``stride``-th camera
    instant (or at most ``max_rate_hz`` per second), replaying the ``start`` skipped ones: what the camera's front
    end gives on those frames here."""
    import numpy as np

    from planefuse.batch._streams import CameraStream
    from planefuse.io import read_recording
    from planefuse.sim import default_scene_config, simulate
    from planefuse.vision import CameraFrontEnd, ForegroundParams, camera_instants, recording_frames

    simulate(default_scene_config(duration_s=1.2, seed=2)).write(tmp_path / "rec", image_format="jpg")
    rec = read_recording(tmp_path / "rec")
    cam, fg = rec.cameras[1], ForegroundParams()
    n = len(camera_instants(rec, **select)) - 3
    stream = CameraStream(str(tmp_path / "rec"), cam.name, fg, start=3, quantise=True, chunk=4, **select)
    got = [x for k in range(-(-n // 4)) for x in stream.chunk(k)]
    here = CameraFrontEnd(cam.intrinsics.width_px, cam.intrinsics.height_px, fg, cam.name,
                          rec.camera(cam.name).background(), quantise=True)
    frames = [images[1] for _, images in recording_frames(rec, **select)]
    for img in frames[:3]:
        here.replay(img)
    want = [here.process(img) for img in frames[3:]]
    assert len(got) == len(want) == n > 5
    for (fa, sa, ba), (fb, sb, bb) in zip(got, want):
        assert sa == sb and ba is None and bb is None  # no person detector: no boxes
        np.testing.assert_array_equal(fa, fb)


def test_workers_take_their_opencv_threads_from_the_cluster_environment(monkeypatch):
    """A batch worker is one core: ``threads_from_environment`` (run by every task) gives OpenCV the cluster's
    single thread, which OpenCV, already imported, would not read again by itself."""
    import cv2

    from planefuse.batch._cluster import SINGLE_THREAD_ENV
    from planefuse.batch._jobs import threads_from_environment

    before = cv2.getNumThreads()
    try:
        cv2.setNumThreads(2)
        monkeypatch.setenv("OPENCV_FOR_THREADS_NUM", SINGLE_THREAD_ENV["OPENCV_FOR_THREADS_NUM"])
        threads_from_environment()
        assert cv2.getNumThreads() == 1
        cv2.setNumThreads(2)
        monkeypatch.delenv("OPENCV_FOR_THREADS_NUM")
        threads_from_environment()  # no cluster environment: left as the process set it
        assert cv2.getNumThreads() == 2
    finally:
        cv2.setNumThreads(before)


#: A user's sweep script: its main module imports planefuse (so numba) at the top, as ``scripts/held_out.py`` does;
#: a spawned worker imports it again before dask's nanny applies the worker's environment.
_SWEEP_SCRIPT = """
import json, os
import numba.np.ufunc.parallel
from planefuse.batch import batch_client

def pool():
    return numba.np.ufunc.parallel.NUM_THREADS, os.environ.get("NUMBA_NUM_THREADS")

if __name__ == "__main__":
    mine = lambda: {k: v for k, v in os.environ.items() if not k.startswith("__DASK")}
    before = mine()
    with batch_client(n_workers=1) as client:
        during = mine()
        (worker,) = client.run(pool).values()
    print(json.dumps({"worker": worker, "during": during == before, "after": mine() == before}))
"""


def test_local_cluster_workers_start_single_threaded_and_leave_the_client_environment(tmp_path):
    """Regression: a LocalCluster's nanny applied the single-thread environment after the spawned worker had
    imported numba (with the client's main module), whose pool then ran one OpenMP thread per core in every
    worker (two workers, four spinning threads on two cores: 1.5x the CPU seconds of a sweep). The workers now
    start with it; the client's own environment is left as it was (dask's nanny copies its pre-spawn variables
    into it, and numba raises at its next compilation if ``NUMBA_NUM_THREADS`` changes under a launched pool)."""
    import json

    script = tmp_path / "sweep.py"
    script.write_text(_SWEEP_SCRIPT)
    env = {k: v for k, v in os.environ.items() if k not in ("NUMBA_NUM_THREADS", "OMP_NUM_THREADS")}
    env["PYTHONPATH"] = SRC + os.pathsep + os.environ.get("PYTHONPATH", "")
    env["NUMBA_NUM_THREADS"] = "2"  # the client's pool, whatever this machine's cores
    out = subprocess.run([sys.executable, str(script)], env=env, capture_output=True, text=True, timeout=300,
                         check=True)
    got = json.loads(out.stdout.strip().splitlines()[-1])
    assert got == {"worker": [1, "1"], "during": True, "after": True}
