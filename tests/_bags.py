"""Test helper: a planefuse recording (simulated) written as a ROS 2 bag with ``rosbags`` -- raw BGR images with
their CameraInfo, Imu, LaserScan (float32 ranges, as the message holds them) and the sensors' poses in
``/tf_static`` -- so that ``planefuse.io.import_bag`` can be checked against the recording it came from."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

ORIGIN_NS = 1_700_000_000 * 1_000_000_000  # an epoch-like clock: time 0 of the recording


def _ns(t_s: float) -> int:
    return ORIGIN_NS + int(round(t_s * 1e9))


def write_bag(rec, path: Path, *, image_order: dict[str, list[int]] | None = None, skip_tf: tuple[str, ...] = (),
              storage: str = "sqlite3", compressed: tuple[str, ...] = (), ros1: bool = False,
              clouds: bool = False, old_tf: bool = False, moving: str | None = None) -> dict[str, str]:
    """Write ``rec``'s cameras, IMUs and lasers (fixed, untilted) into the ROS 2 bag folder ``path``.

    ``image_order[name]`` lists the frame indices of camera ``name`` in the order they are written (repeats,
    omissions and swaps make duplicated, missing and out-of-order frames); ``skip_tf`` leaves out those
    frames' transforms; cameras in ``compressed`` go out as PNG ``CompressedImage``; ``ros1`` writes a ROS 1
    ``.bag`` file (noetic messages: ``seq`` in headers, CameraInfo's upper-case ``D K R P``) instead; ``clouds``
    also writes each laser's scans as a PointCloud2 on ``/<name>/points`` (float32 x y z of the returns at z = 0,
    plus a ring of points 0.5 m away at z = 1 m and a NaN row, which a slice at z = 0 must leave out); ``old_tf``
    (ROS 1) sends the poses on ``/tf`` as ``tf/tfMessage`` (before tf2), at the start and again 1 s later, with
    frame ``moving`` 5 cm farther along x the second time. Returns the topic of every sensor.
    """
    import cv2
    from rosbags.rosbag2 import StoragePlugin, Writer
    from rosbags.typesys import Stores, get_typestore

    ts = get_typestore(Stores.ROS1_NOETIC if ros1 else Stores.ROS2_HUMBLE)
    if ros1:  # noetic's store lacks tf2_msgs (and tf): their one-line definition
        from rosbags.typesys import get_types_from_msg

        for name in ("tf2_msgs/msg/TFMessage", "tf/msg/tfMessage"):
            ts.register(get_types_from_msg("geometry_msgs/TransformStamped[] transforms", name))
    T = ts.types
    Time, Header = T["builtin_interfaces/msg/Time"], T["std_msgs/msg/Header"]
    serialize = ts.serialize_ros1 if ros1 else ts.serialize_cdr
    seq = {"n": 0} if ros1 else None

    def header(t_ns: int, frame: str):
        stamp = Time(sec=t_ns // 1_000_000_000, nanosec=t_ns % 1_000_000_000)
        if seq is None:
            return Header(stamp=stamp, frame_id=frame)
        seq["n"] += 1
        return Header(seq=seq["n"], stamp=stamp, frame_id=frame)

    def tf(parent: str, child: str, T_parent_child: np.ndarray):
        q = Rotation.from_matrix(T_parent_child[:3, :3]).as_quat()
        t = T_parent_child[:3, 3]
        return T["geometry_msgs/msg/TransformStamped"](
            header=header(ORIGIN_NS, parent), child_frame_id=child,
            transform=T["geometry_msgs/msg/Transform"](
                translation=T["geometry_msgs/msg/Vector3"](x=t[0], y=t[1], z=t[2]),
                rotation=T["geometry_msgs/msg/Quaternion"](x=q[0], y=q[1], z=q[2], w=q[3])))

    plugin = StoragePlugin.MCAP if storage == "mcap" else StoragePlugin.SQLITE3
    topics = {}
    edges = []
    if ros1:
        from rosbags.rosbag1 import Writer as Writer1

        writer = Writer1(path)
    else:
        writer = Writer(path, version=9, storage_plugin=plugin)
    with writer as w:
        def conn(topic, msgtype):
            return w.add_connection(topic, msgtype, typestore=ts)

        def put(c, t_ns, msg):
            w.write(c, t_ns, serialize(msg, c.msgtype))

        tf_type = "tf/msg/tfMessage" if old_tf else "tf2_msgs/msg/TFMessage"
        c_tf = conn("/tf" if old_tf else "/tf_static", tf_type)
        for cs in rec.camera_streams.values():
            frame = f"{cs.name}_optical"
            edges.append(("world", frame, cs.camera.T_world_cam))
        for s in rec.imus.values():
            edges.append((f"{s.attached_to}_optical", f"{s.name}_link", s.T_cam_imu))
        for s in rec.lasers.values():
            edges.append(("world", f"{s.name}_link", s.T_world_laser))
        put(c_tf, ORIGIN_NS, T[tf_type](transforms=[tf(p, c, M) for p, c, M in edges if c not in skip_tf]))
        if old_tf:
            shift = np.eye(4)
            shift[0, 3] = 0.05
            put(c_tf, ORIGIN_NS + 1_000_000_000, T[tf_type](transforms=[
                tf(p, c, (shift @ M) if c == moving else M) for p, c, M in edges if c not in skip_tf]))
        for cs in rec.camera_streams.values():
            frame = f"{cs.name}_optical"
            kind = "compressed" if cs.name in compressed else "image_raw"
            c_img = conn(f"/{cs.name}/{kind}", "sensor_msgs/msg/CompressedImage" if cs.name in compressed
                         else "sensor_msgs/msg/Image")
            c_info = conn(f"/{cs.name}/camera_info", "sensor_msgs/msg/CameraInfo")
            topics[cs.name] = c_img.topic
            cam = cs.camera
            W, H = cam.intrinsics.width_px, cam.intrinsics.height_px
            matrices = {"d": np.asarray(cam.intrinsics.dist, dtype=float), "k": np.asarray(cam.K, dtype=float).ravel(),
                        "r": np.eye(3).ravel(), "p": np.column_stack([cam.K, np.zeros(3)]).ravel()}
            info = T["sensor_msgs/msg/CameraInfo"](
                header=header(_ns(cs.times_s[0]), frame), height=H, width=W, distortion_model="plumb_bob",
                **{(k.upper() if ros1 else k): v for k, v in matrices.items()}, binning_x=0, binning_y=0,
                roi=T["sensor_msgs/msg/RegionOfInterest"](x_offset=0, y_offset=0, height=0, width=0, do_rectify=False))
            put(c_info, _ns(cs.times_s[0]), info)
            order = image_order.get(cs.name, range(len(cs))) if image_order else range(len(cs))
            last_ns = 0
            for i in order:
                t_ns = _ns(cs.times_s[i])
                last_ns = max(t_ns, last_ns + 1)  # received in the order sent: the bag's log time
                img = cs.frame(i)
                if cs.name in compressed:
                    msg = T["sensor_msgs/msg/CompressedImage"](header=header(t_ns, frame), format="png",
                                                               data=cv2.imencode(".png", img)[1].ravel())
                else:
                    msg = T["sensor_msgs/msg/Image"](header=header(t_ns, frame), height=H, width=W, encoding="bgr8",
                                                     is_bigendian=0, step=3 * W, data=img.reshape(-1).copy())
                put(c_img, last_ns, msg)
        for s in rec.imus.values():
            c = conn(f"/{s.name}/imu", "sensor_msgs/msg/Imu")
            topics[s.name] = c.topic
            d = s.read()
            V = T["geometry_msgs/msg/Vector3"]
            cov = np.zeros(9)
            for k in range(len(d)):
                t_ns = _ns(d.times_s[k])
                g, a = d.gyro_rad_s[k], d.accel_m_s2[k]
                put(c, t_ns, T["sensor_msgs/msg/Imu"](
                    header=header(t_ns, f"{s.name}_link"),
                    orientation=T["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=0.0, w=1.0),
                    orientation_covariance=np.r_[-1.0, np.zeros(8)],
                    angular_velocity=V(x=g[0], y=g[1], z=g[2]), angular_velocity_covariance=cov,
                    linear_acceleration=V(x=a[0], y=a[1], z=a[2]), linear_acceleration_covariance=cov))
        for s in rec.lasers.values():
            c = conn(f"/{s.name}/scan", "sensor_msgs/msg/LaserScan")
            topics[s.name] = c.topic
            d = s.read()
            if np.any(d.tilt_rad != 0):
                raise ValueError("a LaserScan holds an untilted scan: simulate the laser with tilt 0")
            sc = s.model["scanner"]
            for k in range(len(d)):
                t_ns = _ns(d.times_s[k])
                put(c, t_ns, T["sensor_msgs/msg/LaserScan"](
                    header=header(t_ns, f"{s.name}_link"), angle_min=float(d.angles_rad[0]),
                    angle_max=float(d.angles_rad[-1]), angle_increment=float(sc["angle_increment_rad"]),
                    time_increment=0.0, scan_time=1.0 / s.rate_hz, range_min=float(sc["range_min_m"]),
                    range_max=float(sc["range_max_m"]), ranges=d.ranges_m[k].astype(np.float32),
                    intensities=np.zeros(0, dtype=np.float32)))
            if clouds:
                c_pts = conn(f"/{s.name}/points", "sensor_msgs/msg/PointCloud2")
                F = T["sensor_msgs/msg/PointField"]
                fields = [F(name=a, offset=4 * j, datatype=7, count=1) for j, a in enumerate("xyz")]
                ring = np.linspace(-np.pi, np.pi, 50, endpoint=False)
                for k in range(len(d)):
                    t_ns = _ns(d.times_s[k])
                    r = d.ranges_m[k]
                    ok = np.isfinite(r)
                    pts = np.column_stack([r[ok] * np.cos(d.angles_rad[ok]), r[ok] * np.sin(d.angles_rad[ok]),
                                           np.zeros(ok.sum())])
                    pts = np.vstack([pts, np.column_stack([0.5 * np.cos(ring), 0.5 * np.sin(ring), np.ones(50)]),
                                     [[np.nan, np.nan, np.nan]]]).astype("<f4")
                    put(c_pts, t_ns, T["sensor_msgs/msg/PointCloud2"](
                        header=header(t_ns, f"{s.name}_link"), height=1, width=len(pts), fields=fields,
                        is_bigendian=False, point_step=12, row_step=12 * len(pts),
                        data=np.frombuffer(pts.tobytes(), np.uint8).copy(), is_dense=False))
    return topics
