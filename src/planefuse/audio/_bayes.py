"""Bayesian binaural sensor model (seed eq. 6), its calibration, and the auditory saliency map.

Decomposition (seed eq. 6, after Pinho, Ferreira, Bessiere & Dias 2008), per band b:

    P(tau S_theta theta) = P(theta) P(S_theta | theta) P(tau | S_theta theta)

* ``theta`` -- an azimuth from a discretised span (the model's ``azimuth_rad``, in
  [-90, 90] deg: two ears on the y axis measure the lateral angle, so the span is
  the frontal half and ``180 deg - theta`` behind is indistinguishable);
* ``P(theta)``, ``P(S_theta | theta)`` -- uniform;
* ``P(tau | S_theta = 1, theta)`` -- the calibrated sensor model: a normal
  distribution ``N(mu_b(theta), sigma_b(theta))``, wrapped with the band's period
  ``1 / f_b`` (a narrow-band cross-correlation cannot tell lags one period apart),
  mixed with a small outlier weight ``eps`` (reverberation, other sources);
* ``P(tau | S_theta = 0, theta)`` -- no source on that plane: tau is uniform over
  the lag range ``[-max_itd, max_itd]``.

Bayes' rule inverts it to ``P(S_theta = 1 | tau, theta)``; with the uniform
priors its log-odds is the log-likelihood ratio ``log P(tau|S=1,theta) - log
P(tau|S=0,theta)``, which independent bands add. A frame's posterior over the
azimuth of a source, ``P(theta | tau_1..tau_B) ∝ prod_b P(tau_b | S_theta=1, theta)``,
is the per-frame auditory saliency map; averaged over active frames it becomes
the saliency map of a segment, whose peaks are the sources (MAP = highest).
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from functools import lru_cache
from pathlib import Path

import numpy as np
from scipy.signal import find_peaks

from ._binaural import BinauralCues, binaural_cues
from ._cochlea import GammatoneFilterbank, check_binaural_signal

__all__ = [
    "BinauralSensorModel",
    "Localization",
    "calibrate_sensor_model",
    "default_sensor_model",
    "localize",
]

_SIGMA_MIN_S = 15e-6


@dataclass(frozen=True)
class BinauralSensorModel:
    """Calibrated ``P(tau | S_theta = 1, theta)`` per band, plus the front end that measures tau.

    Attributes
    ----------
    fs_hz : float
        Sampling rate the model was calibrated at [Hz]; signals must match it.
    filterbank : GammatoneFilterbank
        The cochlear front end (same bands as the calibration).
    azimuth_rad : ndarray, shape (A,)
        Discretised azimuth span [rad], increasing, within [-pi/2, pi/2].
    mu_s : ndarray, shape (B, A)
        Mean ITD [s] of each band at each azimuth (wrapped to the band's period).
    sigma_s : ndarray, shape (B, A)
        Standard deviation [s].
    frame_s : float
        Frame length [s] of the binaural unit.
    max_itd_s : float
        Lag range [s] searched (and the support of ``P(tau | S = 0)``).
    outlier_weight : float
        ``eps`` of the outlier mixture.
    source : str
        What it was calibrated from.
    """

    fs_hz: float
    filterbank: GammatoneFilterbank
    azimuth_rad: np.ndarray
    mu_s: np.ndarray
    sigma_s: np.ndarray
    frame_s: float = 0.02
    max_itd_s: float = 1.0e-3
    outlier_weight: float = 0.1
    source: str = ""
    _period_s: np.ndarray = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        az = np.asarray(self.azimuth_rad, dtype=float).reshape(-1)
        mu = np.asarray(self.mu_s, dtype=float)
        sg = np.asarray(self.sigma_s, dtype=float)
        shape = (self.filterbank.n_bands, az.size)
        if mu.shape != shape or sg.shape != shape:
            raise ValueError(f"mu_s and sigma_s must have shape (bands, azimuths) = {shape}, got {mu.shape}, {sg.shape}")
        if not (np.isfinite(mu).all() and np.isfinite(sg).all() and (sg > 0).all()):
            raise ValueError("mu_s/sigma_s must be finite and sigma_s > 0")
        if np.any(np.diff(az) <= 0) or np.abs(az).max() > np.pi / 2 + 1e-9:
            raise ValueError("azimuth_rad must increase within [-pi/2, pi/2]")
        if self.filterbank.fs_hz != self.fs_hz:
            raise ValueError(f"filterbank is at {self.filterbank.fs_hz} Hz, model at {self.fs_hz} Hz")
        if not 0 < self.outlier_weight < 1:
            raise ValueError(f"outlier_weight must be in (0, 1), got {self.outlier_weight}")
        object.__setattr__(self, "azimuth_rad", az)
        object.__setattr__(self, "mu_s", mu)
        object.__setattr__(self, "sigma_s", np.maximum(sg, _SIGMA_MIN_S))
        object.__setattr__(self, "_period_s", 1.0 / self.filterbank.center_freqs_hz)

    # -- the sensor model --------------------------------------------------------
    def log_likelihood_ratio(self, tau_s: np.ndarray, active: np.ndarray) -> np.ndarray:
        """``log P(tau|S_theta=1, theta) - log P(tau|S_theta=0, theta)`` summed over active bands.

        Parameters
        ----------
        tau_s : ndarray, shape (F, B)
            Measured ITDs [s].
        active : ndarray, shape (F, B), bool
            Band-frames that carry evidence.

        Returns
        -------
        ndarray, shape (F, A)
            Per frame, the log-odds of a source on each azimuth plane given all bands.
        """
        P = self._period_s[:, None]  # (B, 1)
        log_u = -np.log(2 * self.max_itd_s)
        out = np.zeros((tau_s.shape[0], self.azimuth_rad.size))
        fi, bi = np.nonzero(active)
        if fi.size == 0:
            return out
        # wrapped residual to the nearest image of the band period
        r = tau_s[fi, bi][:, None] - self.mu_s[bi]
        r -= np.round(r / P[bi]) * P[bi]
        s = self.sigma_s[bi]
        g = np.exp(-0.5 * (r / s) ** 2) / (np.sqrt(2 * np.pi) * s)
        # the wrapped normal repeats once per period inside the lag range: spread the mass over them
        n_images = np.maximum(1.0, 2 * self.max_itd_s / P[bi])
        like = (1 - self.outlier_weight) * g / n_images + self.outlier_weight * np.exp(log_u)
        llr = np.log(like) - log_u
        np.add.at(out, fi, llr)
        return out

    # -- persistence -------------------------------------------------------------
    def save(self, path) -> Path:
        """Write the model as NPZ (arrays + JSON metadata). Returns the path."""
        path = Path(path)
        meta = dict(fs_hz=self.fs_hz, n_bands=self.filterbank.n_bands, f_min_hz=self.filterbank.f_min_hz,
                    f_max_hz=self.filterbank.f_max_hz, envelope_cutoff_hz=self.filterbank.envelope_cutoff_hz,
                    frame_s=self.frame_s, max_itd_s=self.max_itd_s, outlier_weight=self.outlier_weight,
                    source=self.source, format="planefuse.binaural_sensor_model/1")
        np.savez(path, azimuth_rad=self.azimuth_rad, mu_s=self.mu_s, sigma_s=self.sigma_s,
                 meta=np.array(json.dumps(meta)))
        return path

    @classmethod
    def load(cls, path) -> "BinauralSensorModel":
        """Read a model written by :meth:`save`; raises ``ValueError`` naming the file if it is not one."""
        path = Path(path)
        try:
            with np.load(path) as z:
                meta = json.loads(str(z["meta"]))
                arrays = {k: z[k] for k in ("azimuth_rad", "mu_s", "sigma_s")}
        except (OSError, KeyError, ValueError) as e:
            raise ValueError(f"{path} is not a planefuse binaural sensor model: {e}") from e
        if meta.get("format") != "planefuse.binaural_sensor_model/1":
            raise ValueError(f"{path}: unknown format {meta.get('format')!r}")
        fb = GammatoneFilterbank(meta["fs_hz"], meta["n_bands"], meta["f_min_hz"], meta["f_max_hz"],
                                 meta["envelope_cutoff_hz"])
        return cls(meta["fs_hz"], fb, frame_s=meta["frame_s"], max_itd_s=meta["max_itd_s"],
                   outlier_weight=meta["outlier_weight"], source=meta["source"], **arrays)

    def cues(self, signal, fs_hz: float, **gating) -> BinauralCues:
        """Binaural cues of a two-channel signal with this model's front end (checks the sampling rate)."""
        if fs_hz != self.fs_hz:
            raise ValueError(f"signal is at {fs_hz} Hz but the sensor model was calibrated at {self.fs_hz} Hz; "
                             "resample it (planefuse.audio.read_audio(path, fs_hz)) or recalibrate")
        return binaural_cues(signal, fs_hz, self.filterbank, frame_s=self.frame_s, max_itd_s=self.max_itd_s, **gating)


def calibrate_sensor_model(
    recordings,
    azimuths_rad,
    fs_hz: float,
    filterbank: GammatoneFilterbank | None = None,
    azimuth_grid_rad=None,
    frame_s: float = 0.02,
    max_itd_s: float = 1.0e-3,
    source: str = "calibration recordings",
) -> BinauralSensorModel:
    """Fit ``P(tau | S_theta = 1, theta)`` from recordings of one source at known azimuths.

    Per band and calibration azimuth, the active ITDs are summarised by their
    circular mean and spread on the band's period (so that wrapped lags of high
    bands are averaged correctly); means and spreads are then interpolated
    (phase-unwrapped) onto the model's azimuth grid.

    Parameters
    ----------
    recordings : sequence of array_like, each (n, 2)
        Two-channel recordings [left, right] at ``fs_hz``, one per azimuth.
    azimuths_rad : array_like, shape (R,)
        True azimuth of each recording [rad]; back azimuths are folded onto the front
        (``pi - theta``), which two ears cannot tell apart.
    fs_hz : float
        Sampling rate [Hz].
    filterbank : GammatoneFilterbank, optional
        Default: 32 bands 100-4000 Hz.
    azimuth_grid_rad : array_like, optional
        The model's span; default -90..90 deg in 1 deg steps.
    frame_s, max_itd_s : float
        Binaural unit settings [s].
    source : str
        Description stored in the model.
    """
    fb = GammatoneFilterbank(fs_hz=fs_hz) if filterbank is None else filterbank
    az = np.asarray(azimuths_rad, dtype=float).reshape(-1)
    if len(recordings) != az.size:
        raise ValueError(f"{len(recordings)} recordings but {az.size} azimuths")
    lat = np.arcsin(np.clip(np.sin(az), -1, 1))  # fold back onto front
    order = np.argsort(lat)
    if np.unique(np.round(lat, 9)).size != lat.size or lat.size < 2:
        raise ValueError("calibration needs at least two recordings at distinct (lateral) azimuths")
    period = 1.0 / fb.center_freqs_hz
    phase = np.zeros((fb.n_bands, az.size), dtype=complex)
    for k, rec in enumerate(recordings):
        x = check_binaural_signal(rec, f"recordings[{k}]")
        cues = binaural_cues(x, fs_hz, fb, frame_s=frame_s, max_itd_s=max_itd_s)
        for b in range(fb.n_bands):
            t = cues.tau_s[cues.active[:, b], b]
            phase[b, k] = np.mean(np.exp(2j * np.pi * t / period[b])) if t.size >= 3 else 0.0
    grid = np.deg2rad(np.arange(-90.0, 90.5, 1.0)) if azimuth_grid_rad is None else np.asarray(azimuth_grid_rad, float)
    mu = np.zeros((fb.n_bands, grid.size))
    sg = np.full((fb.n_bands, grid.size), 2 * max_itd_s)  # uninformative where calibration saw nothing
    lat_o, phase_o = lat[order], phase[:, order]
    for b in range(fb.n_bands):
        ok = np.abs(phase_o[b]) > 0
        if ok.sum() < 2:
            continue  # band never active: it keeps a flat, uninformative model
        ang = np.unwrap(np.angle(phase_o[b, ok]))
        spread = np.sqrt(-2 * np.log(np.clip(np.abs(phase_o[b, ok]), 1e-6, 1.0)))  # circular std [rad]
        mu[b] = np.interp(grid, lat_o[ok], ang) * period[b] / (2 * np.pi)
        sg[b] = np.interp(grid, lat_o[ok], spread) * period[b] / (2 * np.pi)
    mu = (mu + period[:, None] / 2) % period[:, None] - period[:, None] / 2
    return BinauralSensorModel(fs_hz, fb, grid, mu, sg, frame_s=frame_s, max_itd_s=max_itd_s, source=source)


@lru_cache(maxsize=4)
def default_sensor_model(fs_hz: float = 16000.0) -> BinauralSensorModel:
    """The spherical-head sensor model, calibrated on simulated anechoic recordings (no data needed).

    A seeded speech-like signal is rendered through :class:`SphericalHead` from
    -90 to 90 deg in 10 deg steps (1 s each, 1.5 m, anechoic, 30 dB SNR) and passed to
    :func:`calibrate_sensor_model`. Cached per sampling rate.
    """
    from ._head import SphericalHead
    from ._signals import speech_like_signal
    from ._simulate import ShoeBoxRoom, T_world_head_from_position_yaw, simulate_binaural

    sig = speech_like_signal(1.0, fs_hz, seed=12345)
    head = SphericalHead(fs_hz=fs_hz)
    T = T_world_head_from_position_yaw([2.0, 2.0, 1.5])
    az = np.deg2rad(np.arange(-90.0, 90.5, 10.0))
    room = ShoeBoxRoom(dims_m=(4.0, 4.0, 3.0), rt60_s=0.0)
    recs = [simulate_binaural([(sig, [2.0 + 1.5 * np.cos(a), 2.0 + 1.5 * np.sin(a), 1.5], 0.0)], T, room, head,
                              fs_hz, snr_db=30.0, seed=i).signal for i, a in enumerate(az)]
    return calibrate_sensor_model(recs, az, fs_hz, source="spherical head (simulated, anechoic)")


@dataclass(frozen=True)
class Localization:
    """Result of :func:`localize`.

    Attributes
    ----------
    azimuth_rad : ndarray, shape (A,)
        The model's azimuth span [rad] (frontal; each also stands for ``pi - theta``).
    time_s : ndarray, shape (F,)
        Frame centre times [s].
    frame_saliency : ndarray, shape (F, A)
        Per frame ``P(theta | tau)`` of the bands of the frames within the integration
        window around it; rows of inactive frames are 0 (no evidence).
    frame_active : ndarray, shape (F,), bool
        Frames with at least ``min_bands`` active bands.
    saliency : ndarray, shape (A,)
        Auditory saliency map of the whole signal: mean of the active frames' maps
        (sums to 1 if any frame was active, else all 0).
    map_azimuth_rad : float
        MAP azimuth of the most salient source [rad]: the maximum of the joint
        log-odds ``sum_f sum_b log P(tau_bf|S_theta=1,theta)/P(tau_bf|S_theta=0,theta)``
        over active band-frames (NaN if no evidence).
    source_azimuths_rad : ndarray, shape (S,)
        Peaks of ``saliency`` (several sources), most salient first (empty if no evidence).
        With one source the first is close to ``map_azimuth_rad``, which pools all frames.
    source_saliency : ndarray, shape (S,)
        Their peak saliency.
    cues : BinauralCues
        The binaural cues behind it (ITD, ILD, activity, clipped-frame count).
    """

    azimuth_rad: np.ndarray
    time_s: np.ndarray
    frame_saliency: np.ndarray
    frame_active: np.ndarray
    saliency: np.ndarray
    map_azimuth_rad: float
    source_azimuths_rad: np.ndarray
    source_saliency: np.ndarray
    cues: BinauralCues

    @property
    def n_active_frames(self) -> int:
        return int(self.frame_active.sum())


def _refine_peak(grid: np.ndarray, y: np.ndarray, i: int) -> float:
    if 0 < i < len(y) - 1:
        den = y[i - 1] - 2 * y[i] + y[i + 1]
        if den < 0:
            d = float(np.clip(0.5 * (y[i - 1] - y[i + 1]) / den, -0.5, 0.5))
            return float(grid[i] + d * (grid[1] - grid[0]))
    return float(grid[i])


def localize(
    signal,
    fs_hz: float,
    model: BinauralSensorModel | None = None,
    max_sources: int = 3,
    min_peak_fraction: float = 0.25,
    min_separation_rad: float = np.deg2rad(15.0),
    min_bands: int = 3,
    integration_s: float = 0.5,
    **gating,
) -> Localization:
    """Auditory saliency map over azimuth and the MAP azimuth(s) of a two-channel signal.

    Parameters
    ----------
    signal : array_like, shape (n, 2)
        Ear signals [left, right] at ``fs_hz``.
    fs_hz : float
        Sampling rate [Hz]; must equal the model's.
    model : BinauralSensorModel, optional
        Default: :func:`default_sensor_model` (spherical head).
    max_sources : int
        Most peaks returned.
    min_peak_fraction : float
        Peaks below this fraction of the highest are ignored.
    min_separation_rad : float
        Smallest separation between two reported sources [rad].
    min_bands : int
        A frame gives evidence only if at least this many bands are active.
    integration_s : float
        A frame's saliency map pools the evidence of the frames within +-integration_s/2
        around it (binaural sluggishness): single 20 ms frames are too noisy in reverberation.
    **gating
        Passed to :func:`binaural_cues` (``silence_dbfs``, ``snr_gate_db``, ``onset_db``, ``coherence_min``).
    """
    model = default_sensor_model(fs_hz) if model is None else model
    cues = model.cues(signal, fs_hz, **gating)
    llr = model.log_likelihood_ratio(cues.tau_s, cues.active)
    frame_active = cues.active.sum(axis=1) >= min_bands
    llr[~frame_active] = 0.0
    half = int(round(integration_s / (2 * model.frame_s)))
    c = np.cumsum(np.vstack([np.zeros((1, llr.shape[1])), llr]), axis=0)
    idx = np.arange(llr.shape[0])
    pooled = c[np.minimum(idx + half + 1, len(idx))] - c[np.maximum(idx - half, 0)]
    post = np.exp(pooled - pooled.max(axis=1, keepdims=True))
    post /= post.sum(axis=1, keepdims=True)
    post[~frame_active] = 0.0
    grid = model.azimuth_rad
    joint = llr[frame_active].sum(axis=0)  # log-odds of S_theta given every active band of every frame
    if frame_active.any():
        sal = post[frame_active].mean(axis=0)
        map_az = _refine_peak(grid, joint, int(np.argmax(joint)))
        step = grid[1] - grid[0]
        peaks, _ = find_peaks(np.r_[0.0, sal, 0.0], height=min_peak_fraction * sal.max(),
                              distance=max(1, int(round(min_separation_rad / step))))
        peaks = peaks - 1
        peaks = peaks[np.argsort(sal[peaks])[::-1]]
        peaks = peaks[:max_sources]
        az = np.array([_refine_peak(grid, sal, int(i)) for i in peaks])
        strength = sal[peaks]
    else:
        sal = np.zeros(grid.size)
        az, strength, map_az = np.zeros(0), np.zeros(0), float("nan")
    return Localization(grid, cues.time_s, post, frame_active, sal, map_az, az, strength, cues)
