"""The faster background models: the numba running average (``method="mean"``) and OpenCV contrib's CNT
(``method="cnt"``)."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from planefuse.vision import BackgroundSubtractor, ForegroundParams
from planefuse.vision._mean_background import SHADOW_TAU, MeanBackground

H, W = 48, 64


def _reference(frames: list[np.ndarray], threshold: float, rate: float, fg_rate: float):
    """Masks and final mean of the running-average model written with numpy, float32 (the kernel's equations,
    vectorised, independent of its loops): first frame = the mean; each frame classified, then learnt."""
    mean = frames[0].astype(np.float32).reshape(H, W, -1)
    masks = []
    thr, tau = np.float32(threshold), np.float32(SHADOW_TAU)
    for f in frames[1:]:
        x = f.astype(np.float32).reshape(H, W, -1)
        d = x - mean
        d2 = (d * d).sum(axis=2, dtype=np.float32) if x.shape[2] > 1 else d[..., 0] * d[..., 0]
        fg = d2 > thr
        mm = (mean * mean).sum(axis=2, dtype=np.float32)
        with np.errstate(divide="ignore", invalid="ignore"):
            a = ((x * mean).sum(axis=2, dtype=np.float32) / mm).astype(np.float32)
        e = x - a[..., None] * mean
        e2 = (e * e).sum(axis=2, dtype=np.float32)
        shadow = fg & (mm > 0) & (a >= tau) & (a <= 1) & (e2 < thr * a * a)
        masks.append(np.where(shadow, 127, np.where(fg, 255, 0)).astype(np.uint8))
        q = np.where(fg, np.float32(fg_rate), np.float32(rate))[..., None]
        mean = mean + q * d
    return masks, mean


@pytest.mark.parametrize("channels", [3, 1])
def test_mean_model_is_its_equations(channels, rng):
    """The kernel's masks and learnt background equal a numpy transcription of the model on random scenes with
    people (brighter and darker patches) and shadows (the background darkened), BGR and grey."""
    shape = (H, W, channels) if channels == 3 else (H, W)
    bg = rng.uniform(20, 230, shape)
    frames = [bg.astype(np.uint8)]
    for k in range(30):
        f = bg + rng.normal(0, 4, shape)
        f[10:30, 5 + k:20 + k] *= 0.7  # a shadow moving across
        f[20:40, 40 - k // 2:50 - k // 2] = rng.uniform(0, 255, channels if channels == 3 else ())  # a person
        frames.append(np.clip(f, 0, 255).astype(np.uint8))
    model = MeanBackground(400.0, 100, True, foreground_rate=0.2)
    model.apply(frames[0], learningRate=1.0)
    rate = 0.05
    got = [model.apply(f, learningRate=rate) for f in frames[1:]]
    want, mean = _reference(frames, 400.0, rate, 0.2 * rate)
    assert all(np.array_equal(g, w) for g, w in zip(got, want))
    assert {0, 127, 255} <= set(np.unique(np.concatenate(got)))
    np.testing.assert_allclose(model.background().reshape(mean.shape), mean, rtol=0, atol=1e-3)


def test_mean_model_labels_like_opencv_knn_on_a_clean_scene(rng):
    """Against OpenCV's KNN (the same distance threshold and shadow rule) on a noise-free scene learnt from the
    empty frame: a person of another colour is foreground, the background darkened to 70 % is shadow, the rest
    background -- the same labels from both."""
    bg = cv2.GaussianBlur(rng.uniform(60, 200, (H, W, 3)), (0, 0), 2).astype(np.uint8)
    frame = bg.copy()
    frame[5:25, 10:20] = (30, 160, 220)
    frame[30:45, 30:60] = (bg[30:45, 30:60] * 0.7).astype(np.uint8)
    knn = cv2.createBackgroundSubtractorKNN(history=100, dist2Threshold=400.0, detectShadows=True)
    mean = MeanBackground(400.0, 100, True, foreground_rate=0.2)
    for _ in range(20):
        knn.apply(bg)
        mean.apply(bg)
    got, want = mean.apply(frame, learningRate=0.0), knn.apply(frame, learningRate=0.0)
    assert (got[5:25, 10:20] == 255).all() and (got[32:43, 32:58] == 127).all()
    assert np.mean(got == want) > 0.995


def _still_person(params: ForegroundParams, frames_standing: int, rng) -> np.ndarray:
    """Likelihood of a person who stands still for ``frames_standing`` frames after the model was primed."""
    bg = cv2.GaussianBlur(rng.uniform(60, 200, (H, W, 3)), (0, 0), 2)
    bs = BackgroundSubtractor(W, H, params)
    bs.prime(bg.astype(np.uint8))
    like = None
    for _ in range(frames_standing):
        f = bg + rng.normal(0, 2, bg.shape)
        f[10:40, 20:35] = (40, 40, 200)
        like = bs.apply(np.clip(f, 0, 255).astype(np.uint8))
    return like


def test_mean_model_keeps_a_still_person_that_a_blind_update_absorbs(rng):
    """Foreground learnt at 0.2 of the rate: a person standing for three histories (300 frames) is still
    foreground; learnt like the background (rate 1, a blind update) the person has faded into it."""
    base = dict(method="mean", history=100, close_px=0, floor=0.0, ceiling=1.0)
    kept = _still_person(ForegroundParams(**base, mean_foreground_rate=0.2), 300, rng)
    blind = _still_person(ForegroundParams(**base, mean_foreground_rate=1.0), 300, rng)
    assert kept[12:38, 22:33].mean() == 1.0
    assert blind[12:38, 22:33].mean() < 0.5


def test_mean_model_heals_a_ghost(rng):
    """An object that stays (a ghost of the background as first learnt) is learnt at 0.2 of the rate: gone
    within a few histories, not kept out of the model for ever (rate 0 never learns it)."""
    base = dict(method="mean", history=20, close_px=0, floor=0.0, ceiling=1.0)
    assert _still_person(ForegroundParams(**base, mean_foreground_rate=0.2), 400, rng)[12:38, 22:33].mean() == 0.0
    assert _still_person(ForegroundParams(**base, mean_foreground_rate=0.0), 400, rng)[12:38, 22:33].mean() == 1.0


def test_mean_takes_the_knn_threshold_over_downscale():
    full, half = (BackgroundSubtractor(W, H, ForegroundParams(method="mean", downscale=d)) for d in (1, 2))
    assert isinstance(full._model, MeanBackground)
    assert full._model.getDist2Threshold() == 400.0 and half._model.getDist2Threshold() == 200.0
    assert BackgroundSubtractor(W, H, ForegroundParams(method="mean", threshold=900))._model.getDist2Threshold() == 900
    with pytest.raises(ValueError, match="mean_foreground_rate"):
        ForegroundParams(method="mean", mean_foreground_rate=1.5)
    with pytest.raises(ValueError, match="selective_update"):
        ForegroundParams(method="mean", selective_update=True)  # KNN's decision on protected pixels: knn only


@pytest.mark.skipif(not hasattr(cv2, "bgsegm"), reason="OpenCV without contrib's bgsegm (CNT)")
def test_cnt_primed_with_the_plate_finds_a_person_the_same_on_any_number_of_threads(rng):
    """CNT primed with the empty scene calls a person (40 grey levels from the floor) foreground from the first
    frame, and the rest background; its rows split over OpenCV's threads give the same masks as one thread."""
    bg = cv2.GaussianBlur(rng.uniform(60, 200, (H, W)), (0, 0), 2)
    frames = []
    for k in range(20):
        f = bg + rng.normal(0, 1, bg.shape)
        f[10:40, 5 + 2 * k:15 + 2 * k] += 40
        frames.append(np.clip(f, 0, 255).astype(np.uint8))
    masks = {}
    before = cv2.getNumThreads()
    try:
        for threads in (1, 4):
            cv2.setNumThreads(threads)
            bs = BackgroundSubtractor(W, H, ForegroundParams(method="cnt", close_px=0, floor=0.0, ceiling=1.0))
            bs.prime(bg.astype(np.uint8))
            masks[threads] = [bs.apply(f) for f in frames]
    finally:
        cv2.setNumThreads(before)
    assert all(np.array_equal(a, b) for a, b in zip(masks[1], masks[4]))
    first = masks[1][0]
    assert first[12:38, 7:13].mean() == 1.0 and first[:, 30:].mean() < 0.01


def test_cnt_settings_are_checked():
    with pytest.raises(ValueError, match="threshold"):
        ForegroundParams(method="cnt", threshold=400)
    with pytest.raises(ValueError, match="cnt_min_stability"):
        ForegroundParams(method="cnt", history=10, cnt_min_stability=10)
    with pytest.raises(ValueError, match="cnt_min_stability"):
        ForegroundParams(cnt_min_stability=0)
    assert ForegroundParams(method="knn", history=10).cnt_min_stability == 15  # only CNT's own check
    with pytest.raises(ValueError, match="method"):
        ForegroundParams(method="gsoc")
