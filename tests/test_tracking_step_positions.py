"""Cluster positions from the output step's own evidence (``ClusterParams.position_from_step_evidence``): the
filter decides which people there are, the step's evidence where they stand."""

from __future__ import annotations

import numpy as np
import pytest

from planefuse.grid import PlaneStack
from planefuse.tracking import (
    ClusterParams,
    Clusters,
    EvidenceTracker,
    TrackingParams,
    evidence_from_people,
    positions_from_step_evidence,
    track_evidence,
)

STACK = PlaneStack.from_extent([0.3, 0.7, 1.1, 1.5, 1.9], (0.0, 6.0), (0.0, 5.0), 0.1)


def _walker_who_stops(t_s: float) -> np.ndarray:
    """Walks +x at 1.2 m/s and stops at t = 2 s at (3.4, 2.5) [m]."""
    return np.array([1.0 + 1.2 * min(t_s, 2.0), 2.5])


def _stop_errors_m(params: TrackingParams, seed: int) -> np.ndarray:
    """Signed x error [m] of the walker's cluster at the output steps of the second after he stopped."""
    rng = np.random.default_rng(seed)
    evidence = [evidence_from_people(STACK, t, _walker_who_stops(t)[None], [1.75], "cam", log_odds_occ=8.0,
                                     log_odds_free=-4.0, noise_std=0.5, rng=rng) for t in np.arange(0, 4.0, 0.04)]
    err = []
    for out in track_evidence(STACK, evidence, params):
        if 2.1 <= out.time_s <= 3.0:
            assert len(out.clusters) == 1
            err.append(out.clusters.xy_m[0, 0] - _walker_who_stops(out.time_s)[0])
    return np.array(err)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_a_walker_who_stops_is_not_carried_on_by_the_filter_s_prediction(seed):
    """Regression (baseline and camera_dropout, tuning seeds 1-3, 20-30 s): the filter's mode of a person who stops
    or turns runs on along his old motion (the prediction moves his mass, and each 25 Hz camera frame is weighted
    by its correlation time, 0.08 of an observation), 0.07 m ahead on the tuning scenes, and its clusters lag a
    walker; the Kalman tracks, fed these filtered positions as new measurements, overshot stops and turns, took a
    ghost or the other person of a pair and switched. Taken from the step's own evidence, the cluster stays on the
    stopped walker."""
    params = TrackingParams(output_period_s=0.2, evidence_correlation_s={"cam": 0.5})
    assert params.cluster.position_from_step_evidence  # the library default
    err = _stop_errors_m(params, seed)
    assert len(err) >= 4
    assert np.abs(err).max() < 0.02
    off = TrackingParams(output_period_s=0.2, evidence_correlation_s={"cam": 0.5},
                         cluster=ClusterParams(position_from_step_evidence=False))
    before = _stop_errors_m(off, seed)  # the filter's own mode: ahead of the stopped walker
    assert before.max() > 0.05


def _clusters(xy_m) -> Clusters:
    xy = np.reshape(np.asarray(xy_m, dtype=float), (-1, 2))
    n = len(xy)
    return Clusters(1.0, xy, np.full((n, 2), 0.5), np.full(n, 1.7), np.full(n, 0.9), np.zeros(STACK.shape[1:]),
                    np.full((n, 2), 0.1))


def test_positions_move_onto_the_step_evidence_and_stay_without_it():
    """A cluster 0.15 m off a person of the step's evidence moves onto him (mean-shift in a 0.3 m disc); a cluster
    whose disc holds no positive step evidence (a person hidden this step) keeps the filter's position; velocity,
    height, confidence and column evidence are the filter's."""
    step = evidence_from_people(STACK, 1.0, [[2.0, 2.0]], [1.75], "cam", log_odds_occ=3.0, log_odds_free=-1.0).log_odds
    clusters = _clusters([[2.15, 2.0], [4.5, 3.0]])
    got = positions_from_step_evidence(clusters, step, STACK, 0.1)
    np.testing.assert_allclose(got.xy_m[0], [2.0, 2.0], atol=0.03)
    np.testing.assert_array_equal(got.xy_m[1], clusters.xy_m[1])
    for name in ("velocity_m_s", "height_m", "confidence", "column_log_odds", "velocity_var_m2_s2"):
        np.testing.assert_array_equal(getattr(got, name), getattr(clusters, name))
    empty = _clusters(np.zeros((0, 2)))
    assert len(positions_from_step_evidence(empty, step, STACK, 0.1)) == 0
    with pytest.raises(ValueError, match="step_log_odds must have shape"):
        positions_from_step_evidence(clusters, step[1:], STACK, 0.1)


def test_checkpoint_between_outputs_keeps_the_step_evidence():
    """A state taken between two output steps holds the evidence fused since the last one: the restored tracker
    gives the same clusters and tracks as the original."""
    rng = np.random.default_rng(0)
    msgs = [evidence_from_people(STACK, t, [[1.0 + 0.8 * t, 2.0]], [1.7], "cam", log_odds_occ=6.0, log_odds_free=-3.0,
                                 noise_std=0.4, rng=rng) for t in np.arange(0, 2.0, 0.04)]
    params = TrackingParams(window_s=0.0, output_period_s=0.2, evidence_correlation_s={"cam": 0.5})
    ref = EvidenceTracker(STACK, params)
    ref_outs = []
    for i, ev in enumerate(msgs):
        ref_outs += list(ref.push(ev))
        if i == 27:
            state = ref.state_dict()
            assert state["step_log_odds"].shape == STACK.shape  # mid-step: evidence held
            n_before = len(ref_outs)
    ref_outs += list(ref.flush())
    resumed = EvidenceTracker(STACK, params)
    resumed.load_state_dict(state)
    got = [o for ev in msgs[28:] for o in resumed.push(ev)] + list(resumed.flush())
    assert len(got) == len(ref_outs) - n_before > 3
    for a, b in zip(ref_outs[n_before:], got):
        np.testing.assert_array_equal(a.clusters.xy_m, b.clusters.xy_m)
        np.testing.assert_array_equal(a.tracks.ids, b.tracks.ids)
        np.testing.assert_array_equal(a.tracks.xy_m, b.tracks.xy_m)
    bad = dict(state, step_log_odds=np.zeros((2, 3), np.float32))
    with pytest.raises(ValueError, match="step_log_odds"):
        EvidenceTracker(STACK, params).load_state_dict(bad)
