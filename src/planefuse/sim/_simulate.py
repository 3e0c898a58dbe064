"""Compose the scene, the sensors and the ground truth into a :class:`~planefuse.io.Recording`."""

from __future__ import annotations

from dataclasses import dataclass
from functools import partial

import numpy as np

from ..io import CameraStream, GroundTruth, ImuStream, PeopleTruth, Recording, SoundTruth
from ._config import SceneConfig, default_scene_config
from ._imu import T_cam_imu, simulate_imu
from ._motion import R_world_cam_at, omega_cam_rad_s_at
from ._render import CameraRenderer, make_noise_bank
from ._scene import Scene
from ._sensors import audio_stream, laser_stream

__all__ = ["SimulatedRecording", "simulate", "sample_times", "groundtruth_of"]


@dataclass
class SimulatedRecording(Recording):
    """A :class:`~planefuse.io.Recording` with the :class:`Scene` and :class:`SceneConfig` behind it."""

    scene: Scene | None = None
    config: SceneConfig | None = None


def sample_times(duration_s: float, rate_hz: float, offset_s: float = 0.0) -> np.ndarray:
    """Times ``offset_s + k / rate_hz`` (k = 0, 1, ...) before ``duration_s`` [s]."""
    n = int(np.floor((duration_s - offset_s) * rate_hz - 1e-9)) + 1
    return offset_s + np.arange(max(n, 0)) / rate_hz


def simulate(config: SceneConfig | None = None) -> SimulatedRecording:
    """Simulate a scene: people walking in a room, seen by cameras with IMUs, a nodding laser scanner
    and heard by a binaural head.

    Frames are rendered and laser scans ray cast lazily when their stream is read (so a long simulation
    does not have to fit in memory); IMU data, the ear signals and the ground truth are computed now.

    Parameters
    ----------
    config : SceneConfig, optional
        The scene; default :func:`default_scene_config`.

    Returns
    -------
    SimulatedRecording
        A :class:`~planefuse.io.Recording` with ``.scene`` (the :class:`Scene`, for geometry queries such
        as ``bodies_at``) and ``.config``; ``rec.write(dir)`` stores it.
    """
    cfg = config if config is not None else default_scene_config()
    scene = Scene(cfg)
    rec = SimulatedRecording(
        duration_s=float(cfg.duration_s),
        planes_heights_m=list(cfg.planes_heights_m),
        room_xy_m=cfg.room_xy_m,
        wall_height_m=float(cfg.wall_height_m),
        source=f"planefuse simulate (seed {cfg.seed})",
        provenance=cfg.model_dump(mode="json"),
        scene=scene,
        config=cfg,
    )
    banks: dict[tuple[int, int], np.ndarray] = {}
    for i, spec in enumerate(cfg.cameras):
        cam = spec.pinhole()
        key = (spec.width_px, spec.height_px)
        if key not in banks:
            banks[key] = make_noise_bank(*key, cfg.render.pixel_noise_std, cfg.seed)
        renderer = CameraRenderer(cam, scene, cfg.render, cfg.seed, i, banks[key], motion=spec.motion)
        times = sample_times(cfg.duration_s, spec.rate_hz, spec.time_offset_s)
        frame_of = _faulty_frames(cfg, spec.name, times, np.random.default_rng([cfg.seed, 9, i]))
        rec.camera_streams[spec.name] = CameraStream(
            cam, times[frame_of[0]], partial(_render_faulty, renderer, times, frame_of), True, spec.rate_hz,
            get_background=lambda r=renderer: r.background,
        )
        if cfg.imu is not None:
            T = T_cam_imu()
            t_imu = sample_times(cfg.duration_s, cfg.imu.rate_hz)
            rng = np.random.default_rng([cfg.seed, 5, i])
            if spec.motion:  # the same attitude as the rendered frames; gyro = its body rate in the IMU frame
                R_world_imu = R_world_cam_at(cam.R_world_cam, spec.motion, t_imu) @ T[:3, :3]
                omega_imu = omega_cam_rad_s_at(cam.R_world_cam, spec.motion, t_imu) @ T[:3, :3]
                data = simulate_imu(R_world_imu, t_imu, cfg.imu, rng, omega_imu)
            else:
                data = simulate_imu(cam.R_world_cam @ T[:3, :3], t_imu, cfg.imu, rng)
            name = f"{spec.name}_imu"
            rec.imus[name] = ImuStream(name, spec.name, T, cfg.imu.rate_hz, len(t_imu), cfg.imu.gyro_noise_rad_s,
                                       cfg.imu.accel_noise_m_s2, cfg.imu.gravity_m_s2, data=data)
    if cfg.laser is not None:
        rec.lasers[cfg.laser.name] = laser_stream(scene, cfg.laser, sample_times(cfg.duration_s, cfg.laser.rate_hz),
                                                  cfg.seed)
    if cfg.head is not None:
        rec.audio[cfg.head.name] = audio_stream(scene, cfg.seed)
    rec.groundtruth = groundtruth_of(scene)
    return rec


def _faulty_frames(cfg: SceneConfig, camera: str, times: np.ndarray, rng: np.random.Generator):
    """Frames a camera with faults delivers: ``(kept, source, black)`` over its nominal frames ``times``.

    ``kept`` (F,) bool: the frame arrives (each is dropped with ``cfg.dropped_frame_probability``; without
    it no random number is drawn). For the kept frames, in order: ``source`` (K,) int, the nominal frame
    rendered (a frozen camera repeats the last frame before the fault), ``black`` (K,) bool.
    """
    n = len(times)
    kept = np.ones(n, bool)
    if cfg.dropped_frame_probability > 0:
        kept = rng.random(n) >= cfg.dropped_frame_probability
    source = np.arange(n)
    black = np.zeros(n, bool)
    for f in cfg.camera_faults:
        if f.camera != camera:
            continue
        inside = (times >= f.start_s) & (times < f.end_s)
        if f.kind == "black":
            black |= inside
        else:
            source[inside] = max(int(np.searchsorted(times, f.start_s)) - 1, 0)
    return kept, source[kept], black[kept]


def _render_faulty(renderer: CameraRenderer, times: np.ndarray, frame_of, k: int):
    """Image and mask of the ``k``-th delivered frame (see :func:`_faulty_frames`); black frames have an
    empty mask (nothing is visible)."""
    _, source, black = frame_of
    img, mask = renderer.render(float(times[source[k]]), int(source[k]))
    if black[k]:
        return np.zeros_like(img), np.zeros_like(mask)
    return img, mask


def groundtruth_of(scene: Scene) -> GroundTruth:
    """People and sound-source ground truth of ``scene`` at ``config.groundtruth_rate_hz``."""
    cfg = scene.config
    t = sample_times(cfg.duration_s, cfg.groundtruth_rate_hz)
    st = scene.people_at(t)
    P = scene.n_people
    people = PeopleTruth(t, scene.person_ids.copy(), st.xy_m, st.heading_rad, st.speed_m_s, scene.height_m.copy())
    bodies = np.array([[b.person_id, b.height_m, b.hip_height_m, b.leg_radius_m, b.leg_spacing_m,
                        b.torso_radius_m, b.head_radius_m] for b in scene.bodies]).reshape(P, 7)
    sound = None
    speakers = sorted({s.person_id for s in cfg.speakers})
    if cfg.head is not None and speakers:
        az, el = scene.azimuth_in_head_at(t)
        sound = SoundTruth(t, np.array(speakers), scene.speaking_at(t)[:, speakers],
                           scene.mouth_positions_at(t)[:, speakers], az[:, speakers], el[:, speakers])
    return GroundTruth(people, bodies, sound)
