"""The person detector beside the background subtraction (``ForegroundParams.person_detector``): the bodies of its
boxes are raised to ``person_likelihood``, nothing else changes; OpenCV's HOG people detector finds the people of
a real EPFL terrace frame (its ground-truth boxes, drawn by annotators, are the reference)."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from planefuse.config import config_from_dict
from planefuse.vision import ForegroundParams
from planefuse.vision._foreground import BackgroundSubtractor, PersonDetector
from planefuse.vision._fusion import quantise_foreground
from planefuse.vision._yolox import PersonBoxes

from conftest import shared_data

H, W = 60, 80


def _frames(n: int, seed: int = 0) -> list[np.ndarray]:
    rng = np.random.default_rng(seed)
    bg = rng.uniform(100, 200, (H, W, 3))
    return [np.clip(bg + rng.normal(0, 2, bg.shape), 0, 255).astype(np.uint8) for _ in range(n)]


@pytest.mark.parametrize("quantised", [False, True])
def test_detected_bodies_are_raised_to_the_person_likelihood_and_nothing_else_changes(monkeypatch, quantised):
    plain = BackgroundSubtractor(W, H, ForegroundParams(close_px=0))
    with_people = BackgroundSubtractor(W, H, ForegroundParams(close_px=0, person_detector="hog",
                                                              person_likelihood=0.8))
    # one box 20 px wide, 40 px tall at (10, 8): its body is columns 15-24, rows 13-42
    monkeypatch.setattr(PersonDetector, "detect", lambda self, frame: PersonBoxes(np.array([[10.0, 8.0, 20.0, 40.0]]),
                                                                                  np.array([1.0])))
    for frame in _frames(5):
        a, b = plain.apply(frame, quantised=quantised), with_people.apply(frame, quantised=quantised)
    body = np.zeros((H, W), bool)
    body[13:43, 15:25] = True
    level = quantise_foreground(np.float32([0.8])).ravel()[0] if quantised else np.float32(0.8)
    assert np.array_equal(b[~body], a[~body])
    assert np.array_equal(b[body], np.maximum(a[body], level))
    assert (b[body] == level).all()  # the static scene is background there


def test_boxes_at_the_border_are_clipped_to_the_frame(monkeypatch):
    sub = BackgroundSubtractor(W, H, ForegroundParams(close_px=0, person_detector="hog", person_likelihood=1.0,
                                                      floor=0.0, ceiling=1.0))
    # bodies: columns -10..10, rows -20..40 (clipped to 0..10, 0..40); columns 70..90, rows 40..100 (70..80, 40..60)
    monkeypatch.setattr(PersonDetector, "detect", lambda self, frame: PersonBoxes(np.array([[-20.0, -30.0, 40.0, 80.0],
                                                                                          [60.0, 30.0, 40.0, 80.0]]),
                                                                                  np.ones(2)))
    plain = BackgroundSubtractor(W, H, ForegroundParams(close_px=0, floor=0.0, ceiling=1.0))
    for frame in _frames(5):
        like, before = sub.apply(frame), plain.apply(frame)
    expected = np.zeros((H, W), bool)
    expected[0:40, 0:10] = expected[40:60, 70:80] = True
    assert (like[expected] == 1.0).all()
    assert np.array_equal(like[~expected], before[~expected])
    assert (before[expected] == 0.0).all()


@pytest.mark.parametrize("change, field", [(dict(person_detector="yolo"), "person_detector"),
                                           (dict(person_detector="hog", person_outside_weight=-0.1), "person_outside_weight"),
                                           (dict(person_likelihood=1.5), "person_likelihood"),
                                           (dict(person_upscale=0.0), "person_upscale"),
                                           (dict(person_min_score=float("nan")), "person_min_score")])
def test_bad_person_detector_settings_are_refused_naming_the_field(change, field):
    with pytest.raises(ValueError, match=field):
        ForegroundParams(**change)


def test_config_refuses_an_unknown_detector_naming_the_field():
    with pytest.raises(ValueError, match="person_detector"):
        config_from_dict({"recording": ".", "sensors": {"cameras": {"person_detector": "yolo"}}})


def test_an_opencv_without_hog_is_a_clear_error(monkeypatch):
    monkeypatch.delattr(cv2, "HOGDescriptor")
    with pytest.raises(ValueError, match="person_detector 'hog' needs OpenCV's HOG people detector"):
        BackgroundSubtractor(W, H, ForegroundParams(person_detector="hog"))


@pytest.mark.realdata
def test_hog_finds_the_annotated_people_of_a_real_terrace_frame():
    """Terrace c0, frames 0-1499 every 100th (tuning frames): the detector's boxes against the annotators' boxes
    of people at least 60 px tall (intersection over union >= 0.3)."""
    video, pom = shared_data("epfl_video"), shared_data("epfl_pom") / "EPFL-Terrace"
    truth: dict[int, list] = {}
    for line in (pom / "terrace1-c0" / "gt" / "gt.txt").read_text().splitlines():
        f = line.split()
        if f[6] == "0" and int(f[4]) - int(f[2]) >= 60:
            truth.setdefault(int(f[5]), []).append([float(v) for v in f[1:5]])
    detector = PersonDetector(ForegroundParams(person_detector="hog"))
    cap = cv2.VideoCapture(str(video / "terrace1-c0.mp4"))
    found = n_truth = n_boxes = kept = 0
    for i in range(0, 1500, 100):
        cap.set(cv2.CAP_PROP_POS_FRAMES, i)
        ok, frame = cap.read()
        assert ok
        boxes, scores = detector.boxes(frame)
        assert (scores >= 0.3).all()
        xyxy = np.c_[boxes[:, :2], boxes[:, :2] + boxes[:, 2:]]
        n_boxes += len(xyxy)
        for g in truth.get(i, []):
            n_truth += 1
            iou = [_iou(g, b) for b in xyxy]
            found += bool(iou) and max(iou) >= 0.3
        kept += sum(any(_iou(g, b) >= 0.3 for g in truth.get(i, [])) for b in xyxy)
    assert n_truth >= 20
    assert found / n_truth >= 0.6, (found, n_truth)
    assert kept / max(n_boxes, 1) >= 0.6, (kept, n_boxes)


def _iou(a, b) -> float:
    w = max(0.0, min(a[2], b[2]) - max(a[0], b[0]))
    h = max(0.0, min(a[3], b[3]) - max(a[1], b[1]))
    inter = w * h
    return inter / ((a[2] - a[0]) * (a[3] - a[1]) + (b[2] - b[0]) * (b[3] - b[1]) - inter)
