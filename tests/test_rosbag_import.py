"""ROS bags as recordings (``planefuse.io.import_bag``): a simulated recording written as a ROS 2 bag imports to
the same streams and runs to the same tracks as the folder recording; faulty camera topics are reported per
topic; a missing transform is one line naming the frame."""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
import yaml
from scipy.spatial.transform import Rotation

from _bags import ORIGIN_NS, write_bag
from planefuse.io import read_recording
from planefuse.io import bag_topics, import_bag, static_transform
from planefuse.outputs import OutputSettings, read_table
from planefuse.outputs import read_mcap_messages
from planefuse.pipeline import RunPlan, SystemParams, run_to_folder
from planefuse.sim import default_scene_config, simulate


@pytest.fixture(scope="module")
def sim_dir(tmp_path_factory):
    """3 s, 3 people, 4 cameras with IMUs, an untilted laser (a LaserScan holds a flat scan)."""
    scene = default_scene_config(duration_s=3.0, seed=4, n_people=3, head=None,
                                 laser={"tilt_min_deg": 0.0, "tilt_max_deg": 0.0, "resolution_deg": 1.0})
    d = tmp_path_factory.mktemp("bag") / "folder"
    simulate(scene).write(d)
    return d


@pytest.fixture(scope="module")
def bag(sim_dir):
    p = sim_dir.parent / "bag"
    write_bag(read_recording(sim_dir), p)
    return p


@pytest.fixture(scope="module")
def imported(sim_dir, bag):
    rec = read_recording(sim_dir)
    out = sim_dir.parent / "imported"
    res = import_bag(bag, out, world_frame="world", room_xy_m=rec.room_xy_m, planes_heights_m=rec.planes_heights_m)
    return out, res


def _quantised(T) -> list:
    """A pose as a bag carries it: the rotation through a quaternion (geometry_msgs/Transform)."""
    T = np.array(T, dtype=float)
    T[:3, :3] = Rotation.from_quat(Rotation.from_matrix(T[:3, :3]).as_quat()).as_matrix()
    return T.tolist()


def test_listing_names_every_topic_with_its_type_count_and_use(bag):
    topics = {t.topic: t for t in bag_topics(bag)}
    assert topics["/cam0/image_raw"].msgtype == "sensor_msgs/msg/Image"
    assert topics["/cam0/image_raw"].count == 75  # 3 s at 25 Hz
    assert topics["/laser0/scan"].count == 120  # 3 s at 40 Hz
    assert topics["/tf_static"].use.startswith("sensor poses")
    assert topics["/cam0/camera_info"].use.startswith("camera intrinsics")


def test_imported_streams_are_the_recordings(sim_dir, imported):
    ref, (out, res) = read_recording(sim_dir), imported
    imp = read_recording(out)
    assert res.origin_ns == ORIGIN_NS == imp.clock_origin_ns and res.world_frame == "world"
    assert all(r.n_written == r.n_messages and not (r.n_out_of_order or r.n_duplicate or r.n_missing)
               for r in res.topics)
    assert sorted(imp.camera_streams) == sorted(ref.camera_streams)
    for name, cs in ref.camera_streams.items():
        ci = imp.camera(name)
        np.testing.assert_array_equal(ci.times_s, cs.times_s)  # header stamps in ns, read back exactly
        np.testing.assert_array_equal(ci.camera.K, cs.camera.K)
        np.testing.assert_array_equal(ci.camera.intrinsics.dist, cs.camera.intrinsics.dist)
        np.testing.assert_allclose(ci.camera.T_world_cam, cs.camera.T_world_cam, atol=1e-12)
        for i in range(0, len(cs), 7):
            np.testing.assert_array_equal(ci.frame(i), cs.frame(i))
    for name, s in ref.imus.items():
        a, b = s.read(), imp.imu(name).read()
        assert imp.imu(name).attached_to == s.attached_to
        np.testing.assert_array_equal(b.times_s, a.times_s)
        np.testing.assert_array_equal(b.gyro_rad_s, a.gyro_rad_s)
        np.testing.assert_array_equal(b.accel_m_s2, a.accel_m_s2)
        np.testing.assert_allclose(imp.imu(name).T_cam_imu, s.T_cam_imu, atol=1e-12)
    a, b = ref.laser().read(), imp.laser("laser0").read()
    np.testing.assert_array_equal(b.times_s, a.times_s)
    # LaserScan holds float32 ranges and angle_min/increment: that is all the bag keeps
    np.testing.assert_array_equal(b.ranges_m, a.ranges_m.astype(np.float32).astype(float))
    np.testing.assert_allclose(b.angles_rad, a.angles_rad, atol=1e-6)
    np.testing.assert_allclose(imp.laser("laser0").T_world_laser, ref.laser().T_world_laser, atol=1e-12)
    assert imp.duration_s == pytest.approx(ref.duration_s, abs=1e-12)


def _run(rec_dir: Path, out: Path, **kw) -> None:
    s = OutputSettings(animation="none", figures=False, report=False, **kw)
    run_to_folder(read_recording(rec_dir), RunPlan(SystemParams(), out, s), progress_mode="quiet")


def test_bag_runs_to_the_same_tracks_as_the_folder_recording(sim_dir, imported, tmp_path):
    """The folder recording holding what the bag holds (no background plate, poses through quaternions, float32
    ranges) and the imported bag give byte-identical detections and tracks."""
    out, _ = imported
    ref = tmp_path / "folder"
    shutil.copytree(sim_dir, ref)
    m = yaml.safe_load((ref / "scene.yaml").read_text())
    for s in m["sensors"]:
        s.pop("background_file", None)  # a bag has no background plate
        for key in ("T_world_cam", "T_world_laser"):
            if key in s:
                s[key] = _quantised(s[key])
    (ref / "scene.yaml").write_text(yaml.safe_dump(m, sort_keys=False))
    for f in (ref / "laser").rglob("*.npz"):
        z = dict(np.load(f))
        z["ranges_m"] = z["ranges_m"].astype(np.float32).astype(float)
        np.savez(f, **z)
    _run(ref, tmp_path / "out_folder")
    _run(out, tmp_path / "out_bag", mcap=True)
    a, b = (tmp_path / "out_folder"), (tmp_path / "out_bag")
    assert len((a / "tracks.csv").read_text().splitlines()) > 10  # people are tracked
    for name in ("tracks.csv", "detections.csv", "tracks_mot.txt"):
        assert (a / name).read_bytes() == (b / name).read_bytes(), name
    # the run's MCAP, read back with the mcap reader, holds tracks.csv's values
    table = read_table(b / "tracks.csv")
    got = []
    for _, t_ns, m in read_mcap_messages(b / "planefuse.mcap", topics=["/planefuse/tracks"]):
        for e in m.get("entities", []):
            meta = {kv["key"]: float(kv["value"]) for kv in e["metadata"]}
            got.append((t_ns, int(meta["track_id"]), meta["x_m"], meta["y_m"], meta["vx_m_s"], meta["vy_m_s"]))
    # stamped on the bag's clock: time 0 is the bag's first header stamp
    expected = [(ORIGIN_NS + int(round(t * 1e9)), int(i), x, y, vx, vy) for t, i, x, y, vx, vy in
                zip(*(table[c] for c in ("time_s", "track_id", "x_m", "y_m", "vx_m_s", "vy_m_s")))]
    assert sorted(got) == sorted(expected)


def test_dropped_duplicated_and_out_of_order_images_are_reported_per_topic(sim_dir, tmp_path):
    rec = read_recording(sim_dir)
    n = len(rec.camera("cam0"))
    order = [0, 1, 3, 2, 4, 4] + list(range(6, n))  # 2/3 swapped, 4 twice, 5 never sent
    bag = tmp_path / "faulty"
    write_bag(rec, bag, image_order={"cam0": order})
    with pytest.warns(UserWarning, match=r"/cam0/image_raw .*out of order 1, duplicated 1, missing 1"):
        res = import_bag(bag, tmp_path / "imp", lasers={}, imus={}, world_frame="world",
                         room_xy_m=rec.room_xy_m)
    reps = {r.topic: r for r in res.topics}
    r = reps["/cam0/image_raw"]
    assert (r.n_messages, r.n_written, r.n_out_of_order, r.n_duplicate, r.n_missing) == (n, n - 1, 1, 1, 1)
    for cam in ("cam1", "cam2", "cam3"):
        q = reps[f"/{cam}/image_raw"]
        assert (q.n_messages, q.n_written, q.n_out_of_order, q.n_duplicate, q.n_missing) == (n, n, 0, 0, 0)
    imp = read_recording(tmp_path / "imp").camera("cam0")
    kept = [i for i in range(n) if i != 5]  # in stamp order, the duplicate's second copy left out
    np.testing.assert_array_equal(imp.times_s, rec.camera("cam0").times_s[kept])
    for j in (2, 3, 4, 5):
        np.testing.assert_array_equal(imp.frame(j), rec.camera("cam0").frame(kept[j]))
    assert len(list((tmp_path / "imp" / "cameras" / "cam0" / "frames").iterdir())) == n - 1


def test_missing_transform_is_one_line_naming_the_frame(sim_dir, tmp_path):
    rec = read_recording(sim_dir)
    bag = tmp_path / "no_tf"
    write_bag(rec, bag, image_order={c: [0, 1] for c in rec.camera_streams}, skip_tf=("cam2_optical",))
    with pytest.raises(ValueError, match=r"no transform of frame .cam2_optical. \(camera 'cam2', topic "
                                         r"/cam2/image_raw\).*--tf world,cam2_optical") as err:
        import_bag(bag, tmp_path / "imp", imus={}, lasers={}, world_frame="world")
    assert "\n" not in str(err.value)
    assert not (tmp_path / "imp").exists()  # the frames written before the refusal are removed
    # the frame given with --tf completes the tree
    T = rec.camera("cam2").camera.T_world_cam
    res = import_bag(bag, tmp_path / "imp2", imus={}, lasers={}, world_frame="world",
                     extra_transforms=[("world", "cam2_optical", T)])
    assert res.world_frame == "world"
    np.testing.assert_array_equal(read_recording(tmp_path / "imp2").camera("cam2").camera.T_world_cam, T)


def test_compressed_images_in_an_mcap_bag_keep_their_bytes(sim_dir, tmp_path):
    rec = read_recording(sim_dir)
    bag = tmp_path / "mcap_bag"
    write_bag(rec, bag, storage="mcap", compressed=("cam1",), image_order={c: range(5) for c in rec.camera_streams})
    assert any(p.suffix == ".mcap" for p in bag.iterdir())
    import_bag(bag, tmp_path / "imp", cameras={"cam1": ("/cam1/compressed", "/cam1/camera_info")}, imus={},
               lasers={}, world_frame="world")
    imp = read_recording(tmp_path / "imp").camera("cam1")
    assert imp.frame_files[0].suffix == ".png"
    for i in range(5):
        np.testing.assert_array_equal(imp.frame(i), rec.camera("cam1").frame(i))  # PNG: lossless
    # the bag's .mcap file alone (no metadata.yaml) is read too
    (mcap_file,) = bag.glob("*.mcap")
    import_bag(mcap_file, tmp_path / "imp_file", cameras={"cam1": ("/cam1/compressed", None)}, imus={}, lasers={},
               world_frame="world")
    for i in range(5):
        np.testing.assert_array_equal(read_recording(tmp_path / "imp_file").camera("cam1").frame(i),
                                      rec.camera("cam1").frame(i))



def test_ros1_bag_with_cameras_imports_the_same_streams(sim_dir, tmp_path):
    """A ROS 1 bag (noetic: CameraInfo's K and D upper-case, headers with seq) through the same route."""
    rec = read_recording(sim_dir)
    bag = tmp_path / "rig.bag"
    write_bag(rec, bag, ros1=True, image_order={c: range(6) for c in rec.camera_streams})
    res = import_bag(bag, tmp_path / "imp", world_frame="world", imus={})
    imp = read_recording(tmp_path / "imp")
    assert res.origin_ns == ORIGIN_NS and sorted(imp.camera_streams) == sorted(rec.camera_streams)
    for name, cs in rec.camera_streams.items():
        ci = imp.camera(name)
        np.testing.assert_array_equal(ci.camera.K, cs.camera.K)
        np.testing.assert_array_equal(ci.camera.intrinsics.dist, cs.camera.intrinsics.dist)
        np.testing.assert_allclose(ci.camera.T_world_cam, cs.camera.T_world_cam, atol=1e-12)
        np.testing.assert_array_equal(ci.times_s, cs.times_s[:6])
        np.testing.assert_array_equal(ci.frame(5), cs.frame(5))
    np.testing.assert_array_equal(imp.laser("laser0").read().times_s, rec.laser().read().times_s)


def test_point_cloud_becomes_a_laser_by_slicing_it(sim_dir, tmp_path):
    """The simulated laser's returns sent as PointCloud2 (with points above the slice and a NaN row) come back, at
    1 deg beams over 360 deg, as its ranges (float32 x, y), at the beams of its angles; other beams no return."""
    rec = read_recording(sim_dir)
    bag = tmp_path / "clouds"
    write_bag(rec, bag, clouds=True, image_order={c: [] for c in rec.camera_streams})
    res = import_bag(bag, tmp_path / "imp", cameras={}, imus={}, lasers={}, clouds={"cloud0": "/laser0/points"},
                     cloud_band_m=(-0.1, 0.1), cloud_beams=360, cloud_range_m=(0.1, 30.0), world_frame="world")
    assert res.topics[0].kind == "laser" and res.topics[0].n_written == 120
    got = read_recording(tmp_path / "imp").laser("cloud0").read()
    ref = rec.laser().read()
    np.testing.assert_allclose(got.angles_rad, -np.pi + np.arange(360) * np.pi / 180, atol=1e-12)
    first = int(round((ref.angles_rad[0] + np.pi) / (np.pi / 180)))  # -135 deg: beam 45
    n = len(ref.angles_rad)
    want = np.where(np.isfinite(ref.ranges_m) & (ref.ranges_m <= 30.0), ref.ranges_m, np.inf)
    np.testing.assert_allclose(got.ranges_m[:, first:first + n], want, rtol=1e-6)
    assert np.isinf(np.delete(got.ranges_m, np.s_[first:first + n], axis=1)).all()  # the z = 1 m ring left out
    np.testing.assert_array_equal(got.times_s, ref.times_s)
    np.testing.assert_allclose(read_recording(tmp_path / "imp").laser("cloud0").T_world_laser, rec.laser().T_world_laser,
                               atol=1e-12)


def test_poses_on_tf_of_an_old_ros1_bag_and_a_moving_frame_refused(sim_dir, tmp_path):
    rec = read_recording(sim_dir)
    few = {c: range(3) for c in rec.camera_streams}
    bag = tmp_path / "old.bag"
    write_bag(rec, bag, ros1=True, old_tf=True, image_order=few)  # tf/tfMessage on /tf, the same pose twice
    import_bag(bag, tmp_path / "imp", world_frame="world", imus={}, lasers={})
    np.testing.assert_allclose(read_recording(tmp_path / "imp").camera("cam1").camera.T_world_cam,
                               rec.camera("cam1").camera.T_world_cam, atol=1e-12)
    moved = tmp_path / "moved.bag"
    write_bag(rec, moved, ros1=True, old_tf=True, image_order=few, moving="cam1_optical")
    with pytest.raises(ValueError, match=r"tf frame 'cam1_optical' .* moves in /tf by up to 0.050 m"):
        import_bag(moved, tmp_path / "imp2", world_frame="world", imus={}, lasers={})

def test_bad_inputs_are_one_line_errors(sim_dir, bag, tmp_path):
    with pytest.raises(ValueError, match="bag .*nowhere does not exist"):
        import_bag(tmp_path / "nowhere", tmp_path / "o1")
    with pytest.raises(ValueError, match=r"no topic '/cam9/image_raw'"):
        import_bag(bag, tmp_path / "o2", cameras={"cam9": ("/cam9/image_raw", None)})
    with pytest.raises(ValueError, match=r"topic /laser0/scan of bag .* is a sensor_msgs/msg/LaserScan, not "
                                         r"sensor_msgs/msg/Image"):
        import_bag(bag, tmp_path / "o3", cameras={"cam0": ("/laser0/scan", "/cam0/camera_info")})
    with pytest.raises(ValueError, match="cannot tell the world frame"):
        import_bag(bag, tmp_path / "o4", extra_transforms=[static_transform("other,x,0,0,0,0,0,0")])
    with pytest.raises(ValueError, match="need a camera"):
        import_bag(bag, tmp_path / "o5", cameras={}, imus={"i0": "/cam0_imu/imu"}, lasers={}, world_frame="world")
    res = import_bag(bag, tmp_path / "o6", cameras={}, world_frame="world")  # IMUs chosen for us: left out, said
    assert [r.kind for r in res.topics] == ["laser"] and any("not imported: no camera" in n for n in res.notes)
    with pytest.raises(ValueError, match="PARENT,CHILD,X,Y,Z,YAW,PITCH,ROLL"):
        static_transform("world,laser,1,2,3")
    junk = tmp_path / "junk.bag"
    junk.write_bytes(b"#ROSBAG V2.0\n" + bytes(range(256)) * 4)  # a ROS 1 header, then garbage
    with pytest.raises(ValueError, match=r"cannot read bag .*junk.bag"):
        bag_topics(junk)
    with pytest.raises(ValueError, match=r"output folder is not empty"):
        import_bag(bag, bag)


def test_static_transform_uses_ros_order_and_units():
    parent, child, T = static_transform("/world,laser,1,2,0.5,1.5707963267948966,0,0")
    assert (parent, child) == ("world", "laser")
    np.testing.assert_allclose(T[:3, 3], [1, 2, 0.5])
    np.testing.assert_allclose(T[:3, :3] @ [1, 0, 0], [0, 1, 0], atol=1e-12)  # yaw 90 deg: x -> y


@pytest.mark.realdata
def test_real_ros1_bag_imports_the_scans_the_laser_reader_gives(tmp_path):
    """The leg-tracker's ROS 1 bag through import_bag: the same scans as planefuse.laser.read_laser_scans, 0.0
    ("no return" below range_min) as NaN (invalid), times from the header stamps; no /tf, so --tf places it."""
    from conftest import shared_data
    from planefuse.laser import read_laser_scans

    bag = shared_data("lrf2d_people_leg_tracker") / "positive_1_extracted.bag"
    with pytest.raises(ValueError, match=r"no transform of frame 'right_laser' \(laser 'right', "
                                         r"topic /training_scan\)"):
        import_bag(bag, tmp_path / "r0", lasers={"right": "/training_scan"}, cameras={}, imus={},
                   extra_transforms=[static_transform("world,base,0,0,0,0,0,0")])
    with pytest.warns(UserWarning, match=r"/training_scan .* missing [1-9]"):  # extracted scans: sparse in time
        res = import_bag(bag, tmp_path / "r", lasers={"right": "/training_scan"}, cameras={}, imus={},
                         extra_transforms=[static_transform("world,right_laser,0,0,0.4,0,0,0")])
    rep = res.topics[0]
    assert (rep.n_messages, rep.n_written, rep.frame_id) == (197, 197, "right_laser")
    scans, _ = read_laser_scans(bag, "/training_scan")
    with pytest.warns(UserWarning, match="gap in timestamps"):
        got = read_recording(tmp_path / "r").laser("right").read()
    stamps = np.array([s.time_s for s in scans])
    order = np.argsort(stamps, kind="stable")
    np.testing.assert_allclose(got.times_s, stamps[order] - stamps.min(), atol=1e-6)
    ref = np.array([s.ranges_m for s in scans])[order].astype(np.float32).astype(float)
    below = ref < 0.03  # range_min of this scanner
    np.testing.assert_array_equal(np.isnan(got.ranges_m), below | np.isnan(ref))
    np.testing.assert_array_equal(got.ranges_m[~below], ref[~below])
    np.testing.assert_array_equal(read_recording(tmp_path / "r").laser("right").T_world_laser[:3, 3], [0, 0, 0.4])


def test_cli_lists_topics_imports_chosen_ones_and_refuses_in_one_line(bag, tmp_path, monkeypatch):
    from typer.testing import CliRunner

    from planefuse.cli import app
    from planefuse.cli._app import console

    monkeypatch.setattr(console, "_width", 200)  # the table's cells unwrapped, whatever the suite's terminal

    runner = CliRunner()
    res = runner.invoke(app, ["import-bag", str(bag), "--list"], env={"COLUMNS": "200"})
    assert res.exit_code == 0 and "/cam0/image_raw" in res.output and "sensor_msgs/msg/LaserScan" in res.output
    res = runner.invoke(app, ["import-bag", str(bag), str(tmp_path / "rec"), "--camera", "c0=/cam0/image_raw",
                              "--laser", "lrf=/laser0/scan", "--world-frame", "world", "--room", "0,10,0,10"],
                        env={"COLUMNS": "200"})
    assert res.exit_code == 0, res.output
    rec = read_recording(tmp_path / "rec")
    assert sorted(rec.camera_streams) == ["c0"] and sorted(rec.lasers) == ["lrf"] and not rec.imus
    assert rec.room_xy_m == (0.0, 10.0, 0.0, 10.0)
    res = runner.invoke(app, ["import-bag", str(bag), str(tmp_path / "rec2"), "--laser", "lrf=/laser0/scan",
                              "--world-frame", "nowhere"], env={"COLUMNS": "200"})
    assert res.exit_code == 2 and res.output.startswith("error:") and "laser0_link" in res.output
    assert len(res.output.strip().splitlines()) == 1


# -- message conversions and stamp bookkeeping -----------------------------------------------------------------------
def test_image_encodings_and_padded_rows_give_bgr(rng):
    from types import SimpleNamespace

    import cv2

    from planefuse.io._bag_messages import image_from_msg

    bgr = rng.integers(0, 255, (5, 7, 3), dtype=np.uint8)
    for enc, img in (("bgr8", bgr), ("rgb8", bgr[..., ::-1]), ("bgra8", cv2.cvtColor(bgr, cv2.COLOR_BGR2BGRA)),
                     ("rgba8", cv2.cvtColor(bgr, cv2.COLOR_BGR2RGBA)), ("mono8", bgr[..., 0])):
        ch = 1 if img.ndim == 2 else img.shape[2]
        rows = np.zeros((5, 7 * ch + 3), np.uint8)  # 3 bytes of row padding (step > width * channels)
        rows[:, : 7 * ch] = img.reshape(5, -1)
        msg = SimpleNamespace(encoding=enc, height=5, width=7, step=7 * ch + 3, data=rows.ravel())
        want = cv2.cvtColor(bgr[..., 0], cv2.COLOR_GRAY2BGR) if enc == "mono8" else bgr
        np.testing.assert_array_equal(image_from_msg(msg, "/t"), want)
    with pytest.raises(ValueError, match=r"topic /t: image encoding '16UC1' is not supported"):
        image_from_msg(SimpleNamespace(encoding="16UC1", height=1, width=1, step=2, data=np.zeros(2, np.uint8)), "/t")
    with pytest.raises(ValueError, match="image data of 10 bytes"):
        image_from_msg(SimpleNamespace(encoding="bgr8", height=2, width=2, step=6, data=np.zeros(10, np.uint8)), "/t")


def test_laser_ranges_follow_rep_117_into_planefuse_convention():
    from types import SimpleNamespace

    from planefuse.io._bag_messages import _laser_ranges

    r = np.array([0.0, 0.05, 1.0, 30.0, 31.0, np.inf, -np.inf, np.nan], dtype=np.float32)
    got = _laser_ranges(SimpleNamespace(ranges=r, range_min=0.1, range_max=30.0))
    np.testing.assert_array_equal(got, [np.nan, np.nan, 1.0, 30.0, np.inf, np.inf, np.nan, np.nan])


@settings(max_examples=200, deadline=None, derandomize=True)
@given(st.lists(st.integers(0, 30), min_size=1, max_size=40))
def test_stamp_bookkeeping_counts_against_a_direct_count(sent):
    """Frames k (stamp k x 40 ms) sent in any order, repeated or not at all: written in stamp order once each;
    out of order = messages earlier than one before them; duplicated = repeats; missing = holes at 25 Hz."""
    from planefuse.io._rosbag import TopicReport, _Stamps

    s = _Stamps([ORIGIN_NS + 40_000_000 * k for k in sent])
    rep = TopicReport("/t", "c", "camera")
    idx = s.order(rep)
    uniq = sorted(set(sent))
    assert [sent[i] for i in idx] == uniq
    assert rep.n_duplicate == len(sent) - len(uniq) and rep.n_written == len(uniq)
    assert rep.n_out_of_order == sum(any(sent[j] > sent[i] for j in range(i)) for i in range(len(sent)))
    gaps = np.diff(uniq)
    if len(gaps) and np.median(gaps) == 1:  # a nominal period of 40 ms: every hole counts
        assert rep.n_missing == uniq[-1] - uniq[0] + 1 - len(uniq)


def test_cloud_slice_keeps_the_nearest_point_per_beam_in_the_band():
    from planefuse.io import scan_ranges_from_points

    pts = [[2.0, 0.0, 0.0], [1.0, 0.01, 0.05], [0.5, 0.0, 0.3],  # beam 2 (azimuth 0): 1.0 m; z = 0.3 out of band
           [-3.0, 0.0, 0.0],  # azimuth pi: wraps to beam 0 (-pi)
           [0.0, 0.05, 0.0], [np.nan, 0.0, 0.0], [0.0, -50.0, 0.0]]  # below range_min, NaN, beyond range_max
    r = scan_ranges_from_points(pts, z_band_m=(-0.1, 0.1), n_beams=4, range_min_m=0.1, range_max_m=10.0)
    np.testing.assert_allclose(r, [3.0, np.inf, np.hypot(1.0, 0.01), np.inf])
