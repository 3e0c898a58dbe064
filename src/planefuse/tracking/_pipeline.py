"""End to end: a stream of sensor evidence -> BOF per plane -> clusters -> tracks.

``track_evidence(stack, evidence, params)`` consumes :class:`~planefuse.grid.Evidence` from any sensors in
any order within ``params.window_s`` (re-ordered by :class:`AsyncEvidenceBuffer`), fuses every batch of
simultaneous messages into the filter (predict over the elapsed time, then one update with the summed
log-odds, each message weighted by its share of its sensor's error correlation time) and, at each output
step, clusters the filtered planes (each cluster's position taken from the step's own evidence,
``ClusterParams.position_from_step_evidence``) and advances the tracker.
"""

from __future__ import annotations

from collections.abc import Iterable, Iterator, Mapping
from dataclasses import dataclass, field

import numpy as np

from .._state import StateDict, float_or_none, get, optional_float, strings, sub_state, with_prefix
from ..grid import LOG_ODDS_CLIP, Evidence, GroundDetections, PlaneStack
from ._async import AsyncEvidenceBuffer, EvidenceBatch
from ._bof import BayesianOccupancyFilter, BOFParams
from ._clustering import ClusterParams, Clusters, cluster_occupancy, positions_from_step_evidence
from ._tracker import (MultiPersonTracker, TrackerParams, Tracks, velocity_correlation_time_s,
                       velocity_prior_variance_m2_s2)
from .._params import check_fields

__all__ = ["EvidenceTracker", "TrackerOutput", "TrackingParams", "track_evidence"]


@dataclass(frozen=True)
class TrackingParams:
    """Parameters of :func:`track_evidence`.

    Attributes
    ----------
    bof : BOFParams
        Filter parameters.
    cluster : ClusterParams
        Column clustering parameters.
    tracker : TrackerParams
        Track management parameters.
    window_s : float
        Re-ordering window [s] for out-of-order evidence (see :class:`AsyncEvidenceBuffer`).
    merge_tolerance_s : float
        Messages whose stamps differ by at most this [s] are fused in one update.
    output_period_s : float or None
        None: one output after every fused batch. Otherwise an output at the first batch and then at the
        first batch at or after each further multiple of the period [s].
    evidence_correlation_s : mapping of str to float
        Error correlation time ``tau_s`` [s] per sensor name: each message's log-odds are weighted by
        ``min(1, dt / tau_s)`` before the update, ``dt`` the time since that sensor's previous message
        (:mod:`planefuse.tracking._async`, "Temporally correlated sensor errors"). Sensors not listed: 1.
    """

    bof: BOFParams = field(default_factory=BOFParams)
    cluster: ClusterParams = field(default_factory=ClusterParams)
    tracker: TrackerParams = field(default_factory=TrackerParams)
    window_s: float = 0.2
    merge_tolerance_s: float = 0.05
    output_period_s: float | None = None
    evidence_correlation_s: Mapping[str, float] = field(default_factory=dict)

    def __post_init__(self) -> None:
        check_fields(self, window_s=">=0", merge_tolerance_s=">=0", output_period_s="?>0")
        for name, tau in self.evidence_correlation_s.items():
            if not (np.isfinite(tau) and tau >= 0):
                raise ValueError(f"TrackingParams.evidence_correlation_s[{name!r}] must be >= 0 s, got {tau!r}")


@dataclass(frozen=True)
class TrackerOutput:
    """What :func:`track_evidence` yields at one output step.

    Attributes
    ----------
    time_s : float
        Time of the step [s].
    sensors : tuple of str
        Sensors fused since the previous output.
    occupancy : ndarray, shape (L, ny, nx), float32
        Filtered ``P(occ)`` per plane.
    velocity_m_s : ndarray, shape (L, ny, nx, 2), float32
        Filtered ``E[V | occ]`` per cell (vx, vy) [m/s].
    clusters : Clusters
        Person hypotheses (with the column evidence).
    detections : GroundDetections
        The clusters as ground detections (source ``"bof"``).
    tracks : Tracks
        Reported tracks.
    n_late : int
        Messages so far that arrived too late to be fused (older than the window; a warning was issued).
    """

    time_s: float
    sensors: tuple[str, ...]
    occupancy: np.ndarray
    velocity_m_s: np.ndarray
    clusters: Clusters
    detections: GroundDetections
    tracks: Tracks
    n_late: int


class EvidenceTracker:
    """Filter and track evidence pushed one message at a time, with a state that can be checkpointed.

    ``push(evidence)`` holds the message in the re-ordering buffer and returns an iterator over the
    :class:`TrackerOutput` it makes ready; batches leave the buffer one at a time as that iterator is
    consumed, so :meth:`state_dict` taken at any output (or between messages) is the complete state: the
    held messages, the filter of every plane, the tracks and the output clock. A tracker restored with
    :meth:`load_state_dict` and fed the messages that follow gives exactly the outputs the original would
    have given (call :meth:`drain` first: batches made ready before the checkpoint may still be held).

    Parameters
    ----------
    stack : PlaneStack
        The planes; every evidence must have ``log_odds.shape == stack.shape``.
    params : TrackingParams, optional
    static_cells : ndarray, shape (L, ny, nx), bool, optional
        Cells filled by a known static occluder (:func:`planefuse.grid.cells_filled_by_occluders`). No person
        stands there, and what the sensors say there is about the occluder (a laser's returns off its faces),
        so every batch's log-odds are replaced there by ``-LOG_ODDS_CLIP`` (certainly free of people, the
        strongest evidence the grid takes) before the update: the mass the prediction moves into them from
        a person walking up to the occluder is not kept there either.
    """

    def __init__(self, stack: PlaneStack, params: TrackingParams | None = None,
                 static_cells: np.ndarray | None = None) -> None:
        self.stack = stack
        self.params = params if params is not None else TrackingParams()
        if static_cells is not None:
            static_cells = np.asarray(static_cells, dtype=bool)
            if static_cells.shape != stack.shape:
                raise ValueError(f"static_cells must have the stack's shape {stack.shape}, got {static_cells.shape}")
            if not static_cells.any():
                static_cells = None
        self.static_cells = static_cells
        self.buffer = AsyncEvidenceBuffer(self.params.window_s, self.params.merge_tolerance_s, shape=stack.shape,
                                          correlation_s=self.params.evidence_correlation_s)
        self.bof = BayesianOccupancyFilter(stack, self.params.bof)
        self.tracker = MultiPersonTracker(self.params.tracker, stack.extent_m,
                                          velocity_prior_variance_m2_s2(self.params.bof),
                                          velocity_correlation_time_s(self.params.bof))
        self.next_output_s: float | None = None
        self.sensors: list[str] = []
        #: sum of the log-odds fused since the previous output (the step's own evidence), None: none yet or not kept
        self.step_log_odds: np.ndarray | None = None
        #: outputs given so far (the index of the next output step)
        self.n_outputs = 0

    def push(self, evidence: Evidence, until_s: float | None = None) -> Iterator[TrackerOutput]:
        """Hold ``evidence``; iterate the result to process what became ready (``until_s``: :meth:`drain`)."""
        self.buffer.add(evidence)
        return self.drain(until_s)

    def drain(self, until_s: float | None = None) -> Iterator[TrackerOutput]:
        """Process the batches the buffer can release now; with ``until_s`` [s] also every batch stamped at or
        before it, without waiting ``window_s`` for later messages: the caller knows that no message stamped
        before ``until_s + merge_tolerance_s`` is still to come (a live run's one in-order source,
        :mod:`planefuse.live`), so the batches are those the window would give, released sooner."""
        for batch in self.buffer.ready(until_s=until_s):
            yield from self._process(batch)

    def flush(self) -> Iterator[TrackerOutput]:
        """Process everything still held (end of the stream)."""
        for batch in self.buffer.ready(final=True):
            yield from self._process(batch)

    def _process(self, batch: EvidenceBatch) -> Iterator[TrackerOutput]:
        params, stack = self.params, self.stack
        self.bof.predict_to(batch.time_s)
        log_odds = batch.log_odds
        if self.static_cells is not None:  # no person in an occluder: what sensors say there is about the occluder
            log_odds = np.where(self.static_cells, np.float32(-LOG_ODDS_CLIP), log_odds)
        self.bof.update(log_odds)
        if params.cluster.position_from_step_evidence:
            self.step_log_odds = log_odds.copy() if self.step_log_odds is None else self.step_log_odds + log_odds
        self.sensors.extend(s for s in batch.sensors if s not in self.sensors)
        period = params.output_period_s
        if period is not None and self.next_output_s is not None and batch.time_s < self.next_output_s - 1e-9:
            return
        if period is not None:
            nxt = batch.time_s + period if self.next_output_s is None else self.next_output_s
            while nxt <= batch.time_s + 1e-9:
                nxt += period
            self.next_output_s = nxt
        occ, vel = self.bof.moments()  # computed by the update, in the same pass
        # the joint P(occ, v_k) for the clusters' velocity variance (cells of inactive tiles hold their mass at
        # v = 0 there, but have next to no excess occupancy, so next to no weight in a cluster)
        state = self.bof.state
        clusters = cluster_occupancy(batch.time_s, occ, vel, stack, params.bof.prior_occupancy, params.cluster,
                                     (state.occ_v, state.velocities_m_s))
        if self.step_log_odds is not None:
            clusters = positions_from_step_evidence(clusters, self.step_log_odds, stack, params.bof.prior_occupancy,
                                                    params.cluster)
            self.step_log_odds = None
        tracks = self.tracker.step(clusters)
        sensors = tuple(self.sensors)
        self.sensors.clear()
        self.n_outputs += 1
        # the state is complete here (checkpoints are taken while the output is handled)
        yield TrackerOutput(batch.time_s, sensors, occ, vel, clusters, clusters.to_ground_detections(), tracks,
                            self.buffer.n_late)

    def state_dict(self) -> StateDict:
        """The whole state as arrays under ``buffer.``, ``bof.``, ``tracker.`` (see :mod:`planefuse._state`)."""
        return {
            **with_prefix("buffer", self.buffer.state_dict()),
            **with_prefix("bof", self.bof.state_dict()),
            **with_prefix("tracker", self.tracker.state_dict()),
            "next_output_s": optional_float(self.next_output_s),
            "sensors": strings(self.sensors),
            "n_outputs": np.asarray(self.n_outputs, dtype=np.int64),
            "step_log_odds": (np.zeros((0,) + self.stack.shape, np.float32) if self.step_log_odds is None
                              else self.step_log_odds),
        }

    def load_state_dict(self, state: Mapping[str, np.ndarray]) -> None:
        """Restore what :meth:`state_dict` saved (same planes and parameters)."""
        self.buffer.load_state_dict(sub_state(state, "buffer"))
        self.bof.load_state_dict(sub_state(state, "bof"))
        self.tracker.load_state_dict(sub_state(state, "tracker"))
        self.next_output_s = float_or_none(get(state, "next_output_s", "evidence tracker"))
        self.sensors = [str(s) for s in get(state, "sensors", "evidence tracker")]
        self.n_outputs = int(get(state, "n_outputs", "evidence tracker"))
        step = np.asarray(get(state, "step_log_odds", "evidence tracker"), dtype=np.float32)
        if step.shape not in ((0,) + self.stack.shape, self.stack.shape):
            raise ValueError(f"evidence tracker state: step_log_odds must have shape {self.stack.shape} (or none), "
                             f"got {step.shape}")
        self.step_log_odds = step.copy() if step.shape == self.stack.shape else None


def track_evidence(
    stack: PlaneStack, evidence: Iterable[Evidence], params: TrackingParams | None = None
) -> Iterator[TrackerOutput]:
    """Filter and track a stream of evidence; yields one :class:`TrackerOutput` per output step.

    Parameters
    ----------
    stack : PlaneStack
        The planes; every evidence must have ``log_odds.shape == stack.shape``.
    evidence : iterable of Evidence
        Messages of any sensors, in arrival order (time stamps may be out of order within
        ``params.window_s``; older ones are counted in ``n_late`` and warned about).
    params : TrackingParams, optional
        Parameters.

    See Also
    --------
    EvidenceTracker : the same, one message at a time, with checkpoints.
    """
    tracker = EvidenceTracker(stack, params)
    for ev in evidence:
        yield from tracker.push(ev)
    yield from tracker.flush()
