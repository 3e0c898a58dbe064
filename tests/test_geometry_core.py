"""Geometry core: camera projection vs OpenCV, homography routes, plane stack, lookup."""

from __future__ import annotations

import cv2
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from planefuse.geometry import (
    CameraIntrinsics,
    H_image_plane_from_projection,
    H_plane_image_calibrated,
    H_plane_image_from_projection,
    H_plane_image_imu,
    PinholeCamera,
    T_world_cam_look_at,
    apply_homography,
    apply_transform,
    check_homography,
    default_camera_ring,
    homology,
    infinite_homography,
    invert_transform,
    mu_from_heights,
    normalize_homography,
    parallel_plane_homology,
    rotation_from_roll_pitch_yaw,
    roll_pitch_yaw_from_rotation,
    transform_from_rotation_translation,
)
from planefuse.grid import PlaneStack
from planefuse.registration import ImagePlaneLookup

K0 = np.array([[420.0, 0.0, 179.5], [0.0, 415.0, 143.5], [0.0, 0.0, 1.0]])
DIST0 = np.array([-0.21, 0.07, 0.0012, -0.0009, -0.01])


def random_camera(rng, dist=DIST0, name="cam") -> PinholeCamera:
    c = np.array([rng.uniform(-3, 3), rng.uniform(-3, 3), rng.uniform(2.0, 5.0)])
    target = np.array([rng.uniform(-0.5, 0.5), rng.uniform(-0.5, 0.5), 0.0])
    T = T_world_cam_look_at(c, target)
    # a random roll about the optical axis (the camera's z axis)
    T[:3, :3] = T[:3, :3] @ rotation_from_roll_pitch_yaw(0.0, 0.0, rng.uniform(-0.3, 0.3))
    return PinholeCamera(CameraIntrinsics(K0, 360, 288, dist), T, name)


# --- transforms ---------------------------------------------------------------
def test_transform_round_trip(rng):
    R = rotation_from_roll_pitch_yaw(*rng.uniform(-np.pi, np.pi, 3))
    T = transform_from_rotation_translation(R, rng.normal(size=3))
    p = rng.normal(size=(5, 7, 3))
    back = apply_transform(invert_transform(T), apply_transform(T, p))
    np.testing.assert_allclose(back, p, atol=1e-12)


def test_roll_pitch_yaw_round_trip(rng):
    a = rng.uniform([-3, -1.5, -3], [3, 1.5, 3], size=(20, 3))
    R = rotation_from_roll_pitch_yaw(a[:, 0], a[:, 1], a[:, 2])
    np.testing.assert_allclose(roll_pitch_yaw_from_rotation(R), a, atol=1e-9)


def test_bad_transform_raises():
    with pytest.raises(ValueError, match=r"\(\.\.\., 4, 4\)"):
        apply_transform(np.eye(3), np.zeros((1, 3)))
    with pytest.raises(ValueError, match="orthonormal"):
        apply_transform(np.diag([2.0, 1, 1, 1]), np.zeros((1, 3)))
    # NaN points (e.g. invalid returns) propagate rather than raise, as documented
    assert np.isnan(apply_transform(np.eye(4), np.array([[np.nan, 0, 0]]))).all()


# --- camera -----------------------------------------------------------------------
def test_projection_matches_opencv(rng):
    cam = random_camera(rng)
    pts = np.c_[rng.uniform(-1, 1, (200, 2)), rng.uniform(0, 1, 200)]
    uv = cam.project(pts)
    T = cam.T_cam_world
    rvec, _ = cv2.Rodrigues(T[:3, :3])
    ref, _ = cv2.projectPoints(pts, rvec, T[:3, 3], cam.K, cam.intrinsics.dist)
    ok = np.isfinite(uv).all(axis=1)
    assert ok.mean() > 0.9
    np.testing.assert_allclose(uv[ok], ref.reshape(-1, 2)[ok], atol=1e-6)


def test_points_behind_camera_are_nan():
    cam = PinholeCamera(CameraIntrinsics(K0, 360, 288), np.eye(4))
    uv = cam.project(np.array([[0.0, 0.0, -1.0], [0.0, 0.0, 0.0], [0.1, 0.0, 2.0]]))
    assert np.isnan(uv[:2]).all() and np.isfinite(uv[2]).all()


def test_batched_projection_equals_loop(rng):
    cam = random_camera(rng)
    pts = np.c_[rng.uniform(-3, 3, (4, 6, 2)), rng.uniform(0, 2, (4, 6, 1))]
    batched = cam.project(pts)
    loop = np.stack([cam.project(p) for p in pts])
    np.testing.assert_array_equal(batched, loop)


def test_backprojection_round_trip(rng):
    cam = random_camera(rng)
    pts = np.c_[rng.uniform(-2, 2, (100, 2)), np.full(100, 0.8)]
    uv = cam.project(pts)
    ok = cam.intrinsics.contains(uv)
    back = cam.backproject_to_height(uv[ok], 0.8)
    np.testing.assert_allclose(back, pts[ok], atol=1e-7)


def test_distortion_fold_is_nan():
    intr = CameraIntrinsics(K0, 360, 288, DIST0)
    assert 1.0 < intr.max_radius < 3.0
    uv = intr.pixels_from_normalized(np.array([[0.1, 0.1], [5.0, 0.0]]))
    assert np.isfinite(uv[0]).all() and np.isnan(uv[1]).all()


def test_undistort_matches_opencv(rng):
    intr = CameraIntrinsics(K0, 360, 288, DIST0)
    uv = rng.uniform([0, 0], [359, 287], (100, 2))
    ours = intr.undistort_pixels(uv)
    ref = cv2.undistortPoints(uv.reshape(-1, 1, 2), K0, DIST0, P=K0).reshape(-1, 2)
    np.testing.assert_allclose(ours, ref, atol=1e-3)  # OpenCV's default is 5 iterations
    # our iterative inverse is exact: re-distorting gives the input back
    xy = intr.normalized_from_pixels(uv)
    np.testing.assert_allclose(intr.pixels_from_normalized(xy), uv, atol=1e-8)


@pytest.mark.parametrize("dist", [np.zeros(5), DIST0])
def test_skewed_intrinsics_project_and_back_project(dist, rng):
    """A skew K[0, 1] (accepted by CameraIntrinsics) is used both ways; OpenCV's projectPoints and
    undistortPoints ignore it, so the references are analytic: u = K (x_d, y_d, 1) and round trips."""
    K = K0.copy()
    K[0, 1] = 12.0
    intr = CameraIntrinsics(K, 360, 288, dist)
    xy = rng.uniform(-0.3, 0.3, (50, 2))
    xd = intr.pixels_from_normalized(np.zeros((1, 2)))  # principal point whatever the distortion
    np.testing.assert_allclose(xd, [[K[0, 2], K[1, 2]]])
    uv = intr.pixels_from_normalized(xy)
    if not dist.any():
        np.testing.assert_allclose(uv, (np.c_[xy, np.ones(50)] @ K.T)[:, :2], atol=1e-9)
    np.testing.assert_allclose(intr.normalized_from_pixels(uv), xy, atol=1e-9)
    cam = PinholeCamera(intr, random_camera(rng).T_world_cam)
    pts = np.c_[rng.uniform(-2, 2, (100, 2)), np.full(100, 0.8)]
    uv = cam.project(pts)
    ok = intr.contains(uv)
    assert ok.sum() > 20
    np.testing.assert_allclose(cam.backproject_to_height(uv[ok], 0.8), pts[ok], atol=1e-7)


@pytest.mark.parametrize(
    "K, msg",
    [
        (np.eye(2), r"shape \(3, 3\)"),
        (np.diag([0.0, 1.0, 1.0]), "positive focal"),
        (np.array([[1.0, 0, 0], [0, 1, 0], [0, 0, np.nan]]), "non-finite"),
    ],
)
def test_bad_intrinsics(K, msg):
    with pytest.raises(ValueError, match=msg):
        CameraIntrinsics(K, 10, 10)


# --- homographies -------------------------------------------------------------
def test_eq4_is_eq3_special_case(rng):
    vx, vy, mu = rng.normal(size=3) + [0, 0, 2]
    np.testing.assert_allclose(homology([vx, vy, 1.0], [0, 0, 1.0], mu), parallel_plane_homology(vx, vy, mu))


def test_homology_fixes_vertex_and_axis(rng):
    v = rng.normal(size=3)
    a = rng.normal(size=3)
    H = homology(v, a, 1.7)
    np.testing.assert_allclose(np.cross(H @ v, v), 0, atol=1e-12)  # vertex fixed
    # points on the axis line a^T x = 0 are fixed
    x = np.cross(a, rng.normal(size=3))
    np.testing.assert_allclose(np.cross(H @ x, x), 0, atol=1e-12)


@settings(max_examples=60, deadline=None)
@given(
    cx=st.floats(-5, 5), cy=st.floats(-5, 5), cz=st.floats(1.5, 8),
    tx=st.floats(-4, 4), ty=st.floats(-4, 4), roll=st.floats(-0.5, 0.5),
    h=st.floats(0.0, 1.4),
)
def test_imu_route_equals_calibration_route(cx, cy, cz, tx, ty, roll, h):
    if np.hypot(tx - cx, ty - cy) < 0.2:
        tx += 1.0
    T = T_world_cam_look_at((cx, cy, cz), (tx, ty, 0.0))
    c, s = np.cos(roll), np.sin(roll)
    T[:3, :3] = T[:3, :3] @ np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])
    cam = PinholeCamera(CameraIntrinsics(K0, 360, 288), T)
    a = normalize_homography(H_plane_image_imu(cam.K, cam.R_world_cam, cam.center_world, h))
    b = normalize_homography(H_plane_image_from_projection(cam.P_image_world, h))
    assert np.abs(a - b).max() <= 1e-9


def test_infinite_homography_is_pure_rotation(rng):
    cam = random_camera(rng, dist=np.zeros(5))
    H = infinite_homography(K0, np.eye(3), K0)
    np.testing.assert_allclose(H, np.eye(3), atol=1e-12)
    # the virtual camera's image of a world point equals the infinite homography of the real image
    from planefuse.geometry import R_virtual_cam_from_R_world_cam, R_world_virtual
    R_vc = R_virtual_cam_from_R_world_cam(cam.R_world_cam)
    virt = PinholeCamera(CameraIntrinsics(K0, 360, 288),
                         transform_from_rotation_translation(R_world_virtual, cam.center_world))
    pts = np.c_[rng.uniform(-1, 1, (20, 2)), np.zeros(20)]
    uv_real = cam.project(pts)
    uv_virt = virt.project(pts)
    np.testing.assert_allclose(apply_homography(infinite_homography(K0, R_vc, K0), uv_real), uv_virt, atol=1e-8)


def test_plane_round_trip_and_warp_matches_opencv(rng):
    cam = random_camera(rng, dist=np.zeros(5))
    for h in (0.0, 1.0):
        H_pi = H_plane_image_calibrated(cam, h)
        H_ip = np.linalg.inv(H_pi)
        xy = rng.uniform(-1, 1, (50, 2))
        uv = apply_homography(H_ip, xy)
        np.testing.assert_allclose(apply_homography(H_pi, uv), xy, atol=1e-9)
        np.testing.assert_allclose(uv, cam.project(np.c_[xy, np.full(50, h)]), atol=1e-7)
    # warp an image to a plane grid: our lookup gather vs cv2.warpPerspective (nearest)
    stack = PlaneStack.from_extent([0.0], (-2, 2), (-2, 2), 0.02)
    img = rng.integers(0, 255, (288, 360)).astype(np.float32)
    lut = ImagePlaneLookup.from_camera(cam, stack)
    ours = lut.gather(img)[0]
    H_grid_image = stack.H_grid_plane() @ H_plane_image_calibrated(cam, 0.0)
    ref = cv2.warpPerspective(img, H_grid_image, (stack.nx, stack.ny), flags=cv2.INTER_NEAREST,
                              borderMode=cv2.BORDER_CONSTANT, borderValue=-1)
    both = np.isfinite(ours) & (ref >= 0)
    assert both.sum() > 5000
    assert (ours[both] == ref[both]).mean() > 0.99  # rounding ties may differ


def test_plane_above_camera_raises(rng):
    cam = random_camera(rng)
    with pytest.raises(ValueError, match="above the camera"):
        H_plane_image_calibrated(cam, cam.center_world[2] + 0.1)
    with pytest.raises(ValueError, match="above the camera"):
        mu_from_heights(2.0, 2.0)


def test_camera_looking_up_raises():
    T = T_world_cam_look_at((0, 0, 2.0), (0, 0.1, 10.0), up_world=(0, 1, 0))
    cam = PinholeCamera(CameraIntrinsics(K0, 360, 288), T)
    with pytest.raises(ValueError, match="no pixel ray"):
        H_plane_image_calibrated(cam, 0.0)


def test_camera_in_plane_edge_on_is_singular():
    T = T_world_cam_look_at((0, 0, 1.0), (5, 0, 1.0))
    cam = PinholeCamera(CameraIntrinsics(K0, 360, 288), T)
    with pytest.raises(ValueError, match="singular"):
        H_plane_image_from_projection(cam.P_image_world, 1.0)


def test_singular_homography_raises():
    with pytest.raises(ValueError, match="singular"):
        check_homography(np.diag([1.0, 1.0, 0.0]))
    with pytest.raises(ValueError, match=r"\(\.\.\., 3, 3\)"):
        apply_homography(np.eye(2), np.zeros((1, 2)))
    with pytest.raises(ValueError, match=r"\(\.\.\., N, 2\)"):
        apply_homography(np.eye(3), np.zeros((4, 3)))


def test_batched_plane_homographies(rng):
    cam = random_camera(rng)
    hs = np.array([0.0, 0.5, 1.0])
    H = H_image_plane_from_projection(cam.P_image_world, hs)
    assert H.shape == (3, 3, 3)
    for i, h in enumerate(hs):
        np.testing.assert_allclose(H[i], H_image_plane_from_projection(cam.P_image_world, h))


# --- plane stack and lookup ------------------------------------------------------
def test_plane_stack_indices(rng):
    st_ = PlaneStack.from_extent([0.0, 0.5, 1.0], (-1, 3), (0, 2), 0.1)
    assert st_.shape == (3, 20, 40)
    xy = rng.uniform([-1, 0], [3, 2], (100, 2))
    iy, ix = st_.index_from_xy(xy)
    back = st_.xy_from_index(iy, ix)
    assert np.all(np.abs(back - xy) <= 0.05 + 1e-12)
    iy, ix = st_.index_from_xy(np.array([[-2.0, 0.5], [np.nan, 0.0]]))
    assert (iy == -1).all() and (ix == -1).all()
    fy, fx = st_.fractional_index_from_xy(xy)  # the inverse of xy_from_index, cell centres at whole numbers
    np.testing.assert_allclose(st_.xy_from_index(fy, fx), xy, atol=1e-12)
    np.testing.assert_array_equal(np.floor(fy + 0.5), st_.index_from_xy(xy)[0])
    np.testing.assert_array_equal(np.floor(fx + 0.5), st_.index_from_xy(xy)[1])
    np.testing.assert_array_equal(st_.plane_index_from_z([0.1, 0.3, 0.9, 1.3, -0.1]), [0, 1, 2, -1, -1])


@pytest.mark.parametrize(
    "kw, msg",
    [
        (dict(heights_m=(1.0, 0.5)), "increasing"),
        (dict(heights_m=()), "at least one"),
        (dict(cell_size_m=0.0), "cell_size_m"),
        (dict(nx=0), "positive"),
        (dict(heights_m=(0.0, np.nan)), "finite"),
    ],
)
def test_plane_stack_bad_input(kw, msg):
    base = dict(heights_m=(0.0, 1.0), x_min_m=0.0, y_min_m=0.0, cell_size_m=0.1, nx=10, ny=10)
    base.update(kw)
    with pytest.raises(ValueError, match=msg):
        PlaneStack(**base)


def test_lookup_from_camera_and_homographies_agree(rng):
    cam = random_camera(rng, dist=np.zeros(5))
    stack = PlaneStack.from_extent([0.0, 0.6, 1.2], (-2, 2), (-2, 2), 0.05)
    a = ImagePlaneLookup.from_camera(cam, stack)
    H = np.stack([np.linalg.inv(H_plane_image_calibrated(cam, h)) for h in stack.heights_m])
    b = ImagePlaneLookup.from_homographies(H, 360, 288, stack)
    assert (a.pixel_index == b.pixel_index).mean() > 0.999


def test_lookup_gather_wrong_size_raises(rng):
    cam = default_camera_ring()[0]
    stack = PlaneStack.from_extent([0.0], (0, 10), (0, 10), 0.1)
    lut = ImagePlaneLookup.from_camera(cam, stack)
    with pytest.raises(ValueError, match=r"must have shape \(288, 360\)"):
        lut.gather(np.zeros((100, 100)))
    out = lut.gather(np.ones((288, 360)))
    assert np.isnan(out[~lut.visible]).all() and (out[lut.visible] == 1).all()
