"""The whole system end to end: recording -> every modality on the planes -> BOF -> tracks -> metrics."""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field, replace

import numpy as np

from ..audio import lateral_from_azimuth
from ..eval import detection_scores, tracking_metrics
from ..grid import PlaneStack
from ..io import Recording
from ..tracking import ClusterParams, TrackerOutput, TrackingParams, track_evidence
from ._streams import ModalityReport, camera_evidence, laser_evidence, merged_evidence, sound_evidence

__all__ = ["SystemParams", "SystemResult", "run_system", "evaluate_system", "stack_for_recording",
           "system_laser_model"]


@dataclass(frozen=True)
class SystemParams:
    """What to run.

    Attributes
    ----------
    heights_m : tuple of float
        Plane heights [m] (the recording's suggestion when None).
    cell_size_m : float
        Grid cell side [m].
    cameras, laser, sound : bool
        Modalities to fuse.
    use_filter : bool
        False: no temporal filtering (each output step is the current evidence alone,
        the "no filter" ablation): prediction resets the grid to the prior.
    camera_params : planefuse.vision.CameraParams or None
        Camera pipeline parameters (defaults when None).
    laser_model : planefuse.laser.LaserSensorModel or None
        None: :func:`system_laser_model` (a return is strong evidence, a crossing beam weak, since legs
        fill a small part of a cell).
    tracking : TrackingParams
        Filter, clustering and tracker settings. The default column threshold (``S >= 1.5``, mean
        capped log-odds per observed body plane) is lower than the tracker's own default (2.5), which
        missed people seen by few cameras at 10 cm cells (threshold sweep over seeds 1 and 2 of the demo
        scene in docs/results.md).
    sound_block_s : float
        Length of the audio blocks localised one at a time [s].
    sound_model_path : path, optional
        Calibrated binaural sensor model (default: the spherical-head model).
    output_period_s : float
        Tracker output period [s].
    threshold_m : float
        Match distance for the metrics [m].
    """

    heights_m: tuple[float, ...] | None = (0.1, 0.5, 1.0, 1.5)
    cell_size_m: float = 0.1
    cameras: bool = True
    laser: bool = True
    sound: bool = True
    use_filter: bool = True
    camera_params: object | None = None
    laser_model: object | None = None
    tracking: TrackingParams = field(default_factory=lambda: TrackingParams(
        merge_tolerance_s=0.05, cluster=ClusterParams(threshold=1.5)))
    sound_block_s: float = 0.5
    sound_model_path: object | None = None
    output_period_s: float = 0.2
    threshold_m: float = 0.5


@dataclass
class SystemResult:
    """Outputs of :func:`run_system`."""

    stack: PlaneStack
    outputs: list[TrackerOutput]
    report: ModalityReport
    elapsed_s: float
    metrics: dict = field(default_factory=dict)


def system_laser_model():
    """The laser inverse sensor model the whole system uses by default.

    ``P(occ | return) = 0.9``, ``P(occ | beam crossed) = 0.45``: a person's legs fill a small part of a
    10 cm cell, so a beam passing through a cell says little about it (the laser's own default, 0.35, frees
    the cells between and beside the legs at every sweep and no column forms), while a return off a leg
    is precise. Laser-only recall on the demo scene goes from about 0.1 to about 0.7 at precision 1.0
    (docs/results.md, ``## Whole system (demo scene)``).
    """
    from ..laser import LaserSensorModel

    return LaserSensorModel(p_occupied_hit=0.9, p_occupied_free=0.45)


def stack_for_recording(rec: Recording, params: SystemParams, wall_margin_m: float = 0.2) -> PlaneStack:
    """The plane stack covering the recording's monitored area: ``rec.room_xy_m`` less ``wall_margin_m``
    on every side, so that the walls (static, seen by the laser) are not inside the grid."""
    if rec.room_xy_m is None:
        raise ValueError("recording has no room_xy_m: give the plane stack extent explicitly")
    x0, x1, y0, y1 = rec.room_xy_m
    m = wall_margin_m
    heights = params.heights_m if params.heights_m is not None else tuple(rec.planes_heights_m)
    return PlaneStack.from_extent(heights, (x0 + m, x1 - m), (y0 + m, y1 - m), params.cell_size_m)


def run_system(
    rec: Recording,
    params: SystemParams = SystemParams(),
    stack: PlaneStack | None = None,
    on_output: Callable[[TrackerOutput], None] | None = None,
) -> SystemResult:
    """Register every enabled modality on the planes, filter with one BOF per plane and track people.

    Parameters
    ----------
    rec : Recording
        Simulated (:func:`planefuse.sim.simulate`) or read (:func:`planefuse.io.read_recording`).
    params : SystemParams
    stack : PlaneStack, optional
        Default: :func:`stack_for_recording`.
    on_output : callable, optional
        Called with every :class:`TrackerOutput` (progress, writers).
    """
    from ..vision import CameraParams

    stack = stack if stack is not None else stack_for_recording(rec, params)
    report = ModalityReport()
    streams = []
    if params.cameras and rec.camera_streams:
        streams.append(camera_evidence(rec, stack, params.camera_params or CameraParams(), report))
    if params.laser and rec.lasers:
        streams.append(laser_evidence(rec, stack, params.laser_model or system_laser_model(), report))
    if params.sound and rec.audio:
        model = None
        if params.sound_model_path is not None:
            from ..audio import BinauralSensorModel

            model = BinauralSensorModel.load(params.sound_model_path)
        streams.append(sound_evidence(rec, stack, report, params.sound_block_s, model))
    if not streams:
        raise ValueError("no enabled modality has a stream in this recording")
    tp = replace(params.tracking, output_period_s=params.output_period_s)
    if not params.use_filter:
        # "no filter" ablation: the grid forgets everything between fused steps
        tp = replace(tp, bof=replace(tp.bof, decay_rate_hz=1e6))
    t0 = time.perf_counter()
    outputs = []
    for out in track_evidence(stack, merged_evidence(*streams), tp):
        outputs.append(out)
        if on_output is not None:
            on_output(out)
    return SystemResult(stack, outputs, report, time.perf_counter() - t0)


def _gt_frames(rec: Recording, times_s: np.ndarray):
    gt = rec.groundtruth.people
    for t in times_s:
        yield float(t), gt.person_ids, gt.xy_m[gt.index_at(t)]


def evaluate_system(rec: Recording, result: SystemResult, threshold_m: float = 0.5) -> dict:
    """MODA/MODP/precision/recall of the filtered detections, MOTA/IDF1 of the tracks, the cameras-only
    detection scores and the sound azimuth error, against the recording's ground truth."""
    if rec.groundtruth is None or rec.groundtruth.people is None:
        raise ValueError("recording has no people ground truth to evaluate against")
    gt = rec.groundtruth.people
    # skip the first second: the background model and the filter are still learning
    warm = gt.times_s[0] + 1.0
    outs = [o for o in result.outputs if o.time_s >= warm and o.time_s <= gt.times_s[-1] + 1e-9]
    times = np.array([o.time_s for o in outs])
    gt_frames = list(_gt_frames(rec, times))
    det = detection_scores(((g[2], o.detections.xy_m) for g, o in zip(gt_frames, outs)), threshold_m)
    mot = tracking_metrics(gt_frames, [o.tracks for o in outs], max_distance_m=threshold_m)
    m = {
        "moda": det.moda, "modp": det.modp, "precision": det.precision, "recall": det.recall,
        "mota": mot["mota"], "motp_m": mot.get("motp_m", float("nan")), "idf1": mot["idf1"],
        "id_switches": int(mot.get("num_switches", 0)), "n_eval_steps": len(outs),
        "n_people": int(len(gt.person_ids)), "elapsed_s": result.elapsed_s,
        "n_camera_frames": result.report.n_camera_frames,
        "n_missing_camera_frames": result.report.n_missing_camera_frames,
        "n_laser_scans": result.report.n_laser_scans, "n_sound_blocks": result.report.n_sound_blocks,
    }
    cams = [d for d in result.report.camera_detections if d.time_s >= warm]
    if cams:
        cd = detection_scores(((gt.xy_m[gt.index_at(d.time_s)], d.xy_m) for d in cams), threshold_m)
        m.update(camera_only_moda=cd.moda, camera_only_modp=cd.modp)
    snd = rec.groundtruth.sound
    rep = result.report
    if snd is not None and rep.n_sound_blocks:
        errs = []
        for t, az in zip(rep.sound_times_s, rep.sound_map_azimuth_rad):
            i = int(np.argmin(np.abs(snd.times_s - t)))
            talking = np.nonzero(snd.speaking[i])[0]
            if len(talking) != 1 or not np.isfinite(az):
                continue  # score single-talker blocks only
            # lateral angles: two ears cannot tell front from back
            errs.append(abs(lateral_from_azimuth(az) - lateral_from_azimuth(snd.azimuth_rad[i, talking[0]])))
        m["azimuth_mae_deg"] = float(np.degrees(np.mean(errs))) if errs else float("nan")
        m["n_sound_blocks_scored"] = len(errs)
    return {k: (float(v) if isinstance(v, (float, np.floating)) else v) for k, v in m.items()}
