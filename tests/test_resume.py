"""Resuming a run: every stateful part checkpoints and restores exactly; sources seek; an interrupted or
killed run, re-run with the same configuration, computes only what follows its last finished chunk and ends
with the same files as an uninterrupted run."""

from __future__ import annotations

import io
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
import yaml
import zarr

from planefuse.grid import PlaneStack
from planefuse.io import read_recording
from planefuse.outputs import OutputSettings, OutputWriter
from planefuse.pipeline import RunPlan, SystemParams, SystemRun, run_to_folder
from planefuse.sim import default_scene_config, simulate
from planefuse.tracking import EvidenceTracker, TrackingParams, evidence_from_people
from planefuse.vision import CameraParams, recording_frames
from planefuse.vision._foreground import BackgroundSubtractor

SRC = Path(__file__).resolve().parents[1] / "src"
STACK = PlaneStack.from_extent([0.3, 1.0, 1.6], (0.0, 3.0), (0.0, 2.5), 0.1)
FILES = ("detections.csv", "tracks.csv", "detections_mot.txt", "tracks_mot.txt")


def _through_file(state: dict) -> dict:
    """A state as it comes back from checkpoint.npz (no pickle)."""
    buf = io.BytesIO()
    np.savez(buf, **state)
    buf.seek(0)
    with np.load(buf, allow_pickle=False) as z:
        return {k: z[k] for k in z.files}


def _outputs_and_state_at(run, step: int) -> tuple[list, dict]:
    """Every output of ``run`` and its state (through a file) taken after its ``step``-th output."""
    outputs, state = [], None
    for out in run.outputs():
        outputs.append(out)
        if len(outputs) == step:
            state = _through_file(run.state_dict())
    return outputs, state


# -- the filter and tracker ------------------------------------------------------------------------------------
def _messages(seed: int, n: int = 60):
    """Two people seen by a 25 Hz and a 10 Hz sensor, arriving up to 0.08 s late and out of order."""
    rng = np.random.default_rng(seed)
    msgs = []
    for sensor, period in (("cam", 0.04), ("laser", 0.1)):
        for t in np.arange(n) * period:
            if t > 2.0:
                break
            xy = [[0.5 + 0.8 * t, 1.0], [2.5 - 0.6 * t, 1.6 - 0.2 * t]]
            msgs.append(evidence_from_people(STACK, t, xy, [1.7, 1.2], sensor, noise_std=0.4, rng=rng))
    arrival = np.array([m.time_s for m in msgs]) + rng.uniform(0, 0.08, len(msgs))
    return [msgs[i] for i in np.argsort(arrival, kind="stable")]


@pytest.mark.parametrize("seed", [0, 1])
def test_evidence_tracker_resumes_exactly_from_any_output(seed):
    msgs = _messages(seed)
    params = TrackingParams(window_s=0.1, merge_tolerance_s=0.01, output_period_s=0.15)
    ref, states = [], []
    tracker = EvidenceTracker(STACK, params)
    pushed = 0
    for ev in msgs:
        pushed += 1
        for out in tracker.push(ev):
            ref.append(out)
            states.append((pushed, _through_file(tracker.state_dict())))
    ref += list(tracker.flush())
    assert len(states) > 8 and any(len(s["buffer.held_time_s"]) > 1 for _, s in states)
    for k in (0, len(states) // 3, len(states) - 1):
        n_pushed, state = states[k]
        resumed = EvidenceTracker(STACK, params)
        resumed.load_state_dict(state)
        got = list(resumed.drain())
        for ev in msgs[n_pushed:]:
            got += list(resumed.push(ev))
        got += list(resumed.flush())
        assert len(got) == len(ref) - k - 1
        for a, b in zip(ref[k + 1:], got):
            assert a.time_s == b.time_s and a.sensors == b.sensors
            np.testing.assert_array_equal(a.occupancy, b.occupancy)
            np.testing.assert_array_equal(a.velocity_m_s, b.velocity_m_s)
            np.testing.assert_array_equal(a.tracks.ids, b.tracks.ids)
            np.testing.assert_array_equal(a.tracks.xy_m, b.tracks.xy_m)


def test_checkpoint_of_other_planes_is_refused_naming_the_entry():
    tracker = EvidenceTracker(STACK)
    list(tracker.push(evidence_from_people(STACK, 0.0, [[1.0, 1.0]], [1.7])))
    other = EvidenceTracker(PlaneStack.from_extent([0.3, 1.0], (0.0, 3.0), (0.0, 2.5), 0.1))
    with pytest.raises(ValueError, match=r"held grids have shape \(3, 25, 30\), expected \(2, 25, 30\)"):
        other.load_state_dict(tracker.state_dict())
    with pytest.raises(ValueError, match="occ_v"):
        other.bof.load_state_dict(tracker.bof.state_dict())
    state = tracker.state_dict()
    del state["tracker.next_id"]
    with pytest.raises(ValueError, match="next_id"):
        EvidenceTracker(STACK).load_state_dict(state)


def test_kill_between_checkpoint_and_commit_record_still_resumes(tmp_path):
    """The checkpoint of the chunk the commit record names survives the next chunk's checkpoint."""
    occ = np.zeros(STACK.shape, np.float32)

    def write(out, steps):
        for k in steps:
            out.write_occupancy(k, 0.1 * k, occ, checkpoint=lambda: {"acc": np.array(k)})

    with OutputWriter(tmp_path, STACK, config_hash="h", chunk_steps=3) as out:
        write(out, range(6))
    # as if killed after chunk 2's checkpoint was written but before run_state.json recorded the chunk
    state = json.loads((tmp_path / "run_state.json").read_text())
    (tmp_path / "run_state.json").write_text(json.dumps({**state, "n_chunks_done": 1}))
    with OutputWriter(tmp_path, STACK, config_hash="h", chunk_steps=3) as out:
        assert out.resume_step == 3
        assert int(out.load_checkpoint()["acc"]) == 2  # state after step 2, from checkpoint.prev.npz
        write(out, range(3, 6))
    with OutputWriter(tmp_path, STACK, config_hash="h", chunk_steps=3) as out:
        assert out.resume_step == 6 and int(out.load_checkpoint()["acc"]) == 5


def test_modality_report_round_trips_through_a_checkpoint():
    from planefuse.grid import GroundDetections
    from planefuse.pipeline import ModalityReport
    from planefuse.vision import CameraReport

    rep = ModalityReport(
        camera=CameraReport(12, {"cam1": [0.4, 0.8], "cam3": [0.8]}, ["cam2"]),
        camera_detections=[GroundDetections(0.0, np.zeros((0, 2)), []),
                           GroundDetections(0.04, [[1.0, 2.0], [3.0, 4.5]], [0.9, 0.7], [1.7, np.nan], "cameras")],
        n_laser_scans=41, n_laser_invalid_beams=7,
        laser_points_world=[np.arange(6.0).reshape(2, 3), np.zeros((0, 3))], laser_points_times_s=[0.0, 1.0],
        laser_points_stride=80, n_sound_blocks=2, sound_times_s=[0.25, 0.75], sound_map_azimuth_rad=[0.1, np.nan],
        sound_saliency=[np.full(5, 0.2), np.arange(5.0)], sound_azimuth_grid_rad=np.linspace(-1, 1, 5),
        T_world_head=np.eye(4))
    back = ModalityReport()
    back.load_state_dict(_through_file(rep.state_dict()))
    assert back.camera == rep.camera and back.n_missing_camera_frames == 3
    for a, b in zip(rep.camera_detections, back.camera_detections, strict=True):
        assert a.time_s == b.time_s and a.source == b.source
        np.testing.assert_array_equal(a.xy_m, b.xy_m)
        np.testing.assert_array_equal(a.confidence, b.confidence)
        np.testing.assert_array_equal(a.height_m, b.height_m)
    for a, b in zip(rep.laser_points_world, back.laser_points_world, strict=True):
        np.testing.assert_array_equal(a, b)
    assert back.laser_points_stride == 80
    np.testing.assert_array_equal(np.stack(back.sound_saliency), np.stack(rep.sound_saliency))
    np.testing.assert_array_equal(back.sound_map_azimuth_rad, rep.sound_map_azimuth_rad)
    assert (back.n_laser_scans, back.n_laser_invalid_beams, back.n_sound_blocks) == (41, 7, 2)
    assert back.laser_points_times_s == [0.0, 1.0] and back.sound_times_s == [0.25, 0.75]
    np.testing.assert_array_equal(back.T_world_head, np.eye(4))
    empty = ModalityReport()
    empty.load_state_dict(_through_file(ModalityReport().state_dict()))
    assert empty.camera is None and empty.T_world_head is None and empty.sound_azimuth_grid_rad is None



def test_detection_log_keeps_every_instant_exactly_past_its_buffers():
    """The run's camera detections are kept as flat arrays that grow by doubling: every instant comes back
    exactly (empty ones, NaN heights, several sources), in order, after the buffers have grown, and through a
    checkpoint."""
    from planefuse.grid import GroundDetections
    from planefuse.pipeline import DetectionLog

    rng = np.random.default_rng(3)
    dets = [GroundDetections(0.04 * i, rng.normal(size=(k, 2)) * 5, rng.random(k),
                             np.where(rng.random(k) < 0.3, np.nan, rng.uniform(1.5, 1.9, k)),
                             "cameras" if i % 7 else "replayed")
            for i, k in enumerate(rng.integers(0, 12, 400))]  # past 64 instants and 256 detections
    log = DetectionLog()
    for d in dets:
        log.append(d)
    back = DetectionLog.from_state_dict(_through_file(log.state_dict()))
    assert len(log) == len(back) == 400
    np.testing.assert_array_equal(log.times_s, [d.time_s for d in dets])
    for a, b, c in zip(dets, log, back, strict=True):
        assert a.time_s == b.time_s == c.time_s and a.source == b.source == c.source
        for x in (b, c):
            np.testing.assert_array_equal(x.xy_m, a.xy_m)
            np.testing.assert_array_equal(x.confidence, a.confidence)
            np.testing.assert_array_equal(x.height_m, a.height_m)

# -- sources seek ----------------------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def sim():
    return simulate(default_scene_config(duration_s=3.0, seed=2))


@pytest.fixture(scope="module")
def recording_dir(tmp_path_factory, sim):
    d = tmp_path_factory.mktemp("rec") / "scene"
    sim.write(d, image_format="jpg")
    return d


def _laser_rows(stream, start=0):
    chunks = list(stream.chunks(max_scans=7, start=start))
    return np.concatenate([c.times_s for c in chunks]), np.concatenate([c.ranges_m for c in chunks])


@pytest.mark.parametrize("where", ["simulated", "files"])
def test_laser_chunks_start_skips_exactly(where, sim, recording_dir):
    rec = sim if where == "simulated" else read_recording(recording_dir)
    ls = rec.laser(next(iter(rec.lasers)))
    t_all, r_all = _laser_rows(ls)
    for start in (0, 3, 7, 30, len(t_all) - 1, len(t_all)):
        t, r = _laser_rows(ls, start) if start < len(t_all) else (np.zeros(0), np.zeros((0, r_all.shape[1])))
        np.testing.assert_array_equal(t, t_all[start:])
        np.testing.assert_array_equal(r, r_all[start:])  # simulated: same random streams per chunk


@pytest.mark.parametrize("where", ["simulated", "files"])
def test_audio_blocks_start_skips_exactly(where, sim, recording_dir):
    rec = sim if where == "simulated" else read_recording(recording_dir)
    au = rec.binaural(next(iter(rec.audio)))
    full = list(au.blocks(1000))
    part = list(au.blocks(1000, start=5000))
    assert [t for t, _ in part] == [t for t, _ in full[5:]]
    for (_, a), (_, b) in zip(part, full[5:]):
        np.testing.assert_array_equal(a, b)


def test_background_models_are_reproducible_and_replayable(sim):
    """OpenCV's KNN draws from a process-wide RNG: the masks must not depend on what ran before, and
    updating with frames (replay) must leave the model exactly where applying them did."""
    import cv2

    frames = [f[1][0] for f in recording_frames(sim)]
    h, w = frames[0].shape[:2]
    fg = CameraParams().foreground

    def masks(replay=0, disturb=False):
        sub = BackgroundSubtractor(w, h, fg)
        out = []
        for i, f in enumerate(frames):
            if disturb:
                cv2.randu(np.zeros(8), 0, 1)  # another user of the global RNG
            if i < replay:
                sub.update(f)
            else:
                out.append(sub.apply(f))
        return out

    ref = masks()
    assert any(m.max() > 0.5 for m in ref)
    for a, b in zip(ref, masks(disturb=True)):
        np.testing.assert_array_equal(a, b)
    for a, b in zip(ref[40:], masks(replay=40)):
        np.testing.assert_array_equal(a, b)


@pytest.mark.parametrize("frame_stride, max_rate_hz, track_prior", [(1, None, False), (2, None, False),
                                                                    (1, 10.0, False), (1, None, True)])
def test_system_run_resumes_exactly_and_skips_the_past(sim, frame_stride, max_rate_hz, track_prior, monkeypatch):
    """Also with the generative camera model taking the tracked people as its prior (asked of the tracker as each
    camera instant is computed: the resumed run asks the restored tracker the same)."""
    from dataclasses import replace

    base = SystemParams()
    cp = replace(base.camera_params, frame_stride=frame_stride, max_rate_hz=max_rate_hz)
    asked = []
    if track_prior:
        cp = replace(cp, sensor_model="generative", generative=replace(cp.generative, track_prior_ratio=3.0))
        original = SystemRun._tracked_xy
        monkeypatch.setattr(SystemRun, "_tracked_xy", lambda self, t: asked.append(original(self, t)) or asked[-1])
    params = replace(base, camera_params=cp)
    run = SystemRun(sim, params)
    ref, state = _outputs_and_state_at(run, 6)
    total = run.evidence.n_computed
    resumed = SystemRun(sim, params, checkpoint=state)
    assert resumed.resumed_at_step == 6
    got = list(resumed.outputs())
    assert len(got) == len(ref) - 6
    for a, b in zip(ref[6:], got):
        assert a.time_s == b.time_s
        np.testing.assert_array_equal(a.occupancy, b.occupancy)
        np.testing.assert_array_equal(a.tracks.ids, b.tracks.ids)
        np.testing.assert_array_equal(a.detections.xy_m, b.detections.xy_m)
    # only the messages after the checkpoint were computed; the report covers the whole run
    assert resumed.evidence.n_computed < 0.75 * total
    assert not track_prior or max(map(len, asked)) >= 2  # people were tracked and became the prior
    assert resumed.evidence.consumed == run.evidence.consumed
    assert resumed.report.n_laser_scans == run.report.n_laser_scans
    assert resumed.report.n_sound_blocks == run.report.n_sound_blocks
    assert len(resumed.report.camera_detections) == len(run.report.camera_detections)
    from planefuse.vision import camera_instants

    assert resumed.report.n_camera_frames == len(camera_instants(sim, frame_stride, max_rate_hz))
    with pytest.raises(ValueError, match="sources"):
        SystemRun(sim, SystemParams(sound=False), checkpoint=state)


def test_system_run_with_appearance_resumes_exactly(sim):
    """The tracks' appearance models, lost tracks and the frames kept for the next steps: a resumed run's camera
    source hands the appearance the replayed instants' frames again, and the tracker restores its models."""
    from dataclasses import replace

    base = SystemParams()
    params = replace(base, tracking=replace(base.tracking, tracker=replace(
        base.tracking.tracker, appearance_weight=16.0, reid_max_s=5.0)))
    run = SystemRun(sim, params)
    ref, state = _outputs_and_state_at(run, 6)
    resumed = SystemRun(sim, params, checkpoint=state)
    got = list(resumed.outputs())
    assert len(got) == len(ref) - 6
    for a, b in zip(ref[6:], got):
        np.testing.assert_array_equal(a.tracks.ids, b.tracks.ids)
        np.testing.assert_array_equal(a.tracks.xy_m, b.tracks.xy_m)
    assert run.track_appearance() and resumed.track_appearance() == run.track_appearance()


# -- a run folder ----------------------------------------------------------------------------------------------
def _run(rec, out, resume=True, **kw):
    settings = OutputSettings(animation="none", figures=False, report=False, chunk_steps=4, **kw)
    return run_to_folder(rec, RunPlan(SystemParams(), out, settings, resume=resume), progress_mode="quiet")


def _same_outputs(a: Path, b: Path) -> None:
    for name in FILES:
        assert (a / name).read_bytes() == (b / name).read_bytes(), name
    za, zb = zarr.open_group(a / "occupancy.zarr", mode="r"), zarr.open_group(b / "occupancy.zarr", mode="r")
    np.testing.assert_array_equal(za["occupancy"][:], zb["occupancy"][:])
    np.testing.assert_array_equal(za["time_s"][:], zb["time_s"][:])
    ma, mb = (json.loads((d / "metrics.json").read_text()) for d in (a, b))
    for k in ("elapsed_s", "resumed_at_step"):
        ma.pop(k), mb.pop(k)
    assert ma == mb


def _run_interrupted(rec, out: Path, monkeypatch, step: int) -> None:
    """``_run`` stopped by Ctrl-C when it is about to write output ``step``."""
    original = OutputWriter.write_occupancy

    def write(self, k, *a, **kw):
        if k == step:
            raise KeyboardInterrupt
        return original(self, k, *a, **kw)

    with monkeypatch.context() as m:
        m.setattr(OutputWriter, "write_occupancy", write)
        with pytest.raises(KeyboardInterrupt):
            _run(rec, out)


@pytest.fixture(scope="module")
def reference(recording_dir, tmp_path_factory):
    out = tmp_path_factory.mktemp("ref") / "out"
    _run(read_recording(recording_dir), out)
    return out


def test_interrupted_run_resumes_where_it_stopped(recording_dir, reference, tmp_path, monkeypatch):
    rec = read_recording(recording_dir)
    out = tmp_path / "out"
    _run_interrupted(rec, out, monkeypatch, 10)
    state = json.loads((out / "run_state.json").read_text())
    assert state["status"] == "interrupted" and state["n_chunks_done"] == 2

    computed = []
    original = SystemRun.outputs

    def counting(self):
        yield from original(self)
        computed.append(self.evidence.n_computed)

    monkeypatch.setattr(SystemRun, "outputs", counting)
    _, metrics = _run(rec, out)
    assert metrics["resumed_at_step"] == 8
    _run(rec, tmp_path / "fresh")
    assert computed[0] < 0.8 * computed[1], computed  # the finished chunks' messages were not recomputed
    _same_outputs(reference, out)


def test_unusable_checkpoint_recomputes_from_the_start(recording_dir, reference, tmp_path, monkeypatch):
    rec = read_recording(recording_dir)
    out = tmp_path / "out"
    _run_interrupted(rec, out, monkeypatch, 6)
    (out / "checkpoint.npz").write_bytes(b"not a zip file")
    with pytest.warns(UserWarning, match="checkpoint.npz: cannot resume.*corrupt"):
        _, metrics = _run(rec, out)
    assert metrics["resumed_at_step"] == 0
    _same_outputs(reference, out)


# SIGKILL in the middle of `planefuse run`: slowed down so that the kill lands between two chunks' commits
KILLED = '''
import sys, time
from planefuse.outputs import OutputWriter
original = OutputWriter.write_occupancy
def slow(self, *a, **kw):
    time.sleep(float(sys.argv[2]))
    return original(self, *a, **kw)
OutputWriter.write_occupancy = slow
from planefuse.cli import app
app(["run", sys.argv[1], "--quiet"])
'''


def _config(tmp: Path, recording: Path, out: Path) -> Path:
    cfg = {"recording": str(recording), "planes": {"heights_m": [0.1, 0.5, 1.0, 1.5], "x_range_m": [0.2, 9.8],
                                                    "y_range_m": [0.2, 9.8], "cell_size_m": 0.1},
           "outputs": {"out_dir": str(out), "chunk_steps": 3, "figures": False, "report": False,
                       "animation": "none"}}
    p = tmp / f"{out.name}.yaml"
    p.write_text(yaml.safe_dump(cfg))
    return p


def _planefuse(*args: str, delay: float = 0.0, wait: bool = True):
    env = {**os.environ, "PYTHONPATH": str(SRC), "NUMBA_NUM_THREADS": "1"}
    proc = subprocess.Popen([sys.executable, "-c", KILLED, *args, str(delay)], env=env,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    if wait:
        _, err = proc.communicate(timeout=300)
        assert proc.returncode == 0, err.decode()[-3000:]
    return proc


def test_killed_run_resumes_to_the_same_outputs(recording_dir, tmp_path):
    room = read_recording(recording_dir).room_xy_m
    assert room == (0.0, 10.0, 0.0, 10.0), room  # the planes of _config lie inside it
    ref, out = tmp_path / "ref", tmp_path / "out"
    _planefuse(str(_config(tmp_path, recording_dir, ref)))
    cfg = _config(tmp_path, recording_dir, out)
    proc = _planefuse(str(cfg), delay=0.3, wait=False)
    deadline = time.monotonic() + 240
    while time.monotonic() < deadline:
        try:
            state = json.loads((out / "run_state.json").read_text())
        except (OSError, ValueError):
            state = {}
        if state.get("n_chunks_done", 0) >= 2:
            break
        assert proc.poll() is None, proc.stderr.read().decode()[-3000:]
        time.sleep(0.05)
    proc.send_signal(signal.SIGKILL)
    proc.wait()
    state = json.loads((out / "run_state.json").read_text())
    assert state["status"] == "running" and 2 <= state["n_chunks_done"] < 5, state
    _planefuse(str(cfg))
    metrics = json.loads((out / "metrics.json").read_text())
    assert metrics["resumed_at_step"] == 3 * state["n_chunks_done"]
    _same_outputs(ref, out)


def test_a_changed_recording_is_not_resumed(recording_dir, tmp_path, monkeypatch):
    """Same parameters, same source text and duration, but another manifest: refused, or afresh with --fresh."""
    import shutil

    other = tmp_path / "other"
    shutil.copytree(recording_dir, other)
    with open(other / "scene.yaml", "a", encoding="utf-8") as f:
        f.write("# edited\n")
    out = tmp_path / "out"
    _run_interrupted(read_recording(recording_dir), out, monkeypatch, 6)
    with pytest.raises(ValueError, match="results of another run"):
        _run(read_recording(other), out)  # neither resumed nor replaced silently
    _, metrics = _run(read_recording(other), out, resume=False)  # `planefuse run --fresh`
    assert metrics["resumed_at_step"] == 0
    _, metrics = _run(read_recording(other), out)  # the same recording again: resumed
    assert metrics["resumed_at_step"] > 0


def test_resumed_rerun_recording_covers_the_whole_run(recording_dir, tmp_path, monkeypatch):
    """The .rrd of a resumed run logs the kept steps again, then the computed ones."""
    pytest.importorskip("rerun")
    from rerun.chunk import RrdReader

    rec = read_recording(recording_dir)
    out = tmp_path / "out"
    _run_interrupted(rec, out, monkeypatch, 10)
    _, metrics = _run(rec, out, rerun=True)
    assert metrics["resumed_at_step"] == 8
    steps: dict[str, set[int]] = {}
    for chunk in RrdReader(str(out / "planefuse.rrd")).stream():
        batch = chunk.to_record_batch()
        if "step" in batch.schema.names:
            steps.setdefault(chunk.entity_path, set()).update(batch.column("step").to_pylist())
    n = zarr.open_group(out / "occupancy.zarr", mode="r")["time_s"].shape[0]
    for path in ("/planes/z_0.10m", "/planes/z_1.50m", "/world/detections", "/world/tracks"):
        assert steps[path] == set(range(n)), path
    assert min(steps["/world/laser/laser"]) < 8 and min(steps["/world/sound/front"]) < 8


def test_laser_points_kept_for_the_figures_are_bounded_and_evenly_spaced():
    """However long the run, the report keeps at most LASER_POINTS_KEPT scans' points, evenly spaced over all
    scans seen (every 40th at first, the stride doubling), and a report restored mid-run keeps the same ones."""
    from planefuse.pipeline import ModalityReport
    from planefuse.pipeline._streams import LASER_POINTS_EVERY, LASER_POINTS_KEPT

    def feed(rep, scans):
        for i in scans:
            rep.keep_laser_points(i, 0.025 * i, np.full((1, 3), float(i)))

    short, long_ = ModalityReport(), ModalityReport()
    feed(short, range(200))
    assert [int(p[0, 0]) for p in short.laser_points_world] == list(range(0, 200, LASER_POINTS_EVERY))
    n = 40 * LASER_POINTS_EVERY * LASER_POINTS_KEPT
    feed(long_, range(n // 2))
    back = ModalityReport()
    back.load_state_dict(_through_file(long_.state_dict()))
    feed(long_, range(n // 2, n))
    feed(back, range(n // 2, n))
    kept = [int(p[0, 0]) for p in long_.laser_points_world]
    assert LASER_POINTS_KEPT // 2 <= len(kept) <= LASER_POINTS_KEPT
    assert len(set(np.diff(kept))) == 1 and kept[0] == 0 and n - kept[-1] <= long_.laser_points_stride
    assert [int(p[0, 0]) for p in back.laser_points_world] == kept
    assert long_.laser_points_times_s == back.laser_points_times_s == [0.025 * k for k in kept]


def test_system_run_resumes_exactly_through_a_camera_dropout():
    """A checkpoint taken while cam0 is black (0.9-1.3 s, shorter than the cameras' 0.5 s correlation time) and
    frames drop at random: the resumed run takes each camera's last live frame from the restored report, so its
    outputs are those of the uninterrupted run (cam0's first frame back weighted 0.8, not as a first frame)."""
    from planefuse.sim import CameraFaultSpec

    scene = default_scene_config(duration_s=2.0, seed=3).model_copy(update={
        "camera_faults": [CameraFaultSpec(camera="cam0", start_s=0.9, end_s=1.3, kind="black")],
        "dropped_frame_probability": 0.05})
    rec = simulate(scene)
    run = SystemRun(rec)
    ref, state = [], None
    with pytest.warns(UserWarning):
        for out in run.outputs():
            ref.append(out)
            if np.isclose(out.time_s, 1.0, atol=0.05) and state is None:
                state, at = _through_file(run.state_dict()), len(ref)
        got = list(SystemRun(rec, checkpoint=state).outputs())
    assert state is not None and len(got) == len(ref) - at
    for a, b in zip(ref[at:], got):
        np.testing.assert_array_equal(a.occupancy, b.occupancy)
        np.testing.assert_array_equal(a.tracks.ids, b.tracks.ids)
