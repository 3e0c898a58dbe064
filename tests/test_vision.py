"""Camera pipeline: foreground likelihoods, multi-view fusion on the plane stack, people on the ground."""

from __future__ import annotations

import cv2
import numpy as np
import pytest
from _cylinders import render_cylinder_mask

from planefuse.eval import detection_scores
from planefuse.geometry import (
    CameraIntrinsics,
    H_image_plane_from_projection,
    PinholeCamera,
    T_world_cam_look_at,
    default_camera_ring,
)
from planefuse.grid import PlaneStack
from planefuse.vision import (
    BackgroundSubtractor,
    CameraFusion,
    CameraParams,
    CameraReport,
    ForegroundParams,
    FusionParams,
    PersonParams,
    camera_detections,
    foreground_from_boxes,
    foreground_from_mask,
    ground_detections_from_log_odds,
    log_odds_table,
    lookups_from_cameras,
    max_log_ratio,
    read_mot_detections,
)


def _pinhole_ring():
    cams = []
    for c in default_camera_ring():
        intr = CameraIntrinsics(c.K, c.intrinsics.width_px, c.intrinsics.height_px, np.zeros(5))
        cams.append(PinholeCamera(intr, c.T_world_cam, c.name))
    return cams


def _separated(rng, n, lo=1.0, hi=9.0, min_d=0.7):
    while True:
        xy = rng.uniform(lo, hi, (n, 2))
        d = np.linalg.norm(xy[:, None] - xy[None], axis=-1) + 99 * np.eye(n)
        if d.min() > min_d:
            return xy


# -- foreground ------------------------------------------------------------------------------------------
@pytest.mark.parametrize("downscale", [1, 2])
@pytest.mark.parametrize("method", ["mog2", "knn"])
def test_background_subtraction_likelihood(method, downscale, rng):
    h, w = 96, 128
    bg = cv2.GaussianBlur(rng.uniform(60, 200, (h, w)).astype(np.float32), (0, 0), 3)
    params = ForegroundParams(method=method, history=50, downscale=downscale)
    bs = BackgroundSubtractor(w, h, params, "camX")
    for _ in range(40):
        like = bs.apply(np.clip(bg + rng.normal(0, 2, bg.shape), 0, 255).astype(np.uint8))
    frame = bg.copy()
    frame[30:70, 50:70] = 250.0  # a bright "person"
    frame[75:90, 20:60] *= 0.6  # a shadow: same texture, darker
    like = bs.apply(np.clip(frame + rng.normal(0, 2, bg.shape), 0, 255).astype(np.uint8))
    assert like.dtype == np.float32 and like.shape == (h, w)
    assert params.floor <= like.min() and like.max() <= params.ceiling
    assert like[35:65, 55:65].mean() > 0.9
    assert like[:25].mean() < 0.1
    assert like[78:88, 25:55].mean() < 0.5  # shadows are not people
    with pytest.raises(ValueError, match="camX.*96x128"):
        bs.apply(np.zeros((h, w + 1), np.uint8))


def test_reduced_resolution_subtractor_sees_the_frame_reduced_and_answers_at_full_size(rng):
    h, w = 96, 128
    full, half = (BackgroundSubtractor(w, h, ForegroundParams(downscale=d, relearn_fraction=0.5)) for d in (1, 2))
    assert full._model.getDist2Threshold() == 400 and half._model.getDist2Threshold() == 200  # 400 / downscale
    assert BackgroundSubtractor(w, h, ForegroundParams(downscale=2, threshold=300))._model.getDist2Threshold() == 300
    bg = np.clip(cv2.GaussianBlur(rng.uniform(60, 200, (h, w)).astype(np.float32), (0, 0), 3), 0, 255)
    half.prime(bg.astype(np.uint8))
    like = half.apply(bg.astype(np.uint8))
    assert like.shape == (h, w) and like.max() == pytest.approx(0.02)
    relearn = half.apply(np.full((h, w), 255, np.uint8))  # everything changed: no evidence, at the camera's size
    assert relearn.shape == (h, w) and np.all(relearn == 0.5)
    with pytest.raises(ValueError, match="downscale"):
        ForegroundParams(downscale=0)


def test_knn_samples_reach_opencv_and_fewer_still_find_the_person(rng):
    """``knn_samples`` is OpenCV's nSamples (default 7, OpenCV's own); 3 finds the same bright person."""
    h, w = 96, 128
    assert BackgroundSubtractor(w, h)._model.getNSamples() == 7 == cv2.createBackgroundSubtractorKNN().getNSamples()
    bs = BackgroundSubtractor(w, h, ForegroundParams(history=50, knn_samples=3))
    assert bs._model.getNSamples() == 3
    bg = cv2.GaussianBlur(rng.uniform(60, 200, (h, w)).astype(np.float32), (0, 0), 3)
    for _ in range(40):
        bs.apply(np.clip(bg + rng.normal(0, 2, bg.shape), 0, 255).astype(np.uint8))
    frame = bg.copy()
    frame[30:70, 50:70] = 250.0
    like = bs.apply(np.clip(frame + rng.normal(0, 2, bg.shape), 0, 255).astype(np.uint8))
    assert like[35:65, 55:65].mean() > 0.9 and like[:25].mean() < 0.1
    with pytest.raises(ValueError, match="knn_samples"):
        ForegroundParams(knn_samples=1)


@pytest.mark.parametrize("method", ["mog2", "knn", "mean"])
def test_priming_with_the_empty_scene_sees_people_present_from_the_start(method, rng):
    """A person standing still in view from the first frame: a cold model learns it as background
    (a ghost), one primed with the empty-scene plate keeps it foreground."""
    h, w = 96, 128
    bg = cv2.GaussianBlur(rng.uniform(60, 200, (h, w)).astype(np.float32), (0, 0), 3)
    scene = bg.copy()
    scene[30:70, 50:70] = 250.0
    params = ForegroundParams(method=method, history=500)
    cold, primed = BackgroundSubtractor(w, h, params), BackgroundSubtractor(w, h, params)
    primed.prime(np.clip(bg, 0, 255).astype(np.uint8))
    for _ in range(30):
        frame = np.clip(scene + rng.normal(0, 2, bg.shape), 0, 255).astype(np.uint8)
        like_cold, like_primed = cold.apply(frame), primed.apply(frame)
    assert like_primed[35:65, 55:65].mean() > 0.9 and like_primed[:25].mean() < 0.1
    assert like_cold[35:65, 55:65].mean() < 0.5
    with pytest.raises(ValueError, match="96x128"):
        primed.prime(np.zeros((h + 1, w), np.uint8))
    with pytest.raises(ValueError, match="n_frames"):
        primed.prime(np.clip(bg, 0, 255).astype(np.uint8), n_frames=0)


def test_the_plates_default_frames_fill_knns_sample_memory(rng):
    """KNN primed with too few plate frames calls the empty scene foreground (samples still unfilled); the default
    (10) and more do not; CNT's default is twice its stability count."""
    h, w = 96, 128
    bg = np.clip(cv2.GaussianBlur(rng.uniform(60, 200, (h, w, 3)).astype(np.float32), (0, 0), 3), 0, 255)
    share = {}
    for n in (2, None, 30):
        bs = BackgroundSubtractor(w, h, ForegroundParams())
        bs.prime(bg.astype(np.uint8), n)
        frames = (np.clip(bg + rng.normal(0, 3, bg.shape), 0, 255).astype(np.uint8) for _ in range(5))
        share[n] = np.mean([(bs.apply(f) > 0.5).mean() for f in frames])
    assert share[2] > 0.9 and share[None] == share[30] == 0.0
    assert ForegroundParams().n_plate_frames == 10 and ForegroundParams(plate_frames=3).n_plate_frames == 3
    assert ForegroundParams(method="cnt", cnt_min_stability=12).n_plate_frames == 24
    with pytest.raises(ValueError, match="plate_frames"):
        ForegroundParams(plate_frames=0)


@pytest.mark.parametrize("params", [
    ForegroundParams(),
    ForegroundParams(method="mog2", open_px=3, shadow_likelihood=0.3),
    ForegroundParams(detect_shadows=False, floor=0.0, ceiling=1.0),  # 0.5 * 255 = 127.5: the rounding's tie
    ForegroundParams(relearn_fraction=0.3, relearn_frames=2),
    ForegroundParams(blur_px=3),  # the float image is needed: blurred, then quantised
    ForegroundParams(downscale=2),  # resized, then quantised
], ids=["knn", "mog2-open", "no-shadows", "relearn", "blur", "downscale"])
def test_quantised_foreground_is_the_fusions_levels_of_the_likelihood(params, rng):
    """``apply(quantised=True)`` (what the front ends hand the per-cell fusion) is ``quantise_foreground`` of the
    float likelihood, level for level, frame after frame (two models fed the same frames draw the same seeds)."""
    from planefuse.vision import quantise_foreground

    h, w = 96, 128
    bg = cv2.GaussianBlur(rng.uniform(60, 200, (h, w, 3)).astype(np.float32), (0, 0), 3)
    as_float, as_levels = (BackgroundSubtractor(w, h, params) for _ in range(2))
    for bs in (as_float, as_levels):
        bs.prime(np.clip(bg, 0, 255).astype(np.uint8))
    for k in range(12):
        frame = bg + rng.normal(0, 2, bg.shape)
        frame[20 + 3 * k:60 + 3 * k, 40:60] = 240.0  # a person walking down
        frame[70:85, 10:50] *= 0.6  # a shadow
        if k == 6:
            frame += 120.0  # a sudden global change (relearning where enabled)
        frame = np.clip(frame, 0, 255).astype(np.uint8)
        like, levels = as_float.apply(frame), as_levels.apply(frame, quantised=True)
        assert like.dtype == np.float32 and levels.dtype == np.uint8
        np.testing.assert_array_equal(levels, quantise_foreground(like))
    assert len(np.unique(levels)) >= 2


def test_frozen_frame_is_told_by_every_pixel_not_the_first_row(rng):
    """The frozen-frame check looks at the first row first: a frame whose first row repeats the previous one's
    and whose rest differs is live; only a bit-identical frame is frozen."""
    from planefuse.vision import frame_is_dead

    prev = rng.integers(20, 230, (48, 64, 3), dtype=np.uint8)
    same_top = prev.copy()
    same_top[30, 40, 1] ^= 1  # one pixel below the first row
    other_top = prev.copy()
    other_top[0, 0, 0] ^= 1
    assert not frame_is_dead(same_top, prev) and not frame_is_dead(other_top, prev)
    assert frame_is_dead(prev.copy(), prev)
    assert not frame_is_dead(prev, None) and not frame_is_dead(prev, prev[:40])  # no previous, another size
    assert frame_is_dead(np.full((48, 64, 3), 8, np.uint8), None)  # black: mean level 8


def test_external_masks_and_boxes(tmp_path):
    m = np.zeros((10, 12), np.uint8)
    m[2:5, 3:7] = 255
    f = foreground_from_mask(m, 12, 10)
    assert f[3, 4] == pytest.approx(0.98) and f[0, 0] == pytest.approx(0.02)
    np.testing.assert_allclose(foreground_from_mask(m > 0), f)
    with pytest.raises(ValueError, match=r"10x13.*\(10, 12\)"):
        foreground_from_mask(m, 13, 10)
    with pytest.raises(ValueError, match=r"\[0, 1\]"):
        foreground_from_mask(np.full((4, 4), 2.0))
    # MOTChallenge rows: frame, id, left, top, width, height, conf, x, y, z
    p = tmp_path / "det.txt"
    p.write_text("1,-1,3,2,4,3,0.9,-1,-1,-1\n2,-1,0,0,2,2,0.5,-1,-1,-1\n1,-1,8,6,3,3,1.0,-1,-1,-1\n")
    det = read_mot_detections(p)
    assert sorted(det) == [1, 2] and det[1].shape == (2, 5)
    img = foreground_from_boxes(det[1][:, :4], 12, 10, det[1][:, 4], floor=0.0, ceiling=1.0)
    rows, cols = np.arange(10)[:, None], np.arange(12)
    second = (rows >= 6) & (rows < 9) & (cols >= 8) & (cols < 11)  # left 8, top 6, 3 x 3
    np.testing.assert_array_equal(img > 0, (m > 0) | second)
    assert img[3, 4] == pytest.approx(0.9)
    assert foreground_from_boxes(np.zeros((0, 4)), 12, 10).max() == pytest.approx(0.02)  # empty: background


# -- fusion ------------------------------------------------------------------------------------------------
def test_fusion_matches_warp_perspective_reference(rng):
    cams = _pinhole_ring()
    stack = PlaneStack.from_extent([0.0, 0.8, 1.6], (-6, 16), (-6, 16), 0.1)  # beyond every camera's view
    params = FusionParams()
    fusion = CameraFusion(lookups_from_cameras(cams, stack, route="projection"), stack, params)
    fgs = [np.round(rng.random((288, 360)) * 255).astype(np.float32) / 255 for _ in cams]
    ours = fusion.log_odds(fgs)
    ref = np.zeros(stack.shape)
    G = np.linalg.inv(stack.H_grid_plane())
    table = log_odds_table(params)
    for cam, fg in zip(cams, fgs):
        for l, h in enumerate(stack.heights_m):
            H = H_image_plane_from_projection(cam.P_image_world, h) @ G
            q = cv2.warpPerspective((fg * 255).round().astype(np.float32), H, (stack.nx, stack.ny),
                                    flags=cv2.INTER_NEAREST | cv2.WARP_INVERSE_MAP, borderValue=np.nan)
            ref[l] += np.where(np.isfinite(q), table[np.nan_to_num(q).astype(int)], 0.0)
    # OpenCV's nearest neighbour (fixed-point coordinates) and the lookup's rint differ on near-ties;
    # with per-pixel independent noise every such cell shows, yet they stay below 2 %. Compared in the
    # room only: outside, warpPerspective also maps points behind a camera into its image.
    xy = stack.cell_centers_xy()
    room = np.all((xy > 0) & (xy < 10), axis=-1)
    assert np.mean(np.abs(ours - ref)[:, room] < 1e-4) > 0.98
    # Cells a camera does not see are unknown (0), not free.
    one = CameraFusion(lookups_from_cameras(cams[:1], stack), stack, params)
    alone = one.log_odds(fgs[:1])
    unseen = one.cameras_seeing() == 0
    assert unseen.mean() > 0.3 and np.all(alone[unseen] == 0) and np.all(alone[~unseen] != 0)


def test_imu_and_projection_routes_agree():
    cams = _pinhole_ring()
    stack = PlaneStack.from_extent([0.0, 1.0], (0, 10), (0, 10), 0.1)
    for a, b in zip(lookups_from_cameras(cams, stack, "imu"), lookups_from_cameras(cams, stack, "projection")):
        np.testing.assert_array_equal(a.visible, b.visible)
        # The principal point sits on a half pixel, so cell centres often round to either neighbour.
        ia, ib = a.pixel_index[a.visible], b.pixel_index[b.visible]
        assert np.abs(ia % 360 - ib % 360).max() <= 1 and np.abs(ia // 360 - ib // 360).max() <= 1
        assert np.mean(ia == ib) > 0.98
    with pytest.raises(ValueError, match="route"):
        lookups_from_cameras(cams, stack, "warp")


def test_missing_camera_equals_fusing_the_others(rng):
    cams = _pinhole_ring()
    stack = PlaneStack.from_extent([0.1, 1.0], (0, 10), (0, 10), 0.1)
    lks = lookups_from_cameras(cams, stack)
    fgs = [rng.random((288, 360)).astype(np.float32) for _ in cams]
    with_gap = CameraFusion(lks, stack).log_odds([fgs[0], None, fgs[2], fgs[3]])
    subset = CameraFusion([lks[0], lks[2], lks[3]], stack).log_odds([fgs[0], fgs[2], fgs[3]])
    np.testing.assert_allclose(with_gap, subset, atol=1e-5)


def test_fusion_is_the_sum_of_table_values_at_every_camera_pixel_exactly(rng):
    """The kernel against a plain numpy sum over cameras of ``table[f]`` at the pixel each cell sees, on
    lookups that use every pixel, corners (pixel 0) included; a camera without a frame adds nothing."""
    from planefuse.registration import ImagePlaneLookup

    stack = PlaneStack.from_extent([0.0, 1.0], (0.0, 1.2), (0.0, 0.8), 0.1)  # 8 x 12 cells per plane
    # 12 x 8 px images, one pixel per cell centre (x = 0.05 m -> u = 0); the second camera sees it mirrored
    # and its second plane only half
    H0 = np.array([[10.0, 0.0, -0.5], [0.0, 10.0, -0.5], [0.0, 0.0, 1.0]])
    H1 = np.array([[-10.0, 0.0, 11.5], [0.0, 10.0, -0.5], [0.0, 0.0, 1.0]])
    H1b = H1 @ np.diag([2.0, 1.0, 1.0])
    lks = [ImagePlaneLookup.from_homographies(np.stack([H0, H0]), 12, 8, stack),
           ImagePlaneLookup.from_homographies(np.stack([H1, H1b]), 12, 8, stack)]
    fusion = CameraFusion(lks, stack)
    table = log_odds_table(FusionParams()).astype(np.float64)
    fgs = [rng.integers(0, 256, (8, 12), dtype=np.uint8) for _ in lks]
    assert fgs[0][0, 0] != 0 or fgs[1][0, 0] != 0

    def reference(images):
        ref = np.zeros(stack.shape)
        for lk, img in zip(lks, images):
            if img is None:
                continue
            idx = lk.pixel_index.astype(np.int64)
            seen = idx < lk.sentinel
            ref[seen] += table[img.reshape(-1)[idx[seen]]]
        return ref

    assert np.all(lks[0].pixel_index < lks[0].sentinel) and 0 in lks[0].pixel_index
    np.testing.assert_allclose(fusion.log_odds(fgs), reference(fgs), atol=1e-5)
    np.testing.assert_allclose(fusion.log_odds([None, fgs[1]]), reference([None, fgs[1]]), atol=1e-5)
    np.testing.assert_array_equal(fusion.cameras_seeing([False, True]), (lks[1].pixel_index < lks[1].sentinel))


def test_bad_inputs(rng):
    cams = _pinhole_ring()
    stack = PlaneStack.from_extent([0.1, 1.0], (0, 10), (0, 10), 0.1)
    fusion = CameraFusion(lookups_from_cameras(cams, stack), stack, names=["a", "b", "c", "d"])
    good = np.zeros((288, 360), np.float32)
    with pytest.raises(ValueError, match="b: foreground must be 288x360"):
        fusion.log_odds([good, np.zeros((240, 320), np.float32), good, good])
    with pytest.raises(ValueError, match="expected 4"):
        fusion.log_odds([good])
    # Empty masks: every seen cell is evidence of "free", no detection.
    L = fusion.log_odds([good] * 4)
    assert np.all(L[fusion.cameras_seeing() > 0] < 0)
    det = ground_detections_from_log_odds(L, fusion.cameras_seeing(), stack, 0.0, max_log_ratio(FusionParams()))
    assert len(det) == 0
    # A camera looking at the sky sees no cell: warned, adds nothing.
    sky = PinholeCamera(cams[0].intrinsics, T_world_cam_look_at((5, 5, 3), (5, 6, 10)), "sky")
    with pytest.warns(UserWarning, match="sky"):
        f2 = CameraFusion(lookups_from_cameras(cams + [sky], stack), stack, names=list("abcd") + ["sky"])
    assert f2.blind_cameras == ["sky"]
    np.testing.assert_allclose(f2.log_odds([good] * 4 + [np.ones((288, 360), np.float32)]), L)
    with pytest.raises(ValueError, match="p_false_alarm"):
        FusionParams(p_detect=0.3, p_false_alarm=0.5)


# -- people ------------------------------------------------------------------------------------------------
def test_people_found_and_multiplane_beats_ground_plane(rng):
    cams = default_camera_ring()
    scenes = []
    for _ in range(6):
        xy = _separated(rng, 10)
        hs = rng.uniform(1.55, 1.9, len(xy))
        scenes.append((xy, hs, [foreground_from_mask(render_cylinder_mask(c, xy, hs, 0.2)) for c in cams]))
    moda = {}
    for heights in ([0.1], [0.1, 0.5, 1.0, 1.5]):
        stack = PlaneStack.from_extent(heights, (0, 10), (0, 10), 0.05)
        fusion = CameraFusion(lookups_from_cameras(cams, stack), stack)
        frames = []
        for xy, hs, fgs in scenes:
            det = ground_detections_from_log_odds(fusion.log_odds(fgs), fusion.cameras_seeing(), stack, 0.0,
                                                  max_log_ratio(fusion.params))
            frames.append((xy, det.xy_m))
            if len(heights) > 1:
                assert np.all(det.height_m == pytest.approx(1.75))  # head between the 1.5 m plane and the band top
        s = detection_scores(frames, 0.5)
        moda[len(heights)] = s.moda
        if len(heights) > 1:
            assert s.mean_distance_m < 0.1
    # Exact silhouettes of 10 people in 8 x 8 m: the ground plane alone is fooled by ghosts (silhouette
    # intersections of different people); the column model over 4 planes removes most of them.
    assert moda[4] >= 0.85
    assert moda[4] > moda[1] + 0.1


def test_pipeline_reports_missing_frames(rng):
    cams = default_camera_ring()
    stack = PlaneStack.from_extent([0.1, 0.5, 1.0, 1.5], (0, 10), (0, 10), 0.1)
    xy = np.array([[4.0, 5.0], [6.5, 3.0]])
    fgs = [foreground_from_mask(render_cylinder_mask(c, xy, 1.7)) for c in cams]
    frames = [(0.0, fgs), (0.04, [fgs[0], None, fgs[2], fgs[3]])]
    report = CameraReport()
    with pytest.warns(UserWarning, match="cam1: no frame at t=0.04"):
        out = list(camera_detections(frames, lookups_from_cameras(cams, stack), stack,
                                     CameraParams(foreground=None), report=report))
    assert report.instants == 2 and report.missing_frames == {"cam1": [0.04]}
    for ev, det in out:
        assert ev.log_odds.shape == stack.shape and ev.sensor == "cameras"
        assert detection_scores([(xy, det.xy_m)], 0.3).moda == 1.0
    with pytest.raises(ValueError, match="min_agreement"):
        PersonParams(min_agreement=0.0)


def test_fusion_weights_each_camera_by_its_own_weight(rng):
    """``weights``: the fused log-odds are the weighted sum of each camera fused alone; out-of-range or
    wrongly sized weights are refused."""
    cams = _pinhole_ring()
    stack = PlaneStack.from_extent([0.1, 1.0], (0, 10), (0, 10), 0.1)
    lks = lookups_from_cameras(cams, stack)
    fgs = [rng.random((288, 360)).astype(np.float32) for _ in cams]
    fusion = CameraFusion(lks, stack)
    w = [0.08, 1.0, 0.0, 0.5]
    alone = [fusion.log_odds([fg if k == c else None for k in range(4)]).copy() for c, fg in enumerate(fgs)]
    np.testing.assert_allclose(fusion.log_odds(fgs, weights=w), sum(wc * a for wc, a in zip(w, alone)), atol=1e-5)
    np.testing.assert_array_equal(fusion.log_odds(fgs, weights=[1.0] * 4), fusion.log_odds(fgs))
    for bad in ([1.0] * 3, [1.0, 1.0, 1.0, 1.5], [1.0, 1.0, 1.0, np.nan]):
        with pytest.raises(ValueError, match="weights"):
            fusion.log_odds(fgs, weights=bad)


def test_a_camera_back_from_a_dropout_counts_as_a_fresh_observation():
    """Regression (camera_dropout, tuning seed 1: the cameras' correlation weighting was applied to their fused
    message, so a camera back after seconds black or frozen counted 0.08 of an observation, like a camera that
    had just delivered a frame, and the filter could not catch up with a walker who had turned meanwhile).
    Four cameras at 25 Hz, correlation time 0.5 s; cam1 delivers no frame for 0.2 s. Each camera is weighted by
    the time since its own previous live frame: the three others 0.04 / 0.5 at every instant, cam1 0.24 / 0.5 at
    its return and its first frame ever 1; the detections are those of the unweighted evidence."""
    cams = default_camera_ring()
    stack = PlaneStack.from_extent([0.1, 0.5, 1.0, 1.5], (0, 10), (0, 10), 0.1)
    lks = lookups_from_cameras(cams, stack)
    fgs = [foreground_from_mask(render_cylinder_mask(c, np.array([[4.0, 5.0]]), 1.7)) for c in cams]
    times = np.arange(12) * 0.04
    gap = (times > 0.1) & (times < 0.3)  # cam1's frames at 0.12 .. 0.28 s never arrive
    frames = [(t, [fgs[0], None if g else fgs[1], fgs[2], fgs[3]]) for t, g in zip(times, gap)]
    with pytest.warns(UserWarning, match="cam1: no frame"):
        weighted = list(camera_detections(frames, lks, stack, CameraParams(foreground=None), correlation_s=0.5))
        plain = list(camera_detections(frames, lks, stack, CameraParams(foreground=None)))
    fusion = CameraFusion(lks, stack)
    alone = [fusion.log_odds([fg if k == c else None for k in range(4)]).copy() for c, fg in enumerate(fgs)]
    back = int(np.flatnonzero(~gap & (times > 0.3))[0])  # cam1's first frame after the gap, t = 0.32 s
    expected_w = {0: [1.0] * 4, 1: [0.08] * 4, back: [0.08, 0.48, 0.08, 0.08]}
    for i, w in expected_w.items():
        np.testing.assert_allclose(weighted[i][0].log_odds, sum(wc * a for wc, a in zip(w, alone)), atol=1e-4)
    gap_i = int(np.flatnonzero(gap)[0])
    np.testing.assert_allclose(weighted[gap_i][0].log_odds, 0.08 * (alone[0] + alone[2] + alone[3]), atol=1e-4)
    for (_, a), (_, b) in zip(weighted, plain):
        np.testing.assert_array_equal(a.xy_m, b.xy_m)
    # a resumed stream starts from each camera's last live frame
    resumed = list(camera_detections(frames[back:], lks, stack, CameraParams(foreground=None), correlation_s=0.5,
                                     last_live_s=[times[back - 1], times[gap_i - 1], times[back - 1],
                                                  times[back - 1]]))
    np.testing.assert_array_equal(resumed[0][0].log_odds, weighted[back][0].log_odds)
    with pytest.raises(ValueError, match="correlation_s"):
        next(camera_detections(frames, lks, stack, CameraParams(foreground=None), correlation_s=-1.0))


@pytest.mark.parametrize("params", [
    ForegroundParams(method="mean", open_px=3, close_px=5),
    ForegroundParams(method="mog2", open_px=3, close_px=9, blur_px=5),
    ForegroundParams(method="mean", downscale=2, open_px=5, close_px=9, blur_px=3),
], ids=["mean", "mog2-blur", "mean-downscale"])
def test_subtraction_window_gives_the_whole_images_foreground_at_every_pixel_read(params, rng):
    """A front end subtracting the background in :func:`subtraction_window` only gives, at every pixel its lookup
    reads, the foreground of the whole image (models whose pixels draw no random numbers: each pixel's model is
    its own, and the window holds the cleaning's reach); elsewhere the neutral likelihood."""
    from planefuse.registration import ImagePlaneLookup
    from planefuse.vision import CameraFrontEnd, subtraction_window
    from planefuse.vision._fusion import NEUTRAL_LEVEL

    h, w = 96, 128
    stack = PlaneStack.from_extent((0.0, 1.0), (0.0, 1.0), (0.0, 1.0), 0.1)
    uv = np.stack([rng.integers(31, 100, stack.shape), rng.integers(41, 70, stack.shape)], axis=-1)
    uv[0, 0, 1], uv[0, 0, 2] = (31, 41), (99, 69)  # the read pixels' box: odd edges, off any reduced grid
    pixel_index = (uv[..., 1] * w + uv[..., 0]).astype(np.int32)
    pixel_index[0, 1, 0] = w * h  # a cell the camera does not see
    lookup = ImagePlaneLookup(pixel_index, w, h, stack)
    window = subtraction_window(lookup, CameraParams(foreground=params))
    r0, r1, c0, c1 = window
    assert 0 < r0 < 41 and 70 < r1 < h and 0 < c0 < 31 and 100 < c1 < w
    assert r0 % params.downscale == c0 % params.downscale == 0
    bg = np.clip(cv2.GaussianBlur(rng.uniform(60, 200, (h, w, 3)).astype(np.float32), (0, 0), 3), 0, 255)
    full, part = (CameraFrontEnd(w, h, params, "cam", bg.astype(np.uint8), quantise=True, window=win)
                  for win in (None, window))
    read = lookup.pixel_index[lookup.visible]
    for k in range(10):
        frame = bg + rng.normal(0, 2, bg.shape)
        frame[20 + 4 * k:70 + 4 * k, 40 + 5 * k:60 + 5 * k] = 240.0  # a person walking across the window's edge
        frame[75:90, 10:50] *= 0.6  # a shadow
        frame = np.clip(frame, 0, 255).astype(np.uint8)
        a, b = full.foreground(frame), part.foreground(frame)
        assert b.shape == a.shape and b.dtype == np.uint8
        np.testing.assert_array_equal(b.ravel()[read], a.ravel()[read])
        outside = np.ones((h, w), bool)
        outside[r0:r1, c0:c1] = False
        assert np.all(b[outside] == NEUTRAL_LEVEL)
    assert np.ptp(a.ravel()[read]) > 0  # the person was seen
    with pytest.raises(ValueError, match="must be 96x128"):
        part.foreground(frame[:-1])


def test_subtraction_window_is_the_whole_image_where_the_subtraction_uses_it():
    """No window where the subtraction looks at the whole image (gain, relearning share, person detector,
    selective update, the generative model), without foreground subtraction, or for a camera that reads no
    pixel."""
    from planefuse.registration import ImagePlaneLookup
    from planefuse.vision import CameraFrontEnd, subtraction_window

    stack = PlaneStack.from_extent((0.0,), (0.0, 1.0), (0.0, 1.0), 0.5)
    lookup = ImagePlaneLookup(np.full(stack.shape, 5, np.int32), 64, 48, stack)
    assert subtraction_window(lookup, CameraParams()) == (0, 8, 0, 13)  # pixel (0, 5), reach 7
    for p in (ForegroundParams(gain_compensation=True), ForegroundParams(relearn_fraction=0.5),
              ForegroundParams(person_detector="hog"), ForegroundParams(selective_update=True), None):
        assert subtraction_window(lookup, CameraParams(foreground=p)) is None
    assert subtraction_window(lookup, CameraParams(sensor_model="generative")) is None
    blind = ImagePlaneLookup(np.full(stack.shape, 64 * 48, np.int32), 64, 48, stack)
    assert subtraction_window(blind, CameraParams()) is None
    with pytest.raises(ValueError, match="window"):
        CameraFrontEnd(64, 48, ForegroundParams(), "cam", window=(10, 5, 0, 64))
