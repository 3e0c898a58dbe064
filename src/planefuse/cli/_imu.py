"""``planefuse imu attitude FILE``: attitude filters on a real IMU log, inclination scored where possible."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import typer

from ._app import app, console, exit_with_error, units_table, write_json

imu_app = typer.Typer(help="Real IMU logs: attitude relative to gravity and its accuracy.", no_args_is_help=True)
app.add_typer(imu_app, name="imu")


def _fmt(x: float, digits: int) -> str:
    return "-" if not np.isfinite(x) else f"{x:.{digits}f}"


@imu_app.command("attitude")
def attitude(
    path: Path = typer.Argument(..., help="IMU log: a BROAD trial (.hdf5: imu_gyr [rad/s], imu_acc [m/s^2], "
                                "opt_quat, movement), an x-io Fusion CSV (Time (s), Gyroscope [deg/s], "
                                "Accelerometer [g]), or a planefuse CSV (time_s, gyro_*_rad_s, accel_*_m_s2 "
                                "[, ref_qw, ref_qx, ref_qy, ref_qz [, scored]])."),
    filters: list[str] = typer.Option(["imufusion"], "--filter", help="Attitude filter: imufusion (x-io Fusion, "
                                      "the default) or madgwick, mahony, ekf (ahrs); repeat it, or 'all'."),
    settle_s: float = typer.Option(5.0, help="Samples in the first settle_s seconds are not scored [s]."),
    json_out: Path = typer.Option(None, help="Write the scores (one entry per filter) as JSON here."),
    attitude_csv: Path = typer.Option(None, help="Write the first filter's attitude here: time_s, qw, qx, qy, qz "
                                      "(IMU frame in the z-up gravity frame; heading arbitrary)."),
) -> None:
    """Attitude relative to gravity from a real IMU log; inclination (roll/pitch) error [deg] against the file's
    reference attitude when it has one, and against the accelerometer while the device is still."""
    from ..eval import score_attitude
    from ..geometry import ATTITUDE_METHODS, attitude_from_imu
    from ..io import read_imu_log

    methods = list(ATTITUDE_METHODS) if "all" in filters else list(dict.fromkeys(filters))
    unknown = [m for m in methods if m not in ATTITUDE_METHODS]
    if unknown:
        exit_with_error(f"--filter {unknown[0]!r} unknown; choose from {', '.join(ATTITUDE_METHODS)} or all")
    scores, first_R = [], None
    try:
        log = read_imu_log(path)
        for method in methods:
            R = attitude_from_imu(log.time_s, log.gyro_rad_s, log.accel_m_s2, method=method)
            first_R = R if first_R is None else first_R
            scores.append(score_attitude(log, method, settle_s=settle_s, R_gravity_imu=R))
    except ValueError as err:
        exit_with_error(str(err))
    duration_s = float(log.time_s[-1] - log.time_s[0])
    ref = scores[0].reference
    title = (f"{path.name} ({log.kind}, {len(log)} samples, {duration_s:.1f} s); reference: {ref}"
             + (f" ({scores[0].n_reference_missing} NaN rows, not scored)" if ref != "none" else ""))
    rows = [(s.method, s.n_scored, _fmt(s.rmse_deg, 3), _fmt(s.p95_deg, 2), _fmt(s.max_deg, 2), s.n_rest,
             _fmt(s.rest_rms_deg, 3)) for s in scores]
    caption = ("RMSE, p95, max: inclination error against the reference" if ref != "none"
               else "no reference attitude in the file: only the at-rest error is scored") + \
        ("; still: samples at rest after settle_s, and the RMS angle of the estimated up direction to the "
         "accelerometer's there")
    console.print(units_table(title, ("filter", "scored", "RMSE [deg]", "p95 [deg]", "max [deg]", "still",
                                      "still [deg]"), rows, caption=caption))
    if attitude_csv:
        from scipy.spatial.transform import Rotation

        from ..outputs import atomic_write_text

        q_xyzw = Rotation.from_matrix(first_R).as_quat()
        rows_q = np.column_stack([log.time_s, q_xyzw[:, [3, 0, 1, 2]]])
        text = "time_s,qw,qx,qy,qz\n" + "\n".join(",".join(f"{v:.9g}" for v in r) for r in rows_q) + "\n"
        atomic_write_text(attitude_csv, text)
        console.print(f"wrote {attitude_csv} ({methods[0]})", highlight=False)
    if json_out:
        write_json(json_out, {"input": str(path), "kind": log.kind, "n_samples": len(log), "duration_s": duration_s,
                              "settle_s": settle_s, "filters": [s.as_dict() for s in scores]})
