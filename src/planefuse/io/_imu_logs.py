"""Stand-alone IMU logs: a BROAD trial (HDF5), an x-io Fusion CSV, or planefuse's own IMU CSV.

:func:`read_imu_log` turns any of them into one :class:`ImuLog` in SI units (s, rad/s, m/s^2), with the
reference attitude where the file has one. Formats:

* **BROAD** (``.hdf5``/``.h5``): root datasets ``imu_gyr`` [rad/s] and ``imu_acc`` [m/s^2] (N, 3), attribute
  ``sampling_rate`` [Hz]; optional ``opt_quat`` (N, 4) [w, x, y, z] of the IMU frame in a z-up (ENU) frame,
  NaN rows where the optical markers were lost (kept and counted), and ``movement`` (N,) bool, the samples to
  score.
* **x-io** (``.csv``): header ``Time (s),Gyroscope X (deg/s),..,Accelerometer X (g),..[,Magnetometer ..]``
  (the Fusion library's example format); converted from deg/s and g.
* **planefuse** (``.csv``): header ``time_s,gyro_x_rad_s,gyro_y_rad_s,gyro_z_rad_s,accel_x_m_s2,accel_y_m_s2,
  accel_z_m_s2`` (a recording's ``imu/<name>.csv``, :data:`IMU_COLUMNS`), optionally followed by
  ``ref_qw,ref_qx,ref_qy,ref_qz`` (reference attitude of the IMU frame in a z-up frame; empty or NaN where
  unknown) and then optionally ``scored`` (1 = score this sample, 0 = not).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

from ._streams import IMU_COLUMNS

__all__ = ["ImuLog", "read_imu_log", "IMU_REFERENCE_COLUMNS", "XIO_COLUMNS"]

#: Optional reference-attitude columns of planefuse's IMU CSV (quaternion [w, x, y, z], IMU -> z-up frame).
IMU_REFERENCE_COLUMNS = ["ref_qw", "ref_qx", "ref_qy", "ref_qz"]
#: The first seven columns of an x-io Fusion CSV.
XIO_COLUMNS = ["Time (s)", "Gyroscope X (deg/s)", "Gyroscope Y (deg/s)", "Gyroscope Z (deg/s)",
               "Accelerometer X (g)", "Accelerometer Y (g)", "Accelerometer Z (g)"]

_G_M_S2 = 9.80665
_BROAD_DATASETS = ("imu_gyr", "imu_acc")


@dataclass(frozen=True)
class ImuLog:
    """IMU samples of one file in SI units, IMU (sensor) frame, with an optional reference attitude.

    Attributes
    ----------
    path : Path
    kind : str
        ``"BROAD HDF5"``, ``"x-io CSV"`` or ``"planefuse CSV"``.
    time_s : ndarray, shape (N,)
        Sample times [s].
    gyro_rad_s : ndarray, shape (N, 3)
        Angular rate [rad/s].
    accel_m_s2 : ndarray, shape (N, 3)
        Specific force [m/s^2] (about +9.81 on the up axis at rest).
    R_ref_gravity_imu : ndarray, shape (N, 3, 3), or None
        Reference attitude (IMU axes in a z-up frame) where the file has one; NaN rows where the reference
        was lost (never dropped).
    scored : ndarray, shape (N,) bool, or None
        Samples the file marks for scoring (BROAD ``movement``); None: all.
    """

    path: Path
    kind: str
    time_s: np.ndarray
    gyro_rad_s: np.ndarray
    accel_m_s2: np.ndarray
    R_ref_gravity_imu: np.ndarray | None = None
    scored: np.ndarray | None = None

    def __len__(self) -> int:
        return len(self.time_s)

    @property
    def n_reference_missing(self) -> int:
        """Samples whose reference attitude is NaN (0 without a reference)."""
        if self.R_ref_gravity_imu is None:
            return 0
        return int(np.isnan(self.R_ref_gravity_imu).any(axis=(1, 2)).sum())


def _rotations_from_wxyz(q_wxyz: np.ndarray, where: str) -> np.ndarray:
    """(N, 3, 3) rotations of [w, x, y, z] quaternions; NaN rows stay NaN; other bad rows raise."""
    q = np.asarray(q_wxyz, dtype=float)
    lost = np.isnan(q).any(axis=1)
    norm = np.linalg.norm(q[~lost], axis=1)
    bad = np.flatnonzero(~np.isfinite(norm) | (np.abs(norm - 1.0) > 0.01))
    if bad.size:
        k = int(np.flatnonzero(~lost)[bad[0]])
        raise ValueError(f"{where}: reference quaternion of row {k} has norm {np.linalg.norm(q[k]):.4g}, not 1 "
                         f"({bad.size} such rows)")
    R = np.full((len(q), 3, 3), np.nan)
    if (~lost).any():
        R[~lost] = Rotation.from_quat(q[~lost][:, [1, 2, 3, 0]]).as_matrix()
    return R


def _check_units(path: Path, kind: str, gyro_rad_s: np.ndarray, accel_m_s2: np.ndarray,
                 accel_unit: str, gyro_unit: str) -> None:
    """Reject data whose magnitudes say another unit than the format's (g vs m/s^2, deg/s vs rad/s)."""
    g_norm = float(np.median(np.linalg.norm(accel_m_s2, axis=1)))
    if not 3.0 < g_norm < 30.0:
        raise ValueError(f"{path}: median accelerometer norm is {g_norm:.3g} m/s^2 after reading it as "
                         f"{accel_unit} ({kind}); gravity is 9.81 m/s^2: the accelerometer column is in another unit")
    w = float(np.median(np.linalg.norm(gyro_rad_s, axis=1)))
    if w > 20.0:
        raise ValueError(f"{path}: median gyroscope norm is {w:.3g} rad/s after reading it as {gyro_unit} ({kind}); "
                         f"that is {np.degrees(w):.0f} deg/s all the time: the gyroscope column is in another unit")


def _read_broad(path: Path) -> ImuLog:
    import h5py

    try:
        f = h5py.File(path, "r")
    except OSError as err:
        raise ValueError(f"{path}: not a readable HDF5 file ({err})") from None
    with f:
        names = sorted(f.keys())
        missing = [d for d in _BROAD_DATASETS if d not in f]
        if missing or "sampling_rate" not in f.attrs:
            raise ValueError(f"{path}: not a BROAD trial: needs root datasets imu_gyr, imu_acc and the attribute "
                             f"sampling_rate; it holds datasets {names} and attributes {sorted(f.attrs)}")
        fs_hz = float(np.ravel(f.attrs["sampling_rate"])[0])
        gyr = np.asarray(f["imu_gyr"][:], dtype=float)
        acc = np.asarray(f["imu_acc"][:], dtype=float)
        q = np.asarray(f["opt_quat"][:], dtype=float) if "opt_quat" in f else None
        movement = np.asarray(f["movement"][:]).astype(bool) if "movement" in f else None
    n = len(gyr)
    for name, a in (("imu_gyr", gyr), ("imu_acc", acc), ("opt_quat", q), ("movement", movement)):
        if a is not None and len(a) != n:
            raise ValueError(f"{path}: {name} has {len(a)} rows, imu_gyr has {n}")
    if not np.isfinite(fs_hz) or fs_hz <= 0:
        raise ValueError(f"{path}: sampling_rate must be a positive number of Hz, got {fs_hz}")
    _check_units(path, "BROAD HDF5", gyr, acc, "m/s^2", "rad/s")
    R = None if q is None else _rotations_from_wxyz(q, f"{path} opt_quat")
    return ImuLog(path, "BROAD HDF5", np.arange(n) / fs_hz, gyr, acc, R, movement)


def _numeric_rows(path: Path, n_columns: int) -> np.ndarray:
    try:
        d = np.genfromtxt(path, delimiter=",", skip_header=1, dtype=float, invalid_raise=True, ndmin=2)
    except ValueError as err:
        raise ValueError(f"{path}: malformed CSV row ({' '.join(str(err).split())[:120]})") from None
    if d.size == 0:
        raise ValueError(f"{path}: no samples after the header")
    if d.shape[1] != n_columns:
        raise ValueError(f"{path}: rows have {d.shape[1]} values, the header {n_columns}")
    return d


def _read_csv(path: Path) -> ImuLog:
    with open(path, newline="", errors="replace") as fh:
        header = fh.readline().strip()
    cols = [c.strip() for c in header.split(",")]
    if cols[:7] == XIO_COLUMNS:
        d = _numeric_rows(path, len(cols))
        t, gyr, acc = d[:, 0], np.radians(d[:, 1:4]), d[:, 4:7] * _G_M_S2
        _check_units(path, "x-io CSV", gyr, acc, "g", "deg/s")
        return ImuLog(path, "x-io CSV", t, gyr, acc)
    if cols[:7] == IMU_COLUMNS and cols[7:] in ([], IMU_REFERENCE_COLUMNS, IMU_REFERENCE_COLUMNS + ["scored"]):
        d = _numeric_rows(path, len(cols))
        t, gyr, acc = d[:, 0], d[:, 1:4], d[:, 4:7]
        _check_units(path, "planefuse CSV", gyr, acc, "m/s^2", "rad/s")
        R = _rotations_from_wxyz(d[:, 7:11], f"{path} ref_q*") if len(cols) >= 11 else None
        scored = None
        if len(cols) == 12:
            s = d[:, 11]
            if not np.isin(s, (0.0, 1.0)).all():
                raise ValueError(f"{path}: column 'scored' must hold 0 or 1, got {np.unique(s[~np.isin(s, (0, 1))])[:5]}")
            scored = s.astype(bool)
        return ImuLog(path, "planefuse CSV", t, gyr, acc, R, scored)
    raise ValueError(
        f"{path}: unknown IMU CSV header {header[:160]!r}; expected planefuse's "
        f"{','.join(IMU_COLUMNS)}[,{','.join(IMU_REFERENCE_COLUMNS)}[,scored]] or x-io's {','.join(XIO_COLUMNS)},...")


def read_imu_log(path) -> ImuLog:
    """Read a BROAD HDF5 trial, an x-io Fusion CSV or a planefuse IMU CSV (see the module docstring).

    Raises
    ------
    ValueError
        A folder or a missing file, another file type, a CSV of unknown columns, an HDF5 file without the
        BROAD datasets, malformed rows, reference quaternions that are not unit, accelerometer or gyroscope
        magnitudes of another unit (g read as m/s^2, deg/s read as rad/s); the message names the file and
        what it holds. Time stamps are checked by :func:`planefuse.geometry.attitude_from_imu`.
    """
    path = Path(path)
    if path.is_dir():
        found = sorted(p.name for p in path.iterdir() if p.suffix.lower() in (".hdf5", ".h5", ".csv"))
        raise ValueError(f"{path} is a folder; give one IMU file (IMU-like files in it: {found or 'none'})")
    if not path.is_file():
        raise ValueError(f"{path}: file not found")
    suffix = path.suffix.lower()
    if suffix in (".hdf5", ".h5"):
        return _read_broad(path)
    if suffix == ".csv":
        return _read_csv(path)
    raise ValueError(f"{path}: unknown IMU file type {suffix or '(no suffix)'!r}; expected a BROAD .hdf5/.h5 "
                     "trial or a .csv (x-io Fusion or planefuse columns)")
