"""Selective (conservative) background update: pixels the camera model explains as people are not learnt into the
background model (a person standing still stays foreground), for at most ``selective_max_frames`` frames in a
row (a ghost still heals); every other pixel is exactly what OpenCV's blind update gives."""

from __future__ import annotations

import numpy as np
import pytest

from planefuse.grid import PlaneStack
from planefuse.occupancy import PersonVolume, silhouettes_from_cameras
from planefuse.sim import default_scene_config, simulate
from planefuse.vision import CameraParams, ForegroundParams, lookups_from_cameras, recording_frames
from planefuse.vision._foreground import BackgroundSubtractor
from planefuse.vision._generative import GenerativeSensorParams
from planefuse.vision._pipeline import camera_detections, people_masks

H, W = 60, 80
#: the still person: rows, cols of a block of another colour
PERSON = (slice(20, 50), slice(30, 45))
RAW = dict(close_px=0, floor=0.0, ceiling=1.0, history=100)


def _scene(rng, person: bool) -> np.ndarray:
    """A textured static background with sensor noise, and optionally a uniform dark person on it (BGR uint8)."""
    img = _BACKGROUND + rng.normal(0, 2.0, (H, W, 3))
    if person:
        img[PERSON] = 40.0
    return np.clip(img, 0, 255).astype(np.uint8)


_BACKGROUND = np.random.default_rng(0).uniform(120, 200, (H, W, 3))


def _person_mask() -> np.ndarray:
    m = np.zeros((H, W), bool)
    m[PERSON] = True
    return m


def _run(params: ForegroundParams, n_empty: int, n_person: int, protect: bool, seed: int = 1) -> list[np.ndarray]:
    """Foregrounds of ``n_empty`` frames of the empty scene, then ``n_person`` with a person standing still,
    whose pixels are protected at every frame when ``protect``."""
    rng = np.random.default_rng(seed)
    sub = BackgroundSubtractor(W, H, params)
    out = []
    for i in range(n_empty + n_person):
        if protect and i >= n_empty:
            sub.protect(_person_mask())
        out.append(sub.apply(_scene(rng, i >= n_empty)))
    return out


def test_a_person_standing_still_stays_foreground_only_with_selective_update():
    blind = _run(ForegroundParams(**RAW), 150, 140, protect=False)
    kept = _run(ForegroundParams(**RAW, selective_update=True, selective_max_frames=150), 150, 140, protect=True)
    inside = lambda fg: float(fg[PERSON].mean())  # noqa: E731
    assert inside(blind[151]) > 0.95 and inside(kept[151]) > 0.95     # just arrived: foreground either way
    assert inside(blind[-1]) < 0.2                                      # OpenCV's blind update absorbed them
    assert min(inside(fg) for fg in kept[150:]) > 0.95                  # kept out of the model: still there


def test_a_cold_model_protects_nothing_during_its_first_selective_max_frames():
    """On a cold model's first frames the camera model's people are ghosts of the scene it has not learnt: a
    person there from the first frame is absorbed exactly as without protection."""
    blind = _run(ForegroundParams(**RAW), 0, 60, protect=False)
    kept = _run(ForegroundParams(**RAW, selective_update=True, selective_max_frames=60), 0, 60, protect=True)
    for a, b in zip(blind, kept):
        np.testing.assert_array_equal(a, b)


def test_outside_the_protected_pixels_the_masks_are_the_blind_updates_exactly():
    blind = _run(ForegroundParams(**RAW), 20, 60, protect=False)
    kept = _run(ForegroundParams(**RAW, selective_update=True, selective_max_frames=10), 20, 60, protect=True)
    outside = ~_person_mask()
    assert any(fg[outside].max() > 0.5 for fg in blind)  # the cold start's own foreground: something to compare
    for a, b in zip(blind, kept):
        np.testing.assert_array_equal(a[outside], b[outside])


def test_protection_ends_after_selective_max_frames_so_a_ghost_heals():
    """A ghost: an object learnt as background then gone. The camera model explains it as a person at every
    frame, but after ``selective_max_frames`` frames its pixels are learnt again and it heals as without
    protection; a longer protection keeps it."""
    def ghost(max_frames: int | None) -> list[float]:
        params = ForegroundParams(**RAW, selective_update=max_frames is not None,
                                  selective_max_frames=max_frames or 1)
        rng = np.random.default_rng(2)
        sub = BackgroundSubtractor(W, H, params)
        share = []
        for i in range(180 + 160):
            if max_frames is not None and i >= 180:
                sub.protect(_person_mask())
            share.append(float(sub.apply(_scene(rng, i < 180))[PERSON].mean()))
        return share

    blind, short, long_ = ghost(None), ghost(10), ghost(170)
    assert blind[181] > 0.95 and short[181] > 0.95 and long_[181] > 0.95  # the ghost appears
    assert blind[-1] < 0.2 and short[-1] < 0.2                          # healed, protected or not
    assert long_[-1] > 0.95                                             # never learnt: still a ghost


def test_bad_selective_settings_and_masks_are_refused():
    with pytest.raises(ValueError, match="selective_update.*knn"):
        ForegroundParams(method="mog2", selective_update=True)
    with pytest.raises(ValueError, match="selective_max_frames"):
        ForegroundParams(selective_update=True, selective_max_frames=0)
    with pytest.raises(ValueError, match="needs ForegroundParams.selective_update"):
        BackgroundSubtractor(W, H, ForegroundParams()).protect(_person_mask())
    sub = BackgroundSubtractor(W, H, ForegroundParams(selective_update=True), name="cam7")
    with pytest.raises(ValueError, match="cam7: people mask must be a 60x80 bool image"):
        sub.protect(np.ones((W, H), bool))
    with pytest.raises(ValueError, match="people mask"):
        sub.protect(np.ones((H, W), np.uint8))


def test_downscaled_models_protect_every_model_pixel_a_person_touches():
    kept = _run(ForegroundParams(**RAW, downscale=2, selective_update=True, selective_max_frames=150), 150, 140,
                protect=True)
    assert min(float(fg[PERSON].mean()) for fg in kept[150:]) > 0.9


# -- the feedback from the camera model ---------------------------------------------------------------------------
@pytest.fixture(scope="module")
def sim():
    return simulate(default_scene_config(duration_s=2.0, seed=2))


STACK = PlaneStack.from_extent([0.1, 0.9, 1.5], (0.0, 6.0), (0.0, 6.0), 0.2)


def test_people_masks_are_the_silhouette_boxes(sim):
    cams = list(sim.cameras)
    xy = np.array([[2.0, 3.0], [4.0, 2.5]])
    person = PersonVolume(radius_m=0.2, height_range_m=(0.0, 1.8))
    boxes = silhouettes_from_cameras(cams, xy, person).boxes_px
    masks = people_masks(cams, xy, person)
    for c, m in enumerate(masks):
        ref = np.zeros_like(m)
        for x0, y0, x1, y1 in boxes[c][boxes[c, :, 0] >= 0]:
            ref[y0:y1 + 1, x0:x1 + 1] = True
        assert ref.any()
        np.testing.assert_array_equal(m, ref)
    assert not any(m.any() for m in people_masks(cams, np.zeros((0, 2)), person))


def _detections(sim, params: CameraParams, replay: int = 0):
    return list(camera_detections(recording_frames(sim), lookups_from_cameras(sim.cameras, STACK), STACK, params,
                                  cameras=list(sim.cameras), replay=replay))


def test_the_camera_pipeline_feeds_its_people_back_and_resumes_exactly(sim):
    fg = ForegroundParams(selective_update=True, selective_max_frames=5)
    params = CameraParams(foreground=fg, sensor_model="generative", generative=GenerativeSensorParams())
    ref = _detections(sim, params)
    blind = _detections(sim, CameraParams(foreground=ForegroundParams(), sensor_model="generative"))
    assert sum(len(d.xy_m) for _, d in ref) > 0
    # the feedback changes the evidence (people kept in the foreground) once people were found
    assert any(not np.array_equal(a.log_odds, b.log_odds) for (a, _), (b, _) in zip(ref, blind))
    # a resumed run replays the skipped instants in full: the same outputs as the uninterrupted run
    resumed = _detections(sim, params, replay=20)
    assert len(resumed) == len(ref) - 20
    for (ea, da), (eb, db) in zip(ref[20:], resumed):
        np.testing.assert_array_equal(ea.log_odds, eb.log_odds)
        np.testing.assert_array_equal(da.xy_m, db.xy_m)


def test_selective_update_needs_the_cameras(sim):
    params = CameraParams(foreground=ForegroundParams(selective_update=True))
    with pytest.raises(ValueError, match="selective_update needs the calibrated cameras"):
        next(camera_detections(recording_frames(sim), lookups_from_cameras(sim.cameras, STACK), STACK, params))


def test_the_detectors_boxes_keep_a_person_standing_still_in_the_foreground(monkeypatch, tmp_path):
    """selective_source 'detector': the subtractor protects its own detector's boxes of the previous frame (no
    protect() call from outside); a detector that finds nobody protects nothing (OpenCV's blind update)."""
    from planefuse.vision._foreground import PersonDetector
    from planefuse.vision._yolox import PersonBoxes

    box = np.array([[30.0, 20.0, 15.0, 30.0]])  # the person's block: cols 30-44, rows 20-49
    seen = {"person": False}

    def detect(self, frame):
        return PersonBoxes(box, np.ones(1)) if seen["person"] else PersonBoxes.empty()

    pytest.importorskip("onnx", reason="the onnx package (dev extra) builds the test model")
    from test_vision_yolox import SIDE, constant_model, raw_rows

    monkeypatch.setattr(PersonDetector, "detect", detect)  # a model that loads; its answers are set here
    params = ForegroundParams(**RAW, selective_update=True, selective_max_frames=150, person_detector="yolox",
                              person_model=constant_model(tmp_path / "m.onnx", raw_rows()),
                              person_input_px=(SIDE, SIDE), person_likelihood=None, selective_source="detector")
    rng = np.random.default_rng(1)
    sub = BackgroundSubtractor(W, H, params)
    assert sub.protects_itself
    kept = []
    for i in range(290):
        seen["person"] = i >= 150
        kept.append(sub.apply(_scene(rng, i >= 150)))
    blind = _run(ForegroundParams(**RAW), 150, 140, protect=False)
    inside = lambda fg: float(fg[PERSON].mean())  # noqa: E731
    assert inside(blind[-1]) < 0.2
    assert min(inside(fg) for fg in kept[151:]) > 0.95
    with pytest.raises(ValueError, match="selective_source"):
        ForegroundParams(selective_update=True, selective_source="detector")
