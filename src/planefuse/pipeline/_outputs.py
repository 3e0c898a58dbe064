"""Run the system on a recording and write everything a user looks at (planefuse.outputs / viz / report)."""

from __future__ import annotations

import ctypes
import functools
import time
import warnings
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from ..eval import run_counts, system_metrics
from ..io import Recording
from ..io._paths import check_name
from ..outputs import FIGURES_WRITTEN, MOT_FORMAT, OutputSettings, OutputWriter, atomic_open, atomic_write_bytes, \
    atomic_write_text, mot_rows, progress_steps, rows_by_step
from ._plan import RunPlan, resume_key
from ._streams import ModalityReport
from ._system import EVAL_WARMUP_S, SystemParams, SystemResult, SystemRun, can_evaluate, evaluate_system, \
    check_modalities_present, run_system, stack_for_recording, writer_buffered_steps

if TYPE_CHECKING:  # matplotlib and rerun (~1 s of imports) only where figures or a rerun recording are asked for
    from ..viz import FigureInputs

__all__ = ["run_plan", "run_to_folder", "write_presentation"]


def _figure_inputs(rec: Recording, report: ModalityReport, times_s: np.ndarray) -> FigureInputs:
    from ..viz import FigureInputs

    cams = rec.cameras
    images, labels, frames, ignored = {}, {}, {}, {}
    for c in cams:
        cs = rec.camera(c.name)
        if len(cs):
            mid = len(cs) // 2
            images[c.name] = cs.frame(mid)[..., ::-1]  # BGR -> RGB
            labels[c.name] = f"frame {mid}, t = {cs.times_s[mid]:.2f} s"
            # four frames across the run with the tracks drawn (RGB for matplotlib)
            picks = np.unique(np.linspace(0, len(cs) - 1, min(4, len(cs))).round().astype(int))
            frames[c.name] = [(int(i), float(cs.times_s[i]), cs.frame(int(i))[..., ::-1]) for i in picks]
        if cs.ignore_mask is not None:
            ignored[c.name] = cs.ignore_mask
    rep = report
    laser = np.concatenate([p.reshape(-1, 3) for p in rep.laser_points_world]) if rep.laser_points_world else None
    sal = np.stack(rep.sound_saliency) if rep.sound_saliency else None
    gt = None
    if rec.groundtruth is not None and rec.groundtruth.people is not None:
        p = rec.groundtruth.people
        idx = np.array([p.index_at(t) for t in times_s], dtype=int)
        T, P = len(idx), len(p.person_ids)
        gt = {"step": np.repeat(np.arange(T), P), "track_id": np.tile(p.person_ids, T),
              "x_m": p.xy_m[idx, :, 0].ravel(), "y_m": p.xy_m[idx, :, 1].ravel()}
    return FigureInputs(cameras=cams, camera_images=images, laser_points_world=laser, saliency=sal,
                        saliency_times_s=np.asarray(rep.sound_times_s) if sal is not None else None,
                        saliency_azimuth_rad=rep.sound_azimuth_grid_rad if sal is not None else None,
                        ground_truth=gt, ignore_masks=ignored, camera_image_labels=labels,
                        camera_frames=frames, camera_streams={c.name: rec.camera(c.name) for c in cams})


def _log_modalities(logger, rec: Recording, report: ModalityReport, step_times: np.ndarray,
                    camera_every_s: float = 1.0) -> None:
    """Add the cameras (poses, a frame every ``camera_every_s``), laser points and sound wedges to the rerun
    recording (occupancy, detections and tracks are logged by the writer at every output step)."""
    logger.log_cameras(rec.cameras)

    def step_of(t: float) -> int:
        return int(np.argmin(np.abs(step_times - t))) if len(step_times) else 0

    for cam in rec.cameras:
        cs = rec.camera(cam.name)
        if not len(cs):
            continue
        every = max(1, int(round(camera_every_s * cs.rate_hz)))
        for i in range(0, len(cs), every):
            t = float(cs.times_s[i])
            logger.set_time(step_of(t), t)
            logger.log_camera_image(cam.name, cs.frame(i))
    rep = report
    for t, pts in zip(rep.laser_points_times_s, rep.laser_points_world):
        logger.set_time(step_of(t), t)
        logger.log_laser("laser", pts)
    if rep.T_world_head is not None:
        R = rep.T_world_head[:3, :3]
        yaw = float(np.arctan2(R[1, 0], R[0, 0]))
        half = np.radians(5.0)
        for t, az in zip(rep.sound_times_s, rep.sound_map_azimuth_rad):
            if not np.isfinite(az):
                continue
            logger.set_time(step_of(t), t)
            # two ears: the front half-line and its mirror behind the interaural axis both carry evidence
            for name, a in (("front", yaw + az), ("back", yaw + np.pi - az)):
                logger.log_sound_wedge(name, rep.T_world_head[:3, 3], a - half, a + half)


def _start(rec: Recording, params: SystemParams, stack, out: OutputWriter, client=None) -> SystemRun:
    """The run to continue: from the writer's checkpoint when it resumes, else from the start (a resumed
    folder without a usable checkpoint is recomputed from the start; its finished chunks are not rewritten)."""
    if not out.resumed:
        return SystemRun(rec, params, stack, client=client)
    try:
        state = out.load_checkpoint()
        if state is not None:
            run = SystemRun(rec, params, stack, checkpoint=state, client=client)
            if run.n_outputs == out.resume_step:
                return run
            why = f"it is at step {run.n_outputs}, the finished chunks end at step {out.resume_step}"
        else:
            why = "there is none for the last finished chunk"
    except ValueError as exc:
        why = str(exc)
    warnings.warn(f"{out.out_dir / 'checkpoint.npz'}: cannot resume from the checkpoint ({why}); recomputing "
                  f"from the start, the first {out.resume_step} finished steps are kept", stacklevel=3)
    return SystemRun(rec, params, stack, client=client)


def _steps_from_tables(out: OutputWriter):
    """Per-step detections and tracks read back from the writer (the whole run, resumed or not)."""
    times = out.times_s()
    det_xy = rows_by_step(out.detections_table(), len(times), "x_m", "y_m")
    tracks = [(float(t), rows[:, 0].astype(np.int64), rows[:, 1:3])
              for t, rows in zip(times, rows_by_step(out.tracks_table(), len(times), "track_id", "x_m", "y_m"))]
    return times, det_xy, tracks


def _write_stitched(out: OutputWriter, rec: Recording, run: SystemRun, times, det_xy, tracks,
                    elapsed_s: float) -> dict:
    """Stitch a finished run's tracks (:meth:`SystemRun.stitch`; their gaps filled and their positions
    smoothed where ``stitch.max_fill_gap_s`` and ``stitch.smooth_sigma_s`` are set), write them to
    ``tracks_stitched.csv`` (step, time_s, track_id, x_m, y_m) and ``tracks_stitched_mot.txt`` (MOTChallenge, as
    ``tracks_mot.txt``) and return ``{"stitched_identities": n}`` with, where the run is scored, the stitched
    tracks' ``stitched`` scores (MOTA, IDF1, identity switches and IDF1's labelled bounds)."""
    from ..tracking import fill_gaps, smooth_positions

    mapping, stitched = run.stitch(tracks)
    if run.params.stitch.max_fill_gap_s is not None:  # the gaps within one identity, on the straight line
        stitched = fill_gaps(stitched, run.params.stitch.max_fill_gap_s)
    if run.params.stitch.smooth_sigma_s is not None:  # each identity's positions smoothed in time
        stitched = smooth_positions(stitched, run.params.stitch.smooth_sigma_s)
    rows = ["step,time_s,track_id,x_m,y_m"]
    for k, (t, ids, xy) in enumerate(stitched):
        rows += [f"{k},{float(t)!r},{int(i)},{float(q[0])!r},{float(q[1])!r}" for i, q in zip(ids, xy)]
    atomic_write_text(out.out_dir / "tracks_stitched.csv", "\n".join(rows) + "\n")
    all_steps = np.concatenate([np.full(len(i), k) for k, (_, i, _) in enumerate(stitched)] + [np.zeros(0)])
    all_ids = np.concatenate([np.asarray(i, float).reshape(-1) for _, i, _ in stitched] + [np.zeros(0)])
    all_xy = np.concatenate([np.asarray(q, float).reshape(-1, 2) for _, _, q in stitched] + [np.zeros((0, 2))])
    with atomic_open(out.out_dir / "tracks_stitched_mot.txt", "w") as f:
        np.savetxt(f, mot_rows(all_steps, all_ids, all_xy, 1.0, run.params.tracking.cluster.person_radius_m),
                   fmt=MOT_FORMAT, delimiter=",")
    extra: dict = {"stitched_identities": len(mapping)}
    if _can_score(rec, times):
        m = system_metrics(rec, times, det_xy, stitched, run.report, elapsed_s, run.params.match_distance_m)
        extra["stitched"] = {k: m[k] for k in ("mota", "idf1", "id_switches", "idf1_max_tracklets",
                                               "idf1_max_detections")}
    return extra


def _can_score(rec: Recording, times_s) -> bool:
    """Whether a run with output steps at ``times_s`` [s] is scored: the recording has people ground truth that
    reaches past the evaluation's first second (warned where it does not: the run's counts alone)."""
    if rec.groundtruth is None or rec.groundtruth.people is None:
        return False
    if not can_evaluate(rec, times_s):
        warnings.warn(f"{rec.source}: the recording ends within the first {EVAL_WARMUP_S:g} s skipped by the "
                      "evaluation: no scores computed, the run's counts only", stacklevel=3)
        return False
    return True


def run_plan(rec: Recording, plan: RunPlan, *, progress_mode: str = "rich",
             client=None) -> tuple[SystemResult, dict]:
    """Run ``plan`` on ``rec``: into ``plan.out_dir`` (:func:`run_to_folder`), or in memory when it is None
    (the metrics of :func:`evaluate_system` where the recording has ground truth). With a dask ``client``
    the cameras' front ends run as per-camera streams on its workers (:class:`SystemRun`; same results).

    Returns
    -------
    (SystemResult, dict)
        The result and the metrics (:func:`planefuse.eval.system_metrics`; without ground truth the counts alone,
        :func:`planefuse.eval.run_counts`).
    """
    check_modalities_present(rec, plan.params)
    if plan.out_dir is not None:
        return run_to_folder(rec, plan, progress_mode=progress_mode, client=client)
    result = run_system(rec, plan.params, client=client)
    times = [o.time_s for o in result.outputs]
    metrics = evaluate_system(rec, result, plan.params.match_distance_m) if _can_score(rec, times) else run_counts(
        rec, times, [(o.time_s, o.tracks.ids, o.tracks.xy_m) for o in result.outputs], result.report,
        result.elapsed_s)
    if result.track_appearance:
        metrics["track_appearance"] = result.track_appearance
    metrics.update(_person_engine(plan.params))
    result.metrics = metrics
    return result, metrics


def _person_engine(params) -> dict:
    """``{"person_engine": name}`` of the engine that ran the YOLOX person model (``"auto"`` resolved), or {}."""
    fg = params.camera_params.foreground
    if fg.person_detector != "yolox":
        return {}
    from ..vision import resolve_engine

    return {"person_engine": resolve_engine(fg.person_engine)}


def write_presentation(out: OutputWriter, settings: OutputSettings, figure_inputs: FigureInputs | None = None,
                       progress=None, cameras=(), clock_origin_ns: int | None = None) -> dict[str, Path]:
    """Figures, animation and ``report.html`` of a finished run folder, as ``settings`` asks.

    Parameters
    ----------
    out : OutputWriter
        The run's writer, after :meth:`~planefuse.outputs.OutputWriter.finish`.
    settings : OutputSettings
    figure_inputs : FigureInputs, optional
        Extra material for the figures (cameras and frames, laser points, saliency, ground truth).
    progress : ProgressReporter, optional
        Reports the figure step.
    cameras : sequence of CameraStream
        The recording's cameras, whose frames (with the tracks drawn over them) go into ``planefuse.mcap``.
    clock_origin_ns : int, optional
        The recording's time 0 on its source's clock [ns]: the robotics outputs' stamps start there.

    Returns
    -------
    dict of str -> Path
        What was written: ``"report"``, ``"animation"`` and one entry per figure.
    """
    written: dict[str, Path] = {}
    figs: dict[str, bytes] = {}
    if settings.figures or settings.report:
        from ..viz import FigureInputs, run_figures

        figure_inputs = figure_inputs if figure_inputs is not None else FigureInputs()
        figs = run_figures(out.stack, out.occupancy_array(), out.times_s(), out.detections_table(), out.tracks_table(),
                           out.metrics, figure_inputs, dpi=settings.figure_dpi, progress=progress,
                           camera_boxes=out.camera_boxes_table())
    videos = {}
    if settings.camera_videos and out.n_steps and figure_inputs is not None:
        videos = {cam.name: f"camera_{check_name(cam.name, 'camera name')}_tracks.mp4" for cam in figure_inputs.cameras
                  if cam.name in figure_inputs.camera_streams and len(figure_inputs.camera_streams[cam.name])}
    names = [f"{check_name(name, 'figure name')}.png" for name in figs] if settings.figures else []
    if names or videos:
        # the list first: a later run deletes exactly these files and never the user's own files there
        atomic_write_text(out.out_dir / "figures" / FIGURES_WRITTEN, "\n".join(names + list(videos.values())) + "\n")
    if settings.figures:
        for name, file, png in zip(figs, names, figs.values()):
            p = out.out_dir / "figures" / file
            atomic_write_bytes(p, png)
            written[name] = p
    if settings.animation != "none" and out.n_steps:
        from ..viz import animate_stack

        p = out.out_dir / f"animation.{settings.animation}"
        animate_stack(p, out.stack, out.occupancy_array(), out.tracks_table(),
                      max_frames=settings.animation_max_frames)
        written["animation"] = p
    if videos:
        from ..viz import camera_tracks_video

        fps = 1.0 / float(np.median(np.diff(out.times_s()))) if out.n_steps > 1 else 5.0
        for cam in figure_inputs.cameras:
            if cam.name in videos:
                p = out.out_dir / "figures" / videos[cam.name]
                camera_tracks_video(p, cam, figure_inputs.camera_streams[cam.name], out.times_s(),
                                    out.tracks_table(), fps=fps, max_frames=settings.animation_max_frames)
                written[f"camera_{cam.name}_video"] = p
    if (settings.mcap or settings.ros2_bag) and out.n_steps:
        from ..outputs._mcap import MCAP_FILE, ROS2_BAG_DIR, write_run_mcap, write_run_ros2_bag

        tables = (out.out_dir, out.stack, out.times_s(), out.occupancy_array(), out.detections_table(),
                  out.tracks_table())
        if settings.mcap:
            written[MCAP_FILE] = write_run_mcap(tables[0] / MCAP_FILE, *tables[1:], person_radius_m=out.person_radius_m,
                                                cameras=cameras, clock_origin_ns=clock_origin_ns)
        if settings.ros2_bag:
            written[ROS2_BAG_DIR] = write_run_ros2_bag(tables[0] / ROS2_BAG_DIR, *tables[1:],
                                                       person_radius_m=out.person_radius_m,
                                                       clock_origin_ns=clock_origin_ns)
    if settings.report:
        from ..report import write_report

        p = out.out_dir / "report.html"
        write_report(p, figs, out.metrics, out.config_text, run_summary=out.summary())
        written["report"] = p
    return written


@functools.cache
def _malloc_trim():
    """glibc's ``malloc_trim`` (None where the C library is not glibc)."""
    try:
        return ctypes.CDLL("libc.so.6").malloc_trim
    except (OSError, AttributeError):
        return None


def return_freed_memory() -> None:
    """Hand the C heap's free pages back to the operating system (glibc's ``malloc_trim(0)``; nothing elsewhere).

    A run allocates and frees per step (frames, evidence grids, each chunk's checkpoint); glibc keeps freed
    memory in its arenas, so without this the resident memory of a long run creeps up although nothing is kept
    (docs/benchmarks.md, "Peak RSS"). Called after each committed chunk: a few ms per chunk."""
    trim = _malloc_trim()
    if trim is not None:
        trim(0)


def one_zarr_codec_thread() -> None:
    """Have zarr encode and decode chunks in one worker thread, unless its thread pool is configured already
    (``zarr.config`` ``threading.max_workers``; zarr reads it when it first does I/O in a process).

    A run's occupancy chunks are small (``chunk_steps`` x one plane); a pool of codec threads buys no speed on
    them, and each of its threads gets its own C-heap arena, which keeps what it decoded: reading back 1500
    steps for the figures left ~50 MB resident with the default pool, ~15 MB with one thread
    (docs/benchmarks.md, "Peak RSS")."""
    import zarr

    if zarr.config.get("threading.max_workers", None) is None:
        zarr.config.set({"threading.max_workers": 1})


def _write_camera_boxes(out: OutputWriter, step: int, time_s: float, report: ModalityReport) -> None:
    """Write the person boxes of the camera instants up to ``time_s`` [s] at ``step`` and drop them from the
    report (memory stays flat over a long run)."""
    if report.camera is None:
        return
    for name, items in report.camera.person_boxes.items():
        n = 0
        while n < len(items) and items[n][0] <= time_s + 1e-9:
            t, found = items[n]
            out.write_camera_boxes(step, t, name, found.ltwh_px, found.score)
            n += 1
        del items[:n]


def run_to_folder(rec: Recording, plan: RunPlan, *, progress_mode: str = "rich",
                  client=None) -> tuple[SystemResult, dict]:
    """Run the whole system (:class:`SystemRun`) on ``rec`` and write occupancy (zarr), detections, tracks
    (CSV + MOTChallenge), ``metrics.json``, figures, animation, ``report.html`` (and a rerun recording) into
    ``plan.out_dir``, as ``plan.outputs`` asks.

    Outputs are written atomically, one chunk of ``plan.outputs.chunk_steps`` output steps at a time, each
    with a checkpoint of the run's state; Ctrl-C or a kill leaves the steps written so far valid and
    readable. A re-run with the same :func:`resume_key` (configuration and recording) into the same folder
    resumes after the last finished chunk: it restores the checkpoint and computes only the steps that
    follow (the cameras' background models replay the frames already seen, which is all of the past it
    repeats), and its outputs are identical to an uninterrupted run's (``plan.resume=False`` starts afresh
    instead). Metrics and figures are computed from the folder's outputs, so they cover the whole run.
    With a dask ``client`` the cameras' front ends run as per-camera streams on its workers (same outputs).

    Returns
    -------
    (SystemResult, dict)
        The result and the metrics (:func:`planefuse.eval.system_metrics`; without ground truth the counts alone,
        :func:`planefuse.eval.run_counts`). The output steps are not kept in memory
        (``result.outputs`` is empty): read them from the folder.
    """
    if plan.out_dir is None:
        raise ValueError("run_to_folder needs a plan with an out_dir (run_plan evaluates in memory)")
    params, settings = plan.params, plan.outputs
    # output steps at the multiples of the period before the recording's end (its duration: the end of its last
    # sample period); an estimate for the progress bar, which is set to the steps done at the end
    n_steps = int(np.floor((rec.duration_s - 1e-9) / params.output_period_s)) + 1
    stack = stack_for_recording(rec, params, buffered_steps=writer_buffered_steps(settings.chunk_steps, settings.zarr,
                                                                                  n_steps))
    if settings.zarr:
        one_zarr_codec_thread()
    text = plan.text()
    with progress_steps(progress_mode) as progress, OutputWriter(
        plan.out_dir, stack, config_hash=resume_key(plan, rec), chunk_steps=settings.chunk_steps,
        write_zarr=settings.zarr, config_text=text, person_radius_m=params.tracking.cluster.person_radius_m,
        resume=plan.resume, force=plan.force, protected=rec.root,
    ) as out:
        if settings.rerun:
            from ..viz import RerunLogger

            out.attach_rerun(RerunLogger(plan.out_dir / "planefuse.rrd", stack))
        run = _start(rec, params, stack, out, client)
        if run.resumed_at_step:
            progress.message(f"resuming {out.out_dir} at step {run.resumed_at_step} from its checkpoint (the "
                             "finished chunks are kept, not recomputed)")
        t0 = time.perf_counter()
        with progress.step("register + filter + track", total=max(n_steps, run.n_outputs), unit="steps",
                           completed=run.n_outputs) as advance:
            for o in run.outputs():
                step = run.n_outputs - 1
                if step >= out.resume_step:
                    out.write_detections(step, o.detections)
                    out.write_tracks(step, o.time_s, o.tracks.ids, o.tracks.xy_m, o.tracks.velocity_m_s)
                    _write_camera_boxes(out, step, o.time_s, run.report)
                    if out.write_occupancy(step, o.time_s, o.occupancy, checkpoint=run.state_dict):
                        return_freed_memory()  # a chunk committed
                advance(1)
        result = SystemResult(stack, [], run.report, time.perf_counter() - t0)
        out.flush("running")  # the last, partial chunk: the tables below cover every step
        times, det_xy, tracks = _steps_from_tables(out)
        if out.rerun is not None:
            _log_modalities(out.rerun, rec, run.report, times)
        if _can_score(rec, times):  # the scores, with the counts
            with progress.step("evaluate", total=1, unit="runs") as advance:
                metrics = system_metrics(rec, times, det_xy, tracks, run.report, result.elapsed_s,
                                         params.match_distance_m)
                advance(1)
        else:  # a user's installation: the counts alone (steps, tracks, each sensor's messages and missing frames)
            metrics = run_counts(rec, times, tracks, run.report, result.elapsed_s)
        metrics["resumed_at_step"] = run.resumed_at_step
        metrics.update(_person_engine(params))
        if params.stitch.enabled:  # the offline pass: the live tracks stay as written, the stitched ones beside them
            metrics.update(_write_stitched(out, rec, run, times, det_xy, tracks, result.elapsed_s))
        if run.appearance is not None:  # the identity decisions explained: each track's appearance in words
            metrics["track_appearance"] = run.track_appearance()
        out.write_metrics(metrics)
        result.metrics = metrics
        return_freed_memory()  # before the figures' transient
        out.finish("presenting")
        try:
            # the figures' material (a frame per camera, laser points, saliency) only where figures are drawn
            inputs = _figure_inputs(rec, run.report, times) \
                if settings.figures or settings.report or settings.camera_videos else None
            write_presentation(out, settings, inputs, progress, cameras=list(rec.camera_streams.values()),
                               clock_origin_ns=rec.clock_origin_ns)
        except (KeyboardInterrupt, MemoryError):
            raise
        except Exception as exc:  # the tables are complete: say what failed, in one line, and keep them
            raise ValueError(f"{out.out_dir}: the tables are written but the figures, animation or report failed "
                             f"({type(exc).__name__}: {exc}); run_state.json says failed") from exc
        out.mark_finished()  # the last thing written
    return result, metrics
