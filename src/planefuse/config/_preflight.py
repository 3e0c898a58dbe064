"""The one validation ``planefuse check`` and ``planefuse run`` share: a configuration against its recording.

``run`` refuses exactly the inputs ``check`` reports an error for (a corrupt IMU file, a stream that does not
overlap the others, an unusable frame file, a grid too large for the memory, an output folder in use, ...), with
the same words, so that the two never disagree on the same input.
"""

from __future__ import annotations

import numpy as np

from ._check import CheckReport, check_recording
from ._models import RunConfig

__all__ = ["check_run_config", "read_recording_for_check", "SCENE_FILE"]

SCENE_FILE = "scene.yaml"


def check_run_config(cfg: RunConfig, *, resume: bool = True, force: bool = False):
    """Check ``cfg`` and its recording without running (what ``planefuse check`` prints, what ``planefuse run``
    refuses on an error).

    Parameters
    ----------
    cfg : RunConfig
        A loaded configuration (paths resolved).
    resume, force : bool
        As ``run``'s ``--fresh`` (``resume=False``) and ``--force`` treat the output folder.

    Returns
    -------
    (CheckReport, Recording or None)
        The findings, and the recording where it could be read.
    """
    report = CheckReport()
    if not cfg.recording.is_dir():
        report.add("error", "recording", f"folder {cfg.recording} does not exist")
        return report, None
    if not (cfg.recording / SCENE_FILE).is_file():
        report.add("error", "recording", f"{cfg.recording} has no {SCENE_FILE} manifest")
        return report, None
    rec = _check_with_recording(cfg, report, resume=resume, force=force)
    return report, rec


def read_recording_for_check(cfg: RunConfig):
    """The recording of ``cfg`` and its streams' time stamps [s] (planefuse.io).

    Reads only the streams' time stamps (laser scans chunk by chunk; audio as its first and
    last sample time). Raises ``ValueError`` when the recording or a calibration does not load.
    """
    from ..io import read_recording

    rec = read_recording(cfg.recording)
    times: dict[str, np.ndarray] = {name: cs.times_s for name, cs in rec.camera_streams.items()}
    for name, imu in rec.imus.items():
        times[name] = np.concatenate([c.times_s for c in imu.chunks()]) if imu.n_samples else np.zeros(0)
    for name, ls in rec.lasers.items():
        times[name] = np.concatenate([c.times_s for c in ls.chunks()]) if ls.n_scans else np.zeros(0)
    for name, au in rec.audio.items():
        times[name] = au.start_time_s + np.array([0.0, max(au.n_samples - 1, 0) / au.fs_hz]) \
            if au.n_samples else np.zeros(0)
    return rec, times


def _check_camera_rate(cfg: RunConfig, rec, report: CheckReport) -> None:
    """Say at what rate the cameras will be processed (``sensors.cameras.max_rate_hz``, 5 Hz by default), and warn
    where output steps would get no camera instant."""
    cap_hz, rates = cfg.sensors.cameras.max_rate_hz, [cs.rate_hz for cs in rec.camera_streams.values()]
    if cap_hz is None or not rates or max(rates) <= cap_hz:
        return
    report.add("info", "sensors.cameras.max_rate_hz", f"cameras at up to {max(rates):g} Hz are processed at most "
               f"{cap_hz:g} times a second (every frame: max_rate_hz: null)")
    output_hz = 1.0 / cfg.models.filter.output_period_s
    if output_hz > cap_hz * (1 + 1e-9):
        report.add("warning", "sensors.cameras.max_rate_hz", f"{output_hz:g} output steps per second but at most "
                   f"{cap_hz:g} camera instants: some steps get no camera evidence (raise max_rate_hz to "
                   f"{output_hz:g} Hz or lengthen models.filter.output_period_s)")
    if not cfg.models.filter.enabled:
        report.add("warning", "sensors.cameras.max_rate_hz", f"models.filter.enabled: false sees only the camera "
                   f"instants of each output step, at most {cap_hz * cfg.models.filter.output_period_s:g} at "
                   f"{cap_hz:g} Hz: one frame is weak evidence (demo scene, no filter: MODA 0.63 at 5 Hz, 0.94 with "
                   "every frame; docs/results.md); max_rate_hz: null gives it every frame")


def _check_with_recording(cfg: RunConfig, report: CheckReport, *, resume: bool = True, force: bool = False):
    """The recording's own checks, and the plane stack the run would use on it."""
    from ..pipeline import stack_for_recording, writer_buffered_steps

    try:
        rec, times = read_recording_for_check(cfg)
    except (ValueError, OSError) as err:
        report.add("error", "recording", f"cannot read the recording: {err}")
        return None
    _check_outputs(cfg, rec, report, resume=resume, force=force)
    from ..pipeline import check_cameras_against_stack, check_modalities_present

    params = cfg.system_params()
    try:  # an enabled sensor without a stream: what `planefuse run` refuses, in its words
        check_modalities_present(rec, params)
    except ValueError as err:
        report.add("error", "sensors", str(err))

    try:  # planes above a camera are reported per camera by check_recording (geometry_findings)
        n_steps = int(np.floor((rec.duration_s - 1e-9) / params.output_period_s)) + 1
        stack = stack_for_recording(rec, params, check_cameras=False, buffered_steps=writer_buffered_steps(
            cfg.outputs.chunk_steps, cfg.outputs.zarr, n_steps))
        if cfg.sensors.cameras.enabled:
            check_cameras_against_stack(rec.cameras, stack, above=False)
    except ValueError as err:
        report.add("error", "planes", str(err))
        return rec
    report.add("info", "planes", f"{stack.n_planes} planes of {stack.ny} x {stack.nx} cells "
               f"({stack.cell_size_m:g} m) at z = {', '.join(f'{h:g}' for h in stack.heights_m)} m")
    cams = cfg.sensors.cameras.enabled
    if cams and cfg.sensors.cameras.sensor_model == "cell" and len(rec.cameras) <= 2:
        report.add("warning", "sensors.cameras.sensor_model",
                   f"{len(rec.cameras)} camera(s) with the per-cell model: it reports people where the views' lines of "
                   "sight cross (ghosts); the generative model explains them away (two cameras: EPFL terrace real "
                   "video, filtered MODA 0.58 generative against -3.0 per cell; simulated, 0.65-0.67 against -0.45 to "
                   "-0.80; docs/results.md). Use the real-video profile's sensor_model: generative and its companions: "
                   "planefuse config init --profile real-video")
    if cams:
        from ..registration import camera_view_findings

        _check_camera_rate(cfg, rec, report)
        for level, subject, message in camera_view_findings(rec.cameras, stack):
            report.add(level, subject, message)
    sub = check_recording(rec.cameras if cams else [], stack, times, recording=rec,
                          frame_files={n: cs.frame_files for n, cs in rec.camera_streams.items()} if cams else None)
    report.issues += sub.issues
    if cfg.sensors.laser.enabled:
        from ..laser import tilting_unit_from_device

        for name in rec.lasers:
            try:
                tilting_unit_from_device(rec.laser(name).model)
            except ValueError as err:
                report.add("error", name, f"laser device entry: {err}")
    report.camera_visible_fraction = sub.camera_visible_fraction
    report.coverage_fraction = sub.coverage_fraction
    return rec


def _check_outputs(cfg: RunConfig, rec, report: CheckReport, *, resume: bool = True, force: bool = False) -> None:
    """What ``run`` would refuse about its output folder (with ``run``'s --fresh: ``resume=False``, --force) and
    --rerun."""
    from ..outputs import out_dir_problem
    from ..pipeline import resume_key

    plan = cfg.plan()
    problem = out_dir_problem(plan.out_dir, config_hash=resume_key(plan, rec), resume=resume, force=force,
                              protected=rec.root)
    if problem is not None:
        report.add("error", "outputs.out_dir", problem)
    if plan.outputs.rerun:
        try:
            import rerun as _  # noqa: F401
        except ImportError:
            report.add("error", "outputs.rerun", "needs rerun-sdk: pip install 'planefuse[viz]'")
