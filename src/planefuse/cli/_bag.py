"""``planefuse import-bag BAG OUT``: a recording folder from the camera, IMU and laser topics of a ROS bag."""

from __future__ import annotations

from pathlib import Path

import typer

from ._app import app, console, exit_with_error, units_table
from ._import import _floats, _pairs


@app.command("import-bag")
def import_bag_cmd(
    bag: Path = typer.Argument(..., help="ROS 2 bag folder (sqlite3 or MCAP storage), .mcap file or ROS 1 .bag file."),
    out: Path = typer.Argument(None, help="Recording folder to create (not needed with --list)."),
    list_topics: bool = typer.Option(False, "--list", help="List the bag's topics (type, count, what planefuse "
                                     "makes of them) and stop."),
    camera: list[str] = typer.Option([], "--camera", help="NAME=IMAGE_TOPIC[,CAMERA_INFO_TOPIC]: an Image or "
                                     "CompressedImage topic (CameraInfo default: the one in its namespace)."),
    imu: list[str] = typer.Option([], "--imu", help="NAME=TOPIC[@CAMERA]: an Imu topic and the camera it is "
                                  "attached to (default: the nearest camera)."),
    laser: list[str] = typer.Option([], "--laser", help="NAME=TOPIC: a LaserScan topic."),
    cloud: list[str] = typer.Option([], "--cloud", help="NAME=TOPIC: a PointCloud2 topic, imported as a laser whose "
                                    "scans are a horizontal slice of the cloud (pointcloud_to_laserscan)."),
    cloud_band: str = typer.Option("-0.1,0.1", "--cloud-band", help="Z_MIN,Z_MAX [m] of the slice, in the cloud's "
                                   "(level) frame."),
    cloud_beams: int = typer.Option(1440, "--cloud-beams", help="Beams of the sliced scan over 360 deg."),
    cloud_range: str = typer.Option("0.1,100", "--cloud-range", help="RANGE_MIN,RANGE_MAX [m] of the sliced scan."),
    world_frame: str = typer.Option(None, "--world-frame", help="tf frame of planefuse's world (z up, floor at "
                                    "z = 0, metres); default: the root of the tf tree."),
    tf: list[str] = typer.Option([], "--tf", help="PARENT,CHILD,X,Y,Z,YAW,PITCH,ROLL (m, rad): a transform the bag "
                                 "lacks (static_transform_publisher's order); repeatable."),
    planes: str = typer.Option("0,0.5,1,1.5", "--planes", help="Suggested plane heights [m]."),
    room: str = typer.Option(None, "--room", help="Monitored area X_MIN,X_MAX,Y_MIN,Y_MAX [m] (world frame)."),
    overwrite: bool = typer.Option(False, "--overwrite", help="Write into a non-empty folder."),
) -> None:
    """Import a ROS bag's sensors as a planefuse recording (header stamps; poses from /tf_static and /tf).

    Without --camera, --imu, --laser or --cloud every camera (image topic with a CameraInfo beside it), Imu and LaserScan
    topic is imported; with any of them, only the topics named. Out-of-order, duplicated and missing messages are
    counted per topic and printed.
    """
    import warnings

    from ..io import bag_topics, import_bag, static_transform

    try:
        if list_topics:
            rows = [(t.topic, t.msgtype, t.count, t.use or "-") for t in bag_topics(bag)]
            console.print(units_table(f"topics of {bag}", ("topic", "type", "messages", "planefuse"), rows,
                                      right=False))
            return
        if out is None:
            raise ValueError("give the recording folder OUT to create (or --list)")
        explicit = bool(camera or imu or laser or cloud)
        cams = {n: tuple(v.split(",", 1)) if "," in v else (v, None) for n, v in _pairs(camera, "--camera").items()}
        imus, imu_cams = {}, {}
        for n, v in _pairs(imu, "--imu").items():
            topic, _, cam = v.partition("@")
            imus[n] = topic
            if cam:
                imu_cams[n] = cam
        lasers = _pairs(laser, "--laser")
        with warnings.catch_warnings(record=True):  # the per-topic counts are printed below
            warnings.simplefilter("always")
            res = import_bag(
                bag, out, cameras=cams if explicit else None, imus=imus if explicit else None, imu_cameras=imu_cams,
                lasers=lasers if explicit else None, clouds=_pairs(cloud, "--cloud"),
                cloud_band_m=tuple(_floats(cloud_band, 2, "--cloud-band")), cloud_beams=cloud_beams,
                cloud_range_m=tuple(_floats(cloud_range, 2, "--cloud-range")), world_frame=world_frame,
                extra_transforms=[static_transform(t) for t in tf], planes_heights_m=_floats(planes, None, "--planes"),
                room_xy_m=tuple(_floats(room, 4, "--room")) if room else None, overwrite=overwrite)
    except ValueError as err:
        exit_with_error(str(err))
    rows = [(r.topic, f"{r.kind} {r.sensor}", r.frame_id, r.n_messages, r.n_written, r.n_out_of_order,
             r.n_duplicate, r.n_missing, f"{r.rate_hz:.3f}") for r in res.topics]
    console.print(units_table(f"imported {bag} into {out}", ("topic", "sensor", "frame", "messages", "written",
                                                              "out of order", "duplicated", "missing", "rate [Hz]"),
                              rows))
    for note in res.notes:
        console.print(note, highlight=False)
