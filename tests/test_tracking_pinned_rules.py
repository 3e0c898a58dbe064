"""Three rules of the tracking core pinned by exact cases (issue 39), each written from docs/filter.md:

- the association gate: a cluster is admissible for a track if ``y^T S_p^-1 y <= gate_chi2`` *and*
  ``|y| <= gate_m`` (``y`` the position innovation, ``S_p = P_pp + R_pp``);
- track deletion: a tentative track is deleted at its first miss; a confirmed one after *more than*
  ``max_misses`` misses (alive with exactly ``max_misses``), or when its prediction leaves the grid;
- the asynchronous buffer releases messages in *time* order, whatever their arrival order, once a message
  ``window_s`` newer arrived; a message older than what was released is late and not fused.

Each test fails if its rule changes (the cap or the chi-square bound scaled by 1.5, a deletion one step earlier or
later, messages applied in arrival order): checked by planting those changes (docs/results.md, "Hostile inputs,
round two").
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from planefuse.grid import Evidence
from planefuse.tracking import AsyncEvidenceBuffer, Clusters, LateEvidenceWarning, MultiPersonTracker, TrackerParams

DT = 0.1


def _clusters(t: float, xy) -> Clusters:
    """Clusters at ``xy`` (N, 2) [m] with no velocity information (position measurements only)."""
    xy = np.reshape(np.asarray(xy, dtype=float), (-1, 2))
    n = len(xy)
    return Clusters(float(t), xy, np.zeros((n, 2)), np.full(n, 1.7), np.full(n, 0.9), np.zeros((2, 2)), None)


def _predicted_position_variance(position_std_m: float, initial_velocity_std_m_s: float, acceleration_std_m_s2: float,
                                 dt: float) -> float:
    """Per-axis position variance of a track born at a cluster (``P = R``, velocity variance capped at
    ``initial_velocity_std^2``, no covariance) after one constant-velocity prediction over ``dt``: ``F P F^T + Q``,
    ``Q`` the discrete white-noise acceleration (``q dt^4 / 4`` on the position), written out here."""
    return position_std_m**2 + dt**2 * initial_velocity_std_m_s**2 + acceleration_std_m_s2**2 * dt**4 / 4


def _associated(params: TrackerParams, offset_m: float) -> bool:
    """Whether a track born at (2, 2) takes, one step later, a cluster ``offset_m`` away along x (no other
    cluster; the cluster would otherwise start a second track, ``birth_exclusion_m = 0``)."""
    tr = MultiPersonTracker(params, extent_m=(0.0, 10.0, 0.0, 10.0))
    first = tr.step(_clusters(0.0, [[2.0, 2.0]]))
    (track_id,) = first.ids
    out = tr.step(_clusters(DT, [[2.0 + offset_m, 2.0]]))
    ids = dict(zip(out.ids.tolist(), out.misses.tolist()))
    if ids.get(track_id) == 0:
        assert len(ids) == 1  # taken: no second track
        return True
    assert ids.get(track_id) == 1 and len(ids) == 2  # missed (coasting), and the cluster started a new track
    return False


# pairs are formed wherever the gate admits them: a tiny clutter density makes any gated pair cheaper than a miss
_OPEN = dict(confirm_hits=1, birth_exclusion_m=0.0, clutter_density_per_m2=1e-9, support_threshold=None,
             reacquire_speed_m_s=None, max_coast_report=5)


@pytest.mark.parametrize("offset_m", [0.0, 0.5, 0.74, 0.749, 0.751, 0.76, 0.9, 1.1])
def test_the_gate_distance_cap_is_gate_m(offset_m):
    """position_std 0.3 m: ``S_p`` = 0.0900 + 0.0100 + 0.0001 + 0.09 m^2, the chi-square gate reaches
    sqrt(9.21 x 0.19) = 1.32 m, so the cap ``gate_m = 0.75`` m alone decides up to there."""
    params = TrackerParams(position_std_m=0.3, **_OPEN)
    s = _predicted_position_variance(0.3, params.initial_velocity_std_m_s, params.acceleration_std_m_s2, DT) + 0.3**2
    assert np.sqrt(params.gate_chi2 * s) > 1.3 and params.gate_m == 0.75
    assert _associated(params, offset_m) == (offset_m <= params.gate_m)


@pytest.mark.parametrize("d2", [0.0, 4.0, 9.0, 9.2, 9.22, 9.5, 12.0, 14.0])
def test_the_gate_mahalanobis_bound_is_gate_chi2(d2):
    """gate_m = 10 m: the chi-square bound alone decides. The cluster is placed at Mahalanobis distance ``d2``
    under ``S_p`` computed independently (default position_std 0.15 m: S_p = 0.0551 m^2)."""
    params = TrackerParams(gate_m=10.0, **_OPEN)
    s = (_predicted_position_variance(params.position_std_m, params.initial_velocity_std_m_s,
                                      params.acceleration_std_m_s2, DT) + params.position_std_m**2)
    assert s == pytest.approx(0.0551)
    assert _associated(params, np.sqrt(d2 * s)) == (d2 <= params.gate_chi2)


def _lifetime(params: TrackerParams, hits: int, extent=(0.0, 10.0, 0.0, 10.0), start=(5.0, 5.0),
              velocity=(0.0, 0.0)) -> tuple[list[int], list[int]]:
    """A walker seen for ``hits`` steps, then never again: per step after the last cluster, the number of tracks
    the tracker holds and their miss counts."""
    tr = MultiPersonTracker(params, extent_m=extent)
    xy = np.asarray(start, float)
    v = np.asarray(velocity, float)
    for k in range(hits):
        tr.step(_clusters(k * DT, [xy + v * k * DT]))
    held, misses = [], []
    for k in range(hits, hits + 15):
        tr.step(_clusters(k * DT, np.zeros((0, 2))))
        held.append(len(tr.tracks))
        misses.append(tr.tracks[0].misses if tr.tracks else -1)
    return held, misses


@pytest.mark.parametrize("max_misses", [0, 1, 3, 10])
def test_a_confirmed_track_is_deleted_after_more_than_max_misses(max_misses):
    held, misses = _lifetime(TrackerParams(max_misses=max_misses, confirm_hits=3), hits=5)
    # alive with 1 .. max_misses misses, gone at miss max_misses + 1
    assert held == [1] * max_misses + [0] * (15 - max_misses)
    assert misses[:max_misses] == list(range(1, max_misses + 1))


@pytest.mark.parametrize("hits", [1, 2])
def test_a_tentative_track_is_deleted_at_its_first_miss(hits):
    held, _ = _lifetime(TrackerParams(confirm_hits=3, max_misses=10), hits=hits)
    assert held == [0] * 15


def test_a_coasting_track_is_deleted_when_its_prediction_leaves_the_grid():
    """A walker at 1 m/s towards x = 10 m, last seen at x = 9.45 m: its prediction leaves the grid (x > 10 m)
    at the 6th miss (9.45 + 6 x 0.1 = 10.05), long before max_misses = 10."""
    held, _ = _lifetime(TrackerParams(max_misses=10, confirm_hits=3, acceleration_std_m_s2=0.01),
                        hits=20, start=(7.55, 5.0), velocity=(1.0, 0.0))
    assert held[:5] == [1] * 5 and held[5] == 0


def test_a_deleted_track_s_id_never_comes_back():
    tr = MultiPersonTracker(TrackerParams(max_misses=2, confirm_hits=1), extent_m=(0.0, 10.0, 0.0, 10.0))
    (first,) = tr.step(_clusters(0.0, [[5.0, 5.0]])).ids
    for k in range(1, 4):
        tr.step(_clusters(k * DT, np.zeros((0, 2))))
    assert not tr.tracks
    (second,) = tr.step(_clusters(4 * DT, [[5.0, 5.0]])).ids
    assert second != first


# -- the asynchronous buffer: time order ----------------------------------------------------------------------
def _ev(t: float, name: str) -> Evidence:
    return Evidence(t, name, np.full((1, 2, 2), t, np.float32))


def test_the_buffer_releases_in_time_order_not_arrival_order():
    """Exact case, window 0.3 s: stamps arrive 0.2, 0.0, 0.1, 0.5, 0.4, 0.9 (each within the window of the newest)."""
    buf = AsyncEvidenceBuffer(window_s=0.3)
    released = []
    for t, name in [(0.2, "c"), (0.0, "a"), (0.1, "b"), (0.5, "e"), (0.4, "d"), (0.9, "f")]:
        released.append([(b.time_s, b.sensors) for b in buf.push(_ev(t, name))])
    # 0.5 arrives: everything up to 0.2 is released, oldest first; 0.9 arrives: up to 0.6
    assert released == [[], [], [], [(0.0, ("a",)), (0.1, ("b",)), (0.2, ("c",))], [],
                        [(0.4, ("d",)), (0.5, ("e",))]]
    assert [(b.time_s, b.sensors) for b in buf.flush()] == [(0.9, ("f",))]
    assert buf.n_late == 0


def test_messages_within_the_window_come_out_sorted_whatever_their_arrival(rng):
    """Independent reference: ``sorted``. 200 stamps at 0.05 s, each delayed by less than the window."""
    window = 0.3
    t = np.round(np.arange(200) * 0.05, 6)
    arrival = t + rng.uniform(0.0, window - 0.06, t.size)  # every message arrives within the window
    buf = AsyncEvidenceBuffer(window_s=window)
    out = []
    for k in np.argsort(arrival, kind="stable"):
        out += [b.time_s for b in buf.push(_ev(float(t[k]), f"s{k}"))]
    out += [b.time_s for b in buf.flush()]
    assert buf.n_late == 0 and out == sorted(t.tolist())
    assert any(np.diff(np.argsort(arrival, kind="stable")) < 0)  # the arrival order was not the time order


def test_a_message_older_than_the_released_time_is_late_and_not_fused():
    buf = AsyncEvidenceBuffer(window_s=0.2)
    assert buf.push(_ev(0.0, "a")) == []
    assert [b.time_s for b in buf.push(_ev(0.3, "b"))] == [0.0]
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        assert buf.push(_ev(-0.1, "late")) == []
    assert buf.n_late == 1 and buf.late[0].sensor == "late"
    assert any(issubclass(w.category, LateEvidenceWarning) for w in caught)
    assert [b.sensors for b in buf.flush()] == [("b",)]


def test_messages_at_one_instant_are_summed_into_one_batch():
    buf = AsyncEvidenceBuffer(window_s=0.1, merge_tolerance_s=1e-3)
    released = []
    for t, name in [(0.0005, "laser"), (0.0, "cam"), (0.5, "x")]:
        released += buf.push(_ev(t, name))
    (batch,) = released
    assert batch.time_s == 0.0 and set(batch.sensors) == {"cam", "laser"}
    np.testing.assert_allclose(batch.log_odds, 0.0005)
