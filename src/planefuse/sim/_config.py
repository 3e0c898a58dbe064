"""Scene configuration (``SCENE.yaml``): a pydantic model with units in every field name.

Every field has a default, so an empty file (or :func:`default_scene_config`) is the built-in
default scene: a 10 m x 10 m room, 6 people, 4 cameras with IMUs in the corners, a nodding laser
on a wall and a binaural head on another wall, two people speaking in turn.
"""

from __future__ import annotations

from pathlib import Path
from typing import Annotated, Literal

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, field_validator, model_validator

from ..geometry import CameraIntrinsics, PinholeCamera, T_world_cam_look_at, transform_from_rotation_translation
from ..io._paths import check_name
from ..io._yaml import load_yaml_model
from ._motion import CameraMotionSpec

__all__ = [
    "CameraSpec",
    "ImuSpec",
    "LaserSpec",
    "HeadSpec",
    "SpeakerSpec",
    "PeopleSpec",
    "RenderSpec",
    "OccluderSpec",
    "CameraFaultSpec",
    "SceneConfig",
    "default_scene_config",
    "load_scene_config",
]

Vec3 = tuple[float, float, float]
PositiveFloat = Annotated[float, Field(gt=0)]


class _Model(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)

    @field_validator("name", check_fields=False)
    @classmethod
    def _name(cls, v: str) -> str:
        return check_name(v, "sensor name")  # it becomes a file name in the written recording


class CameraSpec(_Model):
    """A camera looking from ``position_m`` at ``target_m`` (world frame, metres) at rest; ``motion`` turns it
    about its optical centre over time (:mod:`planefuse.sim._motion`; empty = static)."""

    name: str
    position_m: Vec3
    target_m: Vec3
    width_px: int = Field(360, gt=0)
    height_px: int = Field(288, gt=0)
    hfov_deg: float = Field(90.0, gt=0, lt=170)
    dist: tuple[float, float, float, float, float] = (-0.05, 0.01, 0.0, 0.0, 0.0)
    rate_hz: PositiveFloat = 25.0
    time_offset_s: float = Field(0.0, ge=0.0, description="first frame time; frames at offset + k / rate")
    motion: list[CameraMotionSpec] = Field([], description="sway / bump / pan of the camera; empty = static")

    def pinhole(self) -> PinholeCamera:
        """The :class:`~planefuse.geometry.PinholeCamera` this spec describes."""
        f = 0.5 * self.width_px / np.tan(np.radians(self.hfov_deg) / 2)
        K = np.array([[f, 0, (self.width_px - 1) / 2], [0, f, (self.height_px - 1) / 2], [0, 0, 1.0]])
        intr = CameraIntrinsics(K, self.width_px, self.height_px, np.asarray(self.dist, dtype=float))
        return PinholeCamera(intr, T_world_cam_look_at(self.position_m, self.target_m), name=self.name)


class ImuSpec(_Model):
    """Inertial unit rigidly attached to every camera (accelerometer + gyroscope).

    The IMU frame has x forward (the camera's optical axis), y left, z up in the image
    (``T_cam_imu`` in the recording); noise figures are per-sample standard deviations.
    """

    rate_hz: PositiveFloat = 200.0
    gyro_noise_rad_s: float = Field(0.002, ge=0)
    accel_noise_m_s2: float = Field(0.02, ge=0)
    gyro_bias_rad_s: float = Field(0.003, ge=0, description="std of the constant per-axis bias")
    accel_bias_m_s2: float = Field(0.03, ge=0, description="std of the constant per-axis bias")
    vibration_m_s2: float = Field(0.02, ge=0, description="amplitude of a building vibration")
    vibration_hz: PositiveFloat = 13.0
    gravity_m_s2: PositiveFloat = 9.81


class LaserSpec(_Model):
    """A 2-D laser range finder on a nodding (tilting) unit: a 3-D scanner (seed ref. [7])."""

    name: str = "laser0"
    position_m: Vec3 | None = Field(None, description="None = 0.15 m from the x_min wall, mid-way, 1.0 m up")
    yaw_deg: float = 0.0
    rate_hz: PositiveFloat = 40.0
    fov_deg: float = Field(270.0, gt=0, le=360)
    resolution_deg: float = Field(0.25, gt=0)
    range_min_m: float = Field(0.1, ge=0)
    max_range_m: PositiveFloat = 30.0
    range_noise_m: float = Field(0.01, ge=0)
    tilt_min_deg: float = Field(-5.0, description="nodding range; positive tilts look down")
    tilt_max_deg: float = 15.0
    tilt_period_s: PositiveFloat = 2.0

    @model_validator(mode="after")
    def _check(self) -> LaserSpec:
        if self.tilt_min_deg > self.tilt_max_deg:
            raise ValueError(f"tilt_min_deg {self.tilt_min_deg} must not exceed tilt_max_deg {self.tilt_max_deg}")
        if self.range_min_m >= self.max_range_m:
            raise ValueError(f"range_min_m {self.range_min_m} must be below max_range_m {self.max_range_m}")
        return self

    def T_world_laser(self) -> np.ndarray:
        """Pose (4, 4) of the (untilted) laser base in the world: x forward, z up."""
        return _T_world_yaw(self.position_m, self.yaw_deg, "laser")


def _T_world_yaw(position_m, yaw_deg: float, what: str) -> np.ndarray:
    if position_m is None:
        raise ValueError(f"{what}.position_m is not set (it is filled in by SceneConfig)")
    c, s = np.cos(np.radians(yaw_deg)), np.sin(np.radians(yaw_deg))
    R = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    return transform_from_rotation_translation(R, position_m)


class HeadSpec(_Model):
    """A binaural head (two ears). Head frame: x forward (nose), y left, z up; azimuth = atan2(y, x)."""

    name: str = "head"
    position_m: Vec3 | None = Field(None, description="None = 0.3 m from the y_min wall, mid-way, 1.6 m up")
    yaw_deg: float = Field(90.0, description="direction of the nose, counter-clockwise from world +x")
    fs_hz: int = Field(16000, gt=0)
    head_radius_m: PositiveFloat = 0.0875
    hrtf_sofa: Path | None = Field(None, description="SOFA HRTF file; None = spherical head model")
    rt60_s: float = Field(0.3, ge=0, description="reverberation time; 0 = anechoic")

    def T_world_head(self) -> np.ndarray:
        """Pose (4, 4) of the head frame in the world."""
        return _T_world_yaw(self.position_m, self.yaw_deg, "head")


class SpeakerSpec(_Model):
    """Person ``person_id`` speaks during each ``[start_s, end_s]`` interval."""

    person_id: int = Field(ge=0)
    intervals_s: list[tuple[float, float]]
    wav_path: Path | None = Field(None, description="speech WAV; None = seeded speech-like synthetic signal")

    @model_validator(mode="after")
    def _check_intervals(self) -> SpeakerSpec:
        prev = -np.inf
        for i, (a, b) in enumerate(self.intervals_s):
            if not (b > a >= prev):
                raise ValueError(f"intervals_s[{i}] = [{a}, {b}] must satisfy start < end, sorted, not overlapping")
            prev = b
        return self


class PeopleSpec(_Model):
    """How people look and walk."""

    height_range_m: tuple[float, float] = (1.5, 1.95)
    speed_range_m_s: tuple[float, float] = (1.0, 1.5)
    pause_probability: float = Field(0.4, ge=0, le=1, description="chance of stopping at each goal")
    pause_range_s: tuple[float, float] = (0.5, 3.0)
    wall_margin_m: float = Field(0.6, ge=0.3)


class RenderSpec(_Model):
    """Image formation: lighting flicker, sensor noise, shadows."""

    pixel_noise_std: float = Field(3.0, ge=0, description="per-pixel Gaussian noise [grey levels]")
    gain_flicker_std: float = Field(0.01, ge=0, description="per-frame global gain jitter (relative)")
    gain_drift: float = Field(0.04, ge=0, description="amplitude of slow global illumination drift (relative)")
    gain_drift_period_s: PositiveFloat = 7.0
    shadows: bool = True


class OccluderSpec(_Model):
    """A static box on the floor (pillar, shelf, counter), axis-aligned with the room [m].

    It hides what lies behind it from the cameras (rendered in the frames and the masks) and stops laser
    beams (ray cast); people walk around it.
    """

    name: str = "occluder"
    center_xy_m: tuple[float, float]
    size_xy_m: tuple[PositiveFloat, PositiveFloat]
    height_m: PositiveFloat = 2.2
    bgr: tuple[int, int, int] = (150, 150, 150)

    def box_m(self) -> tuple[float, float, float, float, float, float]:
        """``(x_min, x_max, y_min, y_max, z_min, z_max)`` [m]."""
        (cx, cy), (sx, sy) = self.center_xy_m, self.size_xy_m
        return (cx - sx / 2, cx + sx / 2, cy - sy / 2, cy + sy / 2, 0.0, float(self.height_m))


class CameraFaultSpec(_Model):
    """Camera ``camera`` fails during ``[start_s, end_s)``: its frames are black or frozen on the last good one."""

    camera: str
    start_s: float = Field(ge=0)
    end_s: float
    kind: Literal["black", "frozen"] = "black"

    @model_validator(mode="after")
    def _check(self) -> CameraFaultSpec:
        if not self.end_s > self.start_s:
            raise ValueError(f"camera fault of {self.camera!r}: end_s {self.end_s} must exceed start_s {self.start_s}")
        return self


class SceneConfig(_Model):
    """Everything the simulator needs; see ``docs/simulator.md``."""

    duration_s: PositiveFloat = 20.0
    seed: int = 0
    room_size_m: tuple[PositiveFloat, PositiveFloat] = (10.0, 10.0)
    wall_height_m: PositiveFloat = 3.0
    n_people: int = Field(6, ge=0, le=20)
    people: PeopleSpec = PeopleSpec()
    cameras: list[CameraSpec] | None = Field(None, description="None = 4 cameras in the room's corners")
    imu: ImuSpec | None = ImuSpec()
    render: RenderSpec = RenderSpec()
    laser: LaserSpec | None = LaserSpec()
    head: HeadSpec | None = HeadSpec()
    speakers: list[SpeakerSpec] | None = Field(None, description="None = persons 0 and 1 speak in turn")
    planes_heights_m: list[float] = [0.0, 0.5, 1.0, 1.5]
    groundtruth_rate_hz: PositiveFloat = 25.0
    occluders: list[OccluderSpec] = Field(default_factory=list, description="static boxes (pillars, shelves)")
    camera_faults: list[CameraFaultSpec] = Field(default_factory=list, description="black / frozen intervals")
    dropped_frame_probability: float = Field(0.0, ge=0, lt=1, description="chance that a frame never arrives")

    @model_validator(mode="after")
    def _fill_defaults(self) -> SceneConfig:
        if self.cameras is None:
            object.__setattr__(self, "cameras", default_camera_specs(self.room_size_m))
        if self.speakers is None:
            T = self.duration_s
            spk = []
            if self.n_people >= 1:
                spk.append(SpeakerSpec(person_id=0, intervals_s=[(0.05 * T, 0.45 * T)]))
            if self.n_people >= 2:
                spk.append(SpeakerSpec(person_id=1, intervals_s=[(0.55 * T, 0.95 * T)]))
            object.__setattr__(self, "speakers", spk)
        names = [c.name for c in self.cameras]
        if len(set(names)) != len(names):
            raise ValueError(f"camera names must be unique, got {names}")
        for i, f in enumerate(self.camera_faults):
            if f.camera not in names:
                raise ValueError(f"camera_faults[{i}].camera {f.camera!r} is not one of the cameras {names}")
        for i, s in enumerate(self.speakers):
            if s.person_id >= self.n_people:
                raise ValueError(f"speakers[{i}].person_id = {s.person_id} but there are {self.n_people} people")
            if s.intervals_s and s.intervals_s[-1][1] > self.duration_s + 1e-9:
                raise ValueError(f"speakers[{i}].intervals_s ends after duration_s = {self.duration_s}")
        x0, x1, y0, y1 = self.room_xy_m
        if self.head is not None and self.head.position_m is None:
            object.__setattr__(self, "head", self.head.model_copy(update={"position_m": ((x0 + x1) / 2, y0 + 0.3, 1.6)}))
        if self.laser is not None and self.laser.position_m is None:
            object.__setattr__(self, "laser", self.laser.model_copy(update={"position_m": (x0 + 0.15, (y0 + y1) / 2, 1.0)}))
        for what, spec in (("head", self.head), ("laser", self.laser)):
            if spec is not None:
                x, y, z = spec.position_m
                if not (x0 < x < x1 and y0 < y < y1 and 0 < z < self.wall_height_m):
                    raise ValueError(f"{what}.position_m {spec.position_m} is outside the room {self.room_xy_m} "
                                     f"x (0, {self.wall_height_m}) m")
        for i, o in enumerate(self.occluders):
            bx0, bx1, by0, by1, _, _ = o.box_m()
            if not (x0 < bx0 and bx1 < x1 and y0 < by0 and by1 < y1 and o.height_m < self.wall_height_m):
                raise ValueError(f"occluders[{i}] ({o.name}) box {o.box_m()} is not inside the room {self.room_xy_m}")
        lo, hi = self.people.height_range_m
        if not 0.5 < lo <= hi < self.wall_height_m:
            raise ValueError(f"people.height_range_m must satisfy 0.5 < min <= max < wall_height_m, got {lo, hi}")
        if min(self.room_size_m) <= 2 * self.people.wall_margin_m + 0.5:
            raise ValueError(f"room_size_m {self.room_size_m} too small for the people's wall margin")
        return self

    @property
    def room_xy_m(self) -> tuple[float, float, float, float]:
        """``(x_min, x_max, y_min, y_max)`` of the room [m]; the room's corner is the world origin."""
        return (0.0, float(self.room_size_m[0]), 0.0, float(self.room_size_m[1]))


def default_camera_specs(room_size_m=(10.0, 10.0), heights_m=(3.0, 2.8, 3.3, 2.6)) -> list[CameraSpec]:
    """Four cameras in the corners of the room, 0.3 m from the walls, looking down past the centre.

    Same placement as :func:`planefuse.geometry.default_camera_ring` for a square room.
    """
    Lx, Ly = room_size_m
    m = 0.3
    spots = [(m, m), (Lx - m, m), (Lx - m, Ly - m), (m, Ly - m)]
    out = []
    for i, (x, y) in enumerate(spots):
        target = (Lx / 2 + 0.15 * (Lx / 2 - x), Ly / 2 + 0.15 * (Ly / 2 - y), 0.0)
        out.append(CameraSpec(name=f"cam{i}", position_m=(x, y, heights_m[i]), target_m=target))
    return out


def default_scene_config(**overrides) -> SceneConfig:
    """The built-in default scene; keyword arguments override fields (e.g. ``duration_s=10``)."""
    return SceneConfig(**overrides)


def load_scene_config(path: str | Path) -> SceneConfig:
    """Read and validate ``SCENE.yaml``; errors name the file, line and field."""
    return load_yaml_model(path, SceneConfig)
