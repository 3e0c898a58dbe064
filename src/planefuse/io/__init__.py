"""Recording format: a folder with a manifest (``scene.yaml``) and one stream per sensor, plus ground truth.

See ``docs/recording-format.md``. ``read_recording(dir)`` opens a folder lazily; ``Recording.write(dir)``
writes one (simulated recordings come from :func:`planefuse.sim.simulate`); ``import_recording`` builds one from
users' videos or images and calibration files; ``geometry_findings`` checks its cameras.
"""

from ._import import (
    CONTROL_POINT_COLUMNS,
    IMAGE_SUFFIXES,
    VIDEO_SUFFIXES,
    CameraInput,
    ControlPoints,
    ImportReport,
    import_recording,
    frame_times_of,
    people_from_boxes,
    probe_camera_input,
    read_control_points,
    read_ground_positions,
)
from ._rosbag import BAG_SENSOR_TYPES, BagImport, BagTopic, TopicReport, bag_topics, import_bag, \
    scan_ranges_from_points, select_bag_topics, static_transform
from ._validate import geometry_findings
from ._imu_logs import IMU_REFERENCE_COLUMNS, XIO_COLUMNS, ImuLog, read_imu_log
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
from ._recording import DEFAULT_IMAGE_FORMAT, Event, Recording, read_recording, write_recording
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
    "DEFAULT_IMAGE_FORMAT",
    "image_file_problem",
    "CONTROL_POINT_COLUMNS",
    "IMAGE_SUFFIXES",
    "VIDEO_SUFFIXES",
    "CameraInput",
    "ControlPoints",
    "ImportReport",
    "import_recording",
    "people_from_boxes",
    "frame_times_of",
    "probe_camera_input",
    "read_control_points",
    "read_ground_positions",
    "geometry_findings",
    "BAG_SENSOR_TYPES",
    "BagImport",
    "BagTopic",
    "TopicReport",
    "bag_topics",
    "import_bag",
    "scan_ranges_from_points",
    "select_bag_topics",
    "static_transform",
    "BODY_COLUMNS",
    "PEOPLE_COLUMNS",
    "SOUND_COLUMNS",
    "IMU_COLUMNS",
    "IMU_REFERENCE_COLUMNS",
    "XIO_COLUMNS",
    "ImuLog",
    "read_imu_log",
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
