"""Asynchronous sensors: re-ordering within the window, merging simultaneous messages, late messages."""

from __future__ import annotations

import numpy as np
import pytest

from planefuse.grid import Evidence, PlaneStack
from planefuse.tracking import (
    AsyncEvidenceBuffer,
    BayesianOccupancyFilter,
    BOFParams,
    LateEvidenceWarning,
    TrackingParams,
    evidence_from_people,
    track_evidence,
)

STACK = PlaneStack.from_extent([0.3, 1.0, 1.6], (0.0, 3.0), (0.0, 2.5), 0.1)


def _stream(rng, n=30):
    """Three sensors at their own rates (25 Hz camera, 10 Hz laser, 7 Hz sound) seeing one walking person."""
    msgs = []
    for sensor, period, planes in (("cam0", 0.04, [0, 1, 2]), ("laser", 0.1, [0]), ("binaural", 1 / 7, [1])):
        seen = np.zeros(STACK.shape, bool)
        seen[planes] = True
        for t in np.arange(n) * period:
            if t > 1.2:
                break
            xy = np.array([[0.5 + 1.2 * t, 1.2 + 0.3 * t]])
            msgs.append(evidence_from_people(STACK, t, xy, [1.7], sensor, seen=seen, noise_std=0.3, rng=rng))
    msgs.sort(key=lambda e: e.time_s)
    return msgs


def _shuffle_within(msgs, max_delay_s, rng):
    """Arrival order when every message is delayed by up to ``max_delay_s``."""
    arrival = np.array([m.time_s for m in msgs]) + rng.uniform(0, max_delay_s, len(msgs))
    return [msgs[i] for i in np.argsort(arrival, kind="stable")]


def test_buffer_releases_in_time_order_and_merges_simultaneous():
    buf = AsyncEvidenceBuffer(window_s=0.15)
    z = np.zeros(STACK.shape, np.float32)
    out = []
    for t, s, v in [(0.1, "a", 1), (0.0, "b", 2), (0.1, "c", 3), (0.05, "a", 4), (0.3, "b", 5)]:
        out += buf.push(Evidence(t, s, z + v))
    # 0.3 arrived: everything up to 0.15 is released, in order, the two messages at 0.1 merged
    assert [b.time_s for b in out] == [0.0, 0.05, 0.1]
    assert out[2].sensors == ("a", "c")
    np.testing.assert_array_equal(out[2].log_odds, z + 4)
    assert buf.n_pending == 1
    rest = buf.flush()
    assert [b.time_s for b in rest] == [0.3] and buf.n_pending == 0 and buf.n_late == 0


def test_late_message_is_counted_warned_and_kept():
    buf = AsyncEvidenceBuffer(window_s=0.1)
    z = np.zeros(STACK.shape, np.float32)
    buf.push(Evidence(0.0, "cam0", z))
    buf.push(Evidence(0.5, "cam0", z))  # releases 0.0
    late = Evidence(-0.2, "laser", z)
    with pytest.warns(LateEvidenceWarning, match="laser"):
        assert buf.push(late) == []
    assert buf.n_late == 1 and buf.late[0] is late
    # a message exactly at the released instant is one more measurement of it, not late
    assert [b.time_s for b in buf.push(Evidence(0.0, "laser", z))] == [0.0]
    assert buf.n_late == 1


def test_out_of_order_stream_within_window_gives_in_order_result(rng):
    """Delays up to 0.1 s with a 0.12 s window: same filtered occupancy and tracks as the sorted stream."""
    msgs = _stream(rng)
    shuffled = _shuffle_within(msgs, 0.1, np.random.default_rng(1))
    assert [m.time_s for m in shuffled] != [m.time_s for m in msgs]
    params = TrackingParams(window_s=0.12, merge_tolerance_s=1e-6)  # only equal time stamps fused
    ref = list(track_evidence(STACK, msgs, params))
    got = list(track_evidence(STACK, shuffled, params))
    assert [o.time_s for o in got] == [o.time_s for o in ref]
    np.testing.assert_allclose(got[-1].occupancy, ref[-1].occupancy, atol=1e-6)
    np.testing.assert_array_equal(got[-1].tracks.ids, ref[-1].tracks.ids)
    assert got[-1].n_late == 0
    # the time stamps with two sensors were fused in one update each
    assert any(len(o.sensors) > 1 for o in ref)


def test_too_late_messages_are_reported_not_fused(rng):
    msgs = _stream(rng)
    shuffled = _shuffle_within(msgs, 0.3, np.random.default_rng(2))
    with pytest.warns(LateEvidenceWarning):
        outs = list(track_evidence(STACK, shuffled, TrackingParams(window_s=0.05, merge_tolerance_s=1e-6)))
    assert outs[-1].n_late > 0
    assert len(outs) + outs[-1].n_late <= len(msgs)
    assert np.all(np.diff([o.time_s for o in outs]) > 0)


def test_prediction_covers_elapsed_time_whatever_the_rates():
    """Fusing evidence at irregular stamps = predicting over each gap: one long gap equals many short ones
    for an unobserved region (exact exponential relaxation to the prior)."""
    params = BOFParams(decay_rate_hz=1.0, prior_occupancy=0.1, velocity_max_m_s=0.5)  # borders: 3 cells
    a = BayesianOccupancyFilter(STACK, params)
    b = BayesianOccupancyFilter(STACK, params)
    lo = np.full(STACK.shape, 3.0, np.float32)
    for f in (a, b):
        f.predict_to(0.0)
        f.update(lo)
    for t in (0.013, 0.05, 0.2, 0.21, 0.6):
        a.predict_to(t)
        a.update(np.zeros(STACK.shape, np.float32))
    b.predict_to(0.6)
    np.testing.assert_allclose(a.occupancy[:, 6:19, 6:24], b.occupancy[:, 6:19, 6:24], atol=1e-5)


def test_messages_weighted_by_their_share_of_the_correlation_time():
    """w_i = min(1, (t_i - t_{i-1}) / tau): the first message and one after a gap count fully, a 25 Hz frame
    0.04 / 0.2 of one; sensors without a correlation time are not weighted; a checkpoint keeps the clock."""
    z = np.ones(STACK.shape, np.float32)
    buf = AsyncEvidenceBuffer(window_s=0.0, merge_tolerance_s=1e-6, correlation_s={"cam": 0.2, "laser": 0.0})
    got = []
    for t, s in ((0.0, "cam"), (0.04, "cam"), (0.08, "cam"), (0.08, "laser"), (0.12, "laser")):
        got += buf.push(Evidence(t, s, z))
    np.testing.assert_allclose([b.log_odds[0, 0, 0] for b in got], [1.0, 0.2, 0.2, 1.0, 1.0], rtol=1e-6)
    again = AsyncEvidenceBuffer(window_s=0.0, merge_tolerance_s=1e-6, correlation_s={"cam": 0.2})
    again.load_state_dict(buf.state_dict())
    for b in (buf, again):  # after 0.5 s without frames (dropped or a slow camera): one whole observation
        np.testing.assert_allclose([x.log_odds[0, 0, 0] for x in b.push(Evidence(0.58, "cam", z))], [1.0])
    with pytest.raises(ValueError, match="correlation_s"):
        AsyncEvidenceBuffer(correlation_s={"cam": -1.0})


def test_persistent_camera_ghost_does_not_drown_the_laser():
    """A cell a 25 Hz camera calls occupied in every frame (a single-view ray, a ghost: log-odds +1 per frame)
    while a 40 Hz laser's beams cross it (-0.2 per scan), for 3 s. Taken as independent, the camera's frames
    bring 25 log-odds per second against the laser's 8 and the filter believes the ghost (P > 0.8); with the
    cameras' correlation time (the system default) they bring 1 / tau = 2 per second and the cell ends free.
    The same camera at 5 Hz (one frame per 0.2 s) and 25 Hz give about the same belief with the weighting."""
    from planefuse.pipeline import SystemParams

    tau = SystemParams().camera_correlation_s
    ghost = np.zeros(STACK.shape, np.float32)
    ghost[:, 10:13, 10:13] = 1.0

    def final_occupancy(correlation_s, camera_hz=25.0):
        msgs = [Evidence(t, "cameras", ghost) for t in np.arange(0.0, 3.0, 1 / camera_hz)]
        msgs += [Evidence(t, "laser", -0.2 * ghost) for t in np.arange(0.0, 3.0, 1 / 40)]
        msgs.sort(key=lambda e: e.time_s)
        params = TrackingParams(window_s=0.0, merge_tolerance_s=1e-6, evidence_correlation_s=correlation_s)
        return list(track_evidence(STACK, msgs, params))[-1].occupancy[:, 11, 11]

    prior = BOFParams().prior_occupancy
    assert np.all(final_occupancy({}) > 0.8)
    weighted = final_occupancy({"cameras": tau})
    assert np.all(weighted < prior)
    np.testing.assert_allclose(final_occupancy({"cameras": tau}, camera_hz=5.0), weighted, atol=0.02)


def test_bad_input_raises():
    with pytest.raises(ValueError, match="window_s"):
        AsyncEvidenceBuffer(window_s=-1)
    buf = AsyncEvidenceBuffer(shape=STACK.shape)
    with pytest.raises(ValueError, match="expected"):
        buf.push(Evidence(0.0, "x", np.zeros((1, 2, 2), np.float32)))
    with pytest.raises(ValueError, match="Evidence"):
        buf.push(np.zeros(STACK.shape))
