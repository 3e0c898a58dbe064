"""End to end: a stream of sensor evidence -> BOF per plane -> clusters -> tracks.

``track_evidence(stack, evidence, params)`` consumes :class:`~planefuse.grid.Evidence` from any sensors in
any order within ``params.window_s`` (re-ordered by :class:`AsyncEvidenceBuffer`), fuses every batch of
simultaneous messages into the filter (predict over the elapsed time, then one update with the summed
log-odds) and, at each output step, clusters the filtered planes and advances the tracker.
"""

from __future__ import annotations

from collections.abc import Iterable, Iterator
from dataclasses import dataclass, field

import numpy as np

from ..grid import Evidence, GroundDetections, PlaneStack
from ._async import AsyncEvidenceBuffer, EvidenceBatch
from ._bof import BayesianOccupancyFilter, BOFParams
from ._clustering import ClusterParams, Clusters, cluster_occupancy
from ._tracker import MultiPersonTracker, TrackerParams, Tracks

__all__ = ["TrackerOutput", "TrackingParams", "track_evidence"]


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
    """

    bof: BOFParams = field(default_factory=BOFParams)
    cluster: ClusterParams = field(default_factory=ClusterParams)
    tracker: TrackerParams = field(default_factory=TrackerParams)
    window_s: float = 0.2
    merge_tolerance_s: float = 1e-6
    output_period_s: float | None = None

    def __post_init__(self) -> None:
        if self.output_period_s is not None and not (np.isfinite(self.output_period_s) and self.output_period_s > 0):
            raise ValueError(f"output_period_s must be None or finite and > 0, got {self.output_period_s}")


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
    velocity_mps : ndarray, shape (L, ny, nx, 2), float32
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
    velocity_mps: np.ndarray
    clusters: Clusters
    detections: GroundDetections
    tracks: Tracks
    n_late: int


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
    """
    params = params if params is not None else TrackingParams()
    buffer = AsyncEvidenceBuffer(params.window_s, params.merge_tolerance_s, shape=stack.shape)
    bof = BayesianOccupancyFilter(stack, params.bof)
    tracker = MultiPersonTracker(params.tracker, stack.extent_m)
    next_output_s: float | None = None
    sensors: list[str] = []

    def process(batch: EvidenceBatch) -> Iterator[TrackerOutput]:
        nonlocal next_output_s
        bof.predict_to(batch.time_s)
        bof.update(batch.log_odds)
        sensors.extend(s for s in batch.sensors if s not in sensors)
        period = params.output_period_s
        if period is not None and next_output_s is not None and batch.time_s < next_output_s - 1e-9:
            return
        if period is not None:
            next_output_s = batch.time_s + period if next_output_s is None else next_output_s
            while next_output_s <= batch.time_s + 1e-9:
                next_output_s += period
        occ, vel = bof.state.moments()
        clusters = cluster_occupancy(batch.time_s, occ, vel, stack, params.bof.prior_occupancy, params.cluster)
        tracks = tracker.step(clusters)
        yield TrackerOutput(batch.time_s, tuple(sensors), occ, vel, clusters, clusters.to_ground_detections(),
                            tracks, buffer.n_late)
        sensors.clear()

    for ev in evidence:
        for batch in buffer.push(ev):
            yield from process(batch)
    for batch in buffer.flush():
        yield from process(batch)
