"""``planefuse check CONFIG.yaml``: validate a configuration and its recording without running."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import typer
from rich.markup import escape
from rich.table import Table

from ..config import CheckReport, ConfigError, RunConfig, check_recording, load_config
from ._app import app, console
from ._config import exit_on_config_error
from ._import import recording_check_config

SCENE_FILE = "scene.yaml"


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


def _report_json(report: CheckReport) -> str:
    return json.dumps({
        "ok": report.ok,
        "issues": [{"level": i.level, "subject": i.subject, "message": i.message} for i in report.issues],
        "camera_visible_fraction": {k: np.asarray(v).tolist() for k, v in report.camera_visible_fraction.items()},
    })


@app.command()
def check(
    config: Path = typer.Argument(..., help="Run configuration (YAML), or a recording folder (checked with its "
                                  "own plane stack and monitored area, 10 cm cells)."),
    log_json: bool = typer.Option(False, "--log-json", help="Print the findings as one JSON object."),
    figures: Path = typer.Option(None, "--figures", help="Also write pictures to this folder: each camera's image "
                                 "with the monitored area, a 1 m ground grid and each plane's border drawn "
                                 "(camera_NAME.png), and a top view of how many cameras see each cell "
                                 "(coverage.png)."),
    frame: int = typer.Option(0, "--frame", help="With --figures: the recording's frame to draw on (negative: from "
                              "the end)."),
) -> None:
    """Validate CONFIG and its recording (calibrations, streams, time stamps, camera coverage) without running;
    with --figures, draw the ground, the monitored area and the planes on every camera."""
    try:
        cfg, chosen = (load_config(config), ()) if not config.is_dir() else recording_check_config(config)
    except ConfigError as err:
        if log_json:
            print(json.dumps({"ok": False, "file": str(err.file), "issues": [
                {"level": "error", "subject": i.field_path, "message": i.message, "expected": i.expected,
                 "line": i.line} for i in err.issues]}))
            raise typer.Exit(2) from None
        exit_on_config_error(err)
    report = CheckReport()
    _check_person_model(cfg, report)
    for message in chosen:
        report.add("info", "configuration", message)
    if not cfg.recording.is_dir():
        report.add("error", "recording", f"folder {cfg.recording} does not exist")
    elif not (cfg.recording / SCENE_FILE).is_file():
        report.add("error", "recording", f"{cfg.recording} has no {SCENE_FILE} manifest")
    else:
        _check_with_recording(cfg, report, figures, frame)
    if log_json:
        print(_report_json(report))
    else:
        table = Table(title=escape(f"planefuse check {config}"))
        for col in ("level", "subject", "finding"):
            table.add_column(col)
        style = {"error": "bold red", "warning": "yellow", "info": "green"}
        for it in report.issues:
            table.add_row(f"[{style[it.level]}]{it.level}[/]", escape(it.subject), escape(it.message))
        console.print(table)
        console.print("[bold green]OK[/]: ready to run" if report.ok
                      else f"[bold red]{len(report.errors)} error(s)[/]")
    raise typer.Exit(0 if report.ok else 1)


def _check_person_model(cfg: RunConfig, report: CheckReport) -> None:
    """The person detector's model (loaded and checked by :func:`load_config` already): its checksum and its cost
    per frame on one core, measured here."""
    cams = cfg.sensors.cameras
    if not cams.enabled or cams.person_detector != "yolox":
        return
    import cv2

    from ..vision import YoloxDetector

    threads = cv2.getNumThreads()
    cv2.setNumThreads(1)
    try:
        wh = tuple(cams.person_input_px or (416, 416))
        det = YoloxDetector(cams.person_model, wh)
        ms = det.cost_ms(wh)
    finally:
        cv2.setNumThreads(threads)
    info = det.info
    report.add("info", "sensors.cameras.person_model",
               f"{info.path}: sha256 {info.sha256}, {info.n_classes} classes, {ms:.1f} ms per frame on one core at "
               f"{wh[0]} x {wh[1]} px (measured now; person_input_px null fits each camera's frames: their own size, "
               "or a longer side of 416 px)")


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


def _check_with_recording(cfg: RunConfig, report: CheckReport, figures: Path | None = None, frame: int = 0) -> None:
    """The recording's own checks, and the plane stack the run would use on it (drawn into ``figures``)."""
    from ..pipeline import stack_for_recording

    try:
        rec, times = read_recording_for_check(cfg)
    except (ValueError, OSError) as err:
        report.add("error", "recording", f"cannot read the recording: {err}")
        return
    _check_outputs(cfg, rec, report)
    from ..pipeline import check_cameras_against_stack, check_modalities_present

    params = cfg.system_params()
    try:  # an enabled sensor without a stream: what `planefuse run` refuses, in its words
        check_modalities_present(rec, params)
    except ValueError as err:
        report.add("error", "sensors", str(err))

    try:  # planes above a camera are reported per camera by check_recording (geometry_findings)
        stack = stack_for_recording(rec, params, check_cameras=False)
        if cfg.sensors.cameras.enabled:
            check_cameras_against_stack(rec.cameras, stack, above=False)
    except ValueError as err:
        report.add("error", "planes", str(err))
        return
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
        if figures is not None:
            _write_figures(rec, stack, figures, frame, report)
        else:
            report.add("info", "figures", "see where the monitored area, the ground and the planes lie on each "
                       "camera's image: planefuse check ... --figures DIR")
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


def _check_outputs(cfg: RunConfig, rec, report: CheckReport) -> None:
    """What ``run`` would refuse about its output folder (as if run without --fresh/--force) and --rerun."""
    from ..outputs import out_dir_problem
    from ..pipeline import resume_key

    plan = cfg.plan()
    problem = out_dir_problem(plan.out_dir, config_hash=resume_key(plan, rec), protected=rec.root)
    if problem is not None:
        report.add("error", "outputs.out_dir", problem)
    if plan.outputs.rerun:
        try:
            import rerun as _  # noqa: F401
        except ImportError:
            report.add("error", "outputs.rerun", "needs rerun-sdk: pip install 'planefuse[viz]'")


def _write_figures(rec, stack, folder: Path, frame: int, report: CheckReport) -> None:
    """The pictures of :func:`planefuse.viz.installation_preview` written into ``folder``."""
    from ..outputs import atomic_write_bytes
    from ..viz import installation_preview

    try:
        pictures = installation_preview(rec, stack, frame_index=frame)
        folder.mkdir(parents=True, exist_ok=True)
        for stem, png in pictures.items():
            atomic_write_bytes(folder / f"{stem}.png", png)
    except (ValueError, OSError) as err:
        report.add("error", "figures", f"cannot draw the pictures into {folder}: {err}")
        return
    report.add("info", "figures", f"wrote {', '.join(f'{s}.png' for s in pictures)} to {folder}")
