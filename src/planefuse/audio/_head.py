"""Head models: how a sound arriving from a direction reaches the two ears.

Head frame ``{head}``: x forward, y left, z up, origin at the centre of the head;
the ears sit on the y axis (left ear at +y). Azimuth is counter-clockwise seen
from above, 0 = straight ahead, +pi/2 = the listener's left (SOFA convention).
The *lateral angle* ``asin(d_y)`` of a unit direction ``d`` is what a pair of
ears on the y axis can measure: azimuths ``theta`` and ``pi - theta`` (front and
back) share it (the cone of confusion).

Every head model answers two questions for the simulator and the calibration:

* ``direction_bins(directions_head)`` -- quantise unit directions (K, 3) into
  integer bins that share one head-related impulse response (HRIR);
* ``bin_hrirs(bins)`` -- the HRIRs (n, 2, n_taps) of those bins at ``fs_hz``,
  ear 0 = left, ear 1 = right; all of them share one bulk delay.

:class:`SphericalHead` is analytic (Woodworth ITD + Brown-Duda head shadow);
:class:`MeasuredHrirs` holds a measured set (SOFA file via ``sofar`` or the
KU 100 circular npz), resampled to ``fs_hz``.
"""

from __future__ import annotations

from dataclasses import dataclass
from fractions import Fraction
from pathlib import Path

import numpy as np
from scipy.signal import resample_poly
from scipy.signal.windows import tukey

from ..geometry import check_points

__all__ = [
    "SPEED_OF_SOUND_M_S",
    "HEAD_RADIUS_M",
    "SphericalHead",
    "MeasuredHrirs",
    "lateral_from_azimuth",
    "directions_from_azimuth_elevation",
]

#: Speed of sound used throughout [m/s] (pyroomacoustics' default constant).
SPEED_OF_SOUND_M_S = 343.0
#: Radius of an average adult head [m] (Brown & Duda 1998).
HEAD_RADIUS_M = 0.0875


def lateral_from_azimuth(azimuth_rad, elevation_rad=0.0) -> np.ndarray:
    """Lateral angle ``asin(cos(el) sin(az))`` [rad] in [-pi/2, pi/2] of a direction in the head frame."""
    az = np.asarray(azimuth_rad, dtype=float)
    el = np.asarray(elevation_rad, dtype=float)
    return np.arcsin(np.clip(np.cos(el) * np.sin(az), -1.0, 1.0))


def directions_from_azimuth_elevation(azimuth_rad, elevation_rad=0.0) -> np.ndarray:
    """Unit vectors (..., 3) in the head frame from azimuth and elevation [rad]."""
    az, el = np.broadcast_arrays(np.asarray(azimuth_rad, float), np.asarray(elevation_rad, float))
    return np.stack([np.cos(el) * np.cos(az), np.cos(el) * np.sin(az), np.sin(el)], axis=-1)


def _unit_directions(directions_head) -> np.ndarray:
    d = check_points(directions_head, 3, "directions_head").reshape(-1, 3)
    n = np.linalg.norm(d, axis=-1, keepdims=True)
    if np.any(n == 0):
        raise ValueError("directions_head has zero-length vectors")
    return d / n


@dataclass(frozen=True)
class SphericalHead:
    """Rigid spherical head with two antipodal ears on the y axis (Brown & Duda 1998).

    Per ear, with ``theta`` the angle between the source direction and the ear's
    outward axis, the response is a delay and a one-pole/one-zero shadow filter:

    * delay ``T(theta) = -(a/c) cos(theta)`` for ``theta < pi/2`` else
      ``(a/c)(theta - pi/2)``, so the interaural time difference is Woodworth's
      ``ITD = (a/c)(phi + sin(phi))`` for lateral angle ``phi``;
    * shadow ``H(w, theta) = (1 + j alpha w / (2 w0)) / (1 + j w / (2 w0))``,
      ``w0 = c/a``, ``alpha(theta) = (1 + alpha_min/2) + (1 - alpha_min/2) cos(pi theta / theta_min)``
      (a high-shelf boost on the near side, a low-pass shadow on the far side: the ILD).

    The model is front/back symmetric: it cannot resolve the cone of confusion.

    Attributes
    ----------
    radius_m : float
        Head radius a [m].
    speed_of_sound_m_s : float
        c [m/s].
    alpha_min : float
        Deepest shadow (Brown & Duda: 0.1).
    theta_min_rad : float
        Incidence angle of the deepest shadow [rad] (Brown & Duda: 150 deg).
    fs_hz : float
        Sampling rate of the HRIRs [Hz].
    n_taps : int
        HRIR length; the bulk delay is ``n_taps // 2`` samples.
    bin_deg : float
        Width of the lateral-angle bins used by the simulator for reflections [deg].
    """

    radius_m: float = HEAD_RADIUS_M
    speed_of_sound_m_s: float = SPEED_OF_SOUND_M_S
    alpha_min: float = 0.1
    theta_min_rad: float = np.deg2rad(150.0)
    fs_hz: float = 16000.0
    n_taps: int = 64
    bin_deg: float = 0.25

    def __post_init__(self) -> None:
        for name in ("radius_m", "speed_of_sound_m_s", "fs_hz", "bin_deg"):
            v = getattr(self, name)
            if not (np.isfinite(v) and v > 0):
                raise ValueError(f"SphericalHead.{name} must be finite and > 0, got {v}")
        max_delay = self.radius_m / self.speed_of_sound_m_s * (np.pi / 2 + 1) * self.fs_hz
        if self.n_taps < 2 * max_delay + 16:
            raise ValueError(f"SphericalHead.n_taps={self.n_taps} too short for delays of +-{max_delay:.1f} samples")

    @property
    def name(self) -> str:
        return f"spherical head a={self.radius_m * 100:.2f} cm"

    @property
    def ear_distance_m(self) -> float:
        """Straight-line distance between the ears [m] (2a)."""
        return 2.0 * self.radius_m

    def itd_s(self, lateral_rad) -> np.ndarray:
        """Woodworth ITD [s] ``(a/c)(phi + sin phi)``; positive when the left ear leads (source on the left)."""
        phi = np.asarray(lateral_rad, dtype=float)
        return self.radius_m / self.speed_of_sound_m_s * (phi + np.sin(phi))

    # -- HRIRs -----------------------------------------------------------------
    def _ear_delay_s(self, theta: np.ndarray) -> np.ndarray:
        a_c = self.radius_m / self.speed_of_sound_m_s
        return np.where(theta < np.pi / 2, -a_c * np.cos(theta), a_c * (theta - np.pi / 2))

    def hrirs_from_lateral(self, lateral_rad) -> np.ndarray:
        """HRIRs (K, 2, n_taps) at ``fs_hz`` for lateral angles (K,) [rad], designed in frequency.

        The delay and shadow filter of each ear are sampled on an FFT grid of
        ``4 n_taps`` bins and transformed back, then truncated with a Tukey window;
        the bulk delay ``n_taps // 2`` keeps every response causal.
        """
        phi = np.asarray(lateral_rad, dtype=float).reshape(-1)
        theta = np.stack([np.pi / 2 - phi, np.pi / 2 + phi], axis=-1)  # incidence on left, right ear axes
        n_fft = 4 * self.n_taps
        w = 2 * np.pi * np.fft.rfftfreq(n_fft, 1.0 / self.fs_hz)
        w0 = self.speed_of_sound_m_s / self.radius_m
        alpha = (1 + self.alpha_min / 2) + (1 - self.alpha_min / 2) * np.cos(theta / self.theta_min_rad * np.pi)
        shadow = (1 + 1j * alpha[..., None] * w / (2 * w0)) / (1 + 1j * w / (2 * w0))
        delay = self._ear_delay_s(theta)[..., None] + (self.n_taps // 2) / self.fs_hz
        H = shadow * np.exp(-1j * w * delay)
        h = np.fft.irfft(H, n_fft, axis=-1)[..., : self.n_taps]
        return h * tukey(self.n_taps, 0.2)

    def direction_bins(self, directions_head) -> np.ndarray:
        """Bin (K,) int64 of the lateral angle of unit directions (K, 3), ``bin_deg`` wide."""
        d = _unit_directions(directions_head)
        phi_deg = np.rad2deg(np.arcsin(np.clip(d[:, 1], -1, 1)))
        return np.round((phi_deg + 90.0) / self.bin_deg).astype(np.int64)

    def bin_hrirs(self, bins) -> np.ndarray:
        """HRIRs (n, 2, n_taps) of lateral-angle bins from :meth:`direction_bins`."""
        phi = np.deg2rad(np.asarray(bins, dtype=float) * self.bin_deg - 90.0)
        return self.hrirs_from_lateral(phi)


def _resample(x: np.ndarray, fs_from: float, fs_to: float, axis: int = -1) -> np.ndarray:
    if fs_from == fs_to:
        return x
    r = Fraction(float(fs_to) / float(fs_from)).limit_denominator(1000)
    return resample_poly(x, r.numerator, r.denominator, axis=axis)


@dataclass(frozen=True)
class MeasuredHrirs:
    """A measured set of HRIR pairs at known directions, resampled to ``fs_hz``.

    Attributes
    ----------
    directions_head : ndarray, shape (M, 3)
        Unit vectors of the measured source directions in the head frame.
    hrir : ndarray, shape (M, 2, N)
        Impulse responses at ``fs_hz``, ear 0 = left, ear 1 = right.
    fs_hz : float
        Sampling rate of ``hrir`` [Hz].
    name : str
        Where it came from.
    horizontal_only : bool
        The set holds only horizontal-plane directions; other directions are
        binned by their horizontal projection (azimuth only).
    """

    directions_head: np.ndarray
    hrir: np.ndarray
    fs_hz: float
    name: str = "measured HRIRs"
    horizontal_only: bool = False

    def __post_init__(self) -> None:
        d = _unit_directions(self.directions_head)
        h = np.asarray(self.hrir, dtype=float)
        if h.ndim != 3 or h.shape[:2] != (len(d), 2):
            raise ValueError(f"hrir must have shape ({len(d)}, 2, N), got {h.shape}")
        if not np.isfinite(h).all():
            raise ValueError("hrir has non-finite entries")
        object.__setattr__(self, "directions_head", d)
        object.__setattr__(self, "hrir", h)

    @classmethod
    def from_sofa(cls, path, fs_hz: float = 16000.0) -> "MeasuredHrirs":
        """Read a SimpleFreeFieldHRIR SOFA file with ``sofar`` (receiver 0 = left ear) and resample.

        Parameters
        ----------
        path : path-like
            Local SOFA file (nothing is downloaded).
        fs_hz : float
            Target sampling rate [Hz].
        """
        import sofar

        path = Path(path)
        if not path.is_file():
            raise ValueError(f"SOFA file {path} does not exist")
        sofa = sofar.read_sofa(str(path), verify=False, verbose=False)
        ir = np.asarray(sofa.Data_IR, dtype=float)
        if ir.ndim != 3 or ir.shape[1] != 2:
            raise ValueError(f"{path}: Data.IR must have shape (M, 2, N), got {ir.shape}")
        pos = np.asarray(sofa.SourcePosition, dtype=float)
        if "spherical" not in str(sofa.SourcePosition_Type).lower():
            raise ValueError(f"{path}: SourcePosition_Type {sofa.SourcePosition_Type!r} is not spherical")
        dirs = directions_from_azimuth_elevation(np.deg2rad(pos[:, 0]), np.deg2rad(pos[:, 1]))
        fs_src = float(np.ravel(sofa.Data_SamplingRate)[0])
        return cls(dirs, _resample(ir, fs_src, fs_hz), float(fs_hz), name=path.name)

    @classmethod
    def from_ku100_npz(cls, path, fs_hz: float = 16000.0, source_fs_hz: float = 48000.0) -> "MeasuredHrirs":
        """Read the KU 100 circular set (``hrir`` (360, 2, 128), ``azimuths`` deg; 48 kHz) and resample."""
        path = Path(path)
        if not path.is_file():
            raise ValueError(f"KU 100 npz {path} does not exist")
        with np.load(path) as z:
            ir = np.asarray(z["hrir"], dtype=float)
            az = np.deg2rad(np.asarray(z["azimuths"], dtype=float))
        return cls(directions_from_azimuth_elevation(az), _resample(ir, source_fs_hz, fs_hz), float(fs_hz),
                   name=path.name, horizontal_only=True)

    def direction_bins(self, directions_head) -> np.ndarray:
        """Index (K,) int64 of the nearest measured direction (by angle) of unit directions (K, 3)."""
        d = _unit_directions(directions_head)
        ref = self.directions_head
        if self.horizontal_only:
            d = d.copy()
            d[:, 2] = 0.0
            n = np.linalg.norm(d, axis=1, keepdims=True)
            d = np.where(n > 1e-9, d / np.maximum(n, 1e-12), np.array([1.0, 0.0, 0.0]))
        out = np.empty(len(d), dtype=np.int64)
        for s in range(0, len(d), 4096):  # bounded memory for many image sources
            out[s : s + 4096] = np.argmax(d[s : s + 4096] @ ref.T, axis=1)
        return out

    def bin_hrirs(self, bins) -> np.ndarray:
        """HRIRs (n, 2, N) of measured directions ``bins``."""
        return self.hrir[np.asarray(bins, dtype=np.int64)]
