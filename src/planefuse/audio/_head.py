"""Head models: how a sound arriving from a direction reaches the two ears.

Head frame ``{head}``: x forward, y left, z up, origin at the centre of the head;
the ears sit on the y axis (left ear at +y). Azimuth is counter-clockwise seen
from above, 0 = straight ahead, +pi/2 = the listener's left (SOFA convention).
The *lateral angle* ``asin(d_y)`` of a unit direction ``d`` is what a pair of
ears on the y axis can measure: azimuths ``theta`` and ``pi - theta`` (front and
back) share it (the cone of confusion).

Every head model answers three questions for the simulator and the calibration:

* ``render_impulses(directions_head, delay_samples, gain)`` -- the two-ear sum of
  the head-related impulse responses (HRIRs, ear 0 = left, ear 1 = right, one
  bulk delay) of impulses arriving from unit directions (K, 3): a room response;
* ``direction_bins(directions_head)`` / ``bin_hrirs(bins)`` -- integer bins of
  directions that share one HRIR, and the HRIRs (n, 2, n_taps) of those bins;
* ``rendered_directions(directions_head)`` -- the directions whose HRIRs render
  the given ones.

:class:`SphericalHead` is analytic (Woodworth ITD + Brown-Duda head shadow);
:class:`MeasuredHrirs` holds a measured set (SOFA file via ``sofar`` or the
KU 100 circular npz), resampled to ``fs_hz``. Between measured directions it
interpolates (onset-aligned, barycentric on the triangulated sphere of directions,
or linear in azimuth for a horizontal set) or, if asked, snaps to the nearest one;
``rendered_directions`` says which direction a head really renders. Sparse sets and
old SOFA files are reported with an :class:`HrirWarning`.
"""

from __future__ import annotations

import warnings
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
    "HrirWarning",
    "HRIR_INTERPOLATIONS",
    "lateral_from_azimuth",
    "directions_from_azimuth_elevation",
]

#: Speed of sound used throughout [m/s] (pyroomacoustics' default constant).
SPEED_OF_SOUND_M_S = 343.0
#: Radius of an average adult head [m] (Brown & Duda 1998).
HEAD_RADIUS_M = 0.0875
#: How :class:`MeasuredHrirs` renders a direction between measured ones; the first is the default.
HRIR_INTERPOLATIONS = ("barycentric", "nearest")
#: Horizontal-plane gap between measured directions above which a measured set is reported [deg].
SPARSE_GAP_DEG = 6.0


class HrirWarning(UserWarning):
    """A measured HRIR set is sparse (directions rendered between or snapped to measured ones) or its file is
    of an older convention version."""


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

    def render_impulses(self, directions_head, delay_samples, gain) -> np.ndarray:
        """Sum of the HRIRs of impulses from ``directions_head`` (K, 3), delayed by ``delay_samples`` (K,) int
        and scaled by ``gain`` (K,), shape (2, max(delay) + n_taps); one HRIR per lateral-angle bin."""
        delay = np.asarray(delay_samples, dtype=np.int64).reshape(-1)
        bins, which = np.unique(self.direction_bins(directions_head), return_inverse=True)
        return _sum_of_delayed(self.bin_hrirs(bins), which, delay, np.asarray(gain, float).reshape(-1),
                               int(delay.max()) + self.n_taps)

    def rendered_directions(self, directions_head) -> np.ndarray:
        """Unit directions (K, 3) whose HRIRs render ``directions_head`` (K, 3): same lateral-angle bin, in the
        plane of the direction and the ear axis."""
        d = _unit_directions(directions_head)
        phi = np.deg2rad(self.direction_bins(d) * self.bin_deg - 90.0)
        rest = d.copy()
        rest[:, 1] = 0.0
        n = np.linalg.norm(rest, axis=1, keepdims=True)
        rest = np.where(n > 1e-12, rest / np.maximum(n, 1e-12), np.array([1.0, 0.0, 0.0]))
        return np.cos(phi)[:, None] * rest + np.sin(phi)[:, None] * np.array([0.0, 1.0, 0.0])


def _resample(x: np.ndarray, fs_from: float, fs_to: float, axis: int = -1) -> np.ndarray:
    if fs_from == fs_to:
        return x
    r = Fraction(float(fs_to) / float(fs_from)).limit_denominator(1000)
    return resample_poly(x, r.numerator, r.denominator, axis=axis)


def _onsets_samples(h: np.ndarray, up: int = 8, threshold: float = 0.25) -> np.ndarray:
    """Onset (..., ) [samples, 1/up resolution] of each response: first crossing of ``threshold`` x its peak."""
    a = np.abs(resample_poly(h, up, 1, axis=-1))
    first = np.argmax(a >= threshold * a.max(axis=-1, keepdims=True), axis=-1)
    return first / up


def _horizontal_gap_deg(directions: np.ndarray) -> tuple[float, float, float]:
    """Largest azimuth gap (gap, from, to) [deg] between measured directions within 1 deg of the horizontal
    plane; (360, nan, nan) without any."""
    horizontal = np.abs(directions[:, 2]) < np.sin(np.deg2rad(1.0))
    az = np.sort(np.unique(np.round(np.rad2deg(np.arctan2(directions[horizontal, 1],
                                                             directions[horizontal, 0])) % 360.0, 6)))
    if az.size == 0:
        return 360.0, float("nan"), float("nan")
    gaps = np.diff(np.r_[az, az[0] + 360.0])
    k = int(np.argmax(gaps))
    return float(gaps[k]), float(az[k]), float((az[k] + gaps[k]) % 360.0)


def _signed_deg(a: float) -> float:
    return (a + 180.0) % 360.0 - 180.0


@dataclass(frozen=True)
class MeasuredHrirs:
    """A measured set of HRIR pairs at known directions, resampled to ``fs_hz``.

    A direction between measured ones is rendered, with ``interpolation="barycentric"`` (default), by
    interpolating the onset-aligned HRIRs of the measured directions around it (the three corners of its
    triangle on the convex hull of the directions, or the two azimuth neighbours of a horizontal set) with
    barycentric weights and delaying the result by the interpolated onset of each ear, so that the ITD moves
    smoothly instead of jumping at the midpoints; directions are first quantised to ``grid_deg``. With
    ``interpolation="nearest"`` the nearest measured direction is rendered. :meth:`rendered_directions` says
    which direction that is. A set whose horizontal-plane directions are more than ``SPARSE_GAP_DEG`` apart
    emits an :class:`HrirWarning` when it is built.

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
        rendered by their horizontal projection (azimuth only).
    interpolation : {"barycentric", "nearest"}
    grid_deg : float
        Azimuth/elevation quantisation of interpolated directions [deg].
    """

    directions_head: np.ndarray
    hrir: np.ndarray
    fs_hz: float
    name: str = "measured HRIRs"
    horizontal_only: bool = False
    interpolation: str = "barycentric"
    grid_deg: float = 0.5

    def __post_init__(self) -> None:
        d = _unit_directions(self.directions_head)
        h = np.asarray(self.hrir, dtype=float)
        if h.ndim != 3 or h.shape[:2] != (len(d), 2):
            raise ValueError(f"hrir must have shape ({len(d)}, 2, N), got {h.shape}")
        if not np.isfinite(h).all():
            raise ValueError("hrir has non-finite entries")
        if self.interpolation not in HRIR_INTERPOLATIONS:
            raise ValueError(f"interpolation must be one of {HRIR_INTERPOLATIONS}, got {self.interpolation!r}")
        if not (np.isfinite(self.grid_deg) and 0 < self.grid_deg <= 5.0):
            raise ValueError(f"grid_deg must be in (0, 5] deg, got {self.grid_deg}")
        object.__setattr__(self, "directions_head", d)
        object.__setattr__(self, "hrir", h)
        planar = self.horizontal_only or bool(np.all(np.abs(d[:, 2]) < 1e-6))
        object.__setattr__(self, "_planar", planar)
        if self.interpolation == "barycentric":
            self._prepare_interpolation()
        gap, lo, hi = _horizontal_gap_deg(d)
        if gap > SPARSE_GAP_DEG:
            where = "no measured direction in the horizontal plane" if not np.isfinite(lo) else \
                f"measured horizontal-plane directions up to {gap:.0f} deg apart " \
                f"(none between {_signed_deg(lo):+.0f} and {_signed_deg(hi):+.0f} deg azimuth)"
            how = "HRIRs in between are interpolated, not measured" if self.interpolation == "barycentric" else \
                f"sources in between are rendered at the nearest measured direction, up to {gap / 2:.0f} deg away"
            warnings.warn(f"{self.name}: {where}; {how}", HrirWarning, stacklevel=3)

    def _prepare_interpolation(self) -> None:
        """Onsets, onset-aligned spectra and (3-D sets) the triangulated sphere of directions."""
        n = self.hrir.shape[-1]
        n_fft = 2 * int(2 ** np.ceil(np.log2(n)))
        onsets = _onsets_samples(self.hrir)  # (M, 2)
        ref = float(onsets.min())
        w = 2 * np.pi * np.fft.rfftfreq(n_fft)  # [rad/sample]
        aligned = np.fft.rfft(self.hrir, n_fft, axis=-1) * np.exp(1j * w * (onsets - ref)[..., None])
        object.__setattr__(self, "_onsets", onsets)
        object.__setattr__(self, "_onset_ref", ref)
        object.__setattr__(self, "_omega", w)
        object.__setattr__(self, "_aligned", aligned)
        object.__setattr__(self, "_n_fft", n_fft)
        facets = None
        if not self._planar:
            from scipy.spatial import ConvexHull, QhullError, cKDTree

            try:
                tri = ConvexHull(self.directions_head).simplices
                A_inv = np.linalg.inv(np.transpose(self.directions_head[tri], (0, 2, 1)))  # columns: corners
            except (QhullError, np.linalg.LinAlgError) as err:
                raise ValueError(f"{self.name}: measured directions cannot be triangulated ({err}); "
                                 "use interpolation='nearest'") from None
            # facets around each vertex (padded with -1): the facet a ray crosses nearly always has one of the
            # ray's nearest vertices as a corner, so only those facets are tested (all of them otherwise)
            per_vertex = [[] for _ in range(len(self.directions_head))]
            for f, corners in enumerate(tri):
                for v in corners:
                    per_vertex[v].append(f)
            # large facets (spanning an unmeasured cap, e.g. below the lowest elevation) are tested for every ray
            corners = self.directions_head[tri]  # (F, 3, 3)
            edge_cos = np.einsum("fij,fij->fi", corners, np.roll(corners, 1, axis=1)).min(axis=1)
            edge_rad = np.arccos(np.clip(edge_cos, -1.0, 1.0))
            large = np.flatnonzero(edge_rad > 3.0 * np.median(edge_rad))[:256]
            width = max(len(x) for x in per_vertex)
            around = np.full((len(per_vertex), width), -1, dtype=np.int64)
            for v, fs in enumerate(per_vertex):
                around[v, : len(fs)] = fs
            facets = (tri, A_inv, around, large, cKDTree(self.directions_head))
        object.__setattr__(self, "_facets", facets)
        # onset-aligned responses in the time domain, delayed by a common lead so that every shift back is
        # causal: used by render_impulses
        lead = int(np.ceil((onsets - ref).max()))
        aligned_ir = np.fft.irfft(aligned * np.exp(-1j * w * lead), n_fft, axis=-1)[..., : n + lead]
        object.__setattr__(self, "_aligned_ir", aligned_ir)
        object.__setattr__(self, "_lead", lead)

    def _interpolation_weights(self, d: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Indices (K, 3) of measured directions and their weights (K, 3) (summing to 1) for unit ``d``."""
        K = len(d)
        idx = np.zeros((K, 3), dtype=np.int64)
        wts = np.zeros((K, 3))
        if self._planar:
            ref = np.arctan2(self.directions_head[:, 1], self.directions_head[:, 0])
            order = np.argsort(ref)
            a = ref[order]
            q = np.arctan2(d[:, 1], d[:, 0])
            pos = np.searchsorted(a, q)
            i0, i1 = (pos - 1) % len(a), pos % len(a)
            span = (a[i1] - a[i0]) % (2 * np.pi)
            span = np.where(span > 0, span, 2 * np.pi)
            t = ((q - a[i0]) % (2 * np.pi)) / span
            idx[:, 0], idx[:, 1] = order[i0], order[i1]
            wts[:, 0], wts[:, 1] = 1.0 - t, t
            return idx, wts
        tri, A_inv, around, large, tree = self._facets
        for s in range(0, K, 4096):
            q = d[s : s + 4096]
            k_q = len(q)
            _, near = tree.query(q, k=min(3, len(self.directions_head)))
            cand = np.concatenate([around[np.asarray(near).reshape(k_q, -1)].reshape(k_q, -1),
                                   np.broadcast_to(large, (k_q, len(large)))], axis=1)  # (k, C), -1: padding
            lam = np.einsum("kcij,kj->kci", A_inv[np.maximum(cand, 0)], q)  # (k, C, 3)
            ok = (lam.min(axis=-1) >= -1e-9) & (cand >= 0)
            best = np.argmax(np.where(ok, lam.sum(axis=-1), -np.inf), axis=1)
            rows = np.arange(k_q)
            f, lf = cand[rows, best], lam[rows, best]
            miss = np.flatnonzero(~ok[rows, best])  # the crossed facet has none of the 3 nearest vertices
            for m in range(0, len(miss), 256):  # (e.g. large facets over an unmeasured cap): test every facet
                km = miss[m : m + 256]
                lam_all = np.einsum("fij,kj->kfi", A_inv, q[km])
                fa = np.argmax(np.where(lam_all.min(axis=-1) >= -1e-9, lam_all.sum(axis=-1), -np.inf), axis=1)
                f[km], lf[km] = fa, lam_all[np.arange(len(km)), fa]
            lf = np.clip(lf, 0.0, None)
            idx[s : s + 4096] = tri[f]
            wts[s : s + 4096] = lf / lf.sum(axis=1, keepdims=True)
        return idx, wts

    def hrirs_at(self, directions_head) -> np.ndarray:
        """HRIRs (K, 2, N) rendering unit directions (K, 3) as :attr:`interpolation` says (no quantisation)."""
        d = _unit_directions(directions_head)
        if self.horizontal_only:
            d = _horizontal(d)
        if self.interpolation == "nearest":
            return self.hrir[self._nearest(d)]
        n = self.hrir.shape[-1]
        out = np.empty((len(d), 2, n))
        for s in range(0, len(d), 512):
            idx, wts = self._interpolation_weights(d[s : s + 512])
            onset = np.einsum("kj,kje->ke", wts, self._onsets[idx])  # (k, 2)
            H = np.einsum("kj,kjef->kef", wts, self._aligned[idx])
            H *= np.exp(-1j * self._omega * (onset - self._onset_ref)[..., None])
            out[s : s + 512] = np.fft.irfft(H, self._n_fft, axis=-1)[..., :n]
        return out

    def render_impulses(self, directions_head, delay_samples, gain, half_kernel: int = 16) -> np.ndarray:
        """Sum of the HRIRs of impulses from ``directions_head`` (K, 3), delayed by ``delay_samples`` (K,) int
        and scaled by ``gain`` (K,): ``sum_k gain_k h(d_k)(t - delay_k)``, shape (2, max(delay) + N).

        Every HRIR is rendered as :attr:`interpolation` says, without quantising directions (the cost grows
        with the number of measured directions involved, not with K): with ``"barycentric"`` the impulses are
        collected per measured direction and ear with their weights and fractional onset shifts (windowed-sinc
        kernels of ``2 half_kernel`` taps), then convolved with the onset-aligned responses.
        """
        d = _unit_directions(directions_head)
        delay = np.asarray(delay_samples, dtype=np.int64).reshape(-1)
        g = np.asarray(gain, dtype=float).reshape(-1)
        if not (len(delay) == len(g) == len(d)) or len(d) == 0:
            raise ValueError(f"directions_head, delay_samples and gain must have one row per impulse (K >= 1), "
                             f"got {len(d)}, {len(delay)}, {len(g)}")
        if delay.min() < 0:
            raise ValueError(f"delay_samples must be >= 0, got {delay.min()}")
        n = self.hrir.shape[-1]
        n_out = int(delay.max()) + n
        if self.horizontal_only:
            d = _horizontal(d)
        if self.interpolation == "nearest":
            bins, which = np.unique(self._nearest(d), return_inverse=True)
            return _sum_of_delayed(self.hrir[bins], which, delay, g, n_out)
        idx, wts = self._interpolation_weights(d)
        used, slot = np.unique(idx, return_inverse=True)
        slot = slot.reshape(idx.shape)
        # fractional position of each (impulse, corner, ear) in its train, offset so that every kernel tap
        # lands at index >= 0; the aligned responses carry self._lead samples of lead
        shift = np.einsum("kj,kje->ke", wts, self._onsets[idx]) - self._onset_ref - self._lead  # (K, 2)
        offset = self._lead + half_kernel
        pos = delay[:, None] + shift + offset
        n0 = np.floor(pos).astype(np.int64)
        frac = pos - n0
        taps = np.arange(-half_kernel + 1, half_kernel + 1)
        x = taps - frac[..., None]  # (K, 2, T)
        kernel = np.sinc(x) * 0.5 * (1.0 + np.cos(np.pi * np.clip(x / half_kernel, -1.0, 1.0)))
        n_len = n_out + offset + half_kernel + self._lead + 1
        trains = np.zeros(len(used) * 2 * n_len)
        ear = np.arange(2)
        for s in range(0, len(d), 8192):  # bounded memory: (k, 3 corners, 2 ears, taps) entries per block
            sl = slice(s, s + 8192)
            flat = ((slot[sl, :, None, None] * 2 + ear[None, None, :, None]) * n_len
                    + n0[sl, None, :, None] + taps)
            weight = (wts[sl] * g[sl, None])[:, :, None, None] * kernel[sl, None, :, :]
            trains += np.bincount(flat.ravel(), weight.ravel(), minlength=trains.size)
        trains = trains.reshape(len(used), 2, n_len)
        return _convolve_sum(trains, self._aligned_ir[used])[:, offset : offset + n_out]

    def _nearest(self, d: np.ndarray) -> np.ndarray:
        out = np.empty(len(d), dtype=np.int64)
        for s in range(0, len(d), 4096):  # bounded memory for many image sources
            out[s : s + 4096] = np.argmax(d[s : s + 4096] @ self.directions_head.T, axis=1)
        return out

    def _grid_shape(self) -> tuple[int, int]:
        return int(round(360.0 / self.grid_deg)), int(round(180.0 / self.grid_deg)) + 1

    def direction_bins(self, directions_head) -> np.ndarray:
        """Bins (K,) int64 of unit directions (K, 3): the index of the nearest measured direction
        (``"nearest"``), or of the ``grid_deg`` azimuth/elevation cell (``"barycentric"``)."""
        d = _unit_directions(directions_head)
        if self.horizontal_only:
            d = _horizontal(d)
        if self.interpolation == "nearest":
            return self._nearest(d)
        n_az, _ = self._grid_shape()
        az = np.rad2deg(np.arctan2(d[:, 1], d[:, 0]))
        el = np.rad2deg(np.arcsin(np.clip(d[:, 2], -1.0, 1.0)))
        ia = np.round(az / self.grid_deg).astype(np.int64) % n_az
        ie = np.round((el + 90.0) / self.grid_deg).astype(np.int64)
        return ie * n_az + ia

    def _bin_directions(self, bins) -> np.ndarray:
        b = np.asarray(bins, dtype=np.int64)
        if self.interpolation == "nearest":
            return self.directions_head[b]
        n_az, _ = self._grid_shape()
        return directions_from_azimuth_elevation(np.deg2rad((b % n_az) * self.grid_deg),
                                                 np.deg2rad((b // n_az) * self.grid_deg - 90.0))

    def bin_hrirs(self, bins) -> np.ndarray:
        """HRIRs (n, 2, N) of bins from :meth:`direction_bins`."""
        b = np.asarray(bins, dtype=np.int64)
        if self.interpolation == "nearest":
            return self.hrir[b]
        return self.hrirs_at(self._bin_directions(b))

    def rendered_directions(self, directions_head) -> np.ndarray:
        """Unit directions (K, 3) whose HRIRs :meth:`render_impulses` uses for ``directions_head`` (K, 3): the
        nearest measured direction (``"nearest"``) or the direction itself (``"barycentric"``); horizontal sets
        render the horizontal projection."""
        d = _unit_directions(directions_head)
        if self.horizontal_only:
            d = _horizontal(d)
        return self.directions_head[self._nearest(d)] if self.interpolation == "nearest" else d

    @classmethod
    def from_sofa(cls, path, fs_hz: float = 16000.0, **kwargs) -> "MeasuredHrirs":
        """Read a SimpleFreeFieldHRIR SOFA file with ``sofar`` (receiver 0 = left ear) and resample.

        A file of a convention version before 1.0 (e.g. CIPIC's 0.4) is read the same way and reported by an
        :class:`HrirWarning`; other ``sofar`` warnings are passed on as one-line :class:`HrirWarning`. A non-zero
        ``Data.Delay`` [samples] is applied (prepended).

        Parameters
        ----------
        path : path-like
            Local SOFA file (nothing is downloaded).
        fs_hz : float
            Target sampling rate [Hz].
        **kwargs
            ``interpolation``, ``grid_deg``.
        """
        import sofar

        path = Path(path)
        if not path.is_file():
            raise ValueError(f"SOFA file {path} does not exist")
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            try:
                sofa = sofar.read_sofa(str(path), verify=False, verbose=False)
            except (OSError, ValueError, KeyError, TypeError) as err:
                raise ValueError(f"{path}: not a readable SOFA file ({' '.join(str(err).split())[:160]})") from None
        convention = str(getattr(sofa, "GLOBAL_SOFAConventions", "?"))
        version = str(getattr(sofa, "GLOBAL_SOFAConventionsVersion", "?"))
        if "HRIR" not in convention or "FIR" not in str(getattr(sofa, "GLOBAL_DataType", "FIR")):
            raise ValueError(f"{path}: SOFA convention {convention!r} holds no HRIRs; expected SimpleFreeFieldHRIR")
        for w in caught:
            text = " ".join(str(w.message).split())
            if "conventions version" in text.lower():
                continue
            warnings.warn(f"{path.name}: sofar: {text[:200]}", HrirWarning, stacklevel=2)
        try:
            old = float(version.split(".")[0]) < 1.0
        except ValueError:
            old = True
        if old:
            warnings.warn(f"{path.name}: SOFA conventions version {version} (preliminary, before AES69 1.0); "
                          f"read as {convention}: Data.IR, SourcePosition, Data.SamplingRate", HrirWarning,
                          stacklevel=2)
        ir = np.asarray(sofa.Data_IR, dtype=float)
        if ir.ndim != 3 or ir.shape[1] != 2:
            raise ValueError(f"{path}: Data.IR must have shape (M, 2, N), got {ir.shape}")
        delay = np.broadcast_to(np.asarray(getattr(sofa, "Data_Delay", 0.0), dtype=float), ir.shape[:2])
        if np.any(delay != 0):
            if np.any(delay < 0) or np.any(delay != np.round(delay)):
                raise ValueError(f"{path}: Data.Delay must hold whole non-negative samples, got {np.unique(delay)[:5]}")
            n_pad = int(delay.max())
            shifted = np.zeros(ir.shape[:2] + (ir.shape[2] + n_pad,))
            for m, e in np.ndindex(*ir.shape[:2]):
                k = int(delay[m, e])
                shifted[m, e, k : k + ir.shape[2]] = ir[m, e]
            ir = shifted
        pos = np.asarray(sofa.SourcePosition, dtype=float)
        if "spherical" not in str(sofa.SourcePosition_Type).lower():
            raise ValueError(f"{path}: SourcePosition_Type {sofa.SourcePosition_Type!r} is not spherical")
        dirs = directions_from_azimuth_elevation(np.deg2rad(pos[:, 0]), np.deg2rad(pos[:, 1]))
        fs_src = float(np.ravel(sofa.Data_SamplingRate)[0])
        return cls(dirs, _resample(ir, fs_src, fs_hz), float(fs_hz), name=path.name, **kwargs)

    @classmethod
    def from_ku100_npz(cls, path, fs_hz: float = 16000.0, source_fs_hz: float = 48000.0,
                       **kwargs) -> "MeasuredHrirs":
        """Read the KU 100 circular set (``hrir`` (360, 2, 128), ``azimuths`` deg; 48 kHz) and resample.

        ``kwargs``: ``interpolation``, ``grid_deg``.
        """
        path = Path(path)
        if not path.is_file():
            raise ValueError(f"KU 100 npz {path} does not exist")
        try:
            with np.load(path) as z:
                ir = np.asarray(z["hrir"], dtype=float)
                az = np.deg2rad(np.asarray(z["azimuths"], dtype=float))
        except (OSError, ValueError, KeyError) as err:
            raise ValueError(f"{path}: not a KU 100 npz with 'hrir' and 'azimuths' ({err})") from None
        return cls(directions_from_azimuth_elevation(az), _resample(ir, source_fs_hz, fs_hz), float(fs_hz),
                   name=path.name, horizontal_only=True, **kwargs)


def _convolve_sum(trains: np.ndarray, responses: np.ndarray) -> np.ndarray:
    """``sum_j trains[j, e] * responses[j, e]`` (full linear convolution), trains (J, 2 or 1, A), responses
    (J, 2, B) -> (2, A + B - 1); chunked over J to bound the memory of the spectra."""
    n_full = trains.shape[-1] + responses.shape[-1] - 1
    n_fft = int(2 ** np.ceil(np.log2(n_full)))
    spectrum = np.zeros((2, n_fft // 2 + 1), dtype=complex)
    chunk = max(1, 2**22 // n_fft)
    for s in range(0, len(trains), chunk):
        spectrum += np.sum(np.fft.rfft(trains[s : s + chunk], n_fft, axis=-1)
                           * np.fft.rfft(responses[s : s + chunk], n_fft, axis=-1), axis=0)
    return np.fft.irfft(spectrum, n_fft, axis=-1)[:, :n_full]


def _sum_of_delayed(responses: np.ndarray, which: np.ndarray, delay: np.ndarray, gain: np.ndarray,
                    n_out: int) -> np.ndarray:
    """``sum_k gain_k responses[which_k](t - delay_k)`` (2, n_out): one impulse train per response."""
    n_train = int(delay.max()) + 1
    trains = np.bincount(which * n_train + delay, weights=gain, minlength=len(responses) * n_train)
    return _convolve_sum(trains.reshape(len(responses), 1, n_train), responses)[:, :n_out]


def _horizontal(d: np.ndarray) -> np.ndarray:
    """Unit directions projected on the horizontal plane (straight up/down -> straight ahead)."""
    d = d.copy()
    d[:, 2] = 0.0
    n = np.linalg.norm(d, axis=1, keepdims=True)
    return np.where(n > 1e-9, d / np.maximum(n, 1e-12), np.array([1.0, 0.0, 0.0]))
