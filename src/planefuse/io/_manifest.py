"""The recording manifest ``scene.yaml``: planes, every sensor's calibration (frames, units) and data files.

See ``docs/recording-format.md``. Paths in the manifest are relative to the recording folder.
"""

from __future__ import annotations

from pathlib import Path
from typing import Annotated, Any, Literal, Union

import numpy as np
from pydantic import AliasChoices, BaseModel, ConfigDict, Field, field_validator, model_validator

from ..geometry import check_transform
from ._paths import check_name
from ._yaml import load_yaml_model

__all__ = [
    "CameraEntry",
    "ImuEntry",
    "LaserEntry",
    "BinauralEntry",
    "GroundTruthEntry",
    "RecordingManifest",
    "SensorEntry",
    "load_manifest",
    "MANIFEST_NAME",
    "FORMAT_VERSION",
]

MANIFEST_NAME = "scene.yaml"
FORMAT_VERSION = 2

Matrix = list[list[float]]


class _Entry(BaseModel):
    model_config = ConfigDict(extra="forbid")

    @field_validator("name", check_fields=False)
    @classmethod
    def _name(cls, v: str) -> str:
        return check_name(v, "sensor name")  # it becomes a file name (figures, cameras/<name>/)


def _rigid(v: Matrix, what: str) -> Matrix:
    T = np.asarray(v, dtype=float)
    if T.shape != (4, 4):
        raise ValueError(f"{what} must be a 4x4 matrix, got shape {T.shape}")
    check_transform(T, what)
    return v


class CameraEntry(_Entry):
    """A camera: pinhole intrinsics with OpenCV distortion, pose ``T_world_cam`` (camera x right, y down,
    z forward), and its frames: image files listed with their times in ``times_file``, or a video file
    (format version 2) whose frames are timed by ``times_file`` (``time_s,frame_index``) or, without one,
    by ``start_time_s + k / rate_hz``. Pixels that are not scene evidence (a watermark, a TV, a privacy zone)
    are given by ``ignore_rects_px`` and/or ``ignore_mask_file``."""

    type: Literal["camera"]
    name: str
    width_px: int = Field(gt=0)
    height_px: int = Field(gt=0)
    K: Matrix
    dist: list[float] = [0.0, 0.0, 0.0, 0.0, 0.0]
    T_world_cam: Matrix
    rate_hz: float = Field(gt=0, le=1e5)  # [Hz]; above 100 kHz is a unit error
    n_frames: int = Field(ge=0)
    times_file: str | None = Field(None, description="CSV: time_s,image_file[,mask_file] (image frames) or "
                                   "time_s,frame_index (video frames), relative to the recording")
    video_file: str | None = Field(None, description="video (mp4/avi/mkv...) holding the frames (format 2)")
    start_time_s: float = Field(0.0, description="time of video frame 0 when there is no times_file [s]")
    background_file: str | None = Field(None, description="image of the empty scene (optional)")
    ignore_rects_px: list[tuple[int, int, int, int]] = Field(
        [], description="pixel rectangles (u_min, v_min, u_max, v_max), max exclusive, that are not evidence")
    ignore_mask_file: str | None = Field(None, description="8-bit image, non-zero = pixel not evidence")

    @field_validator("K")
    @classmethod
    def _k(cls, v: Matrix) -> Matrix:
        if np.asarray(v, dtype=float).shape != (3, 3):
            raise ValueError("K must be a 3x3 matrix")
        return v

    @field_validator("dist")
    @classmethod
    def _dist(cls, v: list[float]) -> list[float]:
        if len(v) not in (4, 5):
            raise ValueError(f"dist must have 4 or 5 coefficients (k1 k2 p1 p2 [k3]), got {len(v)}")
        return v

    @field_validator("T_world_cam")
    @classmethod
    def _t(cls, v: Matrix) -> Matrix:
        return _rigid(v, "T_world_cam")

    @field_validator("ignore_rects_px")
    @classmethod
    def _rects(cls, v: list[tuple[int, int, int, int]]) -> list[tuple[int, int, int, int]]:
        for r in v:
            if not (0 <= r[0] < r[2] and 0 <= r[1] < r[3]):
                raise ValueError(f"ignore rectangle {list(r)} must be (u_min, v_min, u_max, v_max) with "
                                 "0 <= u_min < u_max and 0 <= v_min < v_max [px]")
        return v

    @model_validator(mode="after")
    def _frames(self) -> CameraEntry:
        if self.times_file is None and self.video_file is None:
            raise ValueError(f"camera {self.name!r} needs a times_file (image frames) or a video_file")
        for r in self.ignore_rects_px:
            if r[2] > self.width_px or r[3] > self.height_px:
                raise ValueError(f"camera {self.name!r}: ignore rectangle {list(r)} reaches past the "
                                 f"{self.width_px}x{self.height_px} px image")
        return self

class ImuEntry(_Entry):
    """An IMU rigidly attached to camera ``attached_to``; CSV columns
    ``time_s,gyro_x_rad_s,gyro_y_rad_s,gyro_z_rad_s,accel_x_m_s2,accel_y_m_s2,accel_z_m_s2`` in the IMU frame."""

    type: Literal["imu"]
    name: str
    attached_to: str
    T_cam_imu: Matrix
    rate_hz: float = Field(gt=0, le=1e5)  # [Hz]; above 100 kHz is a unit error
    n_samples: int = Field(ge=0)
    file: str
    gyro_noise_rad_s: float = Field(0.0, ge=0)
    accel_noise_m_s2: float = Field(0.0, ge=0)
    gravity_m_s2: float = Field(9.81, gt=0)

    @field_validator("T_cam_imu")
    @classmethod
    def _t(cls, v: Matrix) -> Matrix:
        return _rigid(v, "T_cam_imu")


class LaserScannerDevice(BaseModel):
    """The 2-D scanner of a laser unit: the fields of :class:`planefuse.laser.LaserScannerSpec`, whose rules
    (positive increment and beams, ``0 <= range_min_m < range_max_m``) apply when the unit is built."""

    model_config = ConfigDict(extra="forbid")
    angle_min_rad: float
    angle_increment_rad: float
    n_beams: int
    range_min_m: float
    range_max_m: float
    range_noise_sigma_m: float = 0.0
    name: str = "lrf"


class LaserUnitDevice(BaseModel):
    """A laser unit: its scanner on a tilt axis (:class:`planefuse.laser.TiltingUnit`, built by
    :func:`planefuse.laser.tilting_unit_from_device`; a fixed 2-D scanner has tilt 0 and no offset). Frames in
    docs/conventions.md: {S} scanner, {L} unit (base)."""

    model_config = ConfigDict(extra="forbid")
    scanner: LaserScannerDevice
    offset_tilt_scanner_m: tuple[float, float, float] = (0.0, 0.0, 0.0)
    tilt_min_rad: float = 0.0
    tilt_max_rad: float = 0.0
    tilt_period_s: float = 2.0
    scan_duration_s: float | None = None


class LaserEntry(_Entry):
    """A (nodding) laser range finder. Scans are NPZ chunks with ``time_s (S,)``, ``angles_rad (B,)``,
    ``ranges_m (S, B)`` (inf = no return, NaN = invalid) and ``tilt_rad (S,)`` or ``(S, B)``; other per-scan arrays are
    kept. ``T_world_laser`` is the pose of the unit frame {L} (the untilted scanner; older manifests call it
    ``T_world_base``); ``model`` is the device."""

    type: Literal["laser"]
    name: str
    T_world_laser: Matrix = Field(validation_alias=AliasChoices("T_world_laser", "T_world_base"))
    rate_hz: float = Field(gt=0, le=1e5)  # [Hz]; above 100 kHz is a unit error
    n_scans: int = Field(ge=0)
    files: list[str]
    model: LaserUnitDevice

    @field_validator("T_world_laser")
    @classmethod
    def _t(cls, v: Matrix) -> Matrix:
        return _rigid(v, "T_world_laser")


class BinauralEntry(_Entry):
    """A binaural head: a two-channel WAV (left, right), sample ``i`` at ``start_time_s + i / fs_hz``.
    Head frame: x forward (nose), y left (left ear), z up."""

    type: Literal["binaural"]
    name: str
    T_world_head: Matrix
    fs_hz: int = Field(gt=0)
    start_time_s: float = 0.0
    n_samples: int = Field(ge=0)
    file: str
    head_radius_m: float = Field(0.0875, gt=0)
    hrtf_sofa: str | None = None

    @field_validator("T_world_head")
    @classmethod
    def _t(cls, v: Matrix) -> Matrix:
        return _rigid(v, "T_world_head")


SensorEntry = Annotated[Union[CameraEntry, ImuEntry, LaserEntry, BinauralEntry], Field(discriminator="type")]


class GroundTruthEntry(_Entry):
    """Ground-truth files (CSV, relative paths); see ``docs/recording-format.md``."""

    people_file: str | None = None
    bodies_file: str | None = None
    sound_sources_file: str | None = None


class RecordingManifest(_Entry):
    """Top level of ``scene.yaml``."""

    format: Literal["planefuse-recording"] = "planefuse-recording"
    format_version: Literal[1, 2] = FORMAT_VERSION
    duration_s: float = Field(ge=0)
    planes_heights_m: list[float] = [0.0, 0.5, 1.0, 1.5]
    room_xy_m: tuple[float, float, float, float] | None = None
    wall_height_m: float | None = None
    sensors: list[SensorEntry] = []
    groundtruth: GroundTruthEntry | None = None
    calibration_points_file: str | None = Field(
        None, description="CSV camera,u_px,v_px,x_m,y_m,z_m: pixels of known world points (planefuse check)")
    source: str = ""
    clock_origin_ns: int | None = Field(
        None, description="what time 0 of the recording is on the source's clock [ns], e.g. the header stamp of a "
        "ROS bag's first message (planefuse import-bag); the robotics outputs stamp their messages with it")

    @model_validator(mode="after")
    def _refs(self) -> RecordingManifest:
        names = [s.name for s in self.sensors]
        dup = sorted({n for n in names if names.count(n) > 1})
        if dup:
            raise ValueError(f"sensor names must be unique, repeated: {dup}")
        cams = {s.name for s in self.sensors if s.type == "camera"}
        if self.format_version < 2:
            for s in self.sensors:
                if s.type == "camera" and (s.video_file or s.ignore_rects_px or s.ignore_mask_file):
                    raise ValueError(f"camera {s.name!r}: video_file and ignore regions need format_version 2")
        for s in self.sensors:
            if s.type == "imu" and s.attached_to not in cams:
                raise ValueError(f"imu {s.name!r} is attached_to {s.attached_to!r}, which is not a camera here {sorted(cams)}")
        return self

    def entries(self, kind: str) -> list:
        """Sensor entries of one ``type`` ("camera", "imu", "laser", "binaural"), in file order."""
        return [s for s in self.sensors if s.type == kind]


def load_manifest(path: str | Path) -> RecordingManifest:
    """Read and validate a recording's ``scene.yaml``; errors name the file, line and field."""
    return load_yaml_model(path, RecordingManifest)
