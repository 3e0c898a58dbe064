"""Compare the attitude filters of :func:`planefuse.geometry.attitude_from_imu` on real IMU logs.

BROAD trials (optical ground truth): inclination RMSE over the movement phase.
x-io Fusion log (no ground truth): inclination difference to ``imufusion.Ahrs`` with default settings, and the
error against the accelerometer's gravity direction while the device is still.

Run: ``PYTHONPATH=src python scripts/compare_imu_filters.py [../shared/data]`` (about a minute on one core).
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

import h5py
import numpy as np
from scipy.spatial.transform import Rotation

from planefuse.geometry import ATTITUDE_METHODS, attitude_from_imu, inclination_error_rad

G = 9.80665


def rms(x) -> float:
    return float(np.sqrt(np.mean(np.square(x))))


def broad_rows(path: Path) -> list[str]:
    with h5py.File(path, "r") as f:
        fs_hz = float(f.attrs["sampling_rate"])
        gyr, acc, q = f["imu_gyr"][:], f["imu_acc"][:], f["opt_quat"][:]
        movement = f["movement"][:].astype(bool)
    nan_rows = np.isnan(q).any(axis=1)
    scored = movement & ~nan_rows
    R_true = Rotation.from_quat(q[scored][:, [1, 2, 3, 0]]).as_matrix()
    t = np.arange(len(gyr)) / fs_hz
    rows = []
    for method in ATTITUDE_METHODS:
        t0 = time.perf_counter()
        R = attitude_from_imu(t, gyr, acc, method=method)
        run_s = time.perf_counter() - t0
        e = np.degrees(inclination_error_rad(R[scored], R_true))
        rows.append(
            f"| {path.stem} | {method} | {rms(e):.3f} | {np.percentile(e, 95):.2f} | {e.max():.2f} | "
            f"{scored.sum()} ({nan_rows.sum()} NaN GT rows, {(nan_rows & movement).sum()} in movement) | {run_s:.1f} |"
        )
    return rows


def xio_rows(path: Path) -> list[str]:
    d = np.genfromtxt(path, delimiter=",", skip_header=1)
    t, gyr_deg_s, acc_g = d[:, 0], d[:, 1:4], d[:, 4:7]
    # imufusion.Ahrs with its own default settings (no gyro range, no acceleration rejection); the test
    # test_xio_inclination_agrees_with_imufusion drives imufusion directly and checks the same numbers.
    imufusion_defaults = dict(gyroscope_range_deg_s=0.0, acceleration_rejection_deg=0.0, rejection_timeout_s=0.0)
    R_ref = attitude_from_imu(t, np.radians(gyr_deg_s), acc_g * G, method="imufusion", params=imufusion_defaults)
    settled = t > 5.0
    still = settled & (np.linalg.norm(gyr_deg_s, axis=1) < 2.0) & (np.abs(np.linalg.norm(acc_g, axis=1) - 1) < 0.02)
    up_body = acc_g[still] / np.linalg.norm(acc_g[still], axis=1, keepdims=True)
    rows = []
    for method in ATTITUDE_METHODS:
        R = attitude_from_imu(t, np.radians(gyr_deg_s), acc_g * G, method=method)
        e = np.degrees(inclination_error_rad(R[settled], R_ref[settled]))
        rest = np.degrees(np.arccos(np.clip(np.einsum("nj,nj->n", R[still][:, 2, :], up_body), -1, 1)))
        rows.append(f"| {method} | {rms(e):.3f} | {np.percentile(e, 95):.2f} | {e.max():.1f} | {rms(rest):.3f} |")
    return rows


def main(data_root: Path) -> None:
    print("| trial | filter | inclination RMSE [deg] | p95 [deg] | max [deg] | scored samples | run time [s] |")
    print("|---|---|---|---|---|---|---|")
    for name in ("02_undisturbed_slow_rotation_B", "07_undisturbed_fast_rotation_B"):
        path = data_root / "imu_broad" / f"{name}.hdf5"
        if path.exists():
            print("\n".join(broad_rows(path)))
        else:
            print(f"| {name} | (file absent) | | | | | |")
    print()
    print("| filter | vs imufusion RMS [deg] | p95 [deg] | max [deg] | at rest vs accelerometer RMS [deg] |")
    print("|---|---|---|---|---|")
    print("\n".join(xio_rows(data_root / "imu_xio_fusion" / "sensor_data.csv")))


if __name__ == "__main__":
    root = Path(sys.argv[1]) if len(sys.argv) > 1 else Path(__file__).resolve().parents[2] / "shared" / "data"
    main(root)
