"""Monaural cochlear unit: a gammatone filterbank on ERB-spaced centre frequencies per ear.

Each band is scipy's 4th-order IIR gammatone (``scipy.signal.gammatone(f, "iir")``,
Slaney's design), run as four second-order sections; the inner hair cell is modelled by
half-wave rectification followed by a one-pole low-pass (``envelope_cutoff_hz``),
which keeps the fine structure of low bands and the envelope of high ones, as the
auditory nerve does. The filtering runs in one numba kernel, channel by channel
with the filter state in registers.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numba import njit
from scipy.signal import gammatone, sosfreqz, tf2sos

__all__ = ["GammatoneFilterbank", "erb_space_hz", "check_binaural_signal"]


def erb_space_hz(f_min_hz: float, f_max_hz: float, n_bands: int) -> np.ndarray:
    """``n_bands`` centre frequencies [Hz] equally spaced on the ERB-number scale (Glasberg & Moore 1990)."""
    if not (0 < f_min_hz < f_max_hz) or n_bands < 1:
        raise ValueError(f"need 0 < f_min_hz < f_max_hz and n_bands >= 1, got {f_min_hz}, {f_max_hz}, {n_bands}")
    erb = lambda f: 21.4 * np.log10(1 + 0.00437 * f)  # noqa: E731
    e = np.linspace(erb(f_min_hz), erb(f_max_hz), n_bands)
    return (10 ** (e / 21.4) - 1) / 0.00437


def check_binaural_signal(signal, name: str = "signal") -> np.ndarray:
    """Validate a two-channel signal (n, 2) [left, right]; return it as float64.

    Raises ``ValueError`` for mono or multi-channel input, empty input and NaN/inf samples.
    """
    x = np.asarray(signal, dtype=float)
    if x.ndim != 2 or x.shape[1] != 2:
        raise ValueError(f"{name} must be a two-channel signal of shape (n, 2) [left, right], got {x.shape}"
                         + (" (mono: a binaural sensor needs both ears)" if x.ndim == 1 or x.shape[-1] == 1 else ""))
    if x.shape[0] == 0:
        raise ValueError(f"{name} is empty")
    bad = ~np.isfinite(x)
    if bad.any():
        raise ValueError(f"{name} has {int(bad.sum())} NaN/inf samples (first at frame {int(np.argmax(bad.any(1)))})")
    return x


@njit(cache=True, fastmath=True)
def _gammatone_hair_cell(x, ear, sos, lp_a, hair_cell):  # pragma: no cover - compiled
    """Run channel c (band c // E on input column ear[c] of x (n, E)) through its 4 biquads sos (C, 4, 6).

    One channel at a time with the eight state variables in registers (the
    recursion is serial in time); optional HWR + one-pole low-pass. Returns (C, n) float32.
    """
    n = x.shape[0]
    n_ch = sos.shape[0]
    out = np.empty((n_ch, n), dtype=np.float32)
    zero = np.float32(0.0)
    for c in range(n_ch):
        xe = x[:, ear[c]]
        s = sos[c]
        b00, b01, b02, a01, a02 = s[0, 0], s[0, 1], s[0, 2], s[0, 4], s[0, 5]
        b10, b11, b12, a11, a12 = s[1, 0], s[1, 1], s[1, 2], s[1, 4], s[1, 5]
        b20, b21, b22, a21, a22 = s[2, 0], s[2, 1], s[2, 2], s[2, 4], s[2, 5]
        b30, b31, b32, a31, a32 = s[3, 0], s[3, 1], s[3, 2], s[3, 4], s[3, 5]
        z00 = z01 = z10 = z11 = z20 = z21 = z30 = z31 = lp = zero
        a = lp_a[c]
        o = out[c]
        for t in range(n):
            v = xe[t]
            y = b00 * v + z00
            z00 = b01 * v - a01 * y + z01
            z01 = b02 * v - a02 * y
            v = y
            y = b10 * v + z10
            z10 = b11 * v - a11 * y + z11
            z11 = b12 * v - a12 * y
            v = y
            y = b20 * v + z20
            z20 = b21 * v - a21 * y + z21
            z21 = b22 * v - a22 * y
            v = y
            y = b30 * v + z30
            z30 = b31 * v - a31 * y + z31
            z31 = b32 * v - a32 * y
            if hair_cell:
                lp += a * (max(y, zero) - lp)
                y = lp
            o[t] = y
    return out


@dataclass(frozen=True)
class GammatoneFilterbank:
    """ERB-spaced gammatone filterbank with a half-wave-rectifying, low-pass hair cell.

    Attributes
    ----------
    fs_hz : float
        Sampling rate of the input [Hz].
    n_bands : int
        Number of bands B.
    f_min_hz, f_max_hz : float
        Centre frequencies of the lowest and highest band [Hz].
    envelope_cutoff_hz : float or None
        Cut-off of the hair cell's one-pole low-pass [Hz]; None disables the hair
        cell (no rectification, the band-passed signal itself).
    """

    fs_hz: float = 16000.0
    n_bands: int = 32
    f_min_hz: float = 100.0
    f_max_hz: float = 4000.0
    envelope_cutoff_hz: float | None = None
    _sos: np.ndarray = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        if not (np.isfinite(self.fs_hz) and self.fs_hz > 0):
            raise ValueError(f"fs_hz must be > 0, got {self.fs_hz}")
        if self.f_max_hz >= self.fs_hz / 2:
            raise ValueError(f"f_max_hz={self.f_max_hz} must be below Nyquist ({self.fs_hz / 2} Hz)")
        sos = np.stack([tf2sos(*gammatone(f, "iir", fs=self.fs_hz)) for f in self.center_freqs_hz])
        if sos.shape[1] != 4:  # scipy's IIR gammatone is 4th order (8 poles): four biquads
            raise ValueError(f"expected 4 second-order sections per gammatone band, got {sos.shape[1]}")
        # unit gain at each centre frequency, so that band energies compare across bands
        for b, f in enumerate(self.center_freqs_hz):
            zinv = np.exp(-2j * np.pi * f / self.fs_hz)
            s = sos[b]
            g = np.prod((s[:, 0] + s[:, 1] * zinv + s[:, 2] * zinv**2) / (s[:, 3] + s[:, 4] * zinv + s[:, 5] * zinv**2))
            s[0, :3] /= abs(g)
        object.__setattr__(self, "_sos", np.ascontiguousarray(sos))

    @property
    def center_freqs_hz(self) -> np.ndarray:
        """Centre frequencies (B,) [Hz], ERB-spaced."""
        return erb_space_hz(self.f_min_hz, self.f_max_hz, self.n_bands)

    def frequency_response(self, freqs_hz) -> np.ndarray:
        """Complex response (B, K) of every band at ``freqs_hz`` (K,) [Hz] (unit gain at the centre)."""
        f = np.asarray(freqs_hz, dtype=float)
        return np.stack([sosfreqz(s, worN=f, fs=self.fs_hz)[1] for s in self._sos])

    def process(self, signal) -> np.ndarray:
        """Cochleagram of a multi-channel signal.

        Parameters
        ----------
        signal : array_like, shape (n, E)
            Ear signals at ``fs_hz`` (E = 2 for a binaural pair: left, right).

        Returns
        -------
        ndarray, shape (B, E, n), float32
            Hair-cell output per band and ear (band-passed signal if ``envelope_cutoff_hz`` is None).
        """
        x = np.asarray(signal, dtype=float)
        if x.ndim != 2:
            raise ValueError(f"signal must have shape (n, channels), got {x.shape}")
        n_ears = x.shape[1]
        sos = np.ascontiguousarray(np.repeat(self._sos, n_ears, axis=0), dtype=np.float32)  # (B*E, 4, 6)
        ear = np.tile(np.arange(n_ears), self.n_bands)
        cut = self.fs_hz if self.envelope_cutoff_hz is None else self.envelope_cutoff_hz
        a = np.full(self.n_bands * n_ears, 1.0 - np.exp(-2 * np.pi * cut / self.fs_hz), dtype=np.float32)
        out = _gammatone_hair_cell(np.ascontiguousarray(x, dtype=np.float32), ear, sos, a,
                                   self.envelope_cutoff_hz is not None)
        return out.reshape(self.n_bands, n_ears, -1)
