"""Calibration loaders: OpenCV YAML/XML round trips, WILDTRACK and EPFL files, and every malformed case."""

from __future__ import annotations

import cv2
import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

from conftest import shared_data
from planefuse.calib import (
    H_WORLD_TOPVIEW_TERRACE,
    WILDTRACK_CAMERAS,
    load_epfl_boxes,
    load_epfl_homography,
    load_opencv_camera,
    load_opencv_intrinsics,
    load_wildtrack_camera,
    load_wildtrack_rig,
    save_opencv_camera,
)
from planefuse.geometry import CameraIntrinsics, PinholeCamera, apply_homography, transform_from_rotation_translation

K0 = np.array([[820.5, 0.0, 655.25], [0.0, 818.0, 362.75], [0.0, 0.0, 1.0]])
DIST0 = np.array([-0.31, 0.12, 0.001, -0.002, -0.02])


def write_fs(path, **nodes):
    """Write nodes with OpenCV's own FileStorage writer (the independent reference format)."""
    fs = cv2.FileStorage(str(path), cv2.FILE_STORAGE_WRITE)
    for k, v in nodes.items():
        fs.write(k, v)
    fs.release()


# --- round trips ----------------------------------------------------------------------
@pytest.mark.parametrize("suffix", [".yml", ".yaml", ".xml"])
def test_opencv_file_written_by_cv2_reads_back(tmp_path, suffix, rng):
    rvec = rng.normal(size=(3, 1))
    tvec = rng.normal(size=(3, 1)) * 200.0  # centimetres
    p = tmp_path / f"cam{suffix}"
    write_fs(p, camera_matrix=K0, distortion_coefficients=DIST0.reshape(5, 1), image_width=1280, image_height=720,
             rvec=rvec, tvec=tvec)
    cam = load_opencv_camera(p, metres_per_unit=0.01)
    np.testing.assert_array_equal(cam.K, K0)
    np.testing.assert_array_equal(cam.intrinsics.dist, DIST0)
    assert (cam.intrinsics.width_px, cam.intrinsics.height_px) == (1280, 720)
    assert cam.name == "cam"
    # Independent check: our projection of world points [m] equals cv2.projectPoints with the file's rvec/tvec [cm].
    X_m = cam.center_world + cam.R_world_cam @ np.array([0.2, -0.1, 3.0]) + rng.normal(0, 0.3, (20, 3))
    uv_ref = cv2.projectPoints(X_m * 100.0, rvec, tvec, K0, DIST0)[0].reshape(-1, 2)
    np.testing.assert_allclose(cam.project(X_m), uv_ref, atol=1e-6)


def test_opencv_intrinsics_only_file(tmp_path):
    p = tmp_path / "intr.yaml"
    write_fs(p, camera_matrix=K0, image_width=640, image_height=480)
    intr = load_opencv_intrinsics(p)
    np.testing.assert_array_equal(intr.dist, np.zeros(5))
    with pytest.raises(ValueError, match=r"intr.yaml: field 'rvec': missing"):
        load_opencv_camera(p)


@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(
    f=st.floats(100, 3000),
    aspect=st.floats(0.9, 1.1),
    dist=st.lists(st.floats(-0.3, 0.3), min_size=5, max_size=5),
    seed=st.integers(0, 2**31 - 1),
    t=st.lists(st.floats(-50, 50), min_size=3, max_size=3),
    suffix=st.sampled_from([".yml", ".xml"]),
)
def test_save_load_round_trip_property(tmp_path, f, aspect, dist, seed, t, suffix):
    K = np.array([[f, 0.0, 320.0], [0.0, f * aspect, 240.0], [0.0, 0.0, 1.0]])
    R = Rotation.random(random_state=seed).as_matrix()
    cam = PinholeCamera(CameraIntrinsics(K, 640, 480, np.array(dist)), transform_from_rotation_translation(R, t), "x")
    p = tmp_path / f"rt{suffix}"
    save_opencv_camera(p, cam, metres_per_unit=0.001)
    back = load_opencv_camera(p, name="x", metres_per_unit=0.001)
    np.testing.assert_allclose(back.K, cam.K, rtol=1e-15)
    np.testing.assert_allclose(back.intrinsics.dist, cam.intrinsics.dist, rtol=1e-15)
    np.testing.assert_allclose(back.T_world_cam, cam.T_world_cam, atol=1e-9)


@pytest.mark.parametrize("field", ["T_world_cam", "T_cam_world"])
def test_opencv_4x4_extrinsics(tmp_path, field, rng):
    T_world_cam = transform_from_rotation_translation(Rotation.random(random_state=5).as_matrix(), [1.0, 2.0, 3.0])
    T = T_world_cam if field == "T_world_cam" else np.linalg.inv(T_world_cam)
    p = tmp_path / "c.yml"
    write_fs(p, camera_matrix=K0, image_width=1280, image_height=720, **{field: T})
    np.testing.assert_allclose(load_opencv_camera(p).T_world_cam, T_world_cam, atol=1e-12)


# --- malformed OpenCV files ------------------------------------------------------------
def test_malformed_opencv_files_name_file_and_field(tmp_path):
    empty = tmp_path / "empty.yml"
    empty.write_text("")
    with pytest.raises(ValueError, match=r"empty.yml: field '<file>': file is empty"):
        load_opencv_intrinsics(empty)
    with pytest.raises(ValueError, match=r"absent.yml: field '<file>': no such file"):
        load_opencv_intrinsics(tmp_path / "absent.yml")
    garbage = tmp_path / "garbage.yml"
    garbage.write_text("this is : : not [ yaml")
    with pytest.raises(ValueError, match=r"garbage.yml: field '<file>'"):
        load_opencv_intrinsics(garbage)

    cases = {
        "no_k": (dict(image_width=640, image_height=480), "camera_matrix", "missing"),
        "k_shape": (dict(camera_matrix=np.eye(2), image_width=640, image_height=480), "camera_matrix",
                    "expected 9 values, got 4"),
        "dist_shape": (dict(camera_matrix=K0, distortion_coefficients=np.zeros((8, 1)), image_width=640,
                            image_height=480), "distortion_coefficients", "expected 4 or 5 values, got 8"),
        "no_width": (dict(camera_matrix=K0, image_height=480), "image_width", "missing"),
        "text_width": (dict(camera_matrix=K0, image_width="wide", image_height=480), "image_width", "non-numeric"),
        "neg_height": (dict(camera_matrix=K0, image_width=640, image_height=-3), "image_height", "positive integer"),
        "bad_k": (dict(camera_matrix=np.diag([-1.0, 1.0, 1.0]), image_width=640, image_height=480), "camera_matrix",
                  "positive focal"),
        "nan_dist": (dict(camera_matrix=K0, distortion_coefficients=np.array([[np.nan], [0], [0], [0], [0]]),
                          image_width=640, image_height=480), "distortion_coefficients", "non-finite"),
    }
    for stem, (nodes, field, what) in cases.items():
        p = tmp_path / f"{stem}.xml"
        write_fs(p, **nodes)
        with pytest.raises(ValueError, match=rf"{stem}.xml: field '{field}': .*{what}"):
            load_opencv_intrinsics(p)

    # Hand-written YAML: a matrix whose data count disagrees with rows x cols, and non-numeric sequence entries.
    bad_mat = tmp_path / "bad_mat.yml"
    bad_mat.write_text("%YAML:1.0\ncamera_matrix: !!opencv-matrix\n  rows: 3\n  cols: 3\n  dt: d\n  data: [1, 2, 3]\n")
    with pytest.raises(ValueError, match=r"bad_mat.yml: field 'camera_matrix': malformed opencv-matrix"):
        load_opencv_intrinsics(bad_mat, width_px=10, height_px=10)
    bad_seq = tmp_path / "bad_seq.yml"
    bad_seq.write_text("%YAML:1.0\ncamera_matrix: [1, 0, 2, 0, 1, 2, 0, 0, one]\n")
    with pytest.raises(ValueError, match=r"bad_seq.yml: field 'camera_matrix': non-numeric entries at positions \[8\]"):
        load_opencv_intrinsics(bad_seq, width_px=10, height_px=10)

    tv = tmp_path / "no_tvec.yml"
    write_fs(tv, camera_matrix=K0, image_width=640, image_height=480, rvec=np.zeros((3, 1)))
    with pytest.raises(ValueError, match=r"no_tvec.yml: field 'tvec': missing"):
        load_opencv_camera(tv)
    refl = tmp_path / "refl.yml"
    write_fs(refl, camera_matrix=K0, image_width=640, image_height=480, T_world_cam=np.diag([1.0, 1, -1, 1]))
    with pytest.raises(ValueError, match=r"refl.yml: field 'T_world_cam': .*reflection"):
        load_opencv_camera(refl)


# --- WILDTRACK -------------------------------------------------------------------------
@pytest.mark.realdata
def test_wildtrack_rig_matches_documented_centres_and_cv2():
    root = shared_data("wildtrack")
    rig = load_wildtrack_rig(root)
    assert list(rig) == list(WILDTRACK_CAMERAS)
    # Camera centres in cm documented in SOURCE.md (C = -R^T tvec), converted to metres.
    expected_cm = {"C1": (909.5, -584.4, 288.9), "C5": (-399.3, 938.1, 168.2), "C7": (1175.7, 187.5, 339.5)}
    for k, c in expected_cm.items():
        np.testing.assert_allclose(rig[k].center_world, np.array(c) / 100.0, atol=0.001)
    fs = cv2.FileStorage(str(root / "intrinsic" / "intr_IDIAP3.xml"), cv2.FILE_STORAGE_READ)
    K, dist = fs.getNode("camera_matrix").mat(), fs.getNode("distortion_coefficients").mat()
    fs.release()
    cam = rig["C7"]
    rvec, tvec = cv2.Rodrigues(cam.T_cam_world[:3, :3])[0], cam.T_cam_world[:3, 3] * 100.0
    X_m = np.array([[5.0, 2.0, 0.0], [6.0, 3.0, 0.0], [7.0, 1.0, 1.0]])
    uv_ref = cv2.projectPoints(X_m * 100.0, rvec, tvec, K, dist)[0].reshape(-1, 2)
    np.testing.assert_allclose(cam.project(X_m), uv_ref, atol=1e-6)
    assert cam.intrinsics.has_distortion and (cam.intrinsics.width_px, cam.intrinsics.height_px) == (1920, 1080)


def test_wildtrack_extrinsic_malformed(tmp_path):
    intr = tmp_path / "intr_X.xml"
    write_fs(intr, camera_matrix=K0, distortion_coefficients=DIST0.reshape(5, 1))
    extr = tmp_path / "extr_X.xml"
    extr.write_text('<?xml version="1.0"?>\n<opencv_storage>\n<rvec>1.0 0.5</rvec>\n<tvec>1 2 3</tvec>\n</opencv_storage>\n')
    with pytest.raises(ValueError, match=r"extr_X.xml: field 'rvec': expected 3 values, got 2"):
        load_wildtrack_camera(intr, extr)
    extr.write_text('<?xml version="1.0"?>\n<opencv_storage>\n<rvec>1.0 0.5 0.1</rvec>\n</opencv_storage>\n')
    with pytest.raises(ValueError, match=r"extr_X.xml: field 'tvec': missing"):
        load_wildtrack_camera(intr, extr)
    extr.write_text('<?xml version="1.0"?>\n<opencv_storage>\n<rvec>1.0 a 0.1</rvec><tvec>1 2 3</tvec>\n</opencv_storage>\n')
    with pytest.raises(ValueError, match=r"extr_X.xml: field 'rvec': non-numeric"):
        load_wildtrack_camera(intr, extr)


# --- EPFL --------------------------------------------------------------------------------
@pytest.mark.realdata
def test_epfl_homography_direction_and_metric_scale():
    root = shared_data("epfl_pom") / "EPFL-Terrace"
    h = load_epfl_homography(root / "terrace1-c0" / "Homography.txt", H_world_topview=H_WORLD_TOPVIEW_TERRACE)
    assert h.H_topview_image[0, 0] == pytest.approx(-1.6688907435)  # first entry quoted in SOURCE.md
    # Top-view units of the terrace span about 300 x 380 units = 6.9 m x 8.7 m: the metric map must say so.
    corners = apply_homography(np.linalg.inv(H_WORLD_TOPVIEW_TERRACE), np.array([[0.0, 0.0], [6.9, 8.7]]))
    np.testing.assert_allclose(np.abs(np.diff(corners, axis=0)), [[315.3, 399.3]], rtol=0.01)
    uv = np.array([[180.0, 250.0], [60.0, 200.0]])
    np.testing.assert_allclose(apply_homography(h.H_image_plane, apply_homography(h.H_plane_image, uv)), uv, atol=1e-9)


def test_epfl_malformed_files(tmp_path):
    cases = {
        "empty.txt": ("", "'H': file is empty"),
        "short.txt": ("1 0 0\n0 1 0\n", r"'H': expected 3 rows of 3 numbers"),
        "ragged.txt": ("1 0 0\n0 1\n0 0 1\n", r"'H': expected 3 rows of 3 numbers, got rows of \[3, 2, 3\]"),
        "text.txt": ("1 0 0\n0 x 0\n0 0 1\n", "'H': non-numeric"),
        "singular.txt": ("1 2 3\n2 4 6\n0 0 1\n", "'H': .*singular"),
    }
    for name, (text, what) in cases.items():
        (tmp_path / name).write_text(text)
        with pytest.raises(ValueError, match=rf"{name}: field {what}"):
            load_epfl_homography(tmp_path / name)
    gt = tmp_path / "gt.txt"
    gt.write_text('0 2 28 32 142 0 1 0 0 "PERSON"\n0 1 28 31 142 1 1 0\n')
    with pytest.raises(ValueError, match=r"gt.txt: field 'line 2': expected 10 fields, got 8"):
        load_epfl_boxes(gt)
    gt.write_text('0 2 28 32 14.5 0 1 0 0 "PERSON"\n')
    with pytest.raises(ValueError, match=r"gt.txt: field 'line 1': non-integer"):
        load_epfl_boxes(gt)
    gt.write_text("\n")
    with pytest.raises(ValueError, match=r"gt.txt: field 'rows': file is empty"):
        load_epfl_boxes(gt)


def test_epfl_boxes_parse(tmp_path):
    gt = tmp_path / "gt.txt"
    gt.write_text('3 10 20 30 140 7 0 1 1 "PERSON"\n4 1 2 5 9 8 1 0 0 "PERSON"\n')
    b = load_epfl_boxes(gt)
    np.testing.assert_array_equal(b.track_id, [3, 4])
    np.testing.assert_array_equal(b.frame, [7, 8])
    np.testing.assert_array_equal(b.lost, [False, True])
    np.testing.assert_array_equal(b.occluded, [True, False])
    np.testing.assert_allclose(b.foot_uv(), [[20.0, 140.0], [3.0, 9.0]])


# --- CLI ---------------------------------------------------------------------------------
def test_cli_calib_show(tmp_path):
    from typer.testing import CliRunner

    from planefuse.cli import app

    p = tmp_path / "cam.yml"
    T_cam_world = np.linalg.inv(transform_from_rotation_translation(np.diag([1.0, -1.0, -1.0]), [1.0, 2.0, 3.0]))
    write_fs(p, camera_matrix=K0, distortion_coefficients=DIST0.reshape(5, 1), image_width=1280, image_height=720,
             rvec=cv2.Rodrigues(T_cam_world[:3, :3])[0], tvec=T_cam_world[:3, 3] * 100.0)
    res = CliRunner().invoke(app, ["calib-show", str(p), "--metres-per-unit", "0.01"], terminal_width=200)
    assert res.exit_code == 0, res.output
    assert "1280 x 720" in res.output and "[1. 2. 3.]" in res.output
    bad = tmp_path / "bad.yml"
    write_fs(bad, camera_matrix=np.eye(2))
    res = CliRunner().invoke(app, ["calib-show", str(bad)], terminal_width=200)
    assert res.exit_code == 1 and "field 'camera_matrix': expected 9 values" in " ".join(res.output.split())
