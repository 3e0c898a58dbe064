"""Monaural cochlear unit: a gammatone filterbank on ERB-spaced centre frequencies per ear.

Each band is scipy's 4th-order IIR gammatone (``scipy.signal.gammatone(f, "iir")``,
Slaney's design), run as second-order sections; the inner hair cell is modelled by
half-wave rectification followed by a one-pole low-pass (``envelope_cutoff_hz``),
which keeps the fine structure of low bands and the envelope of high ones, as the
auditory nerve does. The filtering runs in one numba kernel over all bands and
both ears at once (the recursions of the 2 x B channels vectorise).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numba import njit
from scipy.signal import gammatone, tf2sos

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
def _sos_hwr_lowpass(x, ear, coef, lp_a, hair_cell):  # pragma: no cover - compiled
    """Filter channels c (input ear[c] of x (n, E)) through SOS coef (6 S, C); optional HWR + low-pass.

    The channel loop is innermost and the state float32 so that all channels run in SIMD lanes.
    Returns (n, C) float32.
    """
    n = x.shape[0]
    n_sec, n_ch = coef.shape[0] // 6, coef.shape[1]
    out = np.empty((n, n_ch), dtype=np.float32)
    z = np.zeros((2 * n_sec, n_ch), dtype=np.float32)
    v = np.zeros(n_ch, dtype=np.float32)
    lp = np.zeros(n_ch, dtype=np.float32)
    for t in range(n):
        for c in range(n_ch):
            v[c] = x[t, ear[c]]
        for s in range(n_sec):
            b0, b1, b2 = coef[6 * s], coef[6 * s + 1], coef[6 * s + 2]
            a1, a2 = coef[6 * s + 4], coef[6 * s + 5]
            za, zb = z[2 * s], z[2 * s + 1]
            for c in range(n_ch):
                vc = v[c]
                y = b0[c] * vc + za[c]
                za[c] = b1[c] * vc - a1[c] * y + zb[c]
                zb[c] = b2[c] * vc - a2[c] * y
                v[c] = y
        o = out[t]
        if hair_cell:
            for c in range(n_ch):
                lp[c] += lp_a[c] * (max(v[c], np.float32(0.0)) - lp[c])
                o[c] = lp[c]
        else:
            for c in range(n_ch):
                o[c] = v[c]
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
        coef = np.repeat(self._sos.transpose(1, 2, 0), n_ears, axis=2)  # (S, 6, B*E)
        coef = np.ascontiguousarray(coef.reshape(-1, coef.shape[-1]), dtype=np.float32)
        ear = np.tile(np.arange(n_ears), self.n_bands)
        cut = self.fs_hz if self.envelope_cutoff_hz is None else self.envelope_cutoff_hz
        a = np.full(self.n_bands * n_ears, 1.0 - np.exp(-2 * np.pi * cut / self.fs_hz), dtype=np.float32)
        out = _sos_hwr_lowpass(np.ascontiguousarray(x, dtype=np.float32), ear, coef, a, self.envelope_cutoff_hz is not None)
        return np.ascontiguousarray(out.T).reshape(self.n_bands, n_ears, -1)
