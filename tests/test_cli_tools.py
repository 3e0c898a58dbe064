"""The real-data commands on the user's files: imu attitude, laser legs / camera-check, cameras epfl, calib-show.

Each command reproduces the docs/results.md numbers on ../shared/data and answers a file of the wrong kind, a
folder without the expected files, or another dataset of the same kind with a one-line error naming what it found.
Help texts and tables keep their units at 80 columns.
"""

from __future__ import annotations

import json
import re
import shutil

import h5py
import numpy as np
import pytest
from conftest import shared_data
from scipy.spatial.transform import Rotation
from typer.main import get_command
from typer.testing import CliRunner

from planefuse.cli import app
from planefuse.eval import score_attitude
from planefuse.geometry import attitude_from_imu, inclination_error_rad
from planefuse.io import IMU_COLUMNS, IMU_REFERENCE_COLUMNS, XIO_COLUMNS, read_imu_log

G = 9.80665


def invoke(args, width: int = 80):
    """Run the CLI at ``width`` columns; (exit code, output with whitespace runs joined)."""
    r = CliRunner(env={"COLUMNS": str(width)}).invoke(app, [str(a) for a in args], terminal_width=width)
    return r.exit_code, r.output


def one_line_error(output: str) -> str:
    """The command's error: exactly one non-empty line starting with 'error:'."""
    lines = [ln for ln in output.splitlines() if ln.strip()]
    assert len(lines) == 1 and lines[0].startswith("error: "), output
    return lines[0]


# --- units in help texts and tables -----------------------------------------------------------------------
UNIT_SUFFIXES = {"_m": "[m]", "_s": "[s]", "_deg": "[deg]", "_db": "[dB]", "_hz": "[Hz]", "_px": "[px]",
                 "_rad": "[rad]"}


def _commands():
    def walk(cmd, path):
        yield path, cmd
        for name, sub in getattr(cmd, "commands", {}).items():
            yield from walk(sub, path + [name])

    return list(walk(get_command(app), []))


@pytest.mark.parametrize("path", [p for p, _ in _commands()], ids=lambda p: " ".join(p) or "planefuse")
def test_every_help_text_shows_its_units_at_80_columns(path):
    cmd = dict((tuple(p), c) for p, c in _commands())[tuple(path)]
    code, out = invoke([*path, "--help"])
    assert code == 0, out
    rendered = " ".join(out.split())
    texts = [cmd.help or ""] + [getattr(p, "help", None) or "" for p in cmd.params]
    for text in texts:
        for unit in re.findall(r"\[[^\]\s]{1,8}\]", text):  # every [unit] written in a help text is printed
            assert unit in rendered, f"{' '.join(path)}: {unit} of {text!r} vanished from --help"
    for p in cmd.params:
        for suffix, unit in UNIT_SUFFIXES.items():
            if p.name.endswith(suffix) and not p.name.endswith("_m_s2"):
                assert unit in (p.help or ""), f"{' '.join(path)} --{p.name}: help does not say {unit}"
    assert max(len(line) for line in out.splitlines()) <= 80


def xio_csv(path, t, gyr_rad_s, acc_m_s2):
    rows = np.column_stack([t, np.degrees(gyr_rad_s), acc_m_s2 / G, np.zeros((len(t), 3))])
    header = ",".join(XIO_COLUMNS + ["Magnetometer X (uT)", "Magnetometer Y (uT)", "Magnetometer Z (uT)"])
    np.savetxt(path, rows, delimiter=",", header=header, comments="", fmt="%.10g")


def rocking_imu(n=1500, fs_hz=100.0):
    """Body rocking about a tilted axis: exact gyro [rad/s], specific force [m/s^2], R_gravity_imu."""
    t = np.arange(n) / fs_hz
    axis = np.array([1.0, 0.4, 0.2]) / np.linalg.norm([1.0, 0.4, 0.2])
    R = Rotation.from_euler("xyz", [0.3, -0.2, 1.0]) * Rotation.from_rotvec((0.5 * np.sin(0.4 * np.pi * t))[:, None] * axis)
    gyr = (0.2 * np.pi * np.cos(0.4 * np.pi * t))[:, None] * axis
    return t, gyr, R.inv().apply([0.0, 0.0, G]), R


def test_imu_attitude_scores_a_planefuse_csv_against_its_reference(tmp_path):
    t, gyr, acc, R = rocking_imu()
    q = R.as_quat()[:, [3, 0, 1, 2]]
    q[100:110] = np.nan  # reference lost: counted, not scored
    scored = (t >= 3.0).astype(float)
    p = tmp_path / "imu.csv"
    np.savetxt(p, np.column_stack([t, gyr, acc, q, scored]), delimiter=",", comments="", fmt="%.17g",
               header=",".join(IMU_COLUMNS + IMU_REFERENCE_COLUMNS + ["scored"]))
    out = tmp_path / "s.json"
    code, text = invoke(["imu", "attitude", p, "--filter", "madgwick", "--filter", "imufusion", "--settle-s", "1",
                         "--json-out", out, "--attitude-csv", tmp_path / "q.csv"])
    assert code == 0, text
    assert "RMSE [deg]" in text and "still [deg]" in text
    assert max(len(ln) for ln in text.splitlines() if not ln.startswith(("wrote", "("))) <= 80
    res = json.loads(out.read_text())
    mad = res["filters"][0]
    assert mad["n_reference_missing"] == 10 and mad["n_scored"] == int((t >= 3.0).sum())
    # independent reference: the filter run directly, the error computed over the same samples
    R_est = attitude_from_imu(t, gyr, acc, method="madgwick")
    sel = t >= 3.0
    e = np.degrees(inclination_error_rad(R_est[sel], R.as_matrix()[sel]))
    assert mad["rmse_deg"] == pytest.approx(np.sqrt(np.mean(e**2)), rel=1e-9) and mad["rmse_deg"] < 1.0
    q_out = np.genfromtxt(tmp_path / "q.csv", delimiter=",", names=True)
    assert q_out.dtype.names == ("time_s", "qw", "qx", "qy", "qz") and len(q_out) == len(t)


def test_imu_xio_and_planefuse_csv_are_the_same_data(tmp_path):
    t, gyr, acc, _ = rocking_imu(n=600)
    xio_csv(tmp_path / "x.csv", t, gyr, acc)
    np.savetxt(tmp_path / "p.csv", np.column_stack([t, gyr, acc]), delimiter=",", comments="", fmt="%.10g",
               header=",".join(IMU_COLUMNS))
    a, b = read_imu_log(tmp_path / "x.csv"), read_imu_log(tmp_path / "p.csv")
    assert a.kind == "x-io CSV" and b.kind == "planefuse CSV" and a.R_ref_gravity_imu is None
    np.testing.assert_allclose(a.gyro_rad_s, b.gyro_rad_s, rtol=1e-8, atol=1e-12)
    np.testing.assert_allclose(a.accel_m_s2, b.accel_m_s2, rtol=1e-8)
    s = score_attitude(a)
    assert s.reference == "none" and np.isnan(s.rmse_deg) and s.n_scored == 0


def test_imu_bad_inputs_name_what_they_found(tmp_path):
    t, gyr, acc, _ = rocking_imu(n=300)
    cases = {}
    (tmp_path / "other.csv").write_text("a,b,c\n1,2,3\n")
    cases["other.csv"] = "unknown IMU CSV header 'a,b,c'"
    xio_csv(tmp_path / "xio_in_ms2.csv", t, gyr, acc * G)  # accelerometer written in m/s^2 under a (g) header
    cases["xio_in_ms2.csv"] = "median accelerometer norm is 96.2 m/s^2 after reading it as g"
    np.savetxt(tmp_path / "deg.csv", np.column_stack([t, np.degrees(gyr) * 50, acc]), delimiter=",", comments="",
               header=",".join(IMU_COLUMNS))
    cases["deg.csv"] = "gyroscope column is in another unit"
    with h5py.File(tmp_path / "other.hdf5", "w") as f:
        f["acc"] = acc
    cases["other.hdf5"] = "not a BROAD trial: needs root datasets imu_gyr, imu_acc and the attribute sampling_rate; " \
                          "it holds datasets ['acc']"
    (tmp_path / "scan.bag").write_bytes(b"#ROSBAG V2.0\n")
    cases["scan.bag"] = "unknown IMU file type '.bag'"
    (tmp_path / "broken.h5").write_bytes(b"not hdf5")
    cases["broken.h5"] = "not a readable HDF5 file"
    back = np.column_stack([t, gyr, acc])
    back[5, 0] = back[4, 0]
    np.savetxt(tmp_path / "back.csv", back, delimiter=",", comments="", header=",".join(IMU_COLUMNS))
    cases["back.csv"] = "time_s must be strictly increasing"
    for name, want in cases.items():
        code, out = invoke(["imu", "attitude", tmp_path / name])
        assert code == 2, out
        line = one_line_error(out)
        assert want in line and (name in line or "time_s" in want), line
    code, out = invoke(["imu", "attitude", tmp_path])
    assert code == 2 and "is a folder; give one IMU file (IMU-like files in it: [" in one_line_error(out)
    code, out = invoke(["imu", "attitude", tmp_path / "other.csv", "--filter", "kalman"])
    assert code == 2 and "--filter 'kalman' unknown" in one_line_error(out)


@pytest.mark.realdata
def test_imu_attitude_on_broad_reproduces_the_docs(tmp_path):
    path = shared_data("imu_broad") / "02_undisturbed_slow_rotation_B.hdf5"
    code, out = invoke(["imu", "attitude", path, "--filter", "madgwick", "--filter", "imufusion",
                        "--json-out", tmp_path / "broad.json"])
    assert code == 0, out
    res = json.loads((tmp_path / "broad.json").read_text())
    mad, fus = res["filters"]
    # docs/results.md, IMU inclination, "BROAD 02 all": madgwick 0.606, imufusion (the default settings) 0.424
    assert round(mad["rmse_deg"], 3) == 0.606 and round(fus["rmse_deg"], 3) == 0.424
    assert mad["n_scored"] == 32280 and mad["n_reference_missing"] == 1706
    assert "1706 NaN rows, not scored" in " ".join(out.split())


@pytest.mark.realdata
def test_imu_attitude_on_xio_reproduces_the_docs():
    path = shared_data("imu_xio_fusion") / "sensor_data.csv"
    code, out = invoke(["imu", "attitude", path, "--filter", "madgwick", "--filter", "imufusion"])
    assert code == 0, out
    flat = " ".join(out.split())
    assert "reference: none" in flat and "only the at-rest error is scored" in flat
    # docs/results.md, IMU inclination, "x-io at rest" (7316 samples): 0.746 (madgwick), 0.728 (imufusion)
    assert re.search(r"madgwick .* 7316 .* 0\.746", flat) and re.search(r"imufusion .* 7316 .* 0\.728", flat)


def test_compare_imu_filters_on_a_root_holding_only_broad_trials(tmp_path, capsys):
    """Regression (issue 20): the script crashed on imu_xio_fusion/sensor_data.csv when a root held only BROAD."""
    import importlib.util
    from pathlib import Path

    spec = importlib.util.spec_from_file_location(
        "compare_imu_filters", Path(__file__).resolve().parents[1] / "scripts" / "compare_imu_filters.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    t, gyr, acc, R = rocking_imu(n=400, fs_hz=100.0)
    (tmp_path / "imu_broad").mkdir()
    with h5py.File(tmp_path / "imu_broad" / "99_synthetic.hdf5", "w") as f:
        f.attrs["sampling_rate"] = 100.0
        f["imu_gyr"], f["imu_acc"] = gyr, acc
        f["opt_quat"] = R.as_quat()[:, [3, 0, 1, 2]]
        f["movement"] = t >= 1.0
    mod.main([str(tmp_path)])
    out = capsys.readouterr().out
    assert out.count("| 99_synthetic |") == 4 and "vs imufusion" not in out
    (tmp_path / "empty").mkdir()
    with pytest.raises(SystemExit, match="no IMU log under"):
        mod.main([str(tmp_path / "empty")])
    with pytest.raises(SystemExit, match="nothing: file not found"):
        mod.main([str(tmp_path / "nothing")])


# --- laser ---------------------------------------------------------------------------------------------
@pytest.mark.realdata
def test_laser_legs_reproduces_the_docs(tmp_path):
    bag = shared_data("lrf2d_people_leg_tracker") / "positive_1_extracted.bag"
    code, out = invoke(["laser", "legs", bag, "--json-out", tmp_path / "legs.json"])
    assert code == 0, out
    assert max(len(ln) for ln in out.splitlines() if not ln.startswith("wrote")) <= 80
    res = json.loads((tmp_path / "legs.json").read_text())
    s = res["leg_scores"]
    assert (s["tp"], s["fp"], s["fn"]) == (323, 10, 1) and round(s["f1"], 3) == 0.983  # docs/results.md
    assert res["n_scans"] == 197 and len(res["scans"]) == 197


@pytest.mark.realdata
def test_laser_legs_bad_inputs_name_what_they_found(tmp_path):
    d = shared_data("lrf3d_camera_lcct")
    code, out = invoke(["laser", "legs", d])
    assert code == 2 and "is not a ROS 2 bag (no metadata.yaml); it holds ['Calib_Results.mat'" in one_line_error(out)
    code, out = invoke(["laser", "legs", d / "img_target1.jpg"])
    assert code == 2 and "img_target1.jpg is neither a ROS bag nor a CARMEN log" in one_line_error(out)
    bag = shared_data("lrf2d_people_leg_tracker") / "positive_1_extracted.bag"
    code, out = invoke(["laser", "legs", bag, "--labels-topic", "/scan_labels"])
    assert code == 2 and "/scan_labels" in one_line_error(out)


@pytest.mark.realdata
def test_laser_camera_check_reproduces_the_docs(tmp_path):
    d = shared_data("lrf3d_camera_lcct")
    code, out = invoke(["laser", "camera-check", d, "--transform", d / "T_camera_laser_stageII.yaml",
                        "--json-out", tmp_path / "lcct.json"])
    assert code == 0, out
    assert "[mm]" in out and "99.2 % of 3272" in out
    pairs = json.loads((tmp_path / "lcct.json").read_text())["pairs"]
    # docs/results.md, Real camera + laser: 3243 / 1.41 / 99.2 % of 3272 ... 3744 / 1.52 / 99.9 % of 3753
    got = {int(i): (r["n_in_hull"], round(1e3 * r["plane_distance_median_m"], 2),
                    round(100 * r["on_board_in_hull_fraction"], 1), r["n_on_board"]) for i, r in pairs.items()}
    assert got == {1: (3243, 1.41, 99.2, 3272), 2: (3387, 0.88, 99.3, 3425), 3: (2984, 0.92, 99.7, 3000),
                   4: (3744, 1.52, 99.9, 3753)}


@pytest.mark.realdata
def test_laser_camera_check_bad_inputs_name_what_they_found(tmp_path):
    d = shared_data("lrf3d_camera_lcct")
    code, out = invoke(["laser", "camera-check", d])  # two transforms: which one?
    assert code == 2 and "has 2 transform files (T_camera_laser*.yaml): ['T_camera_laser_stageI.yaml', " \
        "'T_camera_laser_stageII.yaml']" in one_line_error(out)
    code, out = invoke(["laser", "camera-check", shared_data("lrf2d_carmen")])
    assert code == 2 and "has 0 transform files" in one_line_error(out)
    code, out = invoke(["laser", "camera-check", d / "Calib_Results.mat"])
    assert code == 2 and "Calib_Results.mat is not a folder" in one_line_error(out)
    code, out = invoke(["laser", "camera-check", d, "--transform", d / "T_camera_laser_stageI.yaml",
                        "--pairs", "1,9"])
    assert code == 2 and "pairs [9] have no scan and board view; available: [1, 2, 3, 4]" in one_line_error(out)


# --- cameras epfl, calib-show ----------------------------------------------------------------------------
@pytest.fixture
def laboratory_like(tmp_path):
    """A folder holding another EPFL sequence (terrace files under laboratory6 names, 600 frames)."""
    src = shared_data("epfl_pom") / "EPFL-Terrace"
    for k in range(4):
        d = tmp_path / "EPFL-Laboratory" / f"laboratory6-c{k}"
        (d / "gt").mkdir(parents=True)
        shutil.copy(src / f"terrace1-c{k}" / "Homography.txt", d / "Homography.txt")
        rows = [r for r in (src / f"terrace1-c{k}" / "gt" / "gt.txt").read_text().splitlines()
                if int(r.split()[5]) < 600]
        (d / "gt" / "gt.txt").write_text("\n".join(rows) + "\n")
    return tmp_path


@pytest.mark.realdata
def test_cameras_epfl_names_the_sequences_a_folder_holds(laboratory_like, tmp_path):
    code, out = invoke(["cameras", "epfl", laboratory_like])
    assert code == 2
    assert one_line_error(out).endswith("no 'terrace1-c*/Homography.txt' camera folders; it holds laboratory6 "
                                        "(4 cameras)")
    code, out = invoke(["cameras", "epfl", laboratory_like, "--sequence", "laboratory6"])
    assert code == 2 and "give it in metres (ground_unit_m / --ground-unit-m)" in one_line_error(out)
    code, out = invoke(["cameras", "epfl", laboratory_like, "--sequence", "laboratory6", "--ground-unit-m",
                        "0.0219", "--step", "50", "--json-out", tmp_path / "lab.json"])
    assert code == 0, out
    assert "thr [m]" in out and max(len(ln) for ln in out.splitlines() if not ln.startswith("wrote")) <= 80
    scores = json.loads((tmp_path / "lab.json").read_text())
    assert scores[0]["frames"] == 12 and scores[1]["moda"] > 0.5
    code, out = invoke(["cameras", "epfl", shared_data("imu_broad")])
    assert code == 2 and "it holds no EPFL camera folder at all (entries: ['02_undisturbed" in one_line_error(out)


@pytest.mark.realdata
def test_calib_show_reads_every_calibration_kind(laboratory_like):
    flat = lambda out: " ".join(out.split())  # noqa: E731
    code, out = invoke(["calib-show", shared_data("epfl_pom") / "EPFL-Terrace" / "terrace1-c0" / "Homography.txt"])
    assert code == 0 and "world XY [m] (planefuse's terrace map" in flat(out)
    lab = laboratory_like / "EPFL-Laboratory" / "laboratory6-c0" / "Homography.txt"
    code, out = invoke(["calib-show", lab])
    assert code == 0 and "top-view units (the file's own" in flat(out)
    code, out = invoke(["calib-show", lab, "--metres-per-unit", "0.02"])
    assert code == 0 and "world XY [m] (0.02 m per unit)" in flat(out)
    code, out = invoke(["calib-show", shared_data("lrf3d_camera_lcct") / "Calib_Results.mat"])
    assert code == 0 and "640 x 480" in out and "board views" in out
    code, out = invoke(["calib-show", shared_data("wildtrack") / "extrinsic" / "extr_CVLab1.xml"])
    assert code == 0 and "1920 x 1080" in out and "centre in world [m]" in flat(out)
    code, out = invoke(["calib-show", shared_data("wildtrack") / "intrinsic" / "intr_CVLab1.xml"])
    assert code == 1 and "'image_width': missing; give --width-px and --height-px" in one_line_error(out)
    code, out = invoke(["calib-show", shared_data("imu_broad") / "02_undisturbed_slow_rotation_B.hdf5"])
    assert code == 1 and "unknown calibration file type '.hdf5'" in one_line_error(out)


# --- audio ------------------------------------------------------------------------------------------------
def test_audio_commands_name_a_wrong_file(tmp_path):
    (tmp_path / "bad.sofa").write_bytes(b"garbage")
    code, out = invoke(["audio", "calibrate", "--out", tmp_path / "m.npz", "--head", tmp_path / "bad.sofa"])
    assert code == 2 and "bad.sofa: not a readable SOFA file" in one_line_error(out)
    code, out = invoke(["audio", "evaluate", "--head", tmp_path / "bad.sofa", "--hrir-interpolation", "cubic"])
    assert code == 2 and "--hrir-interpolation must be one of barycentric, nearest" in one_line_error(out)
    (tmp_path / "scan.wav").write_text("not audio")
    code, out = invoke(["audio", "localize", tmp_path / "scan.wav"])
    assert code == 2 and "scan.wav: not a readable audio file" in one_line_error(out)


def test_the_run_summary_shows_the_stitched_tracks_scores(capsys, tmp_path):
    from planefuse.cli._demo import print_summary

    metrics = {"mota": 0.626, "idf1": 0.461, "id_switches": 22, "stitched_identities": 16,
               "stitched": {"mota": 0.685, "idf1": 0.569, "id_switches": 17}}
    print_summary(metrics, tmp_path, "planefuse run run.yaml")
    out = capsys.readouterr().out
    assert "idf1 (stitched)" in out and "0.569" in out and "id_switches (stitched)" in out
    assert "tracks_stitched.csv" in out
    print_summary({"mota": 0.5}, tmp_path, "planefuse run run.yaml")  # no offline pass: no such rows
    assert "stitched" not in capsys.readouterr().out
