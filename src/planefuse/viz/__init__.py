"""What a user looks at: matplotlib figures, the plane-stack animation and the rerun recording."""

from ._animation import animate_stack, camera_track_frames, camera_tracks_video, stack_frames
from ._figures import (
    FigureInputs,
    grid_lines_world,
    occupancy_mean,
    plot_camera_grid,
    plot_camera_tracks,
    plot_laser_points,
    plot_metrics,
    plot_plane_occupancy,
    plot_saliency,
    png_bytes,
    run_figures,
    track_colour,
)
from ._preview import (
    area_outline_world,
    ground_grid_world,
    installation_preview,
    plot_camera_preview,
    plot_coverage,
)
from ._rerun import RerunLogger, plane_entity, rrd_entity_paths

__all__ = [
    "FigureInputs",
    "RerunLogger",
    "animate_stack",
    "area_outline_world",
    "camera_track_frames",
    "camera_tracks_video",
    "ground_grid_world",
    "installation_preview",
    "plot_camera_preview",
    "plot_coverage",
    "grid_lines_world",
    "occupancy_mean",
    "plane_entity",
    "plot_camera_grid",
    "plot_camera_tracks",
    "plot_laser_points",
    "plot_metrics",
    "plot_plane_occupancy",
    "plot_saliency",
    "png_bytes",
    "rrd_entity_paths",
    "run_figures",
    "stack_frames",
    "track_colour",
]
