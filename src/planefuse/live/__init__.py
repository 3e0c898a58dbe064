"""Live: cameras as they stream, the whole system fed as their frames arrive, people on a live page.

``planefuse live LIVE.yaml`` (docs/live.md). :class:`LiveRun` runs the system's own
:class:`~planefuse.pipeline.SystemRun` on the instants :class:`FrameSynchroniser` forms from :class:`CameraSource`
threads (RTSP, HTTP MJPEG, local devices, video files played at their rate), writes the tracks as they come
(:class:`LiveOutputs`) and serves :class:`LivePage`. :class:`MjpegServer` serves frames as MJPEG streams (tests,
demos).
"""

from ._config import LiveConfig, load_live_config
from ._mjpeg import MjpegServer, recording_jpeg_frames
from ._outputs import TRACKS_CSV_COLUMNS, LiveOutputs, track_records
from ._page import LivePage
from ._resume import LIVE_FILES, LiveFolder, live_key
from ._run import CLOCKS, LiveRun, LiveSettings, LiveSummary
from ._sources import (PRESENTATION_KINDS, SOURCE_KINDS, SOURCE_STATES, CameraSource, LiveSource, SourceHealth,
                       camera_reader, device_path, mjpeg_frames, source_kind)
from ._sync import FrameSynchroniser, LiveFrame, LiveInstant

__all__ = ["CLOCKS", "LIVE_FILES", "LiveFolder", "live_key", "PRESENTATION_KINDS", "SOURCE_KINDS", "SOURCE_STATES",
           "CameraSource", "FrameSynchroniser",
           "LiveConfig", "LiveFrame", "LiveInstant", "LiveOutputs", "LivePage", "LiveRun", "LiveSettings", "LiveSource",
           "LiveSummary", "MjpegServer", "SourceHealth", "TRACKS_CSV_COLUMNS", "camera_reader", "device_path",
           "load_live_config", "mjpeg_frames", "recording_jpeg_frames", "source_kind", "track_records"]
