"""From a run configuration (planefuse.config.RunConfig) to the system's parameters."""

from __future__ import annotations

from ..tracking import BOFParams, ClusterParams, TrackerParams, TrackingParams
from ._system import SystemParams

__all__ = ["system_params_from_config", "run_options_from_config"]


def system_params_from_config(cfg) -> SystemParams:
    """Map every field of ``cfg.sensors`` and ``cfg.models`` onto the library's parameter objects."""
    from ..laser import LaserSensorModel
    from ..vision import CameraParams, ForegroundParams, FusionParams

    cam, las, snd = cfg.sensors.cameras, cfg.sensors.laser, cfg.sensors.sound
    flt, det = cfg.models.filter, cfg.models.detection
    camera_params = CameraParams(
        foreground=ForegroundParams(method=cam.foreground_method.lower(), history=cam.history_frames,
                                    threshold=cam.var_threshold, detect_shadows=cam.detect_shadows),
        fusion=FusionParams(p_detect=cam.p_foreground_given_occupied, p_false_alarm=cam.p_foreground_given_free),
        sensor_model=cam.sensor_model,
    )
    laser_model = LaserSensorModel(p_occupied_hit=las.p_occupied_hit, p_occupied_free=las.p_occupied_free,
                                   no_return_free_m=las.no_return_free_m)
    tracking = TrackingParams(
        bof=BOFParams(n_velocities_per_axis=flt.n_velocities_per_axis, velocity_max_mps=flt.velocity_max_m_s,
                      prior_occupancy=flt.prior_occupancy, decay_rate_hz=flt.decay_rate_hz,
                      velocity_noise_rate_hz=flt.velocity_noise_rate_hz),
        cluster=ClusterParams(threshold=det.column_threshold, person_radius_m=det.person_radius_m,
                              min_separation_m=det.min_separation_m),
        tracker=TrackerParams(gate_m=det.gate_m, confirm_hits=det.confirm_hits, max_misses=det.max_misses),
        window_s=flt.window_s,
        merge_tolerance_s=flt.merge_tolerance_s,
    )
    return SystemParams(
        heights_m=tuple(cfg.planes.heights_m), cell_size_m=cfg.planes.cell_size_m, cameras=cam.enabled,
        laser=las.enabled, sound=snd.enabled, camera_params=camera_params, laser_model=laser_model,
        tracking=tracking, sound_block_s=snd.block_length_s, sound_model_path=snd.model_path,
        output_period_s=flt.output_period_s, threshold_m=det.match_distance_m,
    )


def run_options_from_config(cfg) -> dict:
    """The keyword arguments of :func:`~planefuse.pipeline.run_to_folder` that ``cfg.outputs`` and ``cfg.planes``
    set (everything but the recording, the parameters and the progress mode): what ``planefuse run`` and
    ``planefuse batch`` both run with."""
    import yaml

    from ..config import config_hash

    out = cfg.outputs
    return dict(
        animation=out.animation, figures=out.figures, report=out.report, rerun=out.rerun,
        chunk_steps=out.chunk_steps,
        config_text=yaml.safe_dump(cfg.model_dump(mode="json"), sort_keys=False) + f"# {config_hash(cfg)}\n",
        stack=cfg.planes.to_stack(),
    )
