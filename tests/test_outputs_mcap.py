"""Robotics outputs of a run: ``planefuse.mcap`` (Foxglove schemas) and ``ros2_bag/`` (ROS 2 messages) read back
with the ``mcap`` reader and ``rosbags`` give the run's tables and occupancy."""

from __future__ import annotations

import base64

import numpy as np
import pytest

from planefuse.grid import PlaneStack
from planefuse.outputs import occupancy_topic, read_mcap_messages, write_run_mcap, write_run_ros2_bag

STACK = PlaneStack.from_extent([0.0, 1.0], (0.0, 2.0), (0.0, 1.5), 0.25)


@pytest.fixture
def run():
    rng = np.random.default_rng(0)
    T = 4
    L, ny, nx = STACK.shape
    times = np.arange(T) * 0.2
    occ = rng.random((T, L, ny, nx)).astype(np.float32)
    # tracks: id 3 at every step, id 7 from step 2 on; detections: two at step 1, none elsewhere
    tracks = {"step": np.array([0, 1, 2, 2, 3, 3]), "time_s": times[[0, 1, 2, 2, 3, 3]],
              "track_id": np.array([3, 3, 3, 7, 3, 7]), "x_m": rng.random(6) * 2, "y_m": rng.random(6) * 1.5,
              "vx_m_s": rng.normal(size=6), "vy_m_s": rng.normal(size=6)}
    dets = {"step": np.array([1, 1]), "time_s": times[[1, 1]], "x_m": rng.random(2), "y_m": rng.random(2),
            "height_m": np.array([1.0, np.nan]), "confidence": np.array([0.9, 0.4]),
            "source": np.array(["bof", "laser"])}
    return times, occ, dets, tracks


def test_mcap_read_back_gives_the_tables_and_the_grids(run, tmp_path):
    times, occ, dets, tracks = run
    p = write_run_mcap(tmp_path / "run.mcap", STACK, times, occ, dets, tracks)
    from mcap.reader import make_reader

    with open(p, "rb") as f:
        summary = make_reader(f).get_summary()
    assert {ch.topic: summary.schemas[ch.schema_id].name for ch in summary.channels.values()} == {
        "/planefuse/tracks": "foxglove.SceneUpdate", "/planefuse/detections": "foxglove.SceneUpdate",
        occupancy_topic(0.0): "foxglove.Grid", occupancy_topic(1.0): "foxglove.Grid"}  # Foxglove's own schemas
    msgs = list(read_mcap_messages(p))
    assert {t for t, _, _ in msgs} == {"/planefuse/tracks", "/planefuse/detections", occupancy_topic(0.0),
                                      occupancy_topic(1.0)}
    got = []
    for topic, t_ns, m in msgs:
        k = int(np.flatnonzero(np.round(times * 1e9).astype(np.int64) == t_ns)[0])
        if topic == "/planefuse/tracks":
            for e in m.get("entities", []):
                meta = {kv["key"]: kv["value"] for kv in e["metadata"]}
                assert e["frame_id"] == "world" and e["id"] == f"track/{meta['track_id']}"
                got.append((k, int(meta["track_id"]), *(float(meta[c]) for c in ("x_m", "y_m", "vx_m_s", "vy_m_s"))))
                assert e["cylinders"][0]["pose"]["position"]["x"] == float(meta["x_m"])
            if k == 2:
                assert "deletions" not in m
        elif topic.startswith("/planefuse/occupancy/"):
            ll = [occupancy_topic(h) for h in STACK.heights_m].index(topic)
            grid = np.frombuffer(base64.b64decode(m["data"]), dtype="<f4").reshape(STACK.ny, STACK.nx)
            np.testing.assert_array_equal(grid, occ[k, ll])  # rows along +y, as the zarr's (iy, ix)
            assert m["column_count"] == STACK.nx and m["pose"]["position"].get("z", 0.0) == STACK.heights_m[ll]
        else:
            n = len(m.get("entities", []))
            assert n == (2 if k == 1 else 0)
            if n:
                meta = {kv["key"]: kv["value"] for kv in m["entities"][1]["metadata"]}
                assert (meta["source"], float(meta["confidence"])) == ("laser", 0.4)
                assert np.isnan(float(meta["height_m"]))
    expected = sorted(zip(tracks["step"].tolist(), tracks["track_id"].tolist(), tracks["x_m"], tracks["y_m"],
                          tracks["vx_m_s"], tracks["vy_m_s"]))
    assert sorted(got) == expected  # exact float64


def test_track_that_ends_is_deleted_in_the_scene(run, tmp_path):
    times, occ, dets, tracks = run
    keep = np.array([True, True, True, True, True, False])  # id 7 is not there at step 3
    p = write_run_mcap(tmp_path / "run.mcap", STACK, times, occ, dets, {k: v[keep] for k, v in tracks.items()})
    last = [m for t, _, m in read_mcap_messages(p, topics=["/planefuse/tracks"])][-1]
    assert [d["id"] for d in last["deletions"]] == ["track/7"]


def test_ros2_bag_holds_people_markers_detections_and_occupancy_grids(run, tmp_path):
    from rosbags.highlevel import AnyReader

    times, occ, dets, tracks = run
    p = write_run_ros2_bag(tmp_path / "bag", STACK, times, occ, dets, tracks)
    assert sorted(f.name for f in p.iterdir()) == ["bag.mcap", "metadata.yaml"] and len(list(tmp_path.iterdir())) == 1
    people, grids, markers, poses = [], {}, [], []
    with AnyReader([p]) as r:
        for c, t_ns, raw in r.messages():
            m = r.deserialize(raw, c.msgtype)
            assert m.header.frame_id == "world" if hasattr(m, "header") else True
            k = int(np.flatnonzero(np.round(times * 1e9).astype(np.int64) == t_ns)[0])
            if c.msgtype == "people_msgs/msg/People":
                people += [(k, int(q.name), q.position.x, q.position.y, q.velocity.x, q.velocity.y) for q in m.people]
            elif c.msgtype == "nav_msgs/msg/OccupancyGrid":
                grids[(c.topic, k)] = (m.info, np.asarray(m.data))
            elif c.msgtype == "visualization_msgs/msg/MarkerArray":
                markers.append((k, [(mk.ns, mk.id, mk.type, mk.action) for mk in m.markers]))
            else:
                poses.append((k, [(q.position.x, q.position.y) for q in m.poses]))
    expected = sorted(zip(tracks["step"].tolist(), tracks["track_id"].tolist(), tracks["x_m"], tracks["y_m"],
                          tracks["vx_m_s"], tracks["vy_m_s"]))
    assert sorted(people) == expected
    info, data = grids[(occupancy_topic(1.0), 2)]
    assert (info.width, info.height, info.resolution) == (STACK.nx, STACK.ny, STACK.cell_size_m)
    assert info.origin.position.z == 1.0
    np.testing.assert_array_equal(data, np.round(100 * occ[2, 1].astype(float)).astype(np.int8).ravel())
    assert markers[2][1][0][3] == 3  # DELETEALL first
    assert sorted(mk[1] for mk in markers[2][1] if mk[0] == "tracks" and mk[3] == 0) == [3, 7]  # ADD
    assert poses[1][1] == list(zip(dets["x_m"], dets["y_m"])) and poses[0][1] == []


class _Frames:
    """A camera stream in memory: ``camera``, ``times_s``, ``frame(i)``."""

    def __init__(self, camera, times_s, frames):
        self.camera, self.times_s, self.frames = camera, np.asarray(times_s), frames

    def frame(self, i):
        return self.frames[i]


def test_camera_frames_go_out_with_their_calibration_pose_and_projected_tracks(run, tmp_path):
    import cv2

    from planefuse.geometry import CameraIntrinsics, PinholeCamera, T_world_cam_look_at

    times, occ, dets, tracks = run
    K = np.array([[150.0, 0, 79.5], [0, 150.0, 59.5], [0, 0, 1]])
    cam = PinholeCamera(CameraIntrinsics(K, 160, 120, np.array([-0.05, 0.01, 0, 0, 0])),
                        T_world_cam_look_at((1.0, -3.0, 2.5), (1.0, 0.75, 0.0)), name="cam0")
    rng = np.random.default_rng(1)
    frames = [cv2.GaussianBlur(rng.integers(0, 255, (120, 160, 3), dtype=np.uint8), (9, 9), 3) for _ in range(8)]
    # frames at 0.1 s: the latest at or before each output step (0, 0.2, 0.4, 0.6 s) is frame 2k
    p = write_run_mcap(tmp_path / "run.mcap", STACK, times, occ, dets, tracks, cameras=[_Frames(cam, np.arange(8) * 0.1,
                                                                                               frames)])
    msgs = list(read_mcap_messages(p))
    images = [m for t, _, m in msgs if t == "/planefuse/cameras/cam0/image"]
    assert len(images) == len(times)
    for k, m in enumerate(images):
        img = cv2.imdecode(np.frombuffer(base64.b64decode(m["data"]), np.uint8), cv2.IMREAD_COLOR)
        assert m["frame_id"] == "cam0" and np.abs(img.astype(int) - frames[2 * k]).mean() < 3  # JPEG 90
    (calib,) = [m for t, _, m in msgs if t == "/planefuse/cameras/cam0/calibration"]
    np.testing.assert_array_equal(np.reshape(calib["K"], (3, 3)), K)
    (tf,) = [m for t, _, m in msgs if t == "/tf"]
    tr = tf["transforms"][0]
    assert (tr["parent_frame_id"], tr["child_frame_id"]) == ("world", "cam0")
    np.testing.assert_allclose([tr["translation"][a] for a in "xyz"], [1.0, -3.0, 2.5])
    notes = [m for t, _, m in msgs if t == "/planefuse/cameras/cam0/annotations"]
    rows = np.flatnonzero(tracks["step"] == 2)
    feet = cam.project(np.column_stack([tracks["x_m"][rows], tracks["y_m"][rows], np.zeros(len(rows))]))
    got = np.array([[c["position"]["x"], c["position"]["y"]] for c in notes[2]["circles"]])
    assert len(got) == 2  # both tracks of step 2 in view
    np.testing.assert_allclose(got, feet[np.isfinite(feet).all(1)])
    assert [t["text"] for t in notes[2]["texts"]] == [str(i) for i, f in zip(tracks["track_id"][rows], feet)
                                                       if np.isfinite(f).all()]
