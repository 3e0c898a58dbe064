"""planefuse import: calibration formats against cv2.projectPoints, the recording it writes, its one-line errors,
planefuse check on the result, and the real EPFL terrace."""

from __future__ import annotations

import json
import re

import cv2
import numpy as np
import pytest
import yaml
from hypothesis import given, settings
from hypothesis import strategies as st
from typer.testing import CliRunner

from planefuse.calib import (
    EPFL_TERRACE_TSAI,
    TsaiCamera,
    check_metric_scale,
    load_cameras,
    pinhole_from_tsai,
    write_tsai_xml,
)
from planefuse.cli._app import app
from planefuse.config import load_config
from planefuse.geometry import CameraIntrinsics, PinholeCamera, T_world_cam_look_at
from planefuse.io import (
    CameraInput,
    ControlPoints,
    geometry_findings,
    import_recording,
    people_from_boxes,
    read_recording,
)
from planefuse.io._import import _background

from conftest import shared_data

W, H = 96, 72
K = np.array([[80.0, 0.0, 47.3], [0.0, 81.0, 36.1], [0.0, 0.0, 1.0]])
DIST = np.array([-0.21, 0.07, 0.001, -0.002, -0.01])


def _pose(rng):
    """A camera 2.5-3.5 m up looking at the floor: (rvec, tvec [m]) world -> camera, and T_world_cam."""
    c = np.array([rng.uniform(-1, 1), rng.uniform(-6, -4), rng.uniform(2.5, 3.5)])
    T = T_world_cam_look_at(c, [rng.uniform(-0.5, 0.5), rng.uniform(1, 2), 0.0])
    R_cam_world = T[:3, :3].T
    return cv2.Rodrigues(R_cam_world)[0].ravel(), -R_cam_world @ T[:3, 3], T


def _points_in_view(T_world_cam, rng, n=200):
    """World points [m] in front of the camera, on the floor and up to 1.8 m, that land inside the image."""
    cam = PinholeCamera(CameraIntrinsics(K, W, H, DIST), T_world_cam)
    p = np.c_[rng.uniform(-3, 3, (4 * n, 2)) + [0, 1.5], rng.uniform(0, 1.8, 4 * n)]
    return p[cam.intrinsics.contains(cam.project(p))][:n]


def _cv2_pixels(p_m, rvec, tvec_m, dist=DIST):
    return cv2.projectPoints(p_m.reshape(-1, 1, 3), rvec, tvec_m, K, dist)[0].reshape(-1, 2)


# --------------------------------------------------------------------------- formats vs cv2.projectPoints
@pytest.mark.parametrize("suffix,extrinsics,unit", [(".yaml", "rvec", "mm"), (".xml", "rvec", "cm"),
                                                   (".yaml", "RT", "m")])
def test_opencv_filestorage_matches_projectpoints(tmp_path, suffix, extrinsics, unit):
    rng = np.random.default_rng(0)
    rvec, tvec, T = _pose(rng)
    scale = {"mm": 1e3, "cm": 1e2, "m": 1.0}[unit]
    path = tmp_path / f"cam{suffix}"
    fs = cv2.FileStorage(str(path), cv2.FILE_STORAGE_WRITE)
    fs.write("image_width", W)
    fs.write("image_height", H)
    fs.write("camera_matrix", K)
    fs.write("distortion_coefficients", DIST.reshape(5, 1))
    if extrinsics == "rvec":
        fs.write("rvec", rvec.reshape(3, 1))
        fs.write("tvec", (tvec * scale).reshape(3, 1))
    else:
        fs.write("R", cv2.Rodrigues(rvec)[0])
        fs.write("T", (tvec * scale).reshape(3, 1))
    fs.release()
    cams, _ = load_cameras("opencv", {"cam": path}, unit=unit)
    p = _points_in_view(T, rng)
    np.testing.assert_allclose(cams["cam"].project(p), _cv2_pixels(p, rvec, tvec), atol=1e-6)


def test_json_voxelpose_and_panoptic_layouts_match_projectpoints(tmp_path):
    rng = np.random.default_rng(1)
    poses = [_pose(rng) for _ in range(2)]
    vox = {}
    for i, (rvec, tvec, _) in enumerate(poses):
        R = cv2.Rodrigues(rvec)[0]
        vox[str(i)] = {"R": R.tolist(), "T": (-R.T @ tvec * 1e3).reshape(3, 1).tolist(),  # centre, mm
                       "fx": K[0, 0], "fy": K[1, 1], "cx": K[0, 2], "cy": K[1, 2],
                       "k": [[DIST[0]], [DIST[1]], [DIST[4]]], "p": [[DIST[2]], [DIST[3]]]}
    (tmp_path / "voxelpose.json").write_text(json.dumps(vox))
    pan = {"cameras": [{"name": f"00_{i:02d}", "type": "hd", "resolution": [W, H], "K": K.tolist(),
                        "distCoef": DIST.tolist(), "R": cv2.Rodrigues(rvec)[0].tolist(),
                        "t": (tvec * 1e2).reshape(3, 1).tolist()} for i, (rvec, tvec, _) in enumerate(poses)]}
    (tmp_path / "panoptic.json").write_text(json.dumps(pan))
    vcams, _ = load_cameras("json", {"a": f"{tmp_path / 'voxelpose.json'}#0", "b": f"{tmp_path / 'voxelpose.json'}#1"},
                            unit="mm", sizes_px={"a": (W, H), "b": (W, H)})
    pcams, _ = load_cameras("json", {"a": f"{tmp_path / 'panoptic.json'}#00_00",
                                     "b": f"{tmp_path / 'panoptic.json'}#00_01"}, unit="cm")
    for name, (rvec, tvec, T) in zip("ab", poses):
        p = _points_in_view(T, rng)
        ref = _cv2_pixels(p, rvec, tvec)
        np.testing.assert_allclose(vcams[name].project(p), ref, atol=1e-6)
        np.testing.assert_allclose(pcams[name].project(p), ref, atol=1e-6)
        assert vcams[name].name == name


def test_tsai_xml_matches_tsai_equations_and_projectpoints(tmp_path):
    """Pixels made with Tsai's own (distorted -> undistorted) equations, scaled 720x576 -> 360x288, come back."""
    tsai = EPFL_TERRACE_TSAI["c1"]
    write_tsai_xml(tmp_path / "c1.xml", tsai)
    cams, notes = load_cameras("tsai", {"c1": tmp_path / "c1.xml"}, unit="mm", sizes_px={"c1": (360, 288)})
    cam = cams["c1"]
    rng = np.random.default_rng(2)
    uv = np.c_[rng.uniform(0, 720, 300), rng.uniform(0, 576, 300)]  # 720x576 pixels of the calibration
    xd = (uv[:, 0] - tsai.cx_px) * tsai.dpx_mm / tsai.sx
    yd = (uv[:, 1] - tsai.cy_px) * tsai.dpy_mm
    k = 1 + tsai.kappa1_per_mm2 * (xd**2 + yd**2)
    ray_cam = np.c_[xd * k, yd * k, np.full(len(uv), tsai.focal_mm)]
    depth_mm = rng.uniform(3000, 12000, len(uv))
    p_cam = ray_cam / ray_cam[:, 2:] * depth_mm[:, None]
    p_world_mm = (p_cam - tsai.t_cam_world) @ tsai.R_cam_world  # R^T (X_c - T)
    expected = (uv + 0.5) * 0.5 - 0.5  # the same pixel centres in 360x288
    np.testing.assert_allclose(cam.project(p_world_mm * 1e-3), expected, atol=0.01)
    rvec = cv2.Rodrigues(cam.T_cam_world[:3, :3])[0]
    ref = cv2.projectPoints(p_world_mm.reshape(-1, 1, 3) * 1e-3, rvec, cam.T_cam_world[:3, 3], cam.K,
                            cam.intrinsics.dist)[0].reshape(-1, 2)
    np.testing.assert_allclose(cam.project(p_world_mm * 1e-3), ref, atol=1e-6)
    assert notes[0][0] == "info" and "fit within" in notes[0][1]


def test_tsai_xml_round_trip_and_errors(tmp_path):
    from planefuse.calib import load_tsai_xml

    write_tsai_xml(tmp_path / "c0.xml", EPFL_TERRACE_TSAI["c0"])
    assert load_tsai_xml(tmp_path / "c0.xml") == EPFL_TERRACE_TSAI["c0"]
    text = (tmp_path / "c0.xml").read_text()
    (tmp_path / "bad.xml").write_text(text.replace('focal="', 'focalx="'))
    with pytest.raises(ValueError, match=r"bad.xml: field 'Intrinsic.focal': missing"):
        load_tsai_xml(tmp_path / "bad.xml")
    (tmp_path / "bad2.xml").write_text(text[:60])
    with pytest.raises(ValueError, match=r"bad2.xml: field '<file>': not well-formed XML"):
        load_tsai_xml(tmp_path / "bad2.xml")
    with pytest.raises(ValueError, match="not a uniform scaling"):
        pinhole_from_tsai(EPFL_TERRACE_TSAI["c0"], metres_per_unit=1e-3, width_px=360, height_px=300)


def test_ground_homography_camera_matches_projectpoints(tmp_path):
    """A homography file in cm with its y axis flipped gives back the camera that made it (centred principal point,
    square pixels, no distortion)."""
    Kc = np.array([[90.0, 0.0, (W - 1) / 2], [0.0, 90.0, (H - 1) / 2], [0.0, 0.0, 1.0]])
    rng = np.random.default_rng(3)
    rvec, tvec, T = _pose(rng)
    R = cv2.Rodrigues(rvec)[0]
    H_image_world = Kc @ np.c_[R[:, :2], tvec]  # ground (x, y, 1) [m] -> pixels
    flip_cm = np.diag([100.0, -100.0, 1.0])  # world [m] -> file's ground units (cm, y flipped)
    H_unit_image = flip_cm @ np.linalg.inv(H_image_world)
    np.savetxt(tmp_path / "Homography.txt", H_unit_image / H_unit_image[2, 2])
    cams, notes = load_cameras("homography", {"c": tmp_path / "Homography.txt"}, unit="m", sizes_px={"c": (W, H)},
                               ground_unit_m=0.01, ground_flip_y=True)
    p = _points_in_view(T, rng)
    ref = cv2.projectPoints(p.reshape(-1, 1, 3), rvec, tvec, Kc, np.zeros(5))[0].reshape(-1, 2)
    np.testing.assert_allclose(cams["c"].project(p), ref, atol=1e-6)  # planes above the ground too
    with pytest.raises(ValueError, match="below the ground.*left-handed"):
        load_cameras("homography", {"c": tmp_path / "Homography.txt"}, unit="m", sizes_px={"c": (W, H)},
                     ground_unit_m=0.01)
    with pytest.raises(ValueError, match="Homography.txt: a ground homography needs its ground unit"):
        load_cameras("homography", {"c": tmp_path / "Homography.txt"}, unit="m", sizes_px={"c": (W, H)})


# --------------------------------------------------------------------------- the unit check
def test_metric_scale_refuses_mm_read_as_m_and_m_read_as_mm(tmp_path):
    rng = np.random.default_rng(4)
    rvec, tvec, _ = _pose(rng)
    path = tmp_path / "cam.yaml"
    fs = cv2.FileStorage(str(path), cv2.FILE_STORAGE_WRITE)
    for key, val in (("image_width", W), ("image_height", H), ("camera_matrix", K), ("rvec", rvec.reshape(3, 1)),
                     ("tvec", (tvec * 1e3).reshape(3, 1))):
        fs.write(key, val)
    fs.release()
    cams, _ = load_cameras("opencv", {"cam": path}, unit="m")
    with pytest.raises(ValueError, match=r"camera 'cam' is \d+ m above the ground with --units m.*--units mm"):
        check_metric_scale(cams, "m")
    cams, _ = load_cameras("opencv", {"cam": path}, unit="mm")
    check_metric_scale(cams, "mm", room_xy_m=(-2.0, 3.0, -1.0, 3.0))
    with pytest.raises(ValueError, match=r"camera 'cam' is \d+ m from the monitored area .* different length units"):
        check_metric_scale(cams, "mm", room_xy_m=(-2000.0, -1990.0, 1000.0, 1010.0))
    fs = cv2.FileStorage(str(path), cv2.FILE_STORAGE_WRITE)
    for key, val in (("image_width", W), ("image_height", H), ("camera_matrix", K), ("rvec", rvec.reshape(3, 1)),
                     ("tvec", tvec.reshape(3, 1))):
        fs.write(key, val)
    fs.release()
    cams, _ = load_cameras("opencv", {"cam": path}, unit="mm")
    with pytest.raises(ValueError, match=r"0.00\d+ m above the ground with --units mm.*--units m\b"):
        check_metric_scale(cams, "mm")


# --------------------------------------------------------------------------- import end to end
def _camera(name, center, target) -> PinholeCamera:
    return PinholeCamera(CameraIntrinsics(K, W, H, DIST), T_world_cam_look_at(center, target), name)


def _write_video(path, n, fps=25.0):
    rng = np.random.default_rng(5)
    frames = [rng.integers(0, 256, (H, W, 3), dtype=np.uint8) for _ in range(n)]
    writer = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"FFV1"), fps, (W, H))
    for f in frames:
        writer.write(f)
    writer.release()
    return frames


def _write_yaml(path, cam: PinholeCamera, unit_m=1e-3):
    from planefuse.calib import save_opencv_camera

    save_opencv_camera(path, cam, metres_per_unit=unit_m)


def _cli(*args):
    return CliRunner().invoke(app, list(map(str, args)), terminal_width=200)


@pytest.fixture
def installation(tmp_path):
    """Two cameras: c0 a video, c1 a folder of PNGs; OpenCV YAML calibrations in mm; MOT boxes of two people."""
    cams = [_camera("c0", [-3.0, -3.0, 3.0], [1.0, 1.0, 0.0]), _camera("c1", [4.0, -3.0, 2.8], [0.0, 1.0, 0.0])]
    frames = _write_video(tmp_path / "c0.mkv", 8)
    (tmp_path / "c1").mkdir()
    for k, f in enumerate(frames):
        cv2.imwrite(str(tmp_path / "c1" / f"img_{k + 10}.png"), f[::-1])
    for c in cams:
        _write_yaml(tmp_path / f"{c.name}.yaml", c)
    people = {1: lambda t: (0.2 + 0.1 * t, 0.5), 2: lambda t: (1.0, 1.5 - 0.1 * t)}
    for c in cams:
        rows = []
        for k in range(8):
            for pid, f in people.items():
                x, y = f(k)
                u, v = c.project(np.array([[x, y, 0.0]]))[0]
                rows.append(f"{k + 1},{pid},{u - 5:.10f},{v - 20:.10f},10,20,1,1,1")
        (tmp_path / f"{c.name}_gt.txt").write_text("\n".join(rows) + "\n")
    return tmp_path, cams, frames, people


def test_import_cli_writes_a_recording_that_reads_back(installation):
    d, cams, frames, people = installation
    out = d / "rec"
    r = _cli("import", out, "--camera", f"c0={d / 'c0.mkv'}", "--camera", f"c1={d / 'c1'}", "--rate", "c1=25",
             "--calib-format", "opencv", "--units", "mm", "--calib", f"c0={d / 'c0.yaml'}",
             "--calib", f"c1={d / 'c1.yaml'}", "--ignore-rect", "c0=60,50,96,72", "--ignore-rect", "c0=0,0,10,10",
             "--gt-boxes", f"c0={d / 'c0_gt.txt'}", "--gt-boxes", f"c1={d / 'c1_gt.txt'}", "--gt-format", "mot")
    assert r.exit_code == 0, r.output
    m = yaml.safe_load((out / "scene.yaml").read_text())
    c0, c1 = m["sensors"]
    assert m["format_version"] == 2 and c0["video_file"] == "cameras/c0/video.mkv"
    assert c0["ignore_rects_px"] == [[60, 50, 96, 72], [0, 0, 10, 10]] and "ignore_rects_px" in c1
    rec = read_recording(out)
    assert rec.camera("c0").ignore_mask[60, 70] and not rec.camera("c0").ignore_mask[30, 30]
    for k in (0, 5, 2):
        np.testing.assert_array_equal(rec.camera("c0").frame(k), frames[k])
        np.testing.assert_array_equal(rec.camera("c1").frame(k), frames[k][::-1])
    np.testing.assert_allclose(rec.camera("c1").times_s, np.arange(8) / 25.0)
    for cam in cams:
        got = rec.camera(cam.name).camera
        np.testing.assert_allclose(got.T_world_cam, cam.T_world_cam, atol=1e-9)
        np.testing.assert_allclose(got.K, cam.K)
    pt = rec.groundtruth.people
    np.testing.assert_allclose(pt.times_s, np.arange(8) / 25.0)
    for j, pid in enumerate(pt.person_ids):
        want = np.array([people[int(pid)](k) for k in range(8)])
        np.testing.assert_allclose(pt.xy_m[:, j], want, atol=1e-6)
    x0, x1, y0, y1 = m["room_xy_m"]
    assert x0 == pytest.approx(0.2 - 1.0) and y1 == pytest.approx(1.5 + 1.0)
    r = _cli("check", out, "--log-json")
    assert r.exit_code == 0, r.output
    messages = [i["message"] for i in json.loads(r.output)["issues"]]
    assert messages.count("100% of the 16 ground-truth positions project into the image") == 2


def _import_args(d, *extra):
    return ["import", d / "rec", "--camera", f"c0={d / 'c0.mkv'}", "--calib-format", "opencv",
            "--calib", f"c0={d / 'c0.yaml'}", *extra]


@pytest.mark.parametrize("extra,message", [
    (["--units", "mm", "--calib-format", "kalibr"], "calibration format 'kalibr' is unknown"),
    (["--units", "m"], r"camera 'c0' is \d+ m above the ground with --units m: implausible .* with --units mm"),
    (["--units", "mm", "--gt-boxes", "c9=x.txt"], "camera 'c9' has no calibration: give --calib c9=FILE"),
    (["--units", "mm", "--camera", "c1=DIR/c1"], "camera 'c1' has no calibration"),
    (["--units", "mm", "--times", "c0=DIR/times.csv"], r"c0.mkv: camera 'c0' video has 8 decodable frames, shorter "
                                                       r"than its times .*times.csv: row 4 asks for video frame 9"),
    (["--units", "furlong"], "--units 'furlong': use one of mm, cm, m"),
    (["--units", "mm", "--room", "-2000,3000,-1000,3000"], r"monitored area .* is over 1 km across: a length unit "
                                                           r"is wrong \(--units mm, --room is in metres\)"),
    (["--units", "mm", "--camera", "c2=DIR/c0.yaml", "--calib", "c2=DIR/c0.yaml"],
     r"c0.yaml: camera 'c2': not a video .* nor a folder of images"),
    (["--units", "mm", "--camera", "c2=DIR/c1", "--calib", "c2=DIR/c1.yaml"], "an image folder needs a frame rate"),
    (["--units", "mm", "--ignore-rect", "c0=5,5,2,9"], "expected integer pixels with 0 <= U_MIN < U_MAX"),
    (["--units", "mm", "--calib", "c0=DIR/missing.yaml"], "--calib: camera 'c0' given twice"),
    (["--units", "mm", "--rate", "c5=25"], "--rate names camera 'c5', which has no --camera frames"),
    (["--units", "mm", "--gt-boxes", "c0=DIR/c0_gt.txt", "--image-size", "c0=96by72"],
     "--image-size '96by72': expected WIDTHxHEIGHT in pixels"),
    (["--units", "mm", "--ignore-mask", "c0=DIR/small.png"], r"small.png: ignore mask of camera 'c0' is 5x4 px, its "
                                                              r"frames 96x72 px"),
    (["--units", "mm", "--camera", "c0"], r"--camera 'c0': expected NAME=VALUE"),
])
def test_import_errors_are_one_line_naming_the_input(installation, extra, message):
    d = installation[0]
    (d / "times.csv").write_text("time_s,frame_index\n0.0,0\n0.2,5\n0.36,9\n")
    cv2.imwrite(str(d / "small.png"), np.zeros((4, 5), np.uint8))
    args = [str(a).replace("DIR", str(d)) for a in _import_args(d, *extra)]
    r = _cli(*args)
    assert r.exit_code == 2, r.output
    lines = [ln for ln in r.output.splitlines() if ln.strip()]
    assert len(lines) == 1 and lines[0].startswith("error:"), r.output
    assert re.search(message, lines[0]), lines[0]
    assert not (d / "rec").exists()  # nothing written


def test_import_refuses_calibration_of_another_size(installation):
    d, cams, _, _ = installation
    big = PinholeCamera(CameraIntrinsics(K, 2 * W, 2 * H), cams[0].T_world_cam, "c0")
    _write_yaml(d / "c0.yaml", big)
    r = _cli(*_import_args(d, "--units", "mm"))
    assert r.exit_code == 2 and "c0.yaml: field 'image_width': the calibration is 192x144 px, the images of " \
        "camera 'c0' 96x72 px" in " ".join(r.output.split()), r.output


def test_check_finds_plane_above_camera_and_bad_control_points(installation):
    d, cams, _, _ = installation
    pts = np.array([[0.0, 0.0, 0.0], [1.0, 1.0, 0.0], [0.5, 1.5, 1.0]])
    uv = cams[0].project(pts)
    good = ControlPoints(np.array(["c0"] * 3, dtype=object), uv, pts)
    findings = geometry_findings([cams[0]], [0.0, 1.0], control_points=good)
    assert [f[0] for f in findings] == ["info"] and "within 0.00 px" in findings[0][2]
    bad = ControlPoints(good.camera, uv + [[0, 0], [12, 0], [0, 0]], pts)
    assert geometry_findings([cams[0]], [0.0], control_points=bad)[0][0] == "error"
    above = geometry_findings([cams[0]], [0.0, 1.0, 3.5])
    assert above[0][0] == "error" and "3.5 m are at or above the camera centre (z = 3.000 m)" in above[0][2]
    # through the CLI: control points in mm, a plane at 3.5 m above c0
    (d / "points.csv").write_text("camera,u_px,v_px,x,y,z\n" + "".join(
        f"c0,{float(u) + (12 if i == 1 else 0)!r},{float(v)!r},{x * 1e3},{y * 1e3},{z * 1e3}\n"
        for i, ((u, v), (x, y, z)) in enumerate(zip(uv, pts))))
    r = _cli(*_import_args(d, "--units", "mm", "--points", d / "points.csv", "--room", "-2,3,-1,3"))
    assert r.exit_code == 1 and "control points reproject within 12.00 px" in r.output, r.output
    m = yaml.safe_load((d / "rec" / "scene.yaml").read_text())
    m["planes_heights_m"] = [0.0, 1.0, 3.5]
    (d / "rec" / "scene.yaml").write_text(yaml.safe_dump(m))
    r = _cli("check", d / "rec", "--log-json")
    errors = [i["message"] for i in json.loads(r.output)["issues"] if i["level"] == "error"]
    assert r.exit_code == 1 and len(errors) == 2, r.output
    assert "at or above the camera centre" in errors[0] and "within 12.00 px" in errors[1]
    assert read_recording(d / "rec").calibration_points.xyz_m[2, 2] == pytest.approx(1.0)


def test_people_from_boxes_takes_the_median_over_cameras(installation):
    d, cams, _, people = installation
    times = np.array([1.0, np.nan, 1.4, 1.6, 1.8, np.nan])  # frames 1 and 5 not recorded, 6 and 7 past the end
    pt, notes = people_from_boxes({c.name: c for c in cams}, {c.name: d / f"{c.name}_gt.txt" for c in cams}, "mot",
                                  frame_times_s=times)
    np.testing.assert_allclose(pt.times_s, [1.0, 1.4, 1.6, 1.8])
    np.testing.assert_allclose(pt.xy_m[:, list(pt.person_ids).index(1), 0], 0.2 + 0.1 * np.array([0, 2, 3, 4]))
    assert notes[0] == "c0: 8 boxes of frames the recording does not hold (it has 4 of frames 0..5) left out"
    # a camera known by its ground homography keeps that exact mapping (here the identity: feet pixels as metres)
    pt, _ = people_from_boxes({c.name: c for c in cams}, {c.name: d / f"{c.name}_gt.txt" for c in cams}, "mot",
                              frame_times_s=times, H_ground_image={"c0": np.eye(3)})
    foot_c0 = cams[0].project(np.array([[0.2, 0.5, 0.0]]))[0]
    np.testing.assert_allclose(pt.xy_m[0, list(pt.person_ids).index(1)], (foot_c0 + [0.2, 0.5]) / 2, atol=1e-6)
    with pytest.raises(ValueError, match="box format 'coco' is unknown"):
        people_from_boxes({c.name: c for c in cams}, {"c0": d / "c0_gt.txt"}, "coco", frame_times_s=times)


def test_import_recording_library_with_image_times_file(installation):
    d, cams, frames, _ = installation
    (d / "c1_times.csv").write_text("time_s,image_file\n" + "".join(f"{0.5 + 0.1 * k!r},img_{k + 10}.png\n"
                                                                    for k in range(4)))
    rep = import_recording(d / "lib", [CameraInput("c1", d / "c1", times_file=d / "c1_times.csv")], {"c1": cams[1]})
    cs = read_recording(d / "lib").camera("c1")
    np.testing.assert_allclose(cs.times_s, 0.5 + 0.1 * np.arange(4))
    np.testing.assert_array_equal(cs.frame(3), frames[3][::-1])
    assert rep.manifest.sensors[0].rate_hz == pytest.approx(10.0)
    with pytest.raises(ValueError, match="output folder is not empty"):
        import_recording(d / "lib", [CameraInput("c1", d / "c1", rate_hz=25.0)], {"c1": cams[1]})


def test_import_background_median_and_plate(installation):
    """The median estimate is numpy's median of the frames it names (video: decoded through the recording's own
    reader; images: read directly), written as the stream's empty scene that primes background subtraction."""
    d, cams, frames, _ = installation
    out = d / "rec"
    # both at 25 Hz: the first 0.2 s hold frames 0..4
    r = _cli("import", out, "--camera", f"c0={d / 'c0.mkv'}", "--camera", f"c1={d / 'c1'}", "--rate", "c1=25",
             "--calib-format", "opencv", "--units", "mm", "--calib", f"c0={d / 'c0.yaml'}",
             "--calib", f"c1={d / 'c1.yaml'}", "--background-median-s", "0.2")
    assert r.exit_code == 0, r.output
    assert "c0: background = median of 5 frames in the first 0.2 s" in r.output
    rec = read_recording(out)
    want = np.median(np.stack(frames[:5]), axis=0).round().astype(np.uint8)
    np.testing.assert_array_equal(rec.camera("c0").background(), want)
    np.testing.assert_array_equal(rec.camera("c1").background(), np.median(np.stack(
        [f[::-1] for f in frames[:5]]), axis=0).round().astype(np.uint8))
    # a person crossing the window is removed: the median of a constant scene with one frame changed is the scene
    plate = np.full((H, W, 3), 90, np.uint8)
    for k in range(8):  # every pixel under the bar in one frame of eight
        img = plate.copy()
        img[10:30, 10 + 10 * k:20 + 10 * k] = 250
        cv2.imwrite(str(d / "c1" / f"img_{k + 10}.png"), img)
    rep = import_recording(d / "lib", [CameraInput("c1", d / "c1", rate_hz=25.0, background_median_s=1.0)],
                           {"c1": cams[1]})
    np.testing.assert_array_equal(read_recording(d / "lib").camera("c1").background(), plate)
    assert any("median of 8 frames" in n for n in rep.notes)
    # a user's empty-scene image is kept as it is
    cv2.imwrite(str(d / "plate.png"), plate)
    r = _cli(*_import_args(d, "--units", "mm", "--background", f"c0={d / 'plate.png'}", "--overwrite"))
    assert r.exit_code == 0, r.output
    np.testing.assert_array_equal(read_recording(out).camera("c0").background(), plate)


@pytest.mark.parametrize("extra,message", [
    (["--background-median-s", "0.05"], r"camera 'c0': only 2 frame\(s\) in the first 0.05 s, a median background "
                                        r"needs at least 3"),
    (["--background-median-s", "-1"], "camera 'c0': background_median_s must be a positive number of seconds"),
    (["--background-median-s", "nan"], "camera 'c0': background_median_s must be a positive number of seconds"),
    (["--background", "c0=DIR/small.png"], r"small.png: background of camera 'c0' is 5x4 px, its frames 96x72 px"),
    (["--background", "c0=DIR/c0_gt.txt"], r"c0_gt.txt: cannot read the background image of camera 'c0'"),
    (["--background", "c7=DIR/small.png"], "--background names camera 'c7', which has no --camera frames"),
])
def test_import_background_errors_are_one_line(installation, extra, message):
    d = installation[0]
    cv2.imwrite(str(d / "small.png"), np.zeros((4, 5, 3), np.uint8))
    r = _cli(*[str(a).replace("DIR", str(d)) for a in _import_args(d, "--units", "mm", *extra)])
    assert r.exit_code == 2, r.output
    lines = [ln for ln in r.output.splitlines() if ln.strip()]
    assert len(lines) == 1 and re.search(message, lines[0]), r.output
    assert not (d / "rec").exists()
    with pytest.raises(ValueError, match="not both"):
        _background(CameraInput("c0", d / "c0.mkv", background=d / "small.png", background_median_s=1.0), None)


# --------------------------------------------------------------------------- other EPFL sequences
@pytest.mark.realdata
def test_cameras_epfl_other_sequence_needs_its_ground_unit(tmp_path):
    """Regression (issue 14): a non-terrace EPFL sequence ran silently in top-view units with 1 mm cells."""
    src = shared_data("epfl_pom") / "EPFL-Terrace"
    for c in range(4):
        d = tmp_path / f"laboratory6-c{c}"
        (d / "gt").mkdir(parents=True)
        (d / "Homography.txt").write_text((src / f"terrace1-c{c}" / "Homography.txt").read_text())
        lines = (src / f"terrace1-c{c}" / "gt" / "gt.txt").read_text().splitlines()
        (d / "gt" / "gt.txt").write_text("\n".join(ln for ln in lines if int(ln.split()[5]) < 200) + "\n")
    r = _cli("cameras", "epfl", tmp_path, "--sequence", "laboratory6")
    assert r.exit_code == 2 and "ground unit of sequence 'laboratory6' is unknown" in r.output, r.output
    r = _cli("cameras", "epfl", tmp_path, "--sequence", "laboratory6", "--ground-unit-m", "0.00002")
    assert r.exit_code == 2 and "the ground unit (--ground-unit-m) looks wrong" in r.output, r.output
    r = _cli("cameras", "epfl", tmp_path, "--sequence", "laboratory6", "--ground-unit-m", "0.02", "--cell-m", "0.002")
    assert r.exit_code == 2 and "check --ground-unit-m and --cell-m" in r.output, r.output
    r = _cli("cameras", "epfl", tmp_path, "--sequence", "laboratory6", "--ground-unit-m", "0.02", "--step", "40")
    assert r.exit_code == 0 and "laboratory6" in r.output, r.output


# --------------------------------------------------------------------------- the real terrace
WATERMARK = "130,230,356,285"  # u = 130-355, v = 230-284 px (../shared/data/epfl_video/SOURCE.md)


@pytest.mark.realdata
def test_import_epfl_terrace_real_video(tmp_path):
    video, pom = shared_data("epfl_video"), shared_data("epfl_pom") / "EPFL-Terrace"
    r = _cli("cameras", "epfl-tsai", tmp_path / "tsai")
    assert r.exit_code == 0, r.output
    args = ["import", tmp_path / "terrace", "--calib-format", "tsai", "--units", "mm", "--gt-format", "vatic",
            "--image-size", "c2=360x288", "--image-size", "c3=360x288"]
    for c in range(4):
        args += ["--calib", f"c{c}={tmp_path / 'tsai' / f'c{c}.xml'}", "--gt-boxes", f"c{c}={pom / f'terrace1-c{c}' / 'gt' / 'gt.txt'}"]
    for c in range(2):
        args += ["--camera", f"c{c}={video / f'terrace1-c{c}.mp4'}", "--ignore-rect", f"c{c}={WATERMARK}"]
    r = _cli(*args)
    assert r.exit_code == 0, r.output
    assert "3000 frames decoded" in r.output and "boxes of frames the recording does not hold (it has 3000 of frames 0..2999) left out" in r.output
    m = yaml.safe_load((tmp_path / "terrace" / "scene.yaml").read_text())
    assert [s["ignore_rects_px"] for s in m["sensors"]] == [[[130, 230, 356, 285]]] * 2
    rec = read_recording(tmp_path / "terrace")
    assert len(rec.camera("c0")) == 3000 and rec.camera("c1").times_s[-1] == pytest.approx(2999 / 25)
    assert rec.camera("c0").frame(2999).shape == (288, 360, 3)
    # The cameras sit where the Tsai model puts them (SOURCE.md: c0 (6466, -1563, 2046) mm, c1 (-1034, -1225, 2109)).
    np.testing.assert_allclose(rec.camera("c0").camera.center_world, [6.466, -1.563, 2.046], atol=2e-3)
    np.testing.assert_allclose(rec.camera("c1").camera.center_world, [-1.034, -1.225, 2.109], atol=2e-3)
    # GT feet of people c0 annotates (visible boxes) project back inside c0, within a few px of the boxes' feet.
    from planefuse.calib import load_epfl_boxes

    b = load_epfl_boxes(pom / "terrace1-c0" / "gt" / "gt.txt")
    pt = rec.groundtruth.people
    sel = ~b.lost & (b.frame < 3000) & (b.frame % 50 == 0)
    idx = {int(p): j for j, p in enumerate(pt.person_ids)}
    rows = {float(t): k for k, t in enumerate(pt.times_s)}
    xy = np.array([pt.xy_m[rows[f / 25.0], idx[int(i)]] for f, i in zip(b.frame[sel], b.track_id[sel])])
    uv = rec.camera("c0").camera.project(np.c_[xy, np.zeros(len(xy))])
    assert rec.camera("c0").camera.intrinsics.contains(uv).mean() > 0.97
    err = np.linalg.norm(uv - b.foot_uv()[sel], axis=1)
    assert np.median(err) < 12.0  # the four cameras' feet spread ~0.5 m (SOURCE.md); ~25 px/m at 8 m
    # The Tsai model and EPFL's ground homography agree on the ground (to the fitted metric map's accuracy).
    from planefuse.calib import H_WORLD_TOPVIEW_TERRACE, load_epfl_homography
    from planefuse.geometry import apply_homography

    hom = load_epfl_homography(pom / "terrace1-c0" / "Homography.txt", H_world_topview=H_WORLD_TOPVIEW_TERRACE)
    feet = b.foot_uv()[sel]
    d = np.linalg.norm(rec.camera("c0").camera.backproject_to_height(feet, 0.0)[:, :2]
                       - apply_homography(hom.H_plane_image, feet), axis=1)
    assert np.median(d) < 0.25
    r = _cli("check", tmp_path / "terrace")
    assert r.exit_code == 0 and "ready to run" in r.output, r.output


def test_import_ground_positions_and_ignore_mask(installation):
    d, cams, _, _ = installation
    (d / "pos.csv").write_text("frame,person_id,x,y\n0,3,1000,2000\n2,3,1100,2000\n0,4,-500,0\n")
    mask = np.zeros((H, W), np.uint8)
    mask[:10, -20:] = 7
    cv2.imwrite(str(d / "mask.png"), mask)
    r = _cli(*_import_args(d, "--units", "mm", "--gt-positions", d / "pos.csv", "--ignore-mask", f"c0={d / 'mask.png'}",
                           "--ignore-rect", "c0=0,60,5,72"))
    assert r.exit_code == 0, r.output
    rec = read_recording(d / "rec")
    pt = rec.groundtruth.people
    np.testing.assert_allclose(pt.times_s, [0.0, 0.08])
    np.testing.assert_allclose(pt.xy_m[:, list(pt.person_ids).index(3)], [[1.0, 2.0], [1.1, 2.0]])
    ign = rec.camera("c0").ignore_mask
    assert ign.sum() == 10 * 20 + 12 * 5 and ign[0, -1] and ign[70, 2]
    (d / "bad.csv").write_text("t,id,x,y\n")
    r = _cli(*_import_args(d, "--units", "mm", "--gt-positions", d / "bad.csv", "--overwrite"))
    assert r.exit_code == 2 and "bad.csv:1: header must be time_s,person_id,x,y" in r.output, r.output


def test_import_json_for_all_cameras_video_times_and_start_time(installation):
    d, cams, frames, _ = installation
    calib = {}
    for c in cams:
        R, t = c.T_cam_world[:3, :3], c.T_cam_world[:3, 3]
        calib[c.name] = {"K": K.tolist(), "dist": DIST.tolist(), "R": R.tolist(), "T": (-R.T @ t * 100).tolist()}
    (d / "calib.json").write_text(json.dumps(calib))
    (d / "times.csv").write_text("time_s,frame_index\n10.0,1\n10.2,6\n")
    r = _cli("import", d / "rec", "--camera", f"c0={d / 'c0.mkv'}", "--camera", f"c1={d / 'c1'}", "--rate", "c1=5",
             "--start-time-s", "3", "--times", f"c0={d / 'times.csv'}", "--calib-format", "json", "--units", "cm",
             "--calib", d / "calib.json", "--planes", "0,0.8", "--room", "-1,2,0,3")
    assert r.exit_code == 0, r.output
    rec = read_recording(d / "rec")
    np.testing.assert_allclose(rec.camera("c0").times_s, [10.0, 10.2])
    np.testing.assert_array_equal(rec.camera("c0").frame(1), frames[6])
    np.testing.assert_allclose(rec.camera("c1").times_s, 3.0 + np.arange(8) / 5.0)
    np.testing.assert_allclose(rec.camera("c1").camera.T_world_cam, cams[1].T_world_cam, atol=1e-9)
    assert rec.planes_heights_m == [0.0, 0.8] and rec.room_xy_m == (-1.0, 2.0, 0.0, 3.0)
    r = _cli("import", d / "rec2", "--camera", f"c0={d / 'c0.mkv'}", "--calib-format", "opencv", "--units", "cm",
             "--calib", d / "calib.json")
    assert r.exit_code == 2 and "a bare FILE serves every camera only for --calib-format json" in r.output


def test_json_errors_name_file_camera_and_field(tmp_path):
    from planefuse.calib import load_json_cameras

    p = tmp_path / "c.json"
    p.write_text(json.dumps({"cam7": {"fx": 1.0, "fy": 1.0, "cx": 0, "cy": 0, "R": np.eye(3).tolist()}}))
    with pytest.raises(ValueError, match=r"c.json: field 'cam7.t': missing \(give t/tvec"):
        load_json_cameras(p, metres_per_unit=1.0, sizes_px={"cam7": (W, H)})
    p.write_text(json.dumps({"cam7": {"K": K.tolist(), "R": (2 * np.eye(3)).tolist(), "t": [0, 0, 1]}}))
    with pytest.raises(ValueError, match=r"field 'cam7.R': not a rotation"):
        load_json_cameras(p, metres_per_unit=1.0, sizes_px={"cam7": (W, H)})
    with pytest.raises(ValueError, match=r"field 'cam9': no such camera \(the file has cam7\)"):
        load_json_cameras(p, metres_per_unit=1.0, keys=["cam9"])
    p.write_text("{not json")
    with pytest.raises(ValueError, match=r"c.json: field '<file>': not valid JSON"):
        load_json_cameras(p, metres_per_unit=1.0)


def test_ignore_rect_past_the_image_is_refused(installation):
    d = installation[0]
    r = _cli(*_import_args(d, "--units", "mm", "--ignore-rect", "c0=50,50,97,60"))
    assert r.exit_code == 2 and "ignore rectangle [50, 50, 97, 60] reaches past the 96x72 px image" in r.output, r.output


@settings(max_examples=40, deadline=None)
@given(height_m=st.floats(1.5, 12.0), tilt_deg=st.floats(20.0, 75.0), yaw_deg=st.floats(-180.0, 180.0),
       f_px=st.floats(150.0, 1500.0), x_m=st.floats(-20.0, 20.0), y_m=st.floats(-20.0, 20.0))
def test_camera_from_ground_homography_recovers_the_camera(height_m, tilt_deg, yaw_deg, f_px, x_m, y_m):
    """Property: a camera with square pixels and a centred principal point comes back from its ground homography."""
    from planefuse.calib import camera_from_ground_homography
    from planefuse.geometry import H_plane_image_calibrated

    yaw, tilt = np.radians(yaw_deg), np.radians(tilt_deg)
    c = np.array([x_m, y_m, height_m])
    look = np.array([np.cos(yaw) * np.cos(tilt), np.sin(yaw) * np.cos(tilt), -np.sin(tilt)])
    Kc = np.array([[f_px, 0.0, (W - 1) / 2], [0.0, f_px, (H - 1) / 2], [0.0, 0.0, 1.0]])
    cam = PinholeCamera(CameraIntrinsics(Kc, W, H), T_world_cam_look_at(c, c + look))
    got, err = camera_from_ground_homography(H_plane_image_calibrated(cam, 0.0), W, H)
    assert err < 1e-6
    np.testing.assert_allclose(got.K, Kc, rtol=1e-6)
    np.testing.assert_allclose(got.T_world_cam, cam.T_world_cam, atol=1e-6 * max(1.0, np.abs(c).max()))


def test_calib_show_reads_tsai_and_json(tmp_path):
    write_tsai_xml(tmp_path / "c1.xml", EPFL_TERRACE_TSAI["c1"])
    r = _cli("calib-show", tmp_path / "c1.xml", "--metres-per-unit", "0.001", "--width-px", "360", "--height-px", "288")
    assert r.exit_code == 0 and "-1.034 -1.225  2.109" in r.output and "360 x 288" in r.output, r.output
    (tmp_path / "c.json").write_text(json.dumps({"a": {"K": K.tolist(), "R": np.eye(3).tolist(), "T": [0, 0, -2000]}}))
    r = _cli("calib-show", tmp_path / "c.json", "--metres-per-unit", "0.001", "--width-px", str(W), "--height-px", str(H))
    assert r.exit_code == 0 and "a: centre in world [m]" in r.output and "-2.]" in r.output, r.output


def test_config_init_fits_an_imported_recording_and_run_refuses_a_missing_sensor(installation):
    """A camera-only recording: ``config init --recording`` enables the cameras alone, on the recording's planes and
    area; a configuration that asks for the laser and sound (the defaults) is refused by ``run`` with one line naming
    the fields, as ``check`` reports it, instead of running on without them."""
    d, *_ = installation
    out = d / "rec"
    r = _cli("import", out, "--camera", f"c0={d / 'c0.mkv'}", "--camera", f"c1={d / 'c1'}", "--rate", "c1=25",
             "--calib-format", "opencv", "--units", "mm", "--calib", f"c0={d / 'c0.yaml'}",
             "--calib", f"c1={d / 'c1.yaml'}", "--planes", "0.2,0.9", "--room", "-1,2,-1,3")
    assert r.exit_code == 0, r.output
    fitted, default = d / "fitted.yaml", d / "default.yaml"
    assert _cli("config", "init", fitted, "--recording", out).exit_code == 0
    assert _cli("config", "init", default, "--recording", d / "no-such-recording").exit_code == 0
    cfg = load_config(fitted)
    assert (cfg.sensors.cameras.enabled, cfg.sensors.laser.enabled, cfg.sensors.sound.enabled) == (True, False, False)
    assert cfg.planes.heights_m == [0.2, 0.9] and cfg.planes.x_range_m == (-1.0, 2.0)
    assert cfg.recording == out.resolve()
    assert load_config(default).sensors.laser.enabled  # no recording there: every default
    for path in (fitted, default):  # outputs beside the configuration, not in the working directory
        path.write_text(path.read_text().replace("out_dir: planefuse-out", f"out_dir: {d / path.stem}-out")
                        .replace(f"recording: {d / 'no-such-recording'}", f"recording: {out}"))
    r = _cli("check", fitted, "--log-json")
    assert r.exit_code == 0 and json.loads(r.output)["ok"], r.output
    # real video: the real-video profile (the generative model), so no warning about the per-cell model's ghosts
    assert cfg.sensors.cameras.sensor_model == "generative" and cfg.models.detection.column_threshold == 2.0
    assert not [i for i in json.loads(r.output)["issues"] if i["subject"] == "sensors.cameras.sensor_model"]
    # two cameras with the per-cell model (the simulated profile): a warning pointing at the generative model
    cell = d / "cell.yaml"
    assert _cli("config", "init", cell, "--recording", out, "--profile", "simulated").exit_code == 0
    cell.write_text(cell.read_text().replace("out_dir: planefuse-out", f"out_dir: {d / 'cell'}-out"))
    r = _cli("check", cell, "--log-json")
    (ghosts,) = [i for i in json.loads(r.output)["issues"] if i["subject"] == "sensors.cameras.sensor_model"]
    assert ghosts["level"] == "warning" and "sensor_model: generative" in ghosts["message"]
    # 25 Hz cameras at the default 5 Hz: said; an output rate above it: a warning
    (rate,) = [i for i in json.loads(r.output)["issues"] if i["subject"] == "sensors.cameras.max_rate_hz"]
    assert rate["level"] == "info" and "at up to 25 Hz are processed at most 5 times a second" in rate["message"]
    faster = d / "faster.yaml"
    faster.write_text(fitted.read_text().replace("output_period_s: 0.2", "output_period_s: 0.1"))
    r = _cli("check", faster, "--log-json")
    rates = [i for i in json.loads(r.output)["issues"] if i["subject"] == "sensors.cameras.max_rate_hz"]
    assert [i["level"] for i in rates] == ["info", "warning"] and "raise max_rate_hz to 10 Hz" in rates[1]["message"]
    # the "no filter" ablation at the cap: one frame per step, said
    text = fitted.read_text()
    at = text.index("    enabled: true", text.index("  filter:"))
    faster.write_text(text[:at] + "    enabled: false" + text[at + len("    enabled: true"):])
    r = _cli("check", faster, "--log-json")
    rates = [i for i in json.loads(r.output)["issues"] if i["subject"] == "sensors.cameras.max_rate_hz"]
    assert [i["level"] for i in rates] == ["info", "warning"] and "at most 1 at 5 Hz" in rates[1]["message"], rates
    r = _cli("check", default, "--log-json")
    assert r.exit_code == 1 and "no stream for sensors.laser.enabled, sensors.sound.enabled" in r.output, r.output
    r = _cli("run", default, "--quiet")
    assert r.exit_code == 1
    assert re.search(r"recording .*rec has no stream for sensors\.laser\.enabled, sensors\.sound\.enabled \(its "
                     r"streams: c0, c1\): set sensors\.laser\.enabled: false and sensors\.sound\.enabled: false",
                     " ".join(r.output.split())), r.output
    assert not (d / "default-out").exists()
    r = _cli("run", fitted)
    assert r.exit_code == 0, r.output
    assert (d / "fitted-out" / "tracks.csv").is_file()
    # no ground truth: no scores, but what the run consumed and produced, each camera's missing frames included
    m = json.loads((d / "fitted-out" / "metrics.json").read_text())
    # 8 frames at 25 Hz, the cameras at the default 5 Hz: 2 instants (0 and 0.2 s)
    assert "moda" not in m and m["n_steps"] >= 1 and m["n_camera_frames"] == 2
    assert m["missing_camera_frames"] == {"c0": 0, "c1": 0} and m["n_missing_camera_frames"] == 0
    assert re.search(r"n_steps\W+\d+", r.output) and "n_missing_camera_frames" in r.output


def test_a_recording_imported_without_an_area_gets_one_proposed_no_error_loop(installation):
    """Issue 38: without --room (and no ground truth) `check` and `config init` used to refuse with the same line;
    now both use the ground at least two cameras see, and say so."""
    d, *_ = installation
    out = d / "rec"
    r = _cli("import", out, "--camera", f"c0={d / 'c0.mkv'}", "--camera", f"c1={d / 'c1'}", "--rate", "c1=25",
             "--calib-format", "opencv", "--units", "mm", "--calib", f"c0={d / 'c0.yaml'}",
             "--calib", f"c1={d / 'c1.yaml'}")
    assert r.exit_code == 0, r.output
    assert "room_xy_m" not in (out / "scene.yaml").read_text()
    r = _cli("check", out, "--log-json", "--figures", d / "pictures")
    found = json.loads(r.output)
    assert any("monitored area proposed" in i["message"] for i in found["issues"]), r.output
    assert r.exit_code == 0 and found["ok"], r.output
    assert sorted(p.name for p in (d / "pictures").iterdir()) == ["camera_c0.png", "camera_c1.png", "coverage.png"]
    r = _cli("config", "init", d / "run.yaml", "--recording", out)
    assert r.exit_code == 0 and "monitored area proposed" in " ".join(r.output.split()), r.output
    cfg = load_config(d / "run.yaml")
    assert cfg.planes.x_range_m is not None and cfg.planes.y_range_m is not None
    assert cfg.planes.heights_m == [0.1, 0.5, 1.0, 1.5]  # import's default planes are the library's


def test_ignore_rects_in_the_run_configuration_equal_the_imports(installation):
    """Issue 38: an ignore region can be set in the run configuration (sensors.cameras.ignore_rects_px) as well as at
    import (--ignore-rect): the same pixels are unobserved; a wrong camera or a rectangle past the image is refused."""
    from planefuse.io import read_recording
    from planefuse.pipeline import recording_with_ignore_rects

    d, *_ = installation
    base = ["--camera", f"c0={d / 'c0.mkv'}", "--camera", f"c1={d / 'c1'}", "--rate", "c1=25", "--calib-format",
            "opencv", "--units", "mm", "--calib", f"c0={d / 'c0.yaml'}", "--calib", f"c1={d / 'c1.yaml'}"]
    assert _cli("import", d / "with", *base, "--ignore-rect", "c0=10,5,40,30").exit_code == 0
    assert _cli("import", d / "without", *base).exit_code == 0
    imported = read_recording(d / "with").camera("c0").ignore_mask
    plain = read_recording(d / "without")
    configured = recording_with_ignore_rects(plain, (("c0", 10, 5, 40, 30),))
    np.testing.assert_array_equal(configured.camera("c0").ignore_mask, imported)
    assert plain.camera("c0").ignore_mask is None  # the recording itself is not changed
    with pytest.raises(ValueError, match="names camera 'c9', which the recording does not have"):
        recording_with_ignore_rects(plain, (("c9", 0, 0, 5, 5),))
    with pytest.raises(ValueError, match=r"reaches past its 96x72 px image"):
        recording_with_ignore_rects(plain, (("c1", 50, 50, 97, 60),))
    r = _cli("config", "init", d / "run.yaml", "--recording", d / "without")
    assert r.exit_code == 0
    text = (d / "run.yaml").read_text().replace("ignore_rects_px: []", "ignore_rects_px: [[c0, 10, 5, 40, 30]]")
    (d / "run.yaml").write_text(text)
    assert load_config(d / "run.yaml").system_params().camera_ignore_rects_px == (("c0", 10, 5, 40, 30),)


# --------------------------------------------------------------------------- hostile image folders (issue 39)
def test_import_refuses_an_image_of_another_size_naming_it(installation):
    d, cams, frames, _ = installation
    cv2.imwrite(str(d / "c1" / "img_13.png"), np.zeros((H - 8, W - 8, 3), np.uint8))  # one odd frame in the middle
    r = _cli("import", d / "rec", "--camera", f"c1={d / 'c1'}", "--rate", "c1=25", "--calib-format", "opencv",
             "--units", "mm", "--calib", f"c1={d / 'c1.yaml'}")
    line = " ".join(r.output.split())
    assert r.exit_code == 2 and "img_13.png" in line and f"is {W - 8}x{H - 8} px, 7 of its 8 images are {W}x{H}" in line
    assert not (d / "rec").exists()


def test_a_gap_in_the_image_numbering_keeps_its_time(installation):
    """Images 10..17 with 12 and 13 missing at 25 Hz: each image is dated by its number (img_14 at 4 / 25 s, not
    2 / 25 s), the gap is said, and the recording reads back with the frames' own times."""
    d, cams, frames, _ = installation
    (d / "c1" / "img_12.png").unlink()
    (d / "c1" / "img_13.png").unlink()
    rep = import_recording(d / "lib", [CameraInput("c1", d / "c1", rate_hz=25.0)], {"c1": cams[1]})
    cs = read_recording(d / "lib").camera("c1")
    np.testing.assert_allclose(cs.times_s, np.array([0, 1, 4, 5, 6, 7]) / 25.0)
    np.testing.assert_array_equal(cs.frame(2), frames[4][::-1])
    assert "2 image number(s) missing (1 gap(s), the first 12..13 after img_11.png)" in rep.notes[0]


@pytest.mark.parametrize("names, match", [
    (["img_1.png", "img_01.png"], "has the number 1 of img_01.png|has the number 1 of img_1.png"),
    (["f_1000.png", "f_1040.png", "f_1080.png"], "numbers step by 40"),
    (["a_1.png", "a_2.png", "cover.png"], "cover.png: .*no number"),
])
def test_image_numbers_that_cannot_date_the_images_are_refused(tmp_path, names, match):
    (tmp_path / "c").mkdir()
    for n in names:
        cv2.imwrite(str(tmp_path / "c" / n), np.zeros((H, W, 3), np.uint8))
    cam = PinholeCamera(CameraIntrinsics(K, W, H), T_world_cam_look_at([0, -3, 3], [0, 1, 0]), name="c")
    with pytest.raises(ValueError, match=match):
        import_recording(tmp_path / "rec", [CameraInput("c", tmp_path / "c", rate_hz=25.0)], {"c": cam})
