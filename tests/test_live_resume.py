"""planefuse.live: a live run's folder is resumable (planefuse.live.LiveFolder), by the recording run's rule.

Loopback MJPEG streams of the default simulated scene (seed 4, 6 s, 4 cameras at 25 fps): a session stopped
(duration, as Ctrl-C does), then a second on the same folder, reading the same server (which goes on from the frame
it stopped at, so the people move on as after any gap).
"""

from __future__ import annotations

import csv
import json
import shutil
import time
from dataclasses import replace

import numpy as np
import pytest

from planefuse.live import LiveRun, LiveSettings, MjpegServer, recording_jpeg_frames
from planefuse.pipeline import SystemParams
from planefuse.sim import default_scene_config, simulate

PARAMS = SystemParams(laser=False, sound=False)


@pytest.fixture(scope="module")
def scene():
    rec = simulate(default_scene_config(duration_s=6.0, seed=4))
    return rec, recording_jpeg_frames(rec)


def _rows(path) -> list[dict]:
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


def _session(rec, srv, out_dir, duration_s, *, params=PARAMS, on_output=None, **kwargs) -> LiveRun:
    st = LiveSettings(cameras={c.name: srv.url(c.name) for c in rec.cameras}, serve=False, checkpoint_steps=4)
    live = LiveRun(rec, params, st, out_dir=out_dir, on_output=on_output, **kwargs)
    live.run(duration_s=duration_s)
    return live


def test_a_stopped_live_run_resumes_its_folder(scene, tmp_path):
    """Session 2 on session 1's folder: tracks.csv and tracks_mot.txt appended to (session 1's rows kept, one
    header, no step twice), steps and time go on (the gap between the sessions in the run clock, unobserved),
    identities are not reused (a track alive at session 1's end may go on with its identity; every other one is
    new), and the report says where it resumed."""
    rec, frames = scene
    srv = MjpegServer(frames).start()
    try:
        first = _session(rec, srv, tmp_path, 2.5)
        rows1 = _rows(tmp_path / "tracks.csv")
        text1 = (tmp_path / "tracks.csv").read_text()
        mot1 = (tmp_path / "tracks_mot.txt").read_text()
        state1 = json.loads((tmp_path / "run_state.json").read_text())
        alive = {int(i) for i in first.system.tracker.tracker.state_dict()["id"]}
        events = []
        time.sleep(1.0)  # between the sessions
        second = _session(rec, srv, tmp_path, 2.5, on_event=events.append)
    finally:
        srv.stop()
    n1 = first.summary.outputs
    assert state1["status"] == "ended" and state1["n_outputs"] == n1 > 5 and len(rows1) > 0
    text2 = (tmp_path / "tracks.csv").read_text()
    assert text2.startswith(text1) and text2.count("step,time_s") == 1
    assert (tmp_path / "tracks_mot.txt").read_text().startswith(mot1)
    rows2 = _rows(tmp_path / "tracks.csv")[len(rows1):]
    assert len(rows2) > 0 and second.resumed_at_step == n1 and second.summary.outputs > 5
    steps = [int(r["step"]) for r in rows1 + rows2]
    assert steps == sorted(steps) and min(int(r["step"]) for r in rows2) >= n1
    pairs = [(r["step"], r["track_id"]) for r in rows1 + rows2]
    assert len(pairs) == len(set(pairs))  # no row twice
    t1, t2 = max(float(r["time_s"]) for r in rows1), min(float(r["time_s"]) for r in rows2)
    assert t2 > t1 + 1.0  # the run clock counts the time between the sessions
    ids1, ids2 = {int(r["track_id"]) for r in rows1}, {int(r["track_id"]) for r in rows2}
    for i in ids2:
        assert i in alive or i > max(ids1), i
    assert alive & ids2  # over a gap of about a second, people keep their identities
    assert any(f"resuming {tmp_path} at step {n1}" in e for e in events)
    report = json.loads((tmp_path / "live_report.json").read_text())
    assert report["resumed_at_step"] == n1 and report["outputs"] == second.summary.outputs
    mot = np.loadtxt(tmp_path / "tracks_mot.txt", delimiter=",", ndmin=2)
    assert np.array_equal(mot[:, 0], np.array(steps) + 1) and len(mot) == len(rows1) + len(rows2)


def test_resume_goes_on_after_rows_newer_than_the_checkpoint(scene, tmp_path):
    """A session killed between two checkpoints leaves rows newer than its checkpoint: they are kept, and the next
    session's steps and new identities go above every one of them."""
    rec, frames = scene
    srv = MjpegServer(frames).start()
    saved = tmp_path / "saved"
    saved.mkdir()
    out = tmp_path / "out"

    def keep_first_checkpoint(o, latency):
        if (out / "checkpoint.npz").exists() and not (saved / "checkpoint.npz").exists():
            for name in ("checkpoint.npz", "run_state.json"):
                shutil.copy(out / name, saved / name)
    try:
        _session(rec, srv, out, 2.5, on_output=keep_first_checkpoint)
        rows1 = _rows(out / "tracks.csv")
        for name in ("checkpoint.npz", "run_state.json"):  # as if killed: the state of the first checkpoint
            shutil.copy(saved / name, out / name)
        second = _session(rec, srv, out, 1.5)
    finally:
        srv.stop()
    assert json.loads((saved / "run_state.json").read_text())["n_outputs"] == 4
    last_step = max(int(r["step"]) for r in rows1)
    assert last_step > 4 and second.resumed_at_step == last_step + 1
    rows2 = _rows(out / "tracks.csv")[len(rows1):]
    ids1 = {int(r["track_id"]) for r in rows1}
    with np.load(saved / "checkpoint.npz") as z:
        alive = set(z["tracker.tracker.id"].tolist())
    assert rows2 and all(int(r["step"]) > last_step for r in rows2)
    assert all(int(r["track_id"]) in alive or int(r["track_id"]) > max(ids1) for r in rows2)


def test_a_folder_of_another_configuration_is_refused_unless_fresh(scene, tmp_path):
    rec, _ = scene
    (tmp_path / "run_state.json").write_text(json.dumps({"status": "ended", "kind": "live", "config_hash": "x"}))
    (tmp_path / "tracks.csv").write_text("step,time_s,track_id,x_m,y_m,vx_m_s,vy_m_s\n0,0.0,7,1,1,0,0\n")
    st = LiveSettings(cameras={c.name: 0 for c in rec.cameras}, serve=False)
    with pytest.raises(ValueError, match=r"^out_dir .* holds the results of another run \(a different configuration, "
                                         r"recording or person model, ended\): choose another folder, or pass --fresh"):
        LiveRun(rec, PARAMS, st, out_dir=tmp_path)
    live = LiveRun(rec, PARAMS, st, out_dir=tmp_path, resume=False)  # --fresh: the old files deleted
    assert not (tmp_path / "tracks.csv").read_text().count("\n0,0.0,7")
    with pytest.raises(ValueError, match="being written by another planefuse run"):
        LiveRun(rec, PARAMS, st, out_dir=tmp_path)  # the first holds the folder's lock until its run ends
    live.close()  # releases the folder (run() would have, at its end)
    other = replace(PARAMS, match_distance_m=0.7)
    with pytest.raises(ValueError, match="holds the results of another run"):
        LiveRun(rec, other, st, out_dir=tmp_path)
    (tmp_path / "notes.txt").write_text("mine")
    with pytest.raises(ValueError, match=r"holds files planefuse did not write \(notes.txt\)"):
        LiveRun(rec, PARAMS, st, out_dir=tmp_path)


def test_cli_live_resumes_and_refuses_another_configuration(scene, tmp_path):
    from typer.testing import CliRunner

    from planefuse.cli import app
    from test_live import serve_live_config

    srv = serve_live_config(scene, tmp_path)
    live = ["live", str(tmp_path / "live.yaml"), "--no-page", "--duration-s", "1.5"]
    try:
        first = CliRunner().invoke(app, live)
        second = CliRunner().invoke(app, live)
        run_yaml = tmp_path / "run.yaml"
        run_yaml.write_text(run_yaml.read_text() + "models:\n  filter:\n    output_period_s: 0.4\n")
        refused = CliRunner().invoke(app, live)
        fresh = CliRunner().invoke(app, [*live, "--fresh"])
    finally:
        srv.stop()
    assert first.exit_code == 0 and second.exit_code == 0, first.output + second.output
    assert "resuming" not in first.output and "resuming" in second.output
    assert refused.exit_code == 1 and "holds the results of another run" in refused.output
    assert fresh.exit_code == 0 and "resuming" not in fresh.output
    report = json.loads((tmp_path / "out" / "live" / "live_report.json").read_text())
    assert report["resumed_at_step"] == 0


def test_a_resumed_synchroniser_refuses_frames_stamped_before_the_previous_session():
    """With clock: presentation, a resumed run's streams must go on past its previous session's last instant (a
    recording played again from its start is refused, its camera stopped with this error)."""
    from planefuse.live import FrameSynchroniser

    sync = FrameSynchroniser(["cam0"], 0.04, 5.0)
    sync.after_s = 12.0
    with pytest.raises(ValueError, match=r"camera 'cam0': frame stamped 0.04 s, not after 12.0 s where the resumed "
                                         r"run's previous session ended"):
        sync.put(0, np.zeros((2, 2)), 0.04, 100.0)
    sync.put(0, np.zeros((2, 2)), 12.04, 100.1)
    assert sync.t0 == 12.04
