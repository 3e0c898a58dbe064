"""Source signals: a seeded speech-like generator and a WAV reader with resampling."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from scipy.signal import butter, iirpeak, sosfilt, tf2sos

from ._head import _resample

__all__ = ["speech_like_signal", "read_audio"]

# First three formants [Hz] of five vowels (Peterson & Barney averages, rounded).
_VOWEL_FORMANTS_HZ = np.array(
    [[730, 1090, 2440], [530, 1840, 2480], [270, 2290, 3010], [570, 840, 2410], [300, 870, 2240]], dtype=float
)


def speech_like_signal(duration_s: float, fs_hz: float = 16000.0, seed: int = 0) -> np.ndarray:
    """A synthetic, speech-like mono signal: voiced syllables, fricatives and pauses.

    Each syllable is a glottal pulse train (F0 90-220 Hz with a falling/rising
    contour and jitter) shaped by three vowel formant resonators, often preceded
    by a high-passed noise burst (a fricative); syllables last 120-300 ms with a
    syllabic amplitude envelope and are separated by 30-150 ms gaps (sometimes
    a 300 ms pause), giving the 4-5 Hz modulation and the silences of speech.

    Parameters
    ----------
    duration_s : float
        Length [s] (> 0).
    fs_hz : float
        Sampling rate [Hz] (>= 8000 so that the formants fit).
    seed : int
        Seed of ``np.random.default_rng``; the same seed gives the same signal.

    Returns
    -------
    ndarray, shape (round(duration_s * fs_hz),), float64
        Peak-normalised to 0.5.
    """
    if not (np.isfinite(duration_s) and duration_s > 0):
        raise ValueError(f"duration_s must be finite and > 0, got {duration_s}")
    if not (np.isfinite(fs_hz) and fs_hz >= 8000):
        raise ValueError(f"fs_hz must be >= 8000 Hz, got {fs_hz}")
    rng = np.random.default_rng(seed)
    n = int(round(duration_s * fs_hz))
    out = np.zeros(n)
    sos_fric = butter(4, min(2500.0, 0.3 * fs_hz), btype="highpass", fs=fs_hz, output="sos")
    t0 = int(rng.uniform(0.0, 0.1) * fs_hz)
    while t0 < n:
        if rng.random() < 0.6:  # fricative onset
            m = int(rng.uniform(0.03, 0.08) * fs_hz)
            burst = sosfilt(sos_fric, rng.standard_normal(m)) * np.hanning(m) * rng.uniform(0.1, 0.4)
            out[t0 : t0 + m] += burst[: max(0, min(m, n - t0))]
            t0 += m
        m = int(rng.uniform(0.12, 0.30) * fs_hz)
        f0 = rng.uniform(90, 220) * np.linspace(1.0, rng.uniform(0.8, 1.2), m)
        f0 *= 1 + 0.01 * rng.standard_normal(m)  # jitter
        phase = np.cumsum(f0 / fs_hz)
        pulses = np.diff(np.floor(phase), prepend=0.0)  # one impulse per glottal period
        exc = np.convolve(pulses, np.hanning(int(0.002 * fs_hz) + 2), mode="same")
        exc += 0.02 * rng.standard_normal(m)  # aspiration
        formants = _VOWEL_FORMANTS_HZ[rng.integers(len(_VOWEL_FORMANTS_HZ))] * rng.uniform(0.9, 1.1, 3)
        voiced = exc
        for k, f in enumerate(formants[formants < 0.45 * fs_hz]):
            b, a = iirpeak(f, Q=f / (60.0 + 40.0 * k), fs=fs_hz)
            voiced = voiced + (1.0 / (k + 1)) * sosfilt(tf2sos(b, a), exc)
        voiced *= np.hanning(m) ** 0.5 * rng.uniform(0.5, 1.0)
        out[t0 : t0 + m] += voiced[: max(0, min(m, n - t0))]
        t0 += m + int((0.3 if rng.random() < 0.15 else rng.uniform(0.03, 0.15)) * fs_hz)
    peak = np.abs(out).max()
    return out * (0.5 / peak) if peak > 0 else out


def read_audio(path, fs_hz: float | None = None) -> tuple[np.ndarray, float]:
    """Read an audio file with ``soundfile`` as float64 (frames, channels), resampled to ``fs_hz``.

    Parameters
    ----------
    path : path-like
        Audio file (WAV, FLAC, ...).
    fs_hz : float, optional
        Target sampling rate [Hz]; None keeps the file's rate.

    Returns
    -------
    signal : ndarray, shape (n, channels), float64 in [-1, 1] before resampling
    fs_hz : float
        Its sampling rate [Hz].
    """
    import soundfile as sf

    path = Path(path)
    if not path.is_file():
        raise ValueError(f"audio file {path} does not exist")
    try:
        x, fs_file = sf.read(str(path), dtype="float64", always_2d=True)
    except (sf.LibsndfileError, RuntimeError, TypeError) as err:
        raise ValueError(f"{path}: not a readable audio file ({' '.join(str(err).split())[:160]})") from None
    if fs_hz is None or fs_hz == fs_file:
        return x, float(fs_file)
    return _resample(x, fs_file, fs_hz, axis=0), float(fs_hz)
