"""Scores of a whole-system run: detections, tracks, the cameras alone and the sound azimuths."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from ._detection import detection_scores
from ._tracking import tracking_metrics

__all__ = ["run_counts", "system_metrics", "EVAL_WARMUP_S"]

#: The evaluation skips this much of the start of a recording [s] (background models and filter learning).
EVAL_WARMUP_S = 1.0


def _lateral(azimuth_rad: float) -> float:
    """Lateral angle ``asin(sin(az))`` [rad] of a horizontal direction: two ears cannot tell front from back."""
    return float(np.arcsin(np.clip(np.sin(azimuth_rad), -1.0, 1.0)))


def _present(time_s: float, ids: np.ndarray, xy_m: np.ndarray) -> tuple[float, np.ndarray, np.ndarray]:
    """The people of one ground-truth sample who are there (NaN positions: absent, e.g. out of every view)."""
    there = np.isfinite(xy_m).all(axis=1)
    return time_s, ids[there], xy_m[there]


def run_counts(rec, times_s: np.ndarray, tracks: Sequence[tuple[float, np.ndarray, np.ndarray]], report,
               elapsed_s: float) -> dict:
    """What a whole-system run consumed and produced, with or without ground truth: output steps, tracks, each
    sensor's messages and each camera's missing frames.

    Parameters
    ----------
    rec : planefuse.io.Recording
    times_s : ndarray, shape (T,)
        Output step times [s].
    tracks : sequence of (time_s, ids (M_t,), xy_m (M_t, 2))
        Reported tracks per step.
    report : planefuse.pipeline.ModalityReport
    elapsed_s : float
        Computing time of the run [s] (reported as is).

    Returns
    -------
    dict
        ``n_steps``, ``n_tracks`` (identities reported), ``mean_tracks_per_step``, ``n_camera_frames`` (synchronised
        instants), ``n_missing_camera_frames`` and ``missing_camera_frames`` (camera name -> frames missing at those
        instants), ``n_laser_scans``, ``n_laser_invalid_beams``, ``missing_laser_scans`` (laser name -> scans missing
        in the gaps of its time stamps, at its nominal rate), ``n_sound_blocks``, ``elapsed_s``.
    """
    ids = [np.asarray(t[1]) for t in tracks]
    missing = report.camera.missing_frames if report.camera is not None else {}
    return {
        "n_steps": int(len(times_s)),
        "n_tracks": int(np.unique(np.concatenate(ids)).size) if ids else 0,
        "mean_tracks_per_step": float(np.mean([i.size for i in ids])) if ids else 0.0,
        "n_camera_frames": report.n_camera_frames,
        "n_missing_camera_frames": report.n_missing_camera_frames,
        "missing_camera_frames": {c.name: len(missing.get(c.name, ())) for c in rec.cameras},
        "n_laser_scans": report.n_laser_scans, "n_laser_invalid_beams": report.n_laser_invalid_beams,
        "missing_laser_scans": {n: int(sum(g.missing for g in ls.gaps)) for n, ls in rec.lasers.items()},
        "n_sound_blocks": report.n_sound_blocks,
        "elapsed_s": float(elapsed_s),
    }


def system_metrics(rec, times_s: np.ndarray, detections_xy_m: Sequence[np.ndarray],
                   tracks: Sequence[tuple[float, np.ndarray, np.ndarray]], report,
                   elapsed_s: float, match_distance_m: float = 0.5) -> dict:
    """Scores of a whole-system run against its recording's ground truth, from the output steps alone (in
    memory, or read back from a run folder): MODA/MODP/precision/recall of the filtered detections, MOTA/IDF1
    (motmetrics) of the tracks, MODA of the cameras alone and the sound azimuth error on single-talker blocks,
    after the first :data:`EVAL_WARMUP_S` seconds (warm-up).

    Parameters
    ----------
    rec : planefuse.io.Recording
        With people ground truth.
    times_s : ndarray, shape (T,)
        Output step times [s].
    detections_xy_m : sequence of ndarray (N_t, 2)
        Filtered detections per step, world XY [m].
    tracks : sequence of (time_s, ids (M_t,), xy_m (M_t, 2))
        Reported tracks per step.
    report : planefuse.pipeline.ModalityReport
        What the modalities produced (counts, camera-only detections, sound azimuths).
    elapsed_s : float
        Computing time of the run [s] (reported as is).
    match_distance_m : float
        Largest distance [m] of a detection or track from the person it is matched to.
    """
    if rec.groundtruth is None or rec.groundtruth.people is None:
        raise ValueError("recording has no people ground truth to evaluate against")
    times_s = np.asarray(times_s, dtype=float)
    if not (len(times_s) == len(detections_xy_m) == len(tracks)):
        raise ValueError(f"times_s ({len(times_s)}), detections_xy_m ({len(detections_xy_m)}) and tracks "
                         f"({len(tracks)}) must have one entry per step")
    gt = rec.groundtruth.people
    warm = gt.times_s[0] + EVAL_WARMUP_S  # the background model and the filter are still learning
    keep = np.flatnonzero((times_s >= warm) & (times_s <= gt.times_s[-1] + 1e-9))
    gt_frames = [_present(float(t), gt.person_ids, gt.xy_m[gt.index_at(t)]) for t in times_s[keep]]
    det = detection_scores(((g[2], detections_xy_m[i]) for g, i in zip(gt_frames, keep)), match_distance_m)
    mot = tracking_metrics(gt_frames, [tracks[i] for i in keep], match_distance_m=match_distance_m,
                           switch_events=True, identity_bounds=True)
    m = {
        "moda": det.moda, "modp": det.modp, "precision": det.precision, "recall": det.recall,
        "mota": mot["mota"], "motp_m": mot.get("motp_m", float("nan")), "idf1": mot["idf1"],
        "id_switches": int(mot.get("num_switches", 0)), "n_eval_steps": len(keep),
        # what perfect identities would give these positions: whole tracks joined / every position labelled
        "idf1_max_tracklets": mot["idf1_max_tracklets"], "idf1_max_detections": mot["idf1_max_detections"],
        # each switch, explainable: when, which person, from which track to which
        "id_switch_events": {f"{t:.2f} s, person {o}": f"track {p} -> {h}" for t, o, p, h in mot["switch_events"]},
        "n_people": int(len(gt.person_ids)), **run_counts(rec, times_s, tracks, report, elapsed_s),
    }
    reg = getattr(report, "camera_registration", None)
    if reg is not None and reg.tracks:  # cameras registered through their IMU: gaps bridged, maps rebuilt
        m["n_imu_gaps"] = sum(len(g) for g in reg.imu_gaps.values())
        m["n_attitude_map_rebuilds"] = sum(reg.n_rebuilds)
    if np.any(np.asarray(report.camera_detections.times_s) >= warm):
        cd = detection_scores(((_present(d.time_s, gt.person_ids, gt.xy_m[gt.index_at(d.time_s)])[2], d.xy_m)
                               for d in report.camera_detections if d.time_s >= warm), match_distance_m)
        m.update(camera_only_moda=cd.moda, camera_only_modp=cd.modp)
    snd = rec.groundtruth.sound
    rep = report
    if snd is not None and rep.n_sound_blocks:
        errs = []
        for t, az in zip(rep.sound_times_s, rep.sound_map_azimuth_rad):
            i = int(np.argmin(np.abs(snd.times_s - t)))
            talking = np.nonzero(snd.speaking[i])[0]
            if len(talking) != 1 or not np.isfinite(az):
                continue  # score single-talker blocks only
            # lateral angles: two ears cannot tell front from back
            errs.append(abs(_lateral(az) - _lateral(snd.azimuth_rad[i, talking[0]])))
        m["azimuth_mae_deg"] = float(np.degrees(np.mean(errs))) if errs else float("nan")
        m["n_sound_blocks_scored"] = len(errs)
    return {k: (float(v) if isinstance(v, (float, np.floating)) else v) for k, v in m.items()}
