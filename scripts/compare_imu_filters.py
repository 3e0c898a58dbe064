"""Compare the attitude filters of :func:`planefuse.geometry.attitude_from_imu` on real IMU logs (docs/results.md).

Every IMU log given, or found under DATA_ROOT (``imu_broad/*.hdf5``, ``imu_xio_fusion/*.csv``), is read with
:func:`planefuse.io.read_imu_log` and scored with :func:`planefuse.eval.score_attitude`, as
``planefuse imu attitude FILE --filter all`` does. Logs with a reference attitude (BROAD): inclination error over
the scored samples. Logs without one (x-io): inclination difference to ``imufusion.Ahrs`` with its default
settings, and the error against the accelerometer while the device is still.

Run: ``PYTHONPATH=src python scripts/compare_imu_filters.py DATA_ROOT`` or ``... FILE [FILE ...]`` (about a
minute per log on one core).
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

from planefuse.eval import score_attitude
from planefuse.geometry import ATTITUDE_METHODS, attitude_from_imu
from planefuse.io import read_imu_log

# imufusion.Ahrs with its own default settings (no gyro range, no acceleration rejection, no offset tracking, no
# gain schedule); the test
# test_xio_inclination_agrees_with_imufusion drives imufusion directly and checks the same numbers.
IMUFUSION_OWN_DEFAULTS = dict(gyroscope_range_deg_s=0.0, acceleration_rejection_deg=0.0, rejection_timeout_s=0.0,
                              gyro_bias=False, rest_gain=0.0)


def imu_logs(paths: list[Path]) -> list[Path]:
    """The files given, with each folder expanded to the IMU logs of its imu_broad/ and imu_xio_fusion/."""
    out = []
    for p in paths:
        if p.is_dir():
            out += sorted((p / "imu_broad").glob("*.hdf5")) + sorted((p / "imu_xio_fusion").glob("*.csv"))
        else:
            out.append(p)
    return out


def rows_for(path: Path) -> tuple[str, list[str]]:
    log = read_imu_log(path)
    with_reference = log.R_ref_gravity_imu is not None
    R_ref = None if with_reference else attitude_from_imu(log.time_s, log.gyro_rad_s, log.accel_m_s2,
                                                          method="imufusion", params=IMUFUSION_OWN_DEFAULTS)
    rows = []
    for method in ATTITUDE_METHODS:
        t0 = time.perf_counter()
        R = attitude_from_imu(log.time_s, log.gyro_rad_s, log.accel_m_s2, method=method)
        run_s = time.perf_counter() - t0
        s = score_attitude(log, method, R_gravity_imu=R, R_reference=R_ref,
                           reference_name=None if with_reference else "imufusion defaults")
        if with_reference:
            rows.append(f"| {path.stem} | {method} | {s.rmse_deg:.3f} | {s.p95_deg:.2f} | {s.max_deg:.2f} | "
                        f"{s.n_scored} ({s.n_reference_missing} NaN reference rows) | {run_s:.1f} |")
        else:
            rows.append(f"| {path.stem} | {method} | {s.rmse_deg:.3f} | {s.p95_deg:.2f} | {s.max_deg:.1f} | "
                        f"{s.rest_rms_deg:.3f} ({s.n_rest} samples at rest) |")
    return ("with", rows) if with_reference else ("without", rows)


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("paths", nargs="+", type=Path, help="data root (holding imu_broad/, imu_xio_fusion/) or IMU files")
    args = ap.parse_args(argv)
    logs = imu_logs(args.paths)
    if not logs:
        raise SystemExit(f"no IMU log under {', '.join(map(str, args.paths))} (imu_broad/*.hdf5, imu_xio_fusion/*.csv)")
    tables: dict[str, list[str]] = {"with": [], "without": []}
    for path in logs:
        try:
            kind, rows = rows_for(path)
        except ValueError as err:
            raise SystemExit(f"error: {err}") from None
        tables[kind] += rows
    if tables["with"]:
        print("| log | filter | inclination RMSE [deg] | p95 [deg] | max [deg] | scored samples | run time [s] |")
        print("|---|---|---|---|---|---|---|")
        print("\n".join(tables["with"]))
        print()
    if tables["without"]:
        print("| log | filter | vs imufusion RMS [deg] | p95 [deg] | max [deg] | at rest vs accelerometer RMS [deg] |")
        print("|---|---|---|---|---|---|")
        print("\n".join(tables["without"]))


if __name__ == "__main__":
    main()
