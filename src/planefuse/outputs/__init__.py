"""What a run writes: atomic files, the resumable :class:`OutputWriter`, and progress reporting.

See ``docs/outputs.md`` for the folder layout and how the pipeline drives the writer.
"""

from ._atomic import atomic_open, atomic_write_bytes, atomic_write_json, atomic_write_text, remove_stale_temporaries
from ._settings import ANIMATIONS, OutputSettings
from ._progress import ProgressMode, ProgressReporter, progress_mode, progress_steps
from ._mcap import MCAP_FILE, ROS2_BAG_DIR, occupancy_topic, read_mcap_messages, write_run_mcap, write_run_ros2_bag
from ._writer import (DETECTION_COLUMNS, FIGURES_WRITTEN, MOT_FORMAT, TRACK_COLUMNS, OutputWriter, mot_rows,
                      out_dir_problem, read_table, rows_by_step)

__all__ = [
    "FIGURES_WRITTEN",
    "out_dir_problem",
    "ANIMATIONS",
    "OutputSettings",
    "DETECTION_COLUMNS",
    "TRACK_COLUMNS",
    "OutputWriter",
    "ProgressMode",
    "ProgressReporter",
    "atomic_open",
    "atomic_write_bytes",
    "atomic_write_json",
    "atomic_write_text",
    "MOT_FORMAT",
    "mot_rows",
    "progress_mode",
    "progress_steps",
    "read_table",
    "rows_by_step",
    "remove_stale_temporaries",
    "MCAP_FILE",
    "ROS2_BAG_DIR",
    "occupancy_topic",
    "read_mcap_messages",
    "write_run_mcap",
    "write_run_ros2_bag",
]
