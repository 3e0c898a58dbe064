"""What a run writes besides its tables: the ``outputs`` section of the configuration as library values."""

from __future__ import annotations

from dataclasses import dataclass

from .._params import check_fields, require

__all__ = ["OutputSettings", "ANIMATIONS"]

#: Animation formats of :attr:`OutputSettings.animation`.
ANIMATIONS = ("none", "gif", "mp4")


@dataclass(frozen=True)
class OutputSettings:
    """Output options of a run (``planefuse run``'s ``outputs`` section, ``planefuse demo``'s defaults).

    Attributes
    ----------
    zarr : bool
        Keep per-plane occupancy over time on disk (``occupancy.zarr``). False keeps it in memory for the
        figures only, and the run cannot be resumed.
    chunk_steps : int
        Output steps per committed chunk (the unit of resume) [steps].
    figures : bool
        Write ``figures/*.png``.
    animation : {"none", "gif", "mp4"}
        Animation of the plane stack over time.
    report : bool
        Write the self-contained ``report.html``.
    rerun : bool
        Write ``planefuse.rrd`` for the rerun viewer.
    figure_dpi : int
        Resolution of the figures [dots per inch].
    animation_max_frames : int or None
        The animation shows at most this many output steps, evenly spaced (a longer run is subsampled, and a
        warning says so); None = every step.
    camera_videos : bool
        Also write ``figures/camera_<name>_tracks.mp4`` per camera: the frame nearest each output step with the tracks
        drawn from the feet to the head (at most ``animation_max_frames`` steps).
    mcap : bool
        Write ``planefuse.mcap``: tracks, detections and each plane's occupancy grid in Foxglove's schemas
        (``planefuse.outputs.write_run_mcap``; opens in Foxglove with no ROS).
    ros2_bag : bool
        Write ``ros2_bag/``: the same as ROS 2 messages (``people_msgs/People``, ``visualization_msgs/MarkerArray``,
        ``geometry_msgs/PoseArray``, ``nav_msgs/OccupancyGrid`` per plane) in a ROS 2 bag (MCAP storage).

    Only ``zarr`` and ``chunk_steps`` decide what a resumed run can reuse; the others may change between
    an interrupted run and its resumption.
    """

    zarr: bool = True
    chunk_steps: int = 50
    figures: bool = True
    animation: str = "gif"
    report: bool = True
    rerun: bool = False
    figure_dpi: int = 100
    animation_max_frames: int | None = 300
    camera_videos: bool = False
    mcap: bool = False
    ros2_bag: bool = False

    def __post_init__(self) -> None:
        check_fields(self, chunk_steps="int>=1", figure_dpi="int>=1", animation_max_frames="?int>=1")
        require(self.animation in ANIMATIONS, self, "animation",
                f"must be one of {', '.join(ANIMATIONS)}, got {self.animation!r}")
