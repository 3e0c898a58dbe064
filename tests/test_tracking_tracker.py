"""Clustering across planes and tracking: crossing people keep identities, births and deaths, heights,
velocities, a person seen by one modality only."""

from __future__ import annotations

import numpy as np
import pytest

from planefuse.eval import tracking_metrics
from planefuse.grid import PlaneStack
from planefuse.tracking import (
    ClusterParams,
    Clusters,
    MultiPersonTracker,
    TrackerParams,
    TrackingParams,
    cluster_occupancy,
    evidence_from_people,
    track_evidence,
)

STACK = PlaneStack.from_extent([0.3, 0.7, 1.1, 1.5, 1.9], (0.0, 6.0), (0.0, 5.0), 0.1)
DT = 0.1


def _crossing(t):
    """Two people on an X: A walks +x, B walks -x, both +y; they meet at t = 3 s at (2.9, 2.45)."""
    a = np.array([0.5 + 0.8 * t, 0.8 + 0.55 * t])
    b = np.array([5.3 - 0.8 * t, 0.8 + 0.55 * t])
    return np.array([a, b]), np.array([1.75, 1.6])


def test_crossing_people_keep_their_identities(rng):
    times = np.arange(60) * DT
    gt, evidence = [], []
    for t in times:
        xy, h = _crossing(t)
        gt.append((t, np.array([1, 2]), xy))
        evidence.append(evidence_from_people(STACK, t, xy, h, "cam", noise_std=0.5, rng=rng))
    outs = list(track_evidence(STACK, evidence))
    assert len(outs) == len(times)
    merged = [len(o.clusters) for o in outs if abs(o.time_s - 3.0) < 0.25]
    assert min(merged) == 1  # the two people do merge into one cluster while crossing
    m = tracking_metrics(gt, [o.tracks for o in outs])
    assert m["num_switches"] == 0
    assert m["idf1"] >= 0.95
    assert m["mota"] >= 0.93  # only the confirmation delay (2 steps x 2 people) is missed
    assert m["num_false_positives"] == 0
    assert m["motp_m"] < 0.08
    # velocities (BOF cluster velocities) and heights, away from the crossing
    late = outs[-1].tracks
    order = np.argsort(late.xy_m[:, 0])  # B is left of A at the end
    np.testing.assert_allclose(late.velocity_m_s[order], [[-0.8, 0.55], [0.8, 0.55]], atol=0.15)
    assert np.all((late.height_m > 1.5) & (late.height_m < 1.9))
    assert np.all((late.confidence > 0.5) & (late.confidence <= 1))


def test_births_and_deaths(rng):
    """A is there from the start and vanishes at 2.5 s (its cells are then seen free); B appears at 1.5 s."""
    params = TrackingParams(tracker=TrackerParams(confirm_hits=3, max_misses=6, max_coast_report=2))
    evidence = []
    for t in np.arange(50) * DT:
        xy, h = [], []
        if t < 2.5 - 1e-9:
            xy.append([1.5 + 0.4 * t, 2.0])
            h.append(1.8)
        if t >= 1.5 - 1e-9:
            xy.append([4.5, 1.0 + 0.5 * (t - 1.5)])
            h.append(1.65)
        evidence.append(evidence_from_people(STACK, t, np.reshape(xy, (-1, 2)), h, "laser+cam", noise_std=0.3,
                                             rng=rng))
    outs = list(track_evidence(STACK, evidence, params))
    ids_at = {round(o.time_s, 1): set(o.tracks.ids.tolist()) for o in outs}
    assert ids_at[0.0] == set() and ids_at[0.1] == set()  # tentative: not reported before 3 hits
    t_a0 = min(t for t, ids in ids_at.items() if ids)
    assert t_a0 <= 0.4  # the filter lifts A over the threshold in 1-2 updates, then 3 hits confirm it
    (id_a,) = ids_at[t_a0]
    # B: the filter needs 1-2 updates to lift a prior cell over the threshold, then 3 hits confirm it
    t_b = min(t for t, ids in ids_at.items() if ids - {id_a})
    assert 1.5 + 2 * DT <= t_b <= 1.5 + 5 * DT
    (id_b,) = ids_at[t_b] - {id_a}
    assert id_b != id_a
    assert all(id_b in ids_at[t] for t in ids_at if t >= t_b)  # never lost
    # A: its cells are seen free from 2.5 s on; the filter forgets it within a few updates, the track coasts
    # for at most max_coast_report steps and is never reported again
    t_a = min(t for t, ids in ids_at.items() if t >= 2.5 and id_a not in ids)
    assert t_a <= 2.5 + 6 * DT
    assert all(id_a not in ids_at[t] for t in ids_at if t >= t_a)
    assert all(ids <= {id_a, id_b} for ids in ids_at.values())  # no other track ever reported


def test_person_seen_by_one_modality_only_is_found(rng):
    """A person outside the cameras' view but seen by the laser (lowest plane only) still makes a cluster:
    unseen planes stay at the prior and add nothing to the column evidence, they do not veto it."""
    seen = np.zeros(STACK.shape, bool)
    seen[0] = True
    evidence = [evidence_from_people(STACK, t, [[3.0, 2.5]], [1.7], "laser", seen=seen, noise_std=0.3, rng=rng)
                for t in np.arange(10) * DT]
    out = list(track_evidence(STACK, evidence))[-1]
    assert len(out.clusters) == 1
    np.testing.assert_allclose(out.clusters.xy_m[0], [3.0, 2.5], atol=0.1)
    assert len(out.tracks) == 1
    assert np.isnan(out.clusters.height_m[0]) or out.clusters.height_m[0] < 0.7  # the laser sees no head


@pytest.mark.parametrize("height_m, band", [(1.7, (1.5, 1.9)), (1.2, (1.1, 1.5)), (2.2, (1.9, 1.9))])
def test_cluster_height_from_highest_occupied_plane(height_m, band):
    occ = np.full(STACK.shape, 0.05)
    vel = np.zeros(STACK.shape + (2,))
    centres = STACK.cell_centers_xy()
    inside = np.sum((centres - [2.0, 2.0]) ** 2, axis=-1) <= 0.2**2
    occ[:, inside] = np.where(np.asarray(STACK.heights_m) <= height_m, 0.95, 0.05)[:, None]
    vel[:, inside] = [0.3, -0.2]
    c = cluster_occupancy(0.0, occ, vel, STACK, 0.05)
    assert len(c) == 1
    assert band[0] <= c.height_m[0] <= band[1]
    np.testing.assert_allclose(c.velocity_m_s[0], [0.3, -0.2], atol=1e-9)
    np.testing.assert_allclose(c.xy_m[0], [2.0, 2.0], atol=0.06)
    d = c.to_ground_detections()
    assert d.source == "bof" and len(d) == 1


def test_empty_and_bad_input():
    occ = np.full(STACK.shape, 0.05)
    c = cluster_occupancy(0.0, occ, np.zeros(STACK.shape + (2,)), STACK, 0.05)
    assert len(c) == 0 and c.xy_m.shape == (0, 2)
    tr = MultiPersonTracker()
    assert len(tr.step(c)) == 0
    with pytest.raises(ValueError, match="velocity_m_s must have shape"):
        cluster_occupancy(0.0, occ, np.zeros((2, 2)), STACK, 0.05)
    with pytest.raises(ValueError, match="body_max_height_m"):
        cluster_occupancy(0.0, occ, np.zeros(STACK.shape + (2,)), STACK, 0.05, ClusterParams(body_max_height_m=0.1))
    with pytest.raises(ValueError, match="before the tracker time"):
        tr.step(Clusters(-1.0, np.zeros((0, 2)), np.zeros((0, 2)), np.zeros(0), np.zeros(0), occ[0]))
    with pytest.raises(ValueError, match="gate_m"):
        TrackerParams(gate_m=0)


def test_column_observed_free_on_one_body_plane_is_not_a_person():
    """A multi-camera ghost: occupied on three body planes, observed free on the fourth -> no cluster;
    the same column with the fourth plane unobserved (at the prior) -> a cluster (column threshold 2.5)."""
    centres = STACK.cell_centers_xy()
    inside = np.sum((centres - [3.0, 2.5]) ** 2, axis=-1) <= 0.25**2
    vel = np.zeros(STACK.shape + (2,))
    for p_plane3, expected in ((1e-4, 0), (0.05, 1)):
        occ = np.full(STACK.shape, 0.05)
        occ[:3, inside] = 0.99
        occ[3, inside] = p_plane3
        assert len(cluster_occupancy(0.0, occ, vel, STACK, 0.05, ClusterParams(threshold=2.5))) == expected
