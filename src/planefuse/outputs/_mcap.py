"""A run for robotics viewers: an MCAP file in Foxglove's well-known schemas (``planefuse.mcap``, written with
``foxglove-sdk``) and a ROS 2 bag of standard messages (``ros2_bag/``, written with ``rosbags``).

Both hold, at every output step, the tracks (positions, velocities, identities), the detections and each
plane's occupancy as a grid, in the world frame of the recording (``world``: z up, floor at z = 0, metres), with
times on the recording's clock (``time_s * 1e9`` ns). Topics and units: ``docs/outputs.md``, "Robotics outputs".
"""

from __future__ import annotations

import colorsys
import os
import shutil
from collections.abc import Iterator, Mapping, Sequence
from pathlib import Path

import numpy as np

from ._atomic import TMP_MARK

__all__ = ["MCAP_FILE", "ROS2_BAG_DIR", "WORLD_FRAME", "write_run_mcap", "write_run_ros2_bag", "read_mcap_messages",
           "occupancy_topic", "PEOPLE_MSG"]

MCAP_FILE = "planefuse.mcap"
ROS2_BAG_DIR = "ros2_bag"
#: The frame_id of every message: planefuse's world frame.
WORLD_FRAME = "world"
#: Height of the cylinder drawn for a track [m] (drawing only).
_PERSON_HEIGHT_M = 1.7

#: ``people_msgs/msg/People`` (ROS ``people`` stack, also in its ROS 2 port) and ``Person``: the person array of
#: the ROS ecosystem's people trackers (leg_detector, ...). ``name`` holds the track id.
PEOPLE_MSG = {
    "people_msgs/msg/Person": "string name\ngeometry_msgs/Point position\ngeometry_msgs/Point velocity\n"
                              "float64 reliability\nstring[] tagnames\nstring[] tags\n",
    "people_msgs/msg/People": "std_msgs/Header header\npeople_msgs/Person[] people\n",
}


def occupancy_topic(height_m: float) -> str:
    """Topic of the plane at ``height_m``: ``/planefuse/occupancy/z_1.00m``."""
    return f"/planefuse/occupancy/z_{height_m:.2f}m"


def _steps(n_steps: int, table: Mapping[str, np.ndarray]) -> list[np.ndarray]:
    step = np.asarray(table["step"], dtype=np.int64)
    order = np.argsort(step, kind="stable")
    bounds = np.searchsorted(step[order], np.arange(n_steps + 1))
    return [order[bounds[k]:bounds[k + 1]] for k in range(n_steps)]


def _ns(time_s: float, origin_ns: int = 0) -> int:
    return int(origin_ns) + int(round(float(time_s) * 1e9))


def write_run_mcap(path: str | Path, stack, times_s, occupancy, detections: Mapping[str, np.ndarray],
                   tracks: Mapping[str, np.ndarray], *, person_radius_m: float = 0.25, cameras: Sequence = (),
                   jpeg_quality: int = 90, clock_origin_ns: int | None = None) -> Path:
    """Write a run as MCAP in Foxglove's schemas (protobuf encoding), openable in Foxglove with no ROS.

    Parameters
    ----------
    path : path
        The ``.mcap`` file (replaced atomically).
    stack : PlaneStack
    times_s : array_like (T,)
        Output step times [s].
    occupancy : array (T, L, ny, nx) float32
        P(occupied); indexed one step at a time (a zarr array is read lazily).
    detections, tracks : dict of column -> array
        The run's tables (``detections.csv``, ``tracks.csv`` columns).
    person_radius_m : float
        Radius of the cylinders drawn for tracks and detections [m].
    cameras : sequence of camera streams
        Objects with ``camera`` (:class:`~planefuse.geometry.PinholeCamera`), ``times_s`` (F,) and ``frame(i)``
        (H, W, 3) uint8 BGR (``planefuse.io.CameraStream``): at every output step the camera's latest frame at or
        before it goes out as JPEG (``jpeg_quality``) with the tracks drawn over it.
    clock_origin_ns : int, optional
        Time 0 on the source's clock [ns] (``Recording.clock_origin_ns``: a ROS bag's first header stamp): every
        stamp and log time is ``clock_origin_ns + round(time_s * 1e9)``, so the messages line up with the bag's.

    Topics: ``/planefuse/tracks`` and ``/planefuse/detections`` (``foxglove.SceneUpdate``: one entity per track /
    detection, id ``track/<id>`` / ``detection/<step>/<i>``, pose = position [m]; the exact values in the
    entity's metadata: ``track_id``, ``x_m``, ``y_m``, ``vx_m_s``, ``vy_m_s`` / ``x_m``, ``y_m``, ``height_m``,
    ``confidence``, ``source``, as ``repr`` of the float64), and one ``foxglove.Grid`` per plane
    (:func:`occupancy_topic`; float32 field ``occupancy``, row-major with rows along +y). Per camera ``<name>``:
    ``/planefuse/cameras/<name>/image`` (``foxglove.CompressedImage``, frame ``<name>``: the camera's optical
    frame), ``.../calibration`` (``foxglove.CameraCalibration``: K, plumb_bob D, P = K [I | 0]) and
    ``.../annotations`` (``foxglove.ImageAnnotations``: per track a circle at its floor point, a line up to 1.7 m
    and its id, projected with the lens distortion); ``/tf`` (``foxglove.FrameTransforms``, once, at the first
    step): ``world`` -> ``<name>`` from ``T_world_cam``.
    """
    import foxglove
    from foxglove import channels as ch
    from foxglove import messages as fm

    path = Path(path)
    times = np.asarray(times_s, dtype=float)
    tmp = path.with_name(f".{path.name}{TMP_MARK}run")
    tmp.unlink(missing_ok=True)
    ctx = foxglove.Context()
    L, ny, nx = stack.shape
    identity = fm.Quaternion(x=0.0, y=0.0, z=0.0, w=1.0)
    try:
        with foxglove.open_mcap(tmp, context=ctx):
            c_tracks = ch.SceneUpdateChannel("/planefuse/tracks", context=ctx)
            c_dets = ch.SceneUpdateChannel("/planefuse/detections", context=ctx)
            c_grid = [ch.GridChannel(occupancy_topic(h), context=ctx) for h in stack.heights_m]
            tr_rows, det_rows = _steps(len(times), tracks), _steps(len(times), detections)
            views = _CameraViews(ctx, cameras, jpeg_quality) if len(cameras) else None
            alive: set[str] = set()
            for k, t in enumerate(times):
                ns = _ns(t, clock_origin_ns or 0)
                stamp = fm.Timestamp(sec=ns // 1_000_000_000, nsec=ns % 1_000_000_000)
                if views is not None:
                    rows = tr_rows[k]
                    views.log(k, float(t), ns, stamp, np.asarray(tracks["track_id"])[rows].astype(int),
                              np.column_stack([np.asarray(tracks["x_m"])[rows], np.asarray(tracks["y_m"])[rows]]))
                occ = np.asarray(occupancy[k], dtype="<f4")
                for ll in range(L):
                    pose = fm.Pose(position=fm.Vector3(x=stack.x_min_m, y=stack.y_min_m, z=float(stack.heights_m[ll])),
                                   orientation=identity)
                    c_grid[ll].log(fm.Grid(
                        timestamp=stamp, frame_id=WORLD_FRAME, pose=pose, column_count=nx,
                        cell_size=fm.Vector2(x=stack.cell_size_m, y=stack.cell_size_m), row_stride=4 * nx,
                        cell_stride=4, fields=[fm.PackedElementField(name="occupancy", offset=0,
                                                                     type=fm.PackedElementFieldNumericType.Float32)],
                        data=np.ascontiguousarray(occ[ll]).tobytes()), log_time=ns)
                entities, now = [], set()
                for i in tr_rows[k]:
                    tid = int(tracks["track_id"][i])
                    x, y = float(tracks["x_m"][i]), float(tracks["y_m"][i])
                    vx, vy = float(tracks["vx_m_s"][i]), float(tracks["vy_m_s"][i])
                    eid = f"track/{tid}"
                    now.add(eid)
                    centre = fm.Pose(position=fm.Vector3(x=x, y=y, z=_PERSON_HEIGHT_M / 2), orientation=identity)
                    yaw = float(np.arctan2(vy, vx))
                    speed = float(np.hypot(vx, vy))
                    heading = fm.Quaternion(x=0.0, y=0.0, z=float(np.sin(yaw / 2)), w=float(np.cos(yaw / 2)))
                    entities.append(fm.SceneEntity(
                        timestamp=stamp, frame_id=WORLD_FRAME, id=eid,
                        metadata=[fm.KeyValuePair(key=key, value=repr(v)) for key, v in
                                  (("track_id", tid), ("x_m", x), ("y_m", y), ("vx_m_s", vx), ("vy_m_s", vy))],
                        cylinders=[fm.CylinderPrimitive(
                            pose=centre, size=fm.Vector3(x=2 * person_radius_m, y=2 * person_radius_m,
                                                         z=_PERSON_HEIGHT_M),
                            bottom_scale=1.0, top_scale=1.0, color=_color(tid))],
                        arrows=[fm.ArrowPrimitive(
                            pose=fm.Pose(position=fm.Vector3(x=x, y=y, z=0.05), orientation=heading),
                            shaft_length=speed, shaft_diameter=0.05, head_length=0.15, head_diameter=0.12,
                            color=_color(tid))] if speed > 0 else [],
                        texts=[fm.TextPrimitive(
                            pose=fm.Pose(position=fm.Vector3(x=x, y=y, z=_PERSON_HEIGHT_M + 0.2), orientation=identity),
                            billboard=True, font_size=14.0, scale_invariant=True, color=_color(tid), text=str(tid))]))
                gone = [fm.SceneEntityDeletion(timestamp=stamp, type=fm.SceneEntityDeletionType.MatchingId, id=e)
                        for e in sorted(alive - now)]
                alive = now
                c_tracks.log(fm.SceneUpdate(deletions=gone, entities=entities), log_time=ns)
                dets = []
                for j, i in enumerate(det_rows[k]):
                    x, y, h = float(detections["x_m"][i]), float(detections["y_m"][i]), float(detections["height_m"][i])
                    conf = float(detections["confidence"][i])
                    dets.append(fm.SceneEntity(
                        timestamp=stamp, frame_id=WORLD_FRAME, id=f"detection/{k}/{j}",
                        metadata=[fm.KeyValuePair(key=key, value=repr(v)) for key, v in
                                  (("x_m", x), ("y_m", y), ("height_m", h), ("confidence", conf))]
                        + [fm.KeyValuePair(key="source", value=str(detections["source"][i]))],
                        spheres=[fm.SpherePrimitive(
                            pose=fm.Pose(position=fm.Vector3(x=x, y=y, z=0.05), orientation=identity),
                            size=fm.Vector3(x=0.15, y=0.15, z=0.15),
                            color=fm.Color(r=1.0, g=1.0, b=1.0, a=float(np.clip(conf, 0.2, 1.0))))]))
                c_dets.log(fm.SceneUpdate(deletions=[fm.SceneEntityDeletion(
                    timestamp=stamp, type=fm.SceneEntityDeletionType.All, id="")], entities=dets), log_time=ns)
        os.replace(tmp, path)
    finally:
        tmp.unlink(missing_ok=True)
    return path


class _CameraViews:
    """The cameras' channels of :func:`write_run_mcap`: image, calibration and track overlays per output step."""

    def __init__(self, ctx, cameras: Sequence, jpeg_quality: int) -> None:
        from foxglove import channels as ch

        self.cameras = list(cameras)
        self.quality = int(jpeg_quality)
        self.tf = ch.FrameTransformsChannel("/tf", context=ctx)
        self.image, self.calib, self.notes = [], [], []
        for cs in self.cameras:
            base = f"/planefuse/cameras/{cs.camera.name}"
            self.image.append(ch.CompressedImageChannel(f"{base}/image", context=ctx))
            self.calib.append(ch.CameraCalibrationChannel(f"{base}/calibration", context=ctx))
            self.notes.append(ch.ImageAnnotationsChannel(f"{base}/annotations", context=ctx))

    def log(self, k: int, t: float, ns: int, stamp, ids: np.ndarray, xy_m: np.ndarray) -> None:
        import cv2
        from foxglove import messages as fm
        from scipy.spatial.transform import Rotation

        if k == 0:
            transforms = []
            for cs in self.cameras:
                T = cs.camera.T_world_cam
                q = Rotation.from_matrix(T[:3, :3]).as_quat()
                transforms.append(fm.FrameTransform(
                    timestamp=stamp, parent_frame_id=WORLD_FRAME, child_frame_id=cs.camera.name,
                    translation=fm.Vector3(x=float(T[0, 3]), y=float(T[1, 3]), z=float(T[2, 3])),
                    rotation=fm.Quaternion(x=float(q[0]), y=float(q[1]), z=float(q[2]), w=float(q[3]))))
            self.tf.log(fm.FrameTransforms(transforms=transforms), log_time=ns)
        feet = np.column_stack([xy_m, np.zeros(len(xy_m))])
        heads = np.column_stack([xy_m, np.full(len(xy_m), _PERSON_HEIGHT_M)])
        for c, cs in enumerate(self.cameras):
            i = int(np.searchsorted(np.asarray(cs.times_s), t, side="right")) - 1
            if i < 0:
                continue
            cam = cs.camera
            K = np.asarray(cam.K, dtype=float)
            ok, jpg = cv2.imencode(".jpg", cs.frame(i), [cv2.IMWRITE_JPEG_QUALITY, self.quality])
            if not ok:
                raise ValueError(f"camera {cam.name!r}: frame {i} could not be encoded as JPEG")
            self.image[c].log(fm.CompressedImage(timestamp=stamp, frame_id=cam.name, data=jpg.tobytes(),
                                                 format="jpeg"), log_time=ns)
            if k == 0:
                self.calib[c].log(fm.CameraCalibration(
                    timestamp=stamp, frame_id=cam.name, width=cam.intrinsics.width_px, height=cam.intrinsics.height_px,
                    distortion_model="plumb_bob", D=[float(v) for v in cam.intrinsics.dist],
                    K=K.ravel().tolist(), R=np.eye(3).ravel().tolist(),
                    P=np.column_stack([K, np.zeros(3)]).ravel().tolist()), log_time=ns)
            circles, lines, texts = [], [], []
            if len(xy_m):
                uv_feet, uv_heads = cam.project(feet), cam.project(heads)
                for tid, f, h in zip(ids, uv_feet, uv_heads):
                    if not np.isfinite(f).all():
                        continue
                    r, g, b, a = _rgba(int(tid))
                    color = fm.Color(r=r, g=g, b=b, a=1.0)
                    circles.append(fm.CircleAnnotation(
                        timestamp=stamp, position=fm.Point2(x=float(f[0]), y=float(f[1])), diameter=12.0,
                        thickness=2.0, fill_color=fm.Color(r=r, g=g, b=b, a=0.3), outline_color=color))
                    texts.append(fm.TextAnnotation(
                        timestamp=stamp, position=fm.Point2(x=float(f[0]) + 8, y=float(f[1])), text=str(int(tid)),
                        font_size=14.0, text_color=color, background_color=fm.Color(r=0.0, g=0.0, b=0.0, a=0.5)))
                    if np.isfinite(h).all():
                        lines.append(fm.PointsAnnotation(
                            timestamp=stamp, type=fm.PointsAnnotationType.LineStrip,
                            points=[fm.Point2(x=float(f[0]), y=float(f[1])), fm.Point2(x=float(h[0]), y=float(h[1]))],
                            outline_color=color, thickness=2.0))
            self.notes[c].log(fm.ImageAnnotations(circles=circles, points=lines, texts=texts), log_time=ns)


def _rgba(track_id: int) -> tuple[float, float, float, float]:
    """A colour per track id (golden-ratio hues), alpha 0.8."""
    r, g, b = colorsys.hsv_to_rgb((track_id * 0.618033988749895) % 1.0, 0.8, 1.0)
    return r, g, b, 0.8


def _color(track_id: int):
    from foxglove import messages as fm

    r, g, b, a = _rgba(track_id)
    return fm.Color(r=r, g=g, b=b, a=a)


def read_mcap_messages(path: str | Path, topics: list[str] | None = None) -> Iterator[tuple[str, int, dict]]:
    """Messages of a protobuf-encoded MCAP (as :func:`write_run_mcap` writes it), decoded with the schemas the
    file holds (``mcap`` + ``protobuf``): ``(topic, log_time_ns, message as a dict)`` in log-time order.
    Field names are protobuf's JSON names (``frame_id`` -> ``frameId``)."""
    from google.protobuf import descriptor_pb2, descriptor_pool, json_format, message_factory
    from mcap.reader import make_reader

    classes: dict[int, type] = {}
    with open(path, "rb") as f:
        reader = make_reader(f)
        for schema, channel, message in reader.iter_messages(topics=topics, log_time_order=True):
            if schema.id not in classes:
                if schema.encoding != "protobuf":
                    raise ValueError(f"{path}: schema {schema.name!r} is {schema.encoding!r}, not protobuf")
                fds = descriptor_pb2.FileDescriptorSet.FromString(schema.data)
                pool = descriptor_pool.DescriptorPool()
                for fd in fds.file:
                    pool.Add(fd)
                classes[schema.id] = message_factory.GetMessageClass(pool.FindMessageTypeByName(schema.name))
            msg = classes[schema.id].FromString(message.data)
            yield channel.topic, message.log_time, json_format.MessageToDict(msg, preserving_proto_field_name=True)


def _ros_types():
    from rosbags.typesys import Stores, get_typestore, get_types_from_msg

    ts = get_typestore(Stores.ROS2_HUMBLE)
    types = {}
    for name, text in PEOPLE_MSG.items():
        types.update(get_types_from_msg(text, name))
    ts.register(types)
    return ts


def write_run_ros2_bag(path: str | Path, stack, times_s, occupancy, detections: Mapping[str, np.ndarray],
                       tracks: Mapping[str, np.ndarray], *, person_radius_m: float = 0.25,
                       clock_origin_ns: int | None = None) -> Path:
    """Write a run as a ROS 2 bag folder (MCAP storage) of standard messages, with ``rosbags`` (no ROS needed).

    Topics (all in frame ``world``, header stamps = log times = ``clock_origin_ns + round(time_s * 1e9)`` ns, as
    :func:`write_run_mcap`):

    * ``/planefuse/people`` ``people_msgs/msg/People``: one ``Person`` per track, ``name`` = track id,
      ``position`` (x, y [m], z = 0), ``velocity`` (vx, vy [m/s], 0), ``reliability`` 1.
    * ``/planefuse/tracks/markers`` ``visualization_msgs/msg/MarkerArray``: a DELETEALL marker, then per track a
      CYLINDER (namespace ``tracks``, id = track id) and a TEXT_VIEW_FACING label.
    * ``/planefuse/detections`` ``geometry_msgs/msg/PoseArray``: detections' positions (x, y [m], z = 0).
    * :func:`occupancy_topic` per plane, ``nav_msgs/msg/OccupancyGrid``: ``round(100 * P(occupied))`` in 0..100
      (the standard's percent; lossy), origin at the grid's corner (x_min, y_min, plane height), row-major along +y.
    """
    from rosbags.rosbag2 import StoragePlugin, Writer

    path = Path(path)
    work = path.with_name(f".{path.name}{TMP_MARK}run")
    shutil.rmtree(work, ignore_errors=True)
    work.mkdir()
    tmp = work / path.name  # the bag's data file is named after its folder: <name>.mcap
    ts = _ros_types()
    T = ts.types
    Time, Header = T["builtin_interfaces/msg/Time"], T["std_msgs/msg/Header"]
    Point, Quat, Pose, Vec3 = (T["geometry_msgs/msg/Point"], T["geometry_msgs/msg/Quaternion"],
                               T["geometry_msgs/msg/Pose"], T["geometry_msgs/msg/Vector3"])
    Marker, ColorRGBA, Duration = T["visualization_msgs/msg/Marker"], T["std_msgs/msg/ColorRGBA"], \
        T["builtin_interfaces/msg/Duration"]
    times = np.asarray(times_s, dtype=float)
    L, ny, nx = stack.shape
    q0 = Quat(x=0.0, y=0.0, z=0.0, w=1.0)

    def marker(header, mtype: int, action: int, mid: int, ns: str, pose, scale, color, text: str = ""):
        return Marker(header=header, ns=ns, id=mid, type=mtype, action=action, pose=pose, scale=scale, color=color,
                      lifetime=Duration(sec=0, nanosec=0), frame_locked=False, points=[], colors=[],
                      texture_resource="", texture=T["sensor_msgs/msg/CompressedImage"](
                          header=header, format="", data=np.zeros(0, np.uint8)),
                      uv_coordinates=[], text=text, mesh_resource="",
                      mesh_file=T["visualization_msgs/msg/MeshFile"](filename="", data=np.zeros(0, np.uint8)),
                      mesh_use_embedded_materials=False)

    try:
        with Writer(tmp, version=9, storage_plugin=StoragePlugin.MCAP) as w:
            def conn(topic: str, msgtype: str):
                return w.add_connection(topic, msgtype, typestore=ts)

            c_people = conn("/planefuse/people", "people_msgs/msg/People")
            c_markers = conn("/planefuse/tracks/markers", "visualization_msgs/msg/MarkerArray")
            c_dets = conn("/planefuse/detections", "geometry_msgs/msg/PoseArray")
            c_grid = [conn(occupancy_topic(h), "nav_msgs/msg/OccupancyGrid") for h in stack.heights_m]
            tr_rows, det_rows = _steps(len(times), tracks), _steps(len(times), detections)
            for k, t in enumerate(times):
                ns = _ns(t, clock_origin_ns or 0)
                header = Header(stamp=Time(sec=ns // 1_000_000_000, nanosec=ns % 1_000_000_000), frame_id=WORLD_FRAME)
                people, markers = [], [marker(header, 0, 3, 0, "tracks", Pose(position=Point(x=0.0, y=0.0, z=0.0),
                                                                                   orientation=q0),
                                              Vec3(x=1.0, y=1.0, z=1.0), ColorRGBA(r=0.0, g=0.0, b=0.0, a=0.0))]
                for i in tr_rows[k]:
                    tid = int(tracks["track_id"][i])
                    x, y = float(tracks["x_m"][i]), float(tracks["y_m"][i])
                    vx, vy = float(tracks["vx_m_s"][i]), float(tracks["vy_m_s"][i])
                    people.append(T["people_msgs/msg/Person"](
                        name=str(tid), position=Point(x=x, y=y, z=0.0), velocity=Point(x=vx, y=vy, z=0.0),
                        reliability=1.0, tagnames=[], tags=[]))
                    r, g, b, a = _rgba(tid)
                    rgba = ColorRGBA(r=r, g=g, b=b, a=a)
                    markers.append(marker(header, 3, 0, tid, "tracks",
                                          Pose(position=Point(x=x, y=y, z=_PERSON_HEIGHT_M / 2), orientation=q0),
                                          Vec3(x=2 * person_radius_m, y=2 * person_radius_m, z=_PERSON_HEIGHT_M), rgba))
                    markers.append(marker(header, 9, 0, tid, "track_ids",
                                          Pose(position=Point(x=x, y=y, z=_PERSON_HEIGHT_M + 0.2), orientation=q0),
                                          Vec3(x=0.0, y=0.0, z=0.3), rgba, text=str(tid)))
                w.write(c_people, ns, ts.serialize_cdr(T["people_msgs/msg/People"](header=header, people=people),
                                                       c_people.msgtype))
                w.write(c_markers, ns, ts.serialize_cdr(T["visualization_msgs/msg/MarkerArray"](markers=markers),
                                                        c_markers.msgtype))
                poses = [Pose(position=Point(x=float(detections["x_m"][i]), y=float(detections["y_m"][i]), z=0.0),
                              orientation=q0) for i in det_rows[k]]
                w.write(c_dets, ns, ts.serialize_cdr(T["geometry_msgs/msg/PoseArray"](header=header, poses=poses),
                                                     c_dets.msgtype))
                occ = np.asarray(occupancy[k], dtype=float)
                for ll in range(L):
                    info = T["nav_msgs/msg/MapMetaData"](
                        map_load_time=header.stamp, resolution=float(stack.cell_size_m), width=nx, height=ny,
                        origin=Pose(position=Point(x=stack.x_min_m, y=stack.y_min_m, z=float(stack.heights_m[ll])),
                                    orientation=q0))
                    data = np.clip(np.round(100.0 * occ[ll]), 0, 100).astype(np.int8).ravel()
                    w.write(c_grid[ll], ns, ts.serialize_cdr(
                        T["nav_msgs/msg/OccupancyGrid"](header=header, info=info, data=data), c_grid[ll].msgtype))
        shutil.rmtree(path, ignore_errors=True)
        os.replace(tmp, path)
    finally:
        shutil.rmtree(work, ignore_errors=True)
    return path
