"""Multi-modal simulator with ground truth: people (legs, torso, head) walking in a walled room, seen by
cameras with IMUs (rendered frames + exact masks), a nodding laser and a binaural head.

Quick start::

    from planefuse.sim import default_scene_config, simulate
    rec = simulate(default_scene_config(duration_s=10))
    for frame in rec.camera("cam0"):   # frame.image (H, W, 3) BGR, frame.mask (H, W) labels
        ...
    rec.write("out/")                  # planefuse.io.read_recording("out/") gives the same accessors

See ``docs/simulator.md``.
"""

from ._config import (
    CameraFaultSpec,
    CameraSpec,
    HeadSpec,
    ImuSpec,
    LaserSpec,
    OccluderSpec,
    PeopleSpec,
    RenderSpec,
    SceneConfig,
    SpeakerSpec,
    default_camera_specs,
    default_scene_config,
    load_scene_config,
)
from ._imu import R_cam_imu, T_cam_imu, simulate_imu, simulate_rotating_imu, simulate_static_imu
from ._motion import CameraMotionSpec, R_world_cam_at, max_motion_deg, omega_cam_rad_s_at
from ._render import CameraRenderer, body_surface_points, occluder_distance_image, render_background
from ._scenarios import SCENARIOS, scenario_config, scenario_description
from ._scene import Body, PeopleState, Scene, sample_points_in_bodies
from ._sensors import audio_stream, laser_stream, tilting_unit_from_spec
from ._simulate import SimulatedRecording, groundtruth_of, sample_times, simulate

__all__ = [
    "SCENARIOS",
    "scenario_config",
    "scenario_description",
    "occluder_distance_image",
    "CameraFaultSpec",
    "OccluderSpec",
    "CameraSpec",
    "HeadSpec",
    "ImuSpec",
    "LaserSpec",
    "PeopleSpec",
    "RenderSpec",
    "SceneConfig",
    "SpeakerSpec",
    "default_camera_specs",
    "default_scene_config",
    "load_scene_config",
    "R_cam_imu",
    "T_cam_imu",
    "simulate_imu",
    "simulate_rotating_imu",
    "simulate_static_imu",
    "CameraMotionSpec",
    "R_world_cam_at",
    "max_motion_deg",
    "omega_cam_rad_s_at",
    "CameraRenderer",
    "body_surface_points",
    "render_background",
    "audio_stream",
    "laser_stream",
    "tilting_unit_from_spec",
    "Body",
    "PeopleState",
    "Scene",
    "sample_points_in_bodies",
    "SimulatedRecording",
    "groundtruth_of",
    "sample_times",
    "simulate",
]
