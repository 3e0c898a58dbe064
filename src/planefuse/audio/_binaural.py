"""Binaural unit: per band and frame, ITD from the interaural cross-correlation, ILD, and gating.

For band b and frame f (``frame_s`` long, every ``hop_s``) the normalised
interaural cross-correlation of the two cochlear outputs is

    c_bf(l) = N / (N - |l|) sum_k (x_L[k] - m_L)(x_R[k + l] - m_R) / sqrt(E_L E_R),   |l| <= max lag,

(sums over the N samples of the frame; the factor undoes the shrinking overlap at large lags)

so that its peak lag is the ITD ``tau`` (positive when the left ear leads). The
peak is refined to sub-sample precision by a parabola through the three samples
around it. The ILD is ``10 log10(E_L / E_R)`` [dB].

A band-frame gives evidence only if it is *active*: not silent (RMS above
``silence_dbfs`` and within ``dynamic_range_db`` of the loudest band-frame),
above the band's noise floor (10th percentile of its frame energies) by ``snr_gate_db``, with a rising or sustained level (``onset_db``:
its energy is no more than ``onset_db`` below the previous frame's, which drops
reverberant tails), coherent (correlation peak >= ``coherence_min``), with its
peak inside the lag range (not on its border), and in a frame without clipped
samples. Nothing is dropped silently: ``BinauralCues.active`` marks every band-frame
and ``n_clipped_frames`` counts the frames lost to clipping.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.fft as sfft

from ._cochlea import GammatoneFilterbank, check_binaural_signal

__all__ = ["BinauralCues", "binaural_cues", "clipped_samples"]


def _unbias(frame_len: int, max_lag: int) -> np.ndarray:
    """Weights N / (N - |l|) that undo the triangular taper of a correlation within one frame.

    Without them the peak of a within-frame correlation is pulled towards lag 0.
    """
    lags = np.arange(-max_lag, max_lag + 1)
    return (frame_len / (frame_len - np.abs(lags))).astype(np.float32)


def _frames(env: np.ndarray, frame_len: int, hop: int) -> np.ndarray:
    """Mean-removed frames (B, 2, F, N) of cochlear outputs env (B, 2, n)."""
    n = env.shape[-1]
    n_frames = max(0, (n - frame_len) // hop + 1)
    if hop == frame_len:
        fr = env[..., : n_frames * frame_len].reshape(env.shape[:2] + (n_frames, frame_len))
    else:
        fr = env[..., np.arange(n_frames)[:, None] * hop + np.arange(frame_len)]
    return fr - fr.mean(axis=-1, keepdims=True)


def _frame_xcorr_fft(frames: np.ndarray, candidates: np.ndarray, max_lag: int) -> np.ndarray:
    """Cross-correlation (F, B, 2L+1) of the band-frames in ``candidates`` (F, B); 0 elsewhere.

    Each candidate band-frame is transformed once (zero-padded so that lags up to
    ``max_lag`` do not wrap) and the correlation read from the inverse transform of
    ``conj(X_L) X_R``; band-frames that the energy gates already rejected are skipped.
    """
    n_bands, _, n_frames, frame_len = frames.shape
    cc = np.zeros((n_frames, n_bands, 2 * max_lag + 1), dtype=np.float32)
    fi, bi = np.nonzero(candidates)
    if fi.size == 0:
        return cc
    n_fft = sfft.next_fast_len(frame_len + max_lag + 1, real=True)
    step = 4096
    for s in range(0, fi.size, step):
        f, b = fi[s : s + step], bi[s : s + step]
        X = sfft.rfft(frames[b, :, f], n_fft, axis=-1)  # (k, 2, K)
        c = sfft.irfft(np.conj(X[:, 0]) * X[:, 1], n_fft, axis=-1)
        cc[f, b] = np.concatenate([c[:, n_fft - max_lag :], c[:, : max_lag + 1]], axis=-1)
    return cc * _unbias(frame_len, max_lag)


def _frame_xcorr_fd(x, fb: GammatoneFilterbank, frame_len: int, hop: int, max_lag: int):
    """Band cross-correlations (F, B, 2L+1) and energies (F, B, 2) computed in the frequency domain.

    The cross-correlation of ``h_b * x_L`` and ``h_b * x_R`` is the inverse transform
    of ``|H_b|^2 conj(X_L) X_R``: each frame is transformed once and each band costs
    one short inverse FFT (the band-pass acts within the frame only).
    """
    n = len(x)
    n_frames = max(0, (n - frame_len) // hop + 1)
    n_fft = sfft.next_fast_len(frame_len + max_lag + 1, real=True)
    idx = np.arange(n_frames)[:, None] * hop + np.arange(frame_len)
    fr = x[idx].astype(np.float32)  # (F, N, 2)
    fr -= fr.mean(axis=1, keepdims=True)
    X = sfft.rfft(fr, n_fft, axis=1)  # (F, K, 2)
    f = np.fft.rfftfreq(n_fft, 1.0 / fb.fs_hz)
    G = (np.abs(fb.frequency_response(f)) ** 2).astype(np.float32)  # (B, K)
    w = np.full(f.size, 2.0 / n_fft, dtype=np.float32)  # Parseval weights of a one-sided spectrum
    w[0] = 1.0 / n_fft
    if n_fft % 2 == 0:
        w[-1] = 1.0 / n_fft
    en = np.stack([(np.abs(X[:, :, e]) ** 2 * w) @ G.T for e in range(2)], axis=-1)  # (F, B, 2)
    cross = np.conj(X[:, :, 0]) * X[:, :, 1]  # (F, K)
    cc = np.empty((n_frames, fb.n_bands, 2 * max_lag + 1), dtype=np.float32)
    step = max(1, 2**20 // (fb.n_bands * f.size))
    for s in range(0, n_frames, step):
        c = sfft.irfft(cross[s : s + step, None, :] * G[None], n_fft, axis=-1)
        cc[s : s + step] = np.concatenate([c[..., n_fft - max_lag :], c[..., : max_lag + 1]], axis=-1)
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
        ITD [s], > 0 when the left ear leads (NaN where the energy gates failed or the peak was
        on the lag border).
    ild_db : ndarray, shape (F, B)
        ILD ``10 log10(E_L/E_R)`` [dB] (NaN where an ear is silent).
    coherence : ndarray, shape (F, B)
        Peak of the normalised interaural cross-correlation, in [-1, 1] (0 where the energy gates failed).
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
    front_end: str = "time",
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
    front_end : {"time", "fft"}
        ``"time"``: the gammatone filterbank runs continuously over the signal (with the
        hair cell if configured), then each frame is correlated. ``"fft"``: each frame is
        transformed once and every band's correlation is ``irfft(|H_b|^2 conj(X_L) X_R)``
        (same gammatone responses, no hair cell, band-limited within the frame only:
        faster, less accurate in reverberation; see docs/audio.md).
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
    if front_end == "time":
        frames = _frames(fb.process(x), frame_len, hop)
        en = np.einsum("befn,befn->fbe", frames, frames)
    elif front_end == "fft":
        cc, en = _frame_xcorr_fd(x, fb, frame_len, hop, max_lag)
    else:
        raise ValueError(f"front_end must be 'time' or 'fft', got {front_end!r}")
    n_frames, n_bands = en.shape[:2]
    t = (np.arange(n_frames) * hop + frame_len / 2) / fs_hz

    # energy gates first: the correlation is only computed where they pass
    with np.errstate(divide="ignore", invalid="ignore"):
        ild = 10 * np.log10(en[..., 0] / en[..., 1])
        energy = en.sum(-1).astype(float)
        level = 10 * np.log10(energy / (2 * frame_len) + 1e-30)
    ild = np.where(np.isfinite(ild), ild, np.nan)
    active = level > silence_dbfs
    if n_frames:
        active &= level > level.max() - dynamic_range_db
        floor = np.percentile(energy, 10, axis=0)
        active &= energy >= floor * 10 ** (snr_gate_db / 10)
        if onset_db is not None:
            prev = np.vstack([energy[:1], energy[:-1]])
            active &= energy >= prev * 10 ** (-onset_db / 10)
    if front_end == "time":
        cc = _frame_xcorr_fft(frames, active, max_lag)

    norm = np.sqrt(np.maximum(en[..., 0] * en[..., 1], 1e-30))
    j = np.argmax(cc, axis=-1)
    peak = np.take_along_axis(cc, j[..., None], -1)[..., 0]
    coherence = np.where(active, peak / norm, 0.0)
    inner = (j > 0) & (j < cc.shape[-1] - 1)
    jc = np.clip(j, 1, cc.shape[-1] - 2)
    ym = np.take_along_axis(cc, (jc - 1)[..., None], -1)[..., 0].astype(float)
    y0 = np.take_along_axis(cc, jc[..., None], -1)[..., 0].astype(float)
    yp = np.take_along_axis(cc, (jc + 1)[..., None], -1)[..., 0].astype(float)
    den = ym - 2 * y0 + yp
    delta = np.where(den < 0, 0.5 * (ym - yp) / np.where(den < 0, den, -1.0), 0.0)
    tau = np.where(inner & active, (jc - max_lag + np.clip(delta, -0.5, 0.5)) / fs_hz, np.nan)
    active &= inner & (coherence >= coherence_min)
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
