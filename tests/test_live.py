"""planefuse.live: cameras as they stream (loopback MJPEG servers only), the system fed as frames arrive.

The network tests serve a short simulated scene (default scene, seed 4, 4 cameras at 25 fps, 360x288) as MJPEG
streams on 127.0.0.1 with :class:`planefuse.live.MjpegServer`, at the frames' own rate.
"""

from __future__ import annotations

import json
from dataclasses import replace
import os
import re
import shutil
import signal
import subprocess
import threading
from pathlib import Path
from types import SimpleNamespace

import cv2
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

pytest.importorskip("aiohttp")

from planefuse.grid import Evidence, PlaneStack  # noqa: E402
from planefuse.io import Recording  # noqa: E402
from planefuse.io._streams import CameraStream  # noqa: E402
from planefuse.live import (FrameSynchroniser, LiveRun, LiveSettings, MjpegServer, load_live_config,  # noqa: E402
                            mjpeg_frames, recording_jpeg_frames)
from planefuse.pipeline import SystemParams, run_system  # noqa: E402
from planefuse.sim import default_scene_config, simulate  # noqa: E402
from planefuse.tracking import EvidenceTracker, TrackingParams  # noqa: E402
from planefuse.vision import camera_instants  # noqa: E402
from planefuse.vision._datasets import frame_at  # noqa: E402

PARAMS = SystemParams(laser=False, sound=False)


# ---------------------------------------------------------------------------------------------- synchroniser
class _Times:
    """A camera stream's frame times only (what camera_instants and frame_at read)."""

    def __init__(self, times_s, rate_hz):
        self.times_s, self.rate_hz = np.asarray(times_s, float), rate_hz

    def __len__(self):
        return len(self.times_s)


def _fake_recording(times_per_camera, rate_hz=25.0):
    streams = {f"cam{c}": _Times(t, rate_hz) for c, t in enumerate(times_per_camera)}
    return SimpleNamespace(cameras=[SimpleNamespace(name=n) for n in streams], camera=lambda n: streams[n])


def _instants(times_per_camera, max_rate_hz, frame_s=0.04, queue_frames=10_000):
    """Feed every camera's frames to a synchroniser in arrival order (all queued) and collect its instants."""
    sync = FrameSynchroniser([f"cam{c}" for c in range(len(times_per_camera))], frame_s, max_rate_hz,
                             queue_frames, delivering=lambda c: False)
    events = sorted((t, c, i) for c, ts in enumerate(times_per_camera) for i, t in enumerate(ts))
    for t, c, i in events:
        sync.put(c, np.full((2, 2), i, np.uint8), t, t)
    sync.finished = lambda: True
    return list(sync.instants()), sync


@settings(max_examples=30, deadline=None)
@given(st.integers(1, 4), st.integers(10, 80), st.sampled_from([None, 5.0, 12.5]), st.integers(0, 2**31 - 1))
def test_synchroniser_forms_the_offline_instants(n_cameras, n_frames, rate_hz, seed):
    """Every camera delivering every frame (stamps jittered by up to a tenth of a frame): the instants, their stamps
    and each camera's frame in them are :func:`camera_instants` / :func:`frame_at`'s on the same times."""
    rng = np.random.default_rng(seed)
    base = 1.0 + np.arange(n_frames) * 0.04
    times = [base + rng.uniform(-0.004, 0.004, n_frames) * (c > 0) for c in range(n_cameras)]
    for t in times:
        t.sort()
    rec = _fake_recording(times)
    expected = camera_instants(rec, 1, rate_hz)
    got, _ = _instants(times, rate_hz)
    assert np.array_equal([i.time_s for i in got], expected)
    for inst, t in zip(got, expected):
        for c in range(n_cameras):
            j = frame_at(rec.camera(f"cam{c}"), t)
            f = inst.frames[c]
            assert (f is None) == (j is None) and (f is None or f.seq == j)


def test_synchroniser_takes_the_next_frame_of_a_camera_that_lost_one():
    """Where a camera lost the frame at an instant, the live rule takes its next frame in the same slot (the offline
    rule leaves it missing); a camera with no frame in a slot is None (unobserved)."""
    a = 0.04 * np.arange(20)
    b = np.delete(a, [5, 10, 11, 12, 13, 14])  # frame 5 lost; 10-14 (a whole 5 Hz slot) lost
    got, _ = _instants([a, b], 5.0)
    assert [i.time_s for i in got] == pytest.approx([0.0, 0.2, 0.4, 0.6])
    assert got[1].frames[1].stamp_s == pytest.approx(0.24)  # its next frame
    assert got[2].frames[1] is None and got[2].frames[0] is not None


def test_synchroniser_drops_the_oldest_when_behind_and_counts_it():
    got, sync = _instants([0.2 * np.arange(6)], 5.0, frame_s=0.2, queue_frames=2)
    assert [i.slot for i in got] == [4, 5]
    assert sync.health[0].dropped == 4 and sync.health[0].used == 2 and sync.health[0].skipped == 0


def test_synchroniser_counts_skipped_and_late_frames_and_refuses_stamps_going_back():
    sync = FrameSynchroniser(["cam0", "cam1"], 0.04, 5.0, 4, delivering=lambda c: False)
    sync.put(0, np.zeros(1), 0.0, 0.0)
    sync.put(0, np.zeros(1), 0.04, 0.04)  # inside slot 0, after its frame: skipped for the rate
    assert sync.health[0].skipped == 1
    it = sync.instants()
    assert next(it).slot == 0
    sync.put(1, np.zeros(1), 0.01, 0.3)  # cam1's frame of slot 0 after the instant was given
    assert sync.health[1].late == 1
    with pytest.raises(ValueError, match="time stamps must increase"):
        sync.put(1, np.zeros(1), 0.01, 0.31)


def test_tracker_early_release_gives_the_batches_of_the_window():
    """``EvidenceTracker.push(until_s=...)`` releases batches sooner, not other ones: same outputs (one in-order
    source; two messages within the merge tolerance still form one batch)."""
    stack = PlaneStack.from_extent((0.5, 1.0), (0.0, 3.0), (0.0, 2.0), 0.1)
    rng = np.random.default_rng(0)
    times = np.cumsum(rng.choice([0.03, 0.04, 0.2], 40))
    evs = [Evidence(float(t), "cameras", rng.normal(0, 1, stack.shape).astype(np.float32)) for t in times]
    tp = TrackingParams(output_period_s=0.2)
    a, b = EvidenceTracker(stack, tp), EvidenceTracker(stack, tp)
    outs_a = [o for e in evs for o in a.push(e)] + list(a.flush())
    outs_b = []
    for k, e in enumerate(evs):  # the live bound: the next message is stamped at or after times[k + 1]
        nxt = times[k + 1] if k + 1 < len(times) else np.inf
        outs_b += list(b.push(e, until_s=nxt - tp.merge_tolerance_s - 1e-9))
    outs_b += list(b.flush())
    assert [o.time_s for o in outs_a] == [o.time_s for o in outs_b]
    for oa, ob in zip(outs_a, outs_b):
        assert np.array_equal(oa.occupancy, ob.occupancy)


# ---------------------------------------------------------------------------------------------- streams
@pytest.fixture(scope="module")
def scene():
    """A 3 s simulated scene and its frames as JPEG (what the MJPEG server sends)."""
    rec = simulate(default_scene_config(duration_s=3.0, seed=4))
    return rec, recording_jpeg_frames(rec)


def _decoded_recording(rec, frames):
    """``rec``'s cameras with their JPEG-decoded frames: what a live run on the MJPEG streams receives."""
    streams = {}
    for cam in rec.cameras:
        s = rec.camera(cam.name)
        times, jpgs = frames[cam.name]

        def get(i, jpgs=jpgs):
            return cv2.imdecode(np.frombuffer(jpgs[i], np.uint8), cv2.IMREAD_COLOR), None
        streams[cam.name] = CameraStream(cam, times, get, False, s.rate_hz, get_background=s.background)
    return Recording(rec.duration_s, camera_streams=streams, planes_heights_m=rec.planes_heights_m,
                     room_xy_m=rec.room_xy_m)


def test_mjpeg_frames_round_trip(scene):
    rec, frames = scene
    srv = MjpegServer({"cam0": (frames["cam0"][0][:5], frames["cam0"][1][:5])}, speed=100.0).start()
    try:
        got = []
        for data, ts in mjpeg_frames(srv.url("cam0"), 2.0):
            got.append((data, ts))
            if len(got) == 5:
                break
    finally:
        srv.stop()
    assert [d for d, _ in got] == frames["cam0"][1][:5]
    assert [t for _, t in got] == list(frames["cam0"][0][:5])


def test_live_tracks_equal_offline_on_the_same_frames(scene, tmp_path):
    """MJPEG streams at 25 fps, the streams' presentation times (X-Timestamp): where the live run keeps up (no frame
    dropped), its tracks are the offline run's on the same (JPEG-decoded) frames exactly (tolerance 0: the same
    instants, frames and time stamps through the same code, and the tracker's early release gives the window's
    batches)."""
    rec, frames = scene
    offline = run_system(_decoded_recording(rec, frames), PARAMS)
    srv = MjpegServer(frames).start()
    outs = []

    def on_output(out, latency):
        outs.append(out)
        if len(outs) == len(offline.outputs):  # every frame served was fused (keeping up, however slowly)
            live.stop()
    # a long wait for each instant's frames and long queues: keeping up, on a loaded machine too
    st = LiveSettings(cameras={n: srv.url(n) for n in frames}, clock="presentation", serve=False, queue_frames=80,
                      sync_wait_s=5.0)
    live = LiveRun(rec, PARAMS, st, out_dir=tmp_path, jsonl=tmp_path / "tracks.jsonl", on_output=on_output)
    try:
        summary = live.run(duration_s=60.0)
    finally:
        srv.stop()
    assert all(h["dropped"] == 0 and h["late"] == 0 for h in summary.health), summary.health
    assert len(outs) == len(offline.outputs) == 15
    for a, b in zip(offline.outputs, outs):
        assert a.time_s == b.time_s
        assert np.array_equal(a.tracks.ids, b.tracks.ids) and np.array_equal(a.tracks.xy_m, b.tracks.xy_m)
        assert np.array_equal(a.occupancy, b.occupancy)
    assert len(outs[-1].tracks) > 0
    # the outputs written as it went: tracks.csv rows and JSON lines, the report
    rows = (tmp_path / "tracks.csv").read_text().splitlines()
    assert rows[0] == "step,time_s,track_id,x_m,y_m,vx_m_s,vy_m_s"
    assert len(rows) - 1 == sum(len(o.tracks) for o in outs)
    lines = [json.loads(x) for x in (tmp_path / "tracks.jsonl").read_text().splitlines()]
    assert [len(x["tracks"]) for x in lines] == [len(o.tracks) for o in outs]
    assert lines[-1]["tracks"][0]["id"] == int(outs[-1].tracks.ids[0])
    mot = np.loadtxt(tmp_path / "tracks_mot.txt", delimiter=",", ndmin=2)  # frame = step + 1, id, ..., x, y
    expected = [(k + 1, i, x, y) for k, o in enumerate(offline.outputs) for i, (x, y) in zip(o.tracks.ids, o.tracks.xy_m)]
    assert np.allclose(mot[:, [0, 1, 7, 8]], expected, atol=5e-5)  # written with 4 decimals
    report = json.loads((tmp_path / "live_report.json").read_text())
    assert [c["used"] for c in report["cameras"]] == [15] * 4


def test_stalled_and_disconnected_streams_are_survived_and_reported(scene):
    """cam1 goes silent after 20 frames (connection open), cam2's connection closes after 30 frames: the run goes on
    with the other cameras (the silent one unobserved: missing at those instants, not 'empty'), reopens both
    (cam2 streams again from where it stopped) and reports stalls, reconnects and states."""
    rec, frames = scene
    srv = MjpegServer(frames, stall_after={"cam1": 20}, close_after={"cam2": 30}).start()
    events = []
    st = LiveSettings(cameras={n: srv.url(n) for n in frames}, serve=False, stall_s=0.4, retry_min_s=0.1,
                      retry_max_s=0.2)
    live = LiveRun(rec, PARAMS, st, on_event=events.append)
    try:
        summary = live.run(duration_s=3.5)
    finally:
        srv.stop()
    h = {c["name"]: c for c in summary.health}
    assert h["cam1"]["stalls"] >= 1 and h["cam1"]["reconnects"] >= 1 and "timed out" in h["cam1"]["last_error"]
    assert h["cam2"]["reconnects"] >= 1 and srv.connections["cam2"] >= 2
    assert h["cam2"]["received"] > 30  # streamed again after the reconnection
    assert any("cam1" in e and "retrying" in e for e in events)
    # instants went on without cam1 while it was silent: it is missing (unobserved) there, the others fused; after
    # its reconnection it is used again (the server streams on from where it stopped); cam0's stream ends first
    # (cam2's, delayed by its reconnection, goes on a little): each camera is used or missing at every instant
    missing = live.system.report.camera.missing_frames
    assert len(missing.get("cam1", [])) >= 2
    assert min(missing.get("cam0", [np.inf])) > max(missing["cam1"])
    assert h["cam1"]["used"] > 20 // 5
    assert summary.outputs >= 10
    for name in frames:
        assert h[name]["used"] + len(missing.get(name, [])) == summary.instants


def test_ctrl_c_ends_the_run_cleanly_with_outputs_flushed(scene, tmp_path):
    rec, frames = scene
    srv = MjpegServer(frames).start()
    st = LiveSettings(cameras={n: srv.url(n) for n in frames}, serve=False)
    outs = []
    timer = threading.Timer(0.3, lambda: os.kill(os.getpid(), signal.SIGINT))

    def on_output(out, latency):
        outs.append(out)
        if len(outs) == 3:  # Ctrl-C 0.3 s after the third output step
            timer.start()
    live = LiveRun(rec, PARAMS, st, out_dir=tmp_path, on_output=on_output)
    try:
        summary = live.run(duration_s=30.0)
    finally:
        timer.cancel()
        srv.stop()
    assert summary.interrupted and summary.outputs == len(outs) > 0
    assert not any(s.running for s in live.sources)
    rows = (tmp_path / "tracks.csv").read_text().splitlines()
    assert len(rows) - 1 == sum(len(o.tracks) for o in outs)
    assert json.loads((tmp_path / "live_report.json").read_text())["interrupted"] is True
    # the folder is left resumable (tests/test_live_resume.py): the state after the flush, checkpointed
    state = json.loads((tmp_path / "run_state.json").read_text())
    assert state["status"] == "interrupted" and state["n_outputs"] == len(outs)
    assert (tmp_path / "checkpoint.npz").is_file() and not (tmp_path / ".planefuse.lock").exists()


@pytest.fixture(scope="module")
def page_run(scene):
    """A live run with its page on 127.0.0.1 (any free port), ended; the page keeps serving its last state."""
    rec, frames = scene
    srv = MjpegServer(frames).start()
    outs = []
    live = LiveRun(rec, PARAMS, LiveSettings(cameras={n: srv.url(n) for n in frames}, port=0),
                   on_output=lambda o, lat: outs.append(o))
    try:
        live.run(duration_s=3.5)
        yield live, outs
    finally:
        live.close()
        srv.stop()


def test_live_page_websocket_sends_the_state(page_run):
    import asyncio

    import aiohttp

    live, outs = page_run
    assert live.page.host == "127.0.0.1"

    async def first_message():
        async with aiohttp.ClientSession() as session:
            async with session.ws_connect(live.page.url + "ws") as ws:
                return json.loads((await ws.receive(timeout=10)).data)

    state = asyncio.run(first_message())
    last = outs[-1]
    assert [t["id"] for t in state["tracks"]] == [int(i) for i in last.tracks.ids]
    assert state["time_s"] == last.time_s and len(state["health"]) == 4 and all(state["cameras"].values())


def test_live_page_shows_the_tracks_in_headless_chromium(page_run, tmp_path):
    chromium = shutil.which("chromium") or shutil.which("chromium-browser")
    if chromium is None:
        pytest.skip("Debian's chromium is not installed (.ci/run installs it with apt-get)")
    live, outs = page_run
    cmd = [chromium, "--headless", "--no-sandbox", "--disable-gpu", "--disable-dev-shm-usage",
           "--disable-background-networking", f"--user-data-dir={tmp_path / 'profile'}",
           "--virtual-time-budget=3000", "--dump-dom", live.page.url]
    dom = subprocess.run(cmd, capture_output=True, text=True, timeout=90).stdout
    n = len(outs[-1].tracks)
    assert n > 0
    assert re.search(r'<span id="track-count">(\d+)</span>', dom).group(1) == str(n)
    ids = sorted(int(i) for i in re.findall(r'<li class="track" data-id="(\d+)"', dom))
    assert ids == sorted(int(i) for i in outs[-1].tracks.ids)
    assert sorted(re.findall(r'<tr><td>(cam\d)</td><td class="stopped">', dom)) == [f"cam{c}" for c in range(4)]


# ---------------------------------------------------------------------------------------------- configuration, CLI
def test_live_config_defaults_paths_and_errors(tmp_path):
    (tmp_path / "live.yaml").write_text("run: run.yaml\ncameras: {cam0: 'http://127.0.0.1:1/a.mjpg', cam1: 0,"
                                        " cam2: videos/c2.mp4}\ntracks_jsonl: out/t.jsonl\n")
    cfg = load_live_config(tmp_path / "live.yaml")
    s = cfg.settings()
    assert s.host == "127.0.0.1" and s == LiveSettings(cameras=cfg.cameras)
    assert cfg.run == tmp_path / "run.yaml" and cfg.cameras["cam2"] == str(tmp_path / "videos/c2.mp4")
    assert cfg.cameras["cam1"] == 0 and cfg.tracks_jsonl == str(tmp_path / "out/t.jsonl")
    (tmp_path / "bad.yaml").write_text("run: run.yaml\ncameras: {}\nqueue_frame: 2\n")
    with pytest.raises(ValueError, match=r"bad.yaml: queue_frame: Extra inputs"):
        load_live_config(tmp_path / "bad.yaml")
    (tmp_path / "bad2.yaml").write_text("run: run.yaml\ncameras: {}\nclock: gps\n")
    with pytest.raises(ValueError, match=r"bad2.yaml: LiveSettings.clock must be one of"):
        load_live_config(tmp_path / "bad2.yaml")
    with pytest.raises(ValueError, match="retry_max_s"):
        LiveSettings(retry_min_s=2.0, retry_max_s=1.0)


def test_live_refuses_cameras_without_streams(scene):
    rec, _ = scene
    with pytest.raises(ValueError, match=r"no stream given for \['cam3'\]; streams given for unknown cameras \['x'\]"):
        LiveRun(rec, PARAMS, LiveSettings(cameras={"cam0": 0, "cam1": 0, "cam2": 0, "x": 0}, serve=False))


def test_the_offline_stitching_is_announced_and_not_run_live(scene):
    # the real-video profile turns the offline pass on; live, it cannot run, and its views would only pile up
    rec, _ = scene
    params = replace(PARAMS, stitch=replace(PARAMS.stitch, enabled=True))
    events = []
    live = LiveRun(rec, params, LiveSettings(cameras={n: 0 for n in ("cam0", "cam1", "cam2", "cam3")}, serve=False),
                   on_event=events.append)
    assert not live.params.stitch.enabled and not live.system.params.stitch.enabled
    assert any("models.detection.stitch" in e and "not run live" in e for e in events)


def test_wrong_frame_size_stops_the_source_with_an_error(scene):
    rec, frames = scene
    small = {n: (t[:10], [cv2.imencode(".jpg", np.zeros((10, 12, 3), np.uint8))[1].tobytes()] * 10)
             for n, (t, _) in frames.items()}
    srv = MjpegServer(small).start()
    live = LiveRun(rec, PARAMS, LiveSettings(cameras={n: srv.url(n) for n in small}, serve=False))
    try:
        summary = live.run(duration_s=1.5)
    finally:
        srv.stop()
    assert all(h["state"] == "error" and "12x10 px, its calibration 360x288 px" in h["last_error"]
               for h in summary.health)


def serve_live_config(scene, folder: Path) -> MjpegServer:
    """``scene``'s recording written into ``folder/rec``, a run configuration (``folder/run.yaml``, outputs in
    ``folder/out``) and a live configuration (``folder/live.yaml``) whose cameras are the returned server's streams
    of the scene's frames (started; the caller stops it)."""
    from planefuse.io import write_recording

    rec, frames = scene
    write_recording(rec, folder / "rec", masks=False)
    (folder / "run.yaml").write_text(f"recording: {folder / 'rec'}\noutputs:\n  out_dir: {folder / 'out'}\n")
    srv = MjpegServer(frames).start()
    cams = ", ".join(f"{n}: '{srv.url(n)}'" for n in frames)
    (folder / "live.yaml").write_text(f"run: run.yaml\ncameras: {{{cams}}}\n")
    return srv


def test_cli_live_writes_tracks_as_it_goes(scene, tmp_path):
    from typer.testing import CliRunner

    from planefuse.cli import app

    srv = serve_live_config(scene, tmp_path)
    try:
        res = CliRunner().invoke(app, ["live", str(tmp_path / "live.yaml"), "--no-page", "--duration-s", "3",
                                       "--tracks-jsonl", str(tmp_path / "t.jsonl")])
    finally:
        srv.stop()
    assert res.exit_code == 0, res.output
    rows = (tmp_path / "out" / "live" / "tracks.csv").read_text().splitlines()
    assert rows[0].startswith("step,time_s,track_id") and len(rows) > 1
    report = json.loads((tmp_path / "out" / "live" / "live_report.json").read_text())
    assert len(report["cameras"]) == 4 and report["outputs"] == len((tmp_path / "t.jsonl").read_text().splitlines())
    assert any("laser and sound: recording-only" in e for e in report["events"])
    assert any("system ready" in e for e in report["events"]) and any("warmed up" in e for e in report["events"])


def test_video_files_played_at_their_rate_end_the_run_with_the_offline_tracks(scene, tmp_path):
    """Video files (MJPG in AVI, 25 fps) played at their own rate, stamped with their presentation times: the run
    ends by itself when every file has ended, with the offline run's tracks on the decoded frames exactly."""
    rec, frames = scene
    paths, streams = {}, {}
    for cam in rec.cameras:
        s = rec.camera(cam.name)
        paths[cam.name] = tmp_path / f"{cam.name}.avi"
        w = cv2.VideoWriter(str(paths[cam.name]), cv2.VideoWriter_fourcc(*"MJPG"), 25.0,
                            (cam.intrinsics.width_px, cam.intrinsics.height_px))
        for i in range(len(s)):
            w.write(s.frame(i))
        w.release()
        cap, imgs, times = cv2.VideoCapture(str(paths[cam.name])), [], []
        while (ok_img := cap.read())[0]:
            imgs.append(ok_img[1])
            times.append(cap.get(cv2.CAP_PROP_POS_MSEC) / 1e3)
        cap.release()
        streams[cam.name] = CameraStream(cam, times, lambda i, imgs=imgs: (imgs[i], None), False, s.rate_hz,
                                         get_background=s.background)
    offline = run_system(Recording(rec.duration_s, camera_streams=streams, planes_heights_m=rec.planes_heights_m,
                                   room_xy_m=rec.room_xy_m), PARAMS)
    outs = []
    live = LiveRun(rec, PARAMS, LiveSettings(cameras={n: str(p) for n, p in paths.items()}, clock="presentation",
                                             serve=False, queue_frames=80, sync_wait_s=5.0),
                   on_output=lambda o, lat: outs.append(o))
    summary = live.run(duration_s=30.0)  # ends at the files' end, long before
    assert all(h["state"] == "ended" and h["dropped"] == 0 for h in summary.health), summary.health
    assert len(outs) == len(offline.outputs) > 10
    for a, b in zip(offline.outputs, outs):
        assert a.time_s == b.time_s and np.array_equal(a.tracks.ids, b.tracks.ids)
        assert np.array_equal(a.tracks.xy_m, b.tracks.xy_m)


def test_a_missing_video_file_is_an_error_of_its_camera_and_the_run_ends(scene, tmp_path):
    rec, _ = scene
    events = []
    live = LiveRun(rec, PARAMS, LiveSettings(cameras={c.name: str(tmp_path / f"{c.name}.mp4") for c in rec.cameras},
                                             serve=False), on_event=events.append)
    summary = live.run(duration_s=30.0)  # every source failed: the run ends at once
    assert summary.instants == 0 and summary.outputs == 0
    assert all(h["state"] == "error" and "video file not found" in h["last_error"] for h in summary.health)
    assert sum("error" in e for e in events) == 4
