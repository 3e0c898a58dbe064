"""Binaural unit: per band and frame, ITD from the interaural cross-correlation, ILD, and gating.

For band b and frame f (``frame_s`` long, every ``hop_s``) the normalised
interaural cross-correlation of the two cochlear outputs is

    c_bf(l) = sum_k (x_L[k] - m_L)(x_R[k + l] - m_R) / sqrt(E_L E_R),   |l| <= max lag,

so that its peak lag is the ITD ``tau`` (positive when the left ear leads). The
peak is refined to sub-sample precision by a parabola through the three samples
around it. The ILD is ``10 log10(E_L / E_R)`` [dB].

A band-frame gives evidence only if it is *active*: not silent (RMS above
``silence_dbfs`` and within ``dynamic_range_db`` of the loudest band-frame), above the band's noise floor (10th percentile of its frame
energies) by ``snr_gate_db``, with a rising or sustained level (``onset_db``:
its energy is no more than ``onset_db`` below the previous frame's, which drops
reverberant tails), coherent (correlation peak >= ``coherence_min``), with its
peak inside the lag range (not on its border), and in a frame without clipped
samples. Inactive band-frames are counted, never silently dropped.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numba import njit

from ._cochlea import GammatoneFilterbank, check_binaural_signal

__all__ = ["BinauralCues", "binaural_cues", "clipped_samples"]


@njit(cache=True, fastmath=True)
def _frame_xcorr(env, frame_len, hop, max_lag):  # pragma: no cover - compiled
    """Mean-removed cross-correlation (F, B, 2L+1) and energies (F, B, 2) of env (B, 2, n) float32."""
    n_bands, _, n = env.shape
    n_frames = max(0, (n - frame_len) // hop + 1)
    n_lags = 2 * max_lag + 1
    cc = np.zeros((n_frames, n_bands, n_lags), dtype=np.float32)
    en = np.zeros((n_frames, n_bands, 2), dtype=np.float32)
    for b in range(n_bands):
        xl = env[b, 0]
        xr = env[b, 1]
        for f in range(n_frames):
            s = f * hop
            ml = np.float32(0.0)
            mr = np.float32(0.0)
            for k in range(s, s + frame_len):
                ml += xl[k]
                mr += xr[k]
            ml /= frame_len
            mr /= frame_len
            el = np.float32(0.0)
            er = np.float32(0.0)
            for k in range(s, s + frame_len):
                el += (xl[k] - ml) ** 2
                er += (xr[k] - mr) ** 2
            en[f, b, 0] = el
            en[f, b, 1] = er
            for j in range(n_lags):
                lag = j - max_lag
                lo = max(s, -lag)
                hi = min(s + frame_len, n - lag)
                acc = np.float32(0.0)
                for k in range(lo, hi):
                    acc += xl[k] * xr[k + lag]
                cc[f, b, j] = acc - (hi - lo) * ml * mr
    return cc, en


def clipped_samples(signal, rel_tol: float = 1e-4, min_run: int = 2) -> np.ndarray:
    """Boolean mask (n,) of frames where any channel sits at its peak level for ``min_run`` samples or more.

    A clipped (saturated) recording shows flat runs at +-its largest magnitude;
    a single sample at the peak is not clipping.
    """
    x = np.abs(np.asarray(signal, dtype=float))
    peak = x.max(axis=0)
    at = (x >= (1 - rel_tol) * peak) & (peak > 0)
    mask = np.zeros(len(x), dtype=bool)
    for c in range(x.shape[1]):
        a = at[:, c].astype(np.int8)
        run = np.convolve(a, np.ones(min_run, dtype=np.int8), mode="full")[: len(a)] >= min_run
        # mark every sample of a run of >= min_run
        for k in range(min_run):
            mask[: len(a) - k] |= run[k:]
    return mask


@dataclass(frozen=True)
class BinauralCues:
    """Binaural cues per frame and band.

    Attributes
    ----------
    time_s : ndarray, shape (F,)
        Centre time of each frame [s] from the start of the signal.
    tau_s : ndarray, shape (F, B)
        ITD [s], > 0 when the left ear leads (NaN where the peak was on the lag border).
    ild_db : ndarray, shape (F, B)
        ILD ``10 log10(E_L/E_R)`` [dB] (NaN where an ear is silent).
    coherence : ndarray, shape (F, B)
        Peak of the normalised interaural cross-correlation, in [-1, 1].
    level_db : ndarray, shape (F, B)
        Band RMS level [dB], mean of both ears.
    active : ndarray, shape (F, B), bool
        Band-frames that give evidence (see module doc).
    n_clipped_frames : int
        Frames dropped because they contain clipped samples.
    center_freqs_hz : ndarray, shape (B,)
        Band centre frequencies [Hz].
    """

    time_s: np.ndarray
    tau_s: np.ndarray
    ild_db: np.ndarray
    coherence: np.ndarray
    level_db: np.ndarray
    active: np.ndarray
    n_clipped_frames: int
    center_freqs_hz: np.ndarray


def binaural_cues(
    signal,
    fs_hz: float,
    filterbank: GammatoneFilterbank | None = None,
    frame_s: float = 0.02,
    hop_s: float | None = None,
    max_itd_s: float = 1.0e-3,
    silence_dbfs: float = -120.0,
    dynamic_range_db: float = 60.0,
    snr_gate_db: float = 6.0,
    onset_db: float | None = 3.0,
    coherence_min: float = 0.5,
) -> BinauralCues:
    """ITD, ILD and activity of every band and frame of a two-channel signal.

    Parameters
    ----------
    signal : array_like, shape (n, 2)
        Ear signals [left, right] at ``fs_hz``, full scale = 1.
    fs_hz : float
        Sampling rate [Hz]; must equal the filterbank's.
    filterbank : GammatoneFilterbank, optional
        Default: 32 bands 100-4000 Hz at ``fs_hz``.
    frame_s, hop_s : float
        Frame length and hop [s] (hop defaults to the frame length).
    max_itd_s : float
        Largest |ITD| searched [s].
    silence_dbfs : float
        Band-frames quieter than this RMS [dB re full scale] are silent (digital silence).
    dynamic_range_db : float
        Band-frames more than this below the loudest band-frame of the signal are silent [dB].
    snr_gate_db : float
        Required margin above the band's noise floor [dB].
    onset_db : float or None
        A band-frame whose energy dropped by more than this from the previous frame
        is a reverberant tail and gives no evidence [dB]; None disables the test.
    coherence_min : float
        Smallest normalised correlation peak accepted.
    """
    x = check_binaural_signal(signal)
    fb = GammatoneFilterbank(fs_hz=fs_hz) if filterbank is None else filterbank
    if fb.fs_hz != fs_hz:
        raise ValueError(f"signal is at {fs_hz} Hz but the filterbank expects {fb.fs_hz} Hz")
    frame_len = int(round(frame_s * fs_hz))
    hop = frame_len if hop_s is None else int(round(hop_s * fs_hz))
    if frame_len < 8 or hop < 1:
        raise ValueError(f"frame_s={frame_s} s / hop_s={hop_s} s are too short at {fs_hz} Hz")
    max_lag = int(np.ceil(max_itd_s * fs_hz)) + 1
    env = fb.process(x)
    cc, en = _frame_xcorr(env, frame_len, hop, max_lag)
    n_frames, n_bands = cc.shape[:2]
    t = (np.arange(n_frames) * hop + frame_len / 2) / fs_hz

    norm = np.sqrt(np.maximum(en[..., 0] * en[..., 1], 1e-30))
    j = np.argmax(cc, axis=-1)
    peak = np.take_along_axis(cc, j[..., None], -1)[..., 0]
    coherence = peak / norm
    inner = (j > 0) & (j < cc.shape[-1] - 1)
    jc = np.clip(j, 1, cc.shape[-1] - 2)
    ym = np.take_along_axis(cc, (jc - 1)[..., None], -1)[..., 0].astype(float)
    y0 = np.take_along_axis(cc, jc[..., None], -1)[..., 0].astype(float)
    yp = np.take_along_axis(cc, (jc + 1)[..., None], -1)[..., 0].astype(float)
    den = ym - 2 * y0 + yp
    delta = np.where(den < 0, 0.5 * (ym - yp) / np.where(den < 0, den, -1.0), 0.0)
    tau = np.where(inner, (jc - max_lag + np.clip(delta, -0.5, 0.5)) / fs_hz, np.nan)

    with np.errstate(divide="ignore", invalid="ignore"):
        ild = 10 * np.log10(en[..., 0] / en[..., 1])
        energy = en.sum(-1).astype(float)
        level = 10 * np.log10(energy / (2 * frame_len) + 1e-30)
    ild = np.where(np.isfinite(ild), ild, np.nan)

    active = inner & (coherence >= coherence_min) & (level > silence_dbfs)
    if n_frames:
        active &= level > level.max() - dynamic_range_db
        floor = np.percentile(energy, 10, axis=0)
        active &= energy >= floor * 10 ** (snr_gate_db / 10)
        if onset_db is not None:
            prev = np.vstack([energy[:1], energy[:-1]])
            active &= energy >= prev * 10 ** (-onset_db / 10)
    clipped = clipped_samples(x)
    n_clipped = 0
    if clipped.any() and n_frames:
        c = np.concatenate([[0], np.cumsum(clipped)])
        starts = np.arange(n_frames) * hop
        bad = (c[starts + frame_len] - c[starts]) > 0
        n_clipped = int(bad.sum())
        active &= ~bad[:, None]
    return BinauralCues(
        time_s=t,
        tau_s=tau,
        ild_db=ild,
        coherence=coherence.astype(float),
        level_db=level,
        active=active,
        n_clipped_frames=n_clipped,
        center_freqs_hz=fb.center_freqs_hz,
    )
