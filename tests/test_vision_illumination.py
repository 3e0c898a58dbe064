"""Foreground front end under lighting changes (gain compensation, sudden-change relearning); generative evidence."""

from __future__ import annotations

import cv2
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from planefuse.vision import BackgroundSubtractor, ForegroundParams, GainCompensator


def _scene(rng, h=96, w=128):
    """A textured background (tiles of random colours, 8 px, like a paved floor)."""
    tiles = rng.uniform(60, 180, (h // 8 + 1, w // 8 + 1, 3)).astype(np.float32)
    return cv2.GaussianBlur(np.repeat(np.repeat(tiles, 8, 0), 8, 1)[:h, :w], (0, 0), 1)


def _frame(img, rng):
    return np.clip(img + rng.normal(0, 2, img.shape), 0, 255).astype(np.uint8)


@pytest.mark.parametrize("compensate", [False, True])
def test_exposure_step_is_divided_out(compensate, rng):
    """A camera's automatic exposure raises the whole image by 15 % while a person walks in: without
    compensation the subtractor calls most of the image foreground, with it only the person."""
    bg = _scene(rng)
    params = ForegroundParams(history=100, gain_compensation=compensate)
    bs = BackgroundSubtractor(128, 96, params)
    for _ in range(40):
        bs.apply(_frame(bg, rng))
    frame = bg * 1.15
    frame[30:70, 50:70] = (30, 40, 220)  # a red jacket
    like = bs.apply(_frame(frame, rng))
    person = like[35:65, 55:65].mean()
    rest = np.delete(like, np.s_[25:75], axis=0).mean()
    assert person > 0.9
    if compensate:
        assert rest < 0.1
    else:
        assert rest > 0.5  # the failure the compensation removes


def test_gain_field_follows_a_smooth_illumination_gradient(rng):
    """A cloud darkening the left half progressively: the blockwise gain field divides it out to a few grey levels."""
    bg = _scene(rng, 120, 180)
    comp = GainCompensator((3, 4), 0.05)
    comp.compensate(bg.astype(np.uint8))
    comp.learn(bg.astype(np.uint8), np.ones((120, 180), bool))
    ramp = np.linspace(0.7, 1.0, 180)[None, :, None]
    out = comp.compensate(np.clip(bg * ramp, 0, 255).astype(np.uint8)).astype(float)
    err = np.abs(out - bg)
    assert np.median(err) < 3.0
    assert np.median(np.abs(bg * ramp - bg)) > 10.0  # the change was large


def test_sudden_change_gives_no_evidence_then_relearns(rng):
    """A change no gain explains (the scene's texture replaced, e.g. the camera bumped): that frame is
    'unobserved' (0.5 everywhere) and the model relearns within relearn_frames frames."""
    a = _scene(rng)
    b = 240.0 - a  # a different scene: bright where the old one was dark
    params = ForegroundParams(history=100, gain_compensation=True, relearn_fraction=0.4, relearn_frames=5,
                              relearn_rate=0.5)
    bs = BackgroundSubtractor(128, 96, params)
    for _ in range(30):
        bs.apply(_frame(a, rng))
    like = bs.apply(_frame(b, rng))
    assert bs.n_sudden_changes == 1
    np.testing.assert_array_equal(like, 0.5)
    outs = [bs.apply(_frame(b, rng)) for _ in range(12)]
    assert all(np.all(o == 0.5) for o in outs[:5])
    assert outs[-1].mean() < 0.1 and bs.n_sudden_changes == 1


def _frames_until_learnt(params, plate, scene, rng, most=200):
    """Frames of ``scene`` a model primed with ``plate`` needs until it calls < 10 % of the image foreground."""
    bs = BackgroundSubtractor(128, 96, params)
    bs.prime(plate.astype(np.uint8))
    for n in range(1, most + 1):
        if bs.apply(_frame(scene, rng)).mean() < 0.1:
            return n
    return most + 1


def test_estimated_plate_is_corrected_at_the_automatic_rate(rng):
    """A plate that is not the scene (an estimate: other light, people in it): primed with ``primed_rate``
    "steady" the model takes its history's pace to learn the real scene, "automatic" goes on with OpenCV's
    fast start and learns it within tens of frames; both learn the scene eventually, and a plate that is the
    scene gives no foreground either way."""
    plate, scene = _scene(rng), _scene(rng)  # two different floors
    steady = ForegroundParams(history=500, primed_rate="steady")
    automatic = ForegroundParams(history=500, primed_rate="automatic")
    n_auto = _frames_until_learnt(automatic, plate, scene, rng)
    n_steady = _frames_until_learnt(steady, plate, scene, rng, most=400)
    assert n_auto < 100
    assert n_steady > 2 * n_auto
    for params in (steady, automatic):
        bs = BackgroundSubtractor(128, 96, params)
        bs.prime(scene.astype(np.uint8))
        assert bs.apply(_frame(scene, rng)).mean() < 0.1


def test_foreground_params_reject_bad_values():
    for kw, match in [(dict(gain_blocks=(0, 3)), "gain_blocks"), (dict(gain_rate=0.0), "gain_rate"),
                      (dict(relearn_fraction=1.5), "relearn_fraction"), (dict(relearn_frames=0), "relearn_frames"),
                      (dict(relearn_rate=2.0), "relearn_rate"), (dict(primed_rate="fast"), "primed_rate")]:
        with pytest.raises(ValueError, match=match):
            ForegroundParams(**kw)


# -- generative evidence measured against even odds ------------------------------------------------------------
def test_generative_evidence_prior_makes_weak_marginals_evidence_against():
    """``evidence_prior=0.5``: a cell whose disc holds a total marginal below one half (a ghost the explaining-away
    left at q ~ 0.3) gets negative evidence, a person (q ~ 1) positive; with the model's prior both are positive
    (the filter then accumulates the ghost)."""
    from planefuse.geometry import default_camera_ring
    from planefuse.grid import PlaneStack
    from planefuse.vision import GenerativeCameraSensor, GenerativeSensorParams

    stack = PlaneStack.from_extent([0.1, 0.9, 1.6], (0, 10), (0, 10), 0.1)
    cams = [default_camera_ring(4)[i] for i in (0, 1)]
    q = np.zeros((stack.ny, stack.nx))
    person, ghost = (30, 40), (70, 60)
    q[person] = 0.99
    q[ghost] = 0.3
    ev = {}
    for ref in (None, 0.5):
        sensor = GenerativeCameraSensor(cams, stack, GenerativeSensorParams(evidence_prior=ref))
        ev[ref] = sensor.log_odds_from_marginals(q)[0]
    assert ev[None][person] > 0 and ev[None][ghost] > 0
    assert ev[0.5][person] > 0 > ev[0.5][ghost]
    assert ev[0.5][50, 50] < ev[0.5][ghost]  # an empty cell says "nobody" more firmly
    with pytest.raises(ValueError, match="evidence_prior"):
        GenerativeSensorParams(evidence_prior=1.0)


# -- evidence consistent with the per-frame detector -----------------------------------------------------------
@pytest.mark.parametrize("mass, threshold", [(0.5, 2.0), (0.4, 1.5), (1.0, 3.0)])
def test_detection_evidence_prior_makes_one_frame_of_a_detected_person_a_cluster(mass, threshold):
    """With ``evidence_prior = detection_evidence_prior(m, T)``, one frame of marginals holding just the detector's
    mass ``m`` (spread over the disc) is reported by the detector *and*, through the filter on cells at its
    prior, is a cluster with column evidence ``>= T``; 0.8 m is neither. Against even odds (0.5) the same frame is
    evidence against (no cluster) although the detector reports the person."""
    from planefuse.geometry import default_camera_ring
    from planefuse.grid import PlaneStack, probability_from_log_odds, log_odds_from_probability
    from planefuse.tracking import ClusterParams, column_log_odds
    from planefuse.vision import GenerativeCameraSensor, GenerativeSensorParams, detection_evidence_prior
    from planefuse.vision._persons import _disc

    stack = PlaneStack.from_extent([0.1, 0.5, 1.0, 1.5], (0, 8), (0, 8), 0.1)
    cams = [default_camera_ring(4)[i] for i in (0, 1)]
    p0 = 0.05
    cp = ClusterParams(threshold=threshold, smoothing_m=0.0)
    disc = _disc(2.0)  # radius_m 0.2 on 10 cm cells
    centre = (40, 40)

    def frame(m):
        q = np.zeros((stack.ny, stack.nx))
        r = disc.shape[0] // 2
        q[centre[0] - r:centre[0] + r + 1, centre[1] - r:centre[1] + r + 1][disc] = m / disc.sum()
        return q

    p_e = detection_evidence_prior(mass, threshold)
    assert 0.0 < p_e < 0.5
    for ref, expect_cluster in ((p_e, True), (0.5, False)):
        sensor = GenerativeCameraSensor(cams, stack, GenerativeSensorParams(evidence_prior=ref, detection_mass=mass))
        for m, present in ((mass * 1.0001, expect_cluster), (0.8 * mass, False)):
            q = frame(m)
            detected = len(sensor.detections(q, 0.0, 0.45)) == 1
            assert detected == (m >= mass)
            # the filter's posterior of one update from the prior: logit p0 + evidence
            occ = probability_from_log_odds(log_odds_from_probability(p0) + sensor.log_odds_from_marginals(q))
            S = column_log_odds(occ, stack, p0, cp)
            assert (S[centre] >= threshold) == present, (ref, m, S[centre])
    with pytest.raises(ValueError, match="detection_mass"):
        detection_evidence_prior(0.0, 2.0)


def _reference_compensate(comp: GainCompensator, frame: np.ndarray) -> np.ndarray:
    """GainCompensator.compensate's rule in numpy, element-wise (the form it had before its numba kernels): the
    per-block median of frame / max(reference, 1) over the pixels that tell the gain, clipped, bilinear, divided."""
    img = frame.astype(np.float32)
    ref = comp.reference
    ok = (ref > comp.DARK) & (ref < comp.SATURATED) & (img < comp.SATURATED)
    if ok.ndim == 3:
        ok = ok.all(axis=2)
    if comp._valid is not None and np.count_nonzero(ok & comp._valid) >= comp.MIN_VALID * ok.size:
        ok &= comp._valid
    if ok.ndim < img.ndim:
        ok = ok[..., None]
    ratio = np.where(ok, img / np.maximum(ref, 1.0), np.nan)
    h, w = ratio.shape[:2]
    rows, cols = comp.blocks
    flat = ratio.reshape(h * w, -1)
    out = np.empty((rows, cols, flat.shape[1]), np.float32)
    ys, xs = np.linspace(0, h, rows + 1).astype(int), np.linspace(0, w, cols + 1).astype(int)
    for i in range(rows):
        for j in range(cols):
            blk = ratio[ys[i]:ys[i + 1], xs[j]:xs[j + 1]].reshape(-1, flat.shape[1])
            good = np.isfinite(blk[:, 0])
            if good.mean() >= 0.05:
                out[i, j] = np.median(blk[good], axis=0)
            else:
                out[i, j] = [np.median(c[np.isfinite(c)]) if np.isfinite(c).any() else 1.0 for c in flat.T]
    gain = np.clip(out.reshape((rows, cols) + ratio.shape[2:]), 1.0 / comp.MAX_GAIN, comp.MAX_GAIN)
    field = cv2.resize(gain, (w, h), interpolation=cv2.INTER_LINEAR)
    return np.clip(img / field.reshape(img.shape), 0, 255).astype(np.uint8)


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 2**31 - 1), blocks=st.tuples(st.integers(1, 4), st.integers(1, 5)),
       grey=st.booleans(), valid_share=st.sampled_from([None, 0.0, 0.02, 0.5, 1.0]), gain=st.floats(0.2, 5.0))
def test_compensation_is_its_numpy_rule_bit_for_bit(seed, blocks, grey, valid_share, gain):
    """Frames with dark, saturated and foreground pixels, a cold model (few valid pixels) or none, blocks with too few
    telling pixels: the numba kernels give the numpy rule's bytes."""
    rng = np.random.default_rng(seed)
    shape = (37, 53) if grey else (37, 53, 3)
    ref = rng.uniform(0, 255, shape).astype(np.float32)
    ref[:, :7] = 5.0  # a dark band: those pixels say nothing
    frame = np.clip(ref * gain + rng.normal(0, 4, shape), 0, 255).astype(np.uint8)
    frame[20:30, 10:25] = 255  # saturated
    comp = GainCompensator(blocks, 0.05)
    comp.reference = ref
    if valid_share is not None:
        comp._valid = rng.random(shape[:2]) < valid_share
    expected = _reference_compensate(comp, frame)
    np.testing.assert_array_equal(comp.compensate(frame), expected)


@settings(max_examples=200, deadline=None)
@given(values=st.lists(st.floats(0, 300, width=32) | st.sampled_from([0.0, 1.0, 1.5]), min_size=1, max_size=3000))
def test_the_kernels_median_is_numpys_bit_for_bit(values):
    """Odd and even counts, ties, constant runs, a few values and thousands: exact_median is np.median (float32)."""
    from planefuse.vision._gain import _MEDIAN_BINS, exact_median

    a = np.array(values, np.float32)
    buf = np.concatenate([a, np.full(5, np.nan, np.float32)])  # only the first n are read
    got = exact_median(buf, len(a), np.empty(_MEDIAN_BINS, np.int64))
    assert np.float32(got).tobytes() == np.float32(np.median(a)).tobytes()
