"""Laser range finder models: 2-D scanner, 2-D scanner on a tilting (nodding) unit, scans.

Frames (all right-handed, metres):

* {S} -- the 2-D scanner's own frame (ROS convention): x forward, y left, z up; beam ``i``
  lies in the scanner's x-y plane at angle ``angle_min_rad + i * angle_increment_rad``
  counter-clockwise from +x: ``p_S = r (cos a, sin a, 0)``.
* {L} -- the laser *unit* (base) frame: x forward, y left, z up. The tilt axis is the
  y axis of {L} through its origin. The scanner's optical centre sits at
  ``offset_tilt_scanner_m`` in the tilting frame {T} (which coincides with {L} at tilt 0),
  and {S} is rotated in {T} by ``R_tilt_scanner``:

      p_L = Ry(tilt) (R_tilt_scanner p_S + offset_tilt_scanner_m)

  with ``Ry(tilt)`` the right-handed rotation about +y, so a positive tilt pitches the
  scan plane *down* in front of the unit (x is rotated towards -z). This is the model of
  the seed's ref. [7] (a 2-D LRF on a tilt unit forming a 3-D scanner) with the
  mechanical offsets as parameters; a plain 2-D scanner is the same with tilt 0 and no
  offset.
* {W} -- the world: ``p_W = T_world_laser p_L``.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np
from numba import njit

from ..geometry._checks import check_rotation, check_transform

__all__ = [
    "LaserScannerSpec",
    "TiltingUnit",
    "tilting_unit_from_device",
    "LaserScan",
    "R_y",
    "points_laser_from_scan",
    "points_world_from_scan",
    "origins_world_from_scan",
    "scans_from_arrays",
]


@dataclass(frozen=True)
class LaserScannerSpec:
    """A 2-D laser range finder: beam layout, range limits and range noise.

    Attributes
    ----------
    angle_min_rad : float
        Angle of the first beam in the scanner frame [rad], counter-clockwise from +x.
    angle_increment_rad : float
        Angular step between consecutive beams [rad] (> 0).
    n_beams : int
        Number of beams per scan.
    range_min_m, range_max_m : float
        Valid range interval [m]; returns outside it are invalid / no return.
    range_noise_sigma_m : float
        Standard deviation of the additive Gaussian range noise [m].
    name : str
        Device name.
    """

    angle_min_rad: float
    angle_increment_rad: float
    n_beams: int
    range_min_m: float
    range_max_m: float
    range_noise_sigma_m: float = 0.0
    name: str = "lrf"

    def __post_init__(self) -> None:
        for f in ("angle_min_rad", "angle_increment_rad", "range_min_m", "range_max_m", "range_noise_sigma_m"):
            if not np.isfinite(getattr(self, f)):
                raise ValueError(f"LaserScannerSpec.{f} must be finite, got {getattr(self, f)}")
        if self.angle_increment_rad <= 0:
            raise ValueError(f"angle_increment_rad must be > 0, got {self.angle_increment_rad}")
        if int(self.n_beams) < 1:
            raise ValueError(f"n_beams must be >= 1, got {self.n_beams}")
        if not 0 <= self.range_min_m < self.range_max_m:
            raise ValueError(f"need 0 <= range_min_m < range_max_m, got {self.range_min_m}, {self.range_max_m}")
        if self.range_noise_sigma_m < 0:
            raise ValueError(f"range_noise_sigma_m must be >= 0, got {self.range_noise_sigma_m}")
        object.__setattr__(self, "n_beams", int(self.n_beams))

    @classmethod
    def hokuyo_utm30lx(cls, range_noise_sigma_m: float = 0.01) -> "LaserScannerSpec":
        """Hokuyo UTM-30LX: 270 deg field of view, 0.25 deg steps, 1081 beams, 0.1-30 m.

        The data sheet gives +-30 mm accuracy up to 10 m; sigma 10 mm is the default.
        """
        inc = np.deg2rad(0.25)
        return cls(-np.deg2rad(135.0), float(inc), 1081, 0.1, 30.0, range_noise_sigma_m, "hokuyo_utm30lx")

    @classmethod
    def sick_lms200(cls, range_noise_sigma_m: float = 0.01) -> "LaserScannerSpec":
        """SICK LMS-200 as in the CARMEN logs: 180 deg field of view, 1 deg steps, 181 beams, 80 m."""
        return cls(-np.pi / 2, float(np.deg2rad(1.0)), 181, 0.0, 80.0, range_noise_sigma_m, "sick_lms200")

    @property
    def angles_rad(self) -> np.ndarray:
        """Beam angles (n_beams,) [rad] in the scanner frame."""
        return self.angle_min_rad + self.angle_increment_rad * np.arange(self.n_beams)

    @property
    def fov_rad(self) -> float:
        """Angular span from the first to the last beam [rad]."""
        return self.angle_increment_rad * (self.n_beams - 1)


def R_y(angle_rad) -> np.ndarray:
    """Right-handed rotation(s) about +y, shape (..., 3, 3), for angle(s) [rad]."""
    a = np.asarray(angle_rad, dtype=float)
    c, s = np.cos(a), np.sin(a)
    R = np.zeros(a.shape + (3, 3))
    R[..., 0, 0] = c
    R[..., 0, 2] = s
    R[..., 1, 1] = 1.0
    R[..., 2, 0] = -s
    R[..., 2, 2] = c
    return R


@dataclass(frozen=True)
class TiltingUnit:
    """A 2-D scanner mounted on a tilt (nodding) unit: together a 3-D scanner.

    Attributes
    ----------
    scanner : LaserScannerSpec
        The 2-D scanner.
    offset_tilt_scanner_m : tuple of 3 float
        Scanner optical centre in the tilting frame {T} [m] (its offset from the tilt axis).
    R_tilt_scanner : ndarray (3, 3)
        Mounting rotation of the scanner frame in {T} (identity: scan plane = x-y plane of {T}).
    tilt_min_rad, tilt_max_rad : float
        Nodding range [rad] (used by the sweep helpers; positive tilts look down).
    tilt_period_s : float
        Period of one full nod (down and back up) [s].
    """

    scanner: LaserScannerSpec
    offset_tilt_scanner_m: tuple[float, float, float] = (0.0, 0.0, 0.0)
    R_tilt_scanner: np.ndarray = field(default_factory=lambda: np.eye(3))
    tilt_min_rad: float = 0.0
    tilt_max_rad: float = 0.0
    tilt_period_s: float = 2.0

    def __post_init__(self) -> None:
        off = np.asarray(self.offset_tilt_scanner_m, dtype=float).reshape(-1)
        if off.shape != (3,) or not np.isfinite(off).all():
            raise ValueError(f"offset_tilt_scanner_m must be 3 finite numbers [m], got {self.offset_tilt_scanner_m}")
        object.__setattr__(self, "offset_tilt_scanner_m", tuple(float(v) for v in off))
        R = check_rotation(self.R_tilt_scanner, "R_tilt_scanner")
        R.setflags(write=False)
        object.__setattr__(self, "R_tilt_scanner", R)
        if not (np.isfinite(self.tilt_min_rad) and np.isfinite(self.tilt_max_rad)) or self.tilt_min_rad > self.tilt_max_rad:
            raise ValueError(f"need finite tilt_min_rad <= tilt_max_rad, got {self.tilt_min_rad}, {self.tilt_max_rad}")
        if not self.tilt_period_s > 0:
            raise ValueError(f"tilt_period_s must be > 0, got {self.tilt_period_s}")

    @classmethod
    def fixed(cls, scanner: LaserScannerSpec) -> "TiltingUnit":
        """A plain 2-D scanner: no tilt, no offset (the unit frame is the scanner frame)."""
        return cls(scanner)

    def tilt_at(self, time_s) -> np.ndarray:
        """Tilt angle(s) [rad] of a triangle-wave nod at ``time_s`` [s] (starts at ``tilt_min_rad``)."""
        t = np.asarray(time_s, dtype=float)
        phase = np.mod(t / self.tilt_period_s, 1.0)
        tri = 1.0 - np.abs(2.0 * phase - 1.0)  # 0 -> 1 -> 0 over one period
        return self.tilt_min_rad + (self.tilt_max_rad - self.tilt_min_rad) * tri

    def T_laser_scanner(self, tilt_rad) -> np.ndarray:
        """``T_laser_scanner`` (..., 4, 4): scanner frame {S} into the unit frame {L} at tilt(s) [rad]."""
        Ry = R_y(tilt_rad)
        T = np.zeros(Ry.shape[:-2] + (4, 4))
        T[..., :3, :3] = Ry @ self.R_tilt_scanner
        T[..., :3, 3] = Ry @ np.asarray(self.offset_tilt_scanner_m)
        T[..., 3, 3] = 1.0
        return T


def tilting_unit_from_device(device: Mapping) -> TiltingUnit:
    """The :class:`TiltingUnit` of a recording's laser device entry (``model`` of a laser in ``scene.yaml``,
    :class:`planefuse.io.LaserUnitDevice` as a mapping): ``scanner`` (the :class:`LaserScannerSpec` fields),
    ``offset_tilt_scanner_m``, ``tilt_min_rad``, ``tilt_max_rad``, ``tilt_period_s``."""
    try:
        return TiltingUnit(LaserScannerSpec(**device["scanner"]), tuple(device["offset_tilt_scanner_m"]),
                           tilt_min_rad=device["tilt_min_rad"], tilt_max_rad=device["tilt_max_rad"],
                           tilt_period_s=device["tilt_period_s"])
    except (KeyError, TypeError) as exc:
        raise ValueError(f"laser device entry lacks or mistypes a field: {exc}") from None


@dataclass(frozen=True)
class LaserScan:
    """One scan of a 2-D scanner (possibly on a tilting unit), as measured.

    Attributes
    ----------
    time_s : float
        Time stamp [s].
    angles_rad : ndarray (N,)
        Beam angles in the scanner frame [rad].
    ranges_m : ndarray (N,)
        Measured ranges [m]. ``inf`` marks "no return within range_max_m" (max-range
        reading); NaN, 0 or negative values are invalid returns. Use
        :attr:`no_return` / :attr:`valid` rather than testing values yourself.
    tilt_rad : ndarray (N,)
        Tilt of the unit for every beam [rad] (0 for a fixed 2-D scanner).
    range_min_m, range_max_m : float
        Valid range interval of the device [m].
    T_world_laser : ndarray (4, 4) or None
        Pose of the unit frame in the world at this scan, if known.
    """

    time_s: float
    angles_rad: np.ndarray
    ranges_m: np.ndarray
    tilt_rad: np.ndarray
    range_min_m: float
    range_max_m: float
    T_world_laser: np.ndarray | None = None

    def __post_init__(self) -> None:
        a = np.asarray(self.angles_rad, dtype=float).reshape(-1)
        r = np.asarray(self.ranges_m, dtype=float).reshape(-1)
        if a.shape != r.shape:
            raise ValueError(f"LaserScan: angles_rad has {a.size} beams but ranges_m has {r.size}")
        if not np.isfinite(a).all():
            raise ValueError("LaserScan: angles_rad has non-finite entries")
        tilt = np.broadcast_to(np.asarray(self.tilt_rad, dtype=float), a.shape).copy()
        if not np.isfinite(tilt).all():
            raise ValueError("LaserScan: tilt_rad has non-finite entries")
        if not 0 <= self.range_min_m < self.range_max_m:
            raise ValueError(f"LaserScan: need 0 <= range_min_m < range_max_m, got {self.range_min_m}, {self.range_max_m}")
        object.__setattr__(self, "angles_rad", a)
        object.__setattr__(self, "ranges_m", r)
        object.__setattr__(self, "tilt_rad", tilt)
        if self.T_world_laser is not None:
            object.__setattr__(self, "T_world_laser", check_transform(self.T_world_laser, "T_world_laser"))

    def __len__(self) -> int:
        return self.ranges_m.size

    @property
    def no_return(self) -> np.ndarray:
        """(N,) bool: max-range readings (``inf`` or ``>= range_max_m``)."""
        with np.errstate(invalid="ignore"):
            return self.ranges_m >= self.range_max_m

    @property
    def valid(self) -> np.ndarray:
        """(N,) bool: real returns, ``range_min_m <= r < range_max_m`` (0 means no return in ROS)."""
        r = self.ranges_m
        with np.errstate(invalid="ignore"):
            return (r >= max(self.range_min_m, np.finfo(float).tiny)) & (r < self.range_max_m)

    @property
    def invalid(self) -> np.ndarray:
        """(N,) bool: neither valid nor max range (NaN, 0, negative, below range_min_m)."""
        return ~(self.valid | self.no_return)


def _as_beams(angles_rad, ranges_m, tilt_rad) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    a = np.asarray(angles_rad, dtype=float)
    r = np.asarray(ranges_m, dtype=float)
    if a.shape != r.shape:
        raise ValueError(f"angles_rad {a.shape} and ranges_m {r.shape} must have the same shape (one per beam)")
    if not np.isfinite(a).all():
        raise ValueError("angles_rad has non-finite entries")
    t = np.asarray(tilt_rad, dtype=float)
    try:
        t = np.broadcast_to(t, a.shape)
    except ValueError:
        raise ValueError(f"tilt_rad {t.shape} does not broadcast to the beams {a.shape}") from None
    if not np.isfinite(t).all():
        raise ValueError("tilt_rad has non-finite entries")
    return a, r, t


def points_laser_from_scan(angles_rad, ranges_m, tilt_rad=0.0, unit: TiltingUnit | None = None) -> np.ndarray:
    """3-D points in the unit frame {L} from beams (scan angle, tilt angle, range).

    Parameters
    ----------
    angles_rad : array_like (..., N)
        Beam angles in the scanner frame [rad].
    ranges_m : array_like (..., N)
        Ranges [m]; non-finite ranges give non-finite points (filter with
        :attr:`LaserScan.valid` first if needed).
    tilt_rad : float or array_like broadcastable to (..., N)
        Tilt angle of the unit per beam [rad].
    unit : TiltingUnit, optional
        Mechanical model; default: no offset, identity mounting.

    Returns
    -------
    ndarray (..., N, 3)
        ``p_L = Ry(tilt) (R_tilt_scanner r (cos a, sin a, 0) + offset)`` [m].
    """
    a, r, t = _as_beams(angles_rad, ranges_m, tilt_rad)
    p_S = np.stack([r * np.cos(a), r * np.sin(a), np.zeros_like(r)], axis=-1)
    if unit is None:
        p_T = p_S
    else:
        p_T = p_S @ unit.R_tilt_scanner.T + np.asarray(unit.offset_tilt_scanner_m)
    c, s = np.cos(t), np.sin(t)
    x = c * p_T[..., 0] + s * p_T[..., 2]
    z = -s * p_T[..., 0] + c * p_T[..., 2]
    return np.stack([x, p_T[..., 1], z], axis=-1)


def _apply_pose(T_world_laser, p_L: np.ndarray) -> np.ndarray:
    """``T_world_laser`` (4, 4) or per-beam (..., N, 4, 4) applied to ``p_L`` (..., N, 3)."""
    T = check_transform(T_world_laser, "T_world_laser")
    if T.ndim == 2:
        return p_L @ T[:3, :3].T + T[:3, 3]
    try:
        np.broadcast_shapes(T.shape[:-2], p_L.shape[:-1])
    except ValueError:
        raise ValueError(f"T_world_laser batch {T.shape[:-2]} does not match the beams {p_L.shape[:-1]}") from None
    return np.einsum("...ij,...j->...i", T[..., :3, :3], p_L) + T[..., :3, 3]


@njit(cache=True)
def _beams_world_kernel(angles, tilt, R_ts, off, T, o_out, d_out):
    for i in range(angles.shape[0]):
        ca, sa = np.cos(angles[i]), np.sin(angles[i])
        ct, st = np.cos(tilt[i]), np.sin(tilt[i])
        # direction and origin in the tilting frame
        dx = R_ts[0, 0] * ca + R_ts[0, 1] * sa
        dy = R_ts[1, 0] * ca + R_ts[1, 1] * sa
        dz = R_ts[2, 0] * ca + R_ts[2, 1] * sa
        # Ry(tilt): x' = c x + s z, z' = -s x + c z
        lx, ly, lz = ct * dx + st * dz, dy, -st * dx + ct * dz
        ox, oy, oz = ct * off[0] + st * off[2], off[1], -st * off[0] + ct * off[2]
        for k in range(3):
            d_out[i, k] = T[k, 0] * lx + T[k, 1] * ly + T[k, 2] * lz
            o_out[i, k] = T[k, 0] * ox + T[k, 1] * oy + T[k, 2] * oz + T[k, 3]


def _beams_world(angles_rad, tilt_rad, T: np.ndarray, unit: TiltingUnit | None):
    """:func:`origins_world_from_scan` for a ``T`` that :func:`check_transform` has already accepted."""
    a, _, t = _as_beams(angles_rad, np.zeros_like(np.asarray(angles_rad, dtype=float)), tilt_rad)
    R_ts = np.eye(3) if unit is None else unit.R_tilt_scanner
    off = np.zeros(3) if unit is None else np.asarray(unit.offset_tilt_scanner_m)
    if T.ndim == 2 and a.ndim == 1:  # the common case, one fused loop
        o_W = np.empty((a.size, 3))
        d_W = np.empty((a.size, 3))
        _beams_world_kernel(a, np.ascontiguousarray(t), np.ascontiguousarray(R_ts), off,
                            np.ascontiguousarray(T), o_W, d_W)
        return o_W, d_W
    # per-beam poses (moving platform): vectorised numpy
    d_T = np.stack([np.cos(a), np.sin(a), np.zeros_like(a)], axis=-1) @ R_ts.T
    od = np.stack(np.broadcast_arrays(off, d_T))  # Ry(tilt) applied to origins and directions together
    c, s = np.cos(t), np.sin(t)
    od_L = np.stack([c * od[..., 0] + s * od[..., 2], od[..., 1], -s * od[..., 0] + c * od[..., 2]], axis=-1)
    o_W = _apply_pose(T, od_L[0])
    d_W = np.einsum("...ij,...j->...i", T[..., :3, :3], od_L[1])
    return o_W, d_W


def origins_world_from_scan(angles_rad, tilt_rad, T_world_laser, unit: TiltingUnit | None = None):
    """Beam origins and unit directions in {W} for every beam.

    Parameters
    ----------
    angles_rad : array_like (N,)
        Beam angles in the scanner frame [rad].
    tilt_rad : float or array_like (N,)
        Tilt per beam [rad].
    T_world_laser : array_like (4, 4) or (N, 4, 4)
        Unit pose, for the scan or per beam.
    unit : TiltingUnit, optional
        Mechanical model.

    Returns
    -------
    origins_W : ndarray (N, 3)
        Scanner optical centre per beam [m] (depends on tilt when the unit has an offset).
    directions_W : ndarray (N, 3)
        Unit beam directions in {W}; the beam's point at range r is ``origins_W + r directions_W``.
    """
    return _beams_world(angles_rad, tilt_rad, check_transform(T_world_laser, "T_world_laser"), unit)


def points_world_from_scan(angles_rad, ranges_m, tilt_rad, T_world_laser, unit: TiltingUnit | None = None) -> np.ndarray:
    """3-D points in {W}: ``p_W = T_world_laser p_L`` for every beam.

    Parameters
    ----------
    angles_rad, ranges_m : array_like (N,)
        Beam angles [rad] and ranges [m] (non-finite ranges give non-finite points).
    tilt_rad : float or array_like (N,)
        Tilt per beam [rad].
    T_world_laser : array_like (4, 4) or (N, 4, 4)
        Unit pose in the world, one for the scan or one per beam (moving platform).
    unit : TiltingUnit, optional
        Mechanical model.

    Returns
    -------
    ndarray (N, 3)
        World points [m].
    """
    return _apply_pose(T_world_laser, points_laser_from_scan(angles_rad, ranges_m, tilt_rad, unit))


def scans_from_arrays(times_s, angles_rad, ranges_m, tilt_rad, T_world_laser, range_min_m: float, range_max_m: float,
                      *, nan_is_no_return: bool = True) -> list[LaserScan]:
    """:class:`LaserScan` objects from stacked arrays (e.g. ``planefuse.io.LaserScans`` of a recording).

    Parameters
    ----------
    times_s : array_like (S,)
        Scan times [s].
    angles_rad : array_like (B,)
        Beam angles [rad].
    ranges_m : array_like (S, B)
        Ranges [m].
    tilt_rad : array_like (S,) or (S, B)
        Tilt per scan or per beam [rad].
    T_world_laser : array_like (4, 4) or (S, 4, 4)
        Unit pose, fixed or per scan.
    range_min_m, range_max_m : float
        Valid range interval of the device [m].
    nan_is_no_return : bool
        The recording format writes NaN for "no return within max range"; True maps NaN to
        ``inf`` (a max-range reading that frees space), False keeps NaN (an invalid return).

    Returns
    -------
    list of LaserScan
    """
    t = np.asarray(times_s, dtype=float).reshape(-1)
    a = np.asarray(angles_rad, dtype=float).reshape(-1)
    r = np.asarray(ranges_m, dtype=float)
    if r.shape != (t.size, a.size):
        raise ValueError(f"ranges_m must have shape (S, B) = {(t.size, a.size)}, got {r.shape}")
    tilt = np.asarray(tilt_rad, dtype=float)
    if tilt.shape not in ((t.size,), (t.size, a.size)):
        raise ValueError(f"tilt_rad must have shape (S,) or (S, B) = {(t.size, a.size)}, got {tilt.shape}")
    if tilt.ndim == 1:
        tilt = np.broadcast_to(tilt[:, None], r.shape)
    T = check_transform(T_world_laser, "T_world_laser")
    if T.ndim == 2:
        T = np.broadcast_to(T, (t.size, 4, 4))
    elif T.shape != (t.size, 4, 4):
        raise ValueError(f"T_world_laser must be (4, 4) or (S, 4, 4) = {(t.size, 4, 4)}, got {T.shape}")
    if nan_is_no_return:
        r = np.where(np.isnan(r), np.inf, r)
    scans = [LaserScan(float(t[k]), a, r[k], tilt[k], range_min_m, range_max_m) for k in range(t.size)]
    for scan, T_world_laser_k in zip(scans, T):  # checked above as one stack, not again scan by scan
        object.__setattr__(scan, "T_world_laser", T_world_laser_k)
    return scans
