"""Recording format: a folder with a manifest (``scene.yaml``) and one stream per sensor, plus ground truth.

See ``docs/recording-format.md``. ``read_recording(dir)`` opens a folder lazily; ``Recording.write(dir)``
writes one (simulated recordings come from :func:`planefuse.sim.simulate`).
"""

from ._groundtruth import BODY_COLUMNS, PEOPLE_COLUMNS, SOUND_COLUMNS, GroundTruth, PeopleTruth, SoundTruth
from ._manifest import (
    MANIFEST_NAME,
    BinauralEntry,
    CameraEntry,
    GroundTruthEntry,
    ImuEntry,
    LaserEntry,
    LaserScannerDevice,
    LaserUnitDevice,
    RecordingManifest,
    load_manifest,
)
from ._recording import Event, Recording, read_recording, write_recording
from ._streams import (
    IMU_COLUMNS,
    AudioStream,
    CameraFrame,
    CameraStream,
    ImuData,
    ImuStream,
    LaserScans,
    LaserStream,
    camera_from_entry,
    ignore_mask_from_entry,
    image_file_problem,
)
from ._timestamps import Gap
from ._video import VideoFrames, video_info
from ._yaml import load_yaml_model

__all__ = [
    "image_file_problem",
    "BODY_COLUMNS",
    "PEOPLE_COLUMNS",
    "SOUND_COLUMNS",
    "IMU_COLUMNS",
    "MANIFEST_NAME",
    "GroundTruth",
    "PeopleTruth",
    "SoundTruth",
    "BinauralEntry",
    "CameraEntry",
    "GroundTruthEntry",
    "ImuEntry",
    "LaserEntry",
    "LaserScannerDevice",
    "LaserUnitDevice",
    "RecordingManifest",
    "load_manifest",
    "Event",
    "Recording",
    "read_recording",
    "write_recording",
    "AudioStream",
    "CameraFrame",
    "CameraStream",
    "ImuData",
    "ImuStream",
    "LaserScans",
    "LaserStream",
    "camera_from_entry",
    "ignore_mask_from_entry",
    "VideoFrames",
    "video_info",
    "Gap",
    "load_yaml_model",
]
