"""Inclination (roll/pitch) accuracy of an attitude filter on a real IMU log.

Two measures, both yaw-free (:func:`planefuse.geometry.inclination_error_rad`):

* against a reference attitude (the file's own, e.g. BROAD's optical ``opt_quat``, or another filter's output),
  over the samples the file marks for scoring whose reference is known;
* against the accelerometer while the device is still (|gyro| and |acc| - g small): at rest the specific force
  *is* the up direction, so this needs no reference at all.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np

from ..geometry import DEFAULT_ATTITUDE_FILTER, attitude_from_imu, inclination_error_rad
from ..io import ImuLog

__all__ = ["AttitudeScores", "score_attitude", "rest_mask"]

_G_M_S2 = 9.80665


@dataclass(frozen=True)
class AttitudeScores:
    """Inclination errors of one filter on one log [deg]; NaN where there was nothing to score.

    Attributes
    ----------
    method : str
    n_samples : int
        Samples fed to the filter.
    reference : str
        What the error is measured against (``"none"`` without a reference).
    n_scored : int
        Samples scored against the reference (after ``settle_s``, marked for scoring, reference known).
    n_reference_missing : int
        Samples whose reference is NaN (counted, never scored).
    rmse_deg, p95_deg, max_deg : float
        Inclination error against the reference [deg].
    n_rest : int
        Samples at rest (after ``settle_s``).
    rest_rms_deg : float
        RMS angle between the estimated up direction and the accelerometer at rest [deg].
    """

    method: str
    n_samples: int
    reference: str
    n_scored: int
    n_reference_missing: int
    rmse_deg: float
    p95_deg: float
    max_deg: float
    n_rest: int
    rest_rms_deg: float

    def as_dict(self) -> dict:
        """Plain values for JSON (NaN as None)."""
        return {k: None if isinstance(v, float) and not np.isfinite(v) else v for k, v in asdict(self).items()}


def rest_mask(log: ImuLog, settle_s: float = 5.0, gyro_max_deg_s: float = 2.0,
              accel_tolerance: float = 0.02) -> np.ndarray:
    """Samples (N,) bool after ``settle_s`` [s] with |gyro| < ``gyro_max_deg_s`` [deg/s] and |acc| within
    ``accel_tolerance`` (fraction) of 1 g."""
    t = log.time_s
    g = np.linalg.norm(log.accel_m_s2, axis=1) / _G_M_S2
    return (t >= t[0] + settle_s) & (np.degrees(np.linalg.norm(log.gyro_rad_s, axis=1)) < gyro_max_deg_s) \
        & (np.abs(g - 1.0) < accel_tolerance)


def _rms(x: np.ndarray) -> float:
    return float(np.sqrt(np.mean(np.square(x)))) if x.size else float("nan")


def score_attitude(log: ImuLog, method: str = DEFAULT_ATTITUDE_FILTER, params: dict | None = None, *, settle_s: float = 5.0,
                   R_reference=None, reference_name: str | None = None,
                   R_gravity_imu=None) -> AttitudeScores:
    """Run ``method`` (:func:`planefuse.geometry.attitude_from_imu`) on ``log`` and score its inclination.

    Parameters
    ----------
    log : ImuLog
    method, params
        Filter and its parameters, as :func:`attitude_from_imu` takes them.
    settle_s : float
        Samples before ``time_s[0] + settle_s`` [s] are not scored (filters converge from the first sample).
    R_reference : array_like, shape (N, 3, 3), optional
        Reference attitude to score against instead of the log's own (e.g. another filter's output); NaN rows
        are not scored.
    reference_name : str, optional
        What ``R_reference`` is, for the report.
    R_gravity_imu : array_like, shape (N, 3, 3), optional
        The filter's output when already computed (``method`` is then only its name).

    Returns
    -------
    AttitudeScores
    """
    R = attitude_from_imu(log.time_s, log.gyro_rad_s, log.accel_m_s2, method=method, params=params) \
        if R_gravity_imu is None else np.asarray(R_gravity_imu, dtype=float)
    if R.shape != (len(log), 3, 3):
        raise ValueError(f"R_gravity_imu must have shape ({len(log)}, 3, 3), got {R.shape}")
    settled = log.time_s >= log.time_s[0] + settle_s
    if R_reference is not None:
        R_ref = np.asarray(R_reference, dtype=float)
        if R_ref.shape != R.shape:
            raise ValueError(f"R_reference must have shape {R.shape}, got {R_ref.shape}")
        ref_name = reference_name or "given reference"
    else:
        R_ref = log.R_ref_gravity_imu
        ref_name = {"BROAD HDF5": "optical opt_quat"}.get(log.kind, "file's ref_q columns") if R_ref is not None \
            else "none"
    n_missing, scored, err = 0, np.zeros(len(log), bool), np.zeros(0)
    if R_ref is not None:
        lost = np.isnan(R_ref).any(axis=(1, 2))
        n_missing = int(lost.sum())
        scored = settled & ~lost & (log.scored if log.scored is not None and R_reference is None else True)
        err = np.degrees(inclination_error_rad(R[scored], R_ref[scored])) if scored.any() else np.zeros(0)
    rest = rest_mask(log, settle_s)
    up_body = log.accel_m_s2[rest] / np.linalg.norm(log.accel_m_s2[rest], axis=1, keepdims=True)
    rest_deg = np.degrees(np.arccos(np.clip(np.einsum("nj,nj->n", R[rest][:, 2, :], up_body), -1.0, 1.0)))
    nan = float("nan")
    return AttitudeScores(
        method=method, n_samples=len(log), reference=ref_name, n_scored=int(scored.sum()),
        n_reference_missing=n_missing, rmse_deg=_rms(err),
        p95_deg=float(np.percentile(err, 95)) if err.size else nan, max_deg=float(err.max()) if err.size else nan,
        n_rest=int(rest.sum()), rest_rms_deg=_rms(rest_deg))
