"""Bayesian Occupancy Filter per plane, asynchronous multi-sensor fusion, clustering and tracking.

``track_evidence(stack, evidence, params)`` is the end-to-end entry point; the pieces are the filter
(:func:`bof_predict`, :func:`bof_update`, :class:`BayesianOccupancyFilter`), the re-ordering buffer
(:class:`AsyncEvidenceBuffer`), the column clustering (:func:`cluster_occupancy`) and the tracker
(:class:`MultiPersonTracker`). See docs/filter.md.
"""

from ._appearance import (AppearanceObserver, AppearanceParams, TrackAppearance, ViewDescriptors, describe_boxes,
                          describe_positions, descriptor_distance)
from ._async import AsyncEvidenceBuffer, EvidenceBatch, LateEvidenceWarning
from ._bof import (
    BayesianOccupancyFilter,
    BOFParams,
    BOFState,
    bof_initial_state,
    bof_predict,
    bof_predict_update,
    bof_update,
    transition_probabilities,
    velocity_grid_m_s,
)
from ._bof_numpy import bof_predict_numpy, bof_update_numpy
from ._clustering import (ClusterParams, Clusters, cluster_occupancy, column_log_odds, positions_from_step_evidence,
                          velocity_variance_m2_s2)
from ._pipeline import EvidenceTracker, TrackerOutput, TrackingParams, track_evidence
from ._split import TrackViews, split_times, split_tracklets, stitch_tracks
from ._stitch import (StitchParams, chain_links, fill_gaps, fill_track_gaps, link_costs, relabel_tracks,
                      smooth_positions, smooth_track_positions, stitch_identities, tracklet_links)
from ._synthetic import evidence_from_people
from ._tracker import (MultiPersonTracker, TrackerParams, Tracks, cluster_measurements, velocity_correlation_time_s,
                       velocity_prior_variance_m2_s2)

__all__ = [
    "AppearanceObserver",
    "StitchParams",
    "relabel_tracks",
    "stitch_identities",
    "fill_gaps",
    "fill_track_gaps",
    "link_costs",
    "tracklet_links",
    "chain_links",
    "TrackViews",
    "split_times",
    "split_tracklets",
    "stitch_tracks",
    "smooth_positions",
    "smooth_track_positions",
    "AppearanceParams",
    "TrackAppearance",
    "ViewDescriptors",
    "describe_boxes",
    "describe_positions",
    "descriptor_distance",
    "AsyncEvidenceBuffer",
    "BOFParams",
    "BOFState",
    "BayesianOccupancyFilter",
    "ClusterParams",
    "Clusters",
    "EvidenceBatch",
    "LateEvidenceWarning",
    "MultiPersonTracker",
    "TrackerOutput",
    "TrackerParams",
    "TrackingParams",
    "Tracks",
    "bof_initial_state",
    "bof_predict",
    "bof_predict_update",
    "bof_predict_numpy",
    "bof_update",
    "bof_update_numpy",
    "cluster_occupancy",
    "column_log_odds",
    "positions_from_step_evidence",
    "evidence_from_people",
    "track_evidence",
    "EvidenceTracker",
    "transition_probabilities",
    "velocity_grid_m_s",
    "velocity_variance_m2_s2",
    "velocity_correlation_time_s",
    "velocity_prior_variance_m2_s2",
    "cluster_measurements",
]
