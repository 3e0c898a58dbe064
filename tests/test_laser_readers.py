"""Laser readers: CARMEN logs, ROS bags (round trips through rosbags' writer), XYZ clouds; bad inputs."""

from __future__ import annotations

import gzip
import warnings

import numpy as np
import pytest
from rosbags.rosbag1 import Writer
from rosbags.typesys import Stores, get_typestore

from planefuse.laser import (
    NonMonotonicTimeWarning,
    PointCloudFrame,
    read_carmen_log,
    read_rosbag,
    read_rosbag_topics,
    read_transform_yaml,
    read_xyz,
)

from conftest import shared_data

TS = get_typestore(Stores.ROS1_NOETIC)


def _flaser(n, ranges, pose, t):
    return " ".join(["FLASER", str(n), *map(str, ranges), *map(str, pose), *map(str, pose), str(t), "host", str(t)])


def test_carmen_round_trip_and_backwards_time(tmp_path):
    rng = np.random.default_rng(0)
    r = np.round(rng.uniform(0.5, 10, (3, 4)), 3)
    lines = ["# comment", "PARAM robot_frontlaser_offset 0.0 nohost 0",
             _flaser(4, r[0], (1.0, 2.0, 0.5), 10.0), "ODOM 0 0 0 0 0 0 1 h 1",
             _flaser(4, r[1], (1.5, 2.0, 0.6), 9.5), _flaser(4, r[2], (2.0, 2.0, 0.7), 11.0)]
    path = tmp_path / "x.log.gz"
    with gzip.open(path, "wt") as f:
        f.write("\n".join(lines) + "\n")
    with pytest.warns(NonMonotonicTimeWarning, match="backwards 1 times"):
        log = read_carmen_log(path)
    np.testing.assert_allclose(log.ranges_m, r)
    np.testing.assert_allclose(log.time_s, [10.0, 9.5, 11.0])  # kept, in file order
    assert log.time_backwards_at.tolist() == [1]
    np.testing.assert_allclose(np.rad2deg(log.angles_rad), [-90, -45, 0, 45])
    assert log.params["robot_frontlaser_offset"] == "0.0"
    T = log.T_world_laser()
    np.testing.assert_allclose(T[2, :2, 3], [2.0, 2.0])
    np.testing.assert_allclose(T[2, :2, 0], [np.cos(0.7), np.sin(0.7)])


def test_carmen_bad_inputs(tmp_path):
    bad = tmp_path / "bad.log"
    bad.write_text("FLASER 3 1 2 3 0 0 0 0 0 0 1.0 host\n")
    with pytest.raises(ValueError, match=r"bad.log:1: malformed FLASER record"):
        read_carmen_log(bad)
    bad.write_text(_flaser(3, [1, 2, 3], (0, 0, 0), 1) + "\n" + _flaser(2, [1, 2], (0, 0, 0), 2) + "\n")
    with pytest.raises(ValueError, match=":2: FLASER has 2 beams"):
        read_carmen_log(bad)
    bad.write_text("ODOM 0 0 0 0 0 0 1 h 1\n")
    with pytest.raises(ValueError, match="no FLASER"):
        read_carmen_log(bad)
    corrupt = tmp_path / "corrupt.log.gz"
    corrupt.write_bytes(gzip.compress(b"FLASER 1 1.0 0 0 0 0 0 0 1 h 1\n" * 100)[:60])
    with pytest.raises(ValueError, match="cannot read CARMEN log"):
        read_carmen_log(corrupt)


@pytest.mark.realdata
def test_intel_log_reports_its_four_backward_time_stamps():
    path = shared_data("lrf2d_carmen") / "intel-corrected.log.gz"
    with pytest.warns(NonMonotonicTimeWarning):
        log = read_carmen_log(path)
    assert len(log) == 910 and log.ranges_m.shape == (910, 180)
    assert log.n_time_backwards == 4
    # SOURCE.md: backwards at log lines 5647, 10805, 11190, 12936, by up to 0.86 s
    drops = log.time_s[log.time_backwards_at - 1] - log.time_s[log.time_backwards_at]
    assert 0 < drops.max() <= 0.87
    # max-range readings (>= 80 m) are 2-3 % and are kept, classified by the scans
    scans = log.scans()
    assert 0.02 < np.mean([s.no_return.mean() for s in scans]) < 0.03
    assert sum(s.valid.sum() + s.no_return.sum() + s.invalid.sum() for s in scans) == 910 * 180


def _header(t_s, frame):
    sec = int(t_s)
    return TS.types["std_msgs/msg/Header"](seq=0, stamp=TS.types["builtin_interfaces/msg/Time"](
        sec=sec, nanosec=int(round((t_s - sec) * 1e9))), frame_id=frame)


def _write_bag(path, ranges, cloud):
    LaserScan = TS.types["sensor_msgs/msg/LaserScan"]
    PointCloud2 = TS.types["sensor_msgs/msg/PointCloud2"]
    PointField = TS.types["sensor_msgs/msg/PointField"]
    String = TS.types["std_msgs/msg/String"]
    # x, y, z float32 plus an intensity, padded to 20 bytes per point
    rec = np.zeros(len(cloud), dtype=np.dtype({"names": ["x", "y", "z", "i"], "formats": ["<f4"] * 4,
                                                "offsets": [0, 4, 8, 16], "itemsize": 20}))
    rec["x"], rec["y"], rec["z"] = cloud.T
    fields = [PointField(name=n, offset=o, datatype=7, count=1) for n, o in (("x", 0), ("y", 4), ("z", 8), ("i", 16))]
    with Writer(path) as w:
        c_scan = w.add_connection("/scan", LaserScan.__msgtype__, typestore=TS)
        c_pc = w.add_connection("/cloud", PointCloud2.__msgtype__, typestore=TS)
        c_str = w.add_connection("/chatter", String.__msgtype__, typestore=TS)
        for k, r in enumerate(ranges):
            msg = LaserScan(header=_header(100.0 + 0.1 * k, "laser"), angle_min=-1.0, angle_max=1.0,
                            angle_increment=0.5, time_increment=0.0, scan_time=0.1, range_min=0.05,
                            range_max=5.0, ranges=np.asarray(r, np.float32), intensities=np.zeros(0, np.float32))
            w.write(c_scan, int((100.0 + 0.1 * k) * 1e9), TS.serialize_ros1(msg, LaserScan.__msgtype__))
        pc = PointCloud2(header=_header(101.0, "lidar"), height=1, width=len(cloud), fields=fields,
                         is_bigendian=False, point_step=20, row_step=20 * len(cloud),
                         data=np.frombuffer(rec.tobytes(), np.uint8), is_dense=False)
        w.write(c_pc, int(101e9), TS.serialize_ros1(pc, PointCloud2.__msgtype__))
        w.write(c_str, int(101e9), TS.serialize_ros1(String(data="hi"), String.__msgtype__))


def test_rosbag_round_trip_laserscan_pointcloud2_and_bad_inputs(tmp_path):
    rng = np.random.default_rng(0)
    ranges = [[1.0, 2.0, 0.0, np.inf, np.nan], [1.5, 2.5, 3.5, 4.5, 6.0]]
    cloud = rng.uniform(-5, 5, (7, 3)).astype(np.float32)
    cloud[3] = np.nan
    bag = tmp_path / "t.bag"
    _write_bag(bag, ranges, cloud)
    topics = read_rosbag_topics(bag)
    assert topics["/scan"] == ("sensor_msgs/msg/LaserScan", 2)
    t, scans = read_rosbag(bag, "/scan")
    np.testing.assert_allclose(t, [100.0, 100.1])
    assert scans[0].time_s == pytest.approx(100.0)
    np.testing.assert_allclose(scans[0].angles_rad, [-1.0, -0.5, 0.0, 0.5, 1.0])
    np.testing.assert_array_equal(scans[0].ranges_m, np.asarray(ranges[0], np.float32))  # kept as recorded
    assert scans[0].valid.tolist() == [True, True, False, False, False]
    assert scans[0].no_return.tolist() == [False, False, False, True, False]
    assert scans[0].invalid.tolist() == [False, False, True, False, True]
    assert scans[1].no_return.tolist() == [False] * 4 + [True]  # 6 m > range_max 5 m
    _, frames = read_rosbag(bag, "/cloud")
    assert isinstance(frames[0], PointCloudFrame) and frames[0].frame_id == "lidar"
    np.testing.assert_array_equal(frames[0].points, cloud.astype(float))
    assert frames[0].n_nonfinite == 1
    with pytest.raises(ValueError, match=r"type std_msgs/msg/String, not one of"):
        read_rosbag(bag, "/chatter")
    with pytest.raises(ValueError, match="no topic '/nope'"):
        read_rosbag(bag, "/nope")
    corrupt = tmp_path / "corrupt.bag"
    corrupt.write_bytes(bag.read_bytes()[: len(bag.read_bytes()) // 2])
    with pytest.raises(ValueError, match="cannot read bag"):
        read_rosbag(corrupt, "/scan")
    junk = tmp_path / "junk.bag"
    junk.write_bytes(b"not a bag at all")
    with pytest.raises(ValueError, match="cannot read bag"):
        read_rosbag_topics(junk)
    with pytest.raises(ValueError, match="does not exist"):
        read_rosbag(tmp_path / "missing.bag", "/scan")


@pytest.mark.realdata
def test_leg_tracker_demo_bag_reads_every_beam():
    bag = shared_data("lrf2d_people_leg_tracker") / "demo_stationary_simple_environment.bag"
    t, scans = read_rosbag(bag, "/scan")
    assert len(scans) == 1265 and len(scans[0]) == 512
    stamps = np.array([s.time_s for s in scans])
    assert np.all(np.diff(stamps) > 0)
    assert np.rad2deg(scans[0].angles_rad[[0, -1]]) == pytest.approx([-90.0, 89.65], abs=0.01)
    counts = np.array([[s.valid.sum(), s.no_return.sum(), s.invalid.sum()] for s in scans])
    assert np.all(counts.sum(axis=1) == 512)
    assert counts[:, 2].sum() > 0  # range 0.0 = no return below range_min: classified invalid, not an obstacle


@pytest.mark.realdata
def test_xyz_reader_on_the_lcct_target():
    p = read_xyz(shared_data("lrf3d_camera_lcct") / "laser_target1.xyz")
    assert p.shape[1] == 3 and 24_000 < len(p) < 27_000
    r = np.linalg.norm(p, axis=1)
    assert 1.3 < r.min() and r.max() < 2.3  # SOURCE.md: range 1.37-2.28 m


def test_xyz_reader_bad_inputs(tmp_path):
    good = tmp_path / "good.xyz"
    good.write_text("1 2 3\n4.5 -5 6e-1\n")
    np.testing.assert_array_equal(read_xyz(good), [[1, 2, 3], [4.5, -5, 0.6]])
    bad = tmp_path / "bad.xyz"
    bad.write_text("1 2 3\n4 5\n")
    with pytest.raises(ValueError, match="cannot read XYZ cloud"):
        read_xyz(bad)
    bad.write_text("1 2 3 4\n")
    with pytest.raises(ValueError, match="3 columns"):
        read_xyz(bad)


@pytest.mark.realdata
def test_transform_yaml_of_the_lcct_calibration():
    T = read_transform_yaml(shared_data("lrf3d_camera_lcct") / "T_camera_laser_stageII.yaml")
    np.testing.assert_allclose(T[:3, 3], [-0.194578, 0.032626, -0.093925])


def test_transform_yaml_bad_inputs(tmp_path):
    bad = tmp_path / "b.yaml"
    bad.write_text("t: [1, 2, 3]\n")
    with pytest.raises(ValueError, match="cannot read R and t"):
        read_transform_yaml(bad)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        bad.write_text("R: [[1, 0, 0], [0, 1, 0], [0, 0, -1]]\nt: [0, 0, 0]\n")
        with pytest.raises(ValueError, match="determinant"):
            read_transform_yaml(bad)


def test_laser_map_cli_writes_png_and_reports_backwards_time(tmp_path):
    from typer.testing import CliRunner

    from planefuse.cli import app

    # a square room 4 x 4 m seen from its centre with 1-degree beams, three poses, one stamp going back
    angles = -np.pi / 2 + np.arange(180) * np.pi / 180
    lines = []
    for k, (theta, t) in enumerate([(0.0, 1.0), (np.pi / 2, 0.5), (np.pi, 2.0)]):
        a = angles + theta
        r = np.minimum(2.0 / np.maximum(np.abs(np.cos(a)), 1e-9), 2.0 / np.maximum(np.abs(np.sin(a)), 1e-9))
        lines.append(_flaser(180, np.round(r, 4), (0.0, 0.0, theta), t))
    log = tmp_path / "room.log"
    log.write_text("\n".join(lines) + "\n")
    out = tmp_path / "map.png"
    res = CliRunner().invoke(app, ["laser-map", str(log), "--out", str(out), "--cell-size-m", "0.1"])
    assert res.exit_code == 0, res.output
    assert out.exists() and out.stat().st_size > 1000
    assert "backwards 1 times" in res.output.replace("\n", " ")
    assert "540" in res.output  # 3 x 180 real returns, all counted
