"""Cameras: foreground likelihoods, multi-view fusion on the plane stack, people on the ground."""

from ._datasets import (
    EpflSequence,
    camera_instants,
    epfl_box_frames,
    epfl_ground_truth,
    epfl_ground_truth_from_cameras,
    epfl_lookups,
    epfl_sequences,
    image_folder_frames,
    load_epfl_sequence,
    read_epfl_detections,
    recording_frames,
    wildtrack_frames,
)
from ._foreground import (
    BackgroundSubtractor,
    ForegroundParams,
    GainCompensator,
    foreground_from_boxes,
    foreground_from_mask,
    read_mot_detections,
)
from ._fusion import CameraFusion, FusionParams, log_odds_table, max_log_ratio, quantise_foreground
from ._generative import GenerativeCameraSensor, GenerativeSensorParams, detection_evidence_prior
from ._persons import PersonParams, ground_detections_from_log_odds, person_score_map
from ._pipeline import (CameraFrontEnd, CameraParams, CameraReport, camera_detections, camera_foregrounds,
                        frame_is_dead, lookups_from_cameras, subtraction_window)

__all__ = [
    "BackgroundSubtractor",
    "CameraFusion",
    "CameraFrontEnd",
    "CameraParams",
    "camera_foregrounds",
    "quantise_foreground",
    "CameraReport",
    "EpflSequence",
    "ForegroundParams",
    "GainCompensator",
    "FusionParams",
    "GenerativeCameraSensor",
    "GenerativeSensorParams",
    "detection_evidence_prior",
    "PersonParams",
    "camera_detections",
    "frame_is_dead",
    "epfl_box_frames",
    "epfl_ground_truth",
    "epfl_ground_truth_from_cameras",
    "epfl_lookups",
    "epfl_sequences",
    "foreground_from_boxes",
    "foreground_from_mask",
    "ground_detections_from_log_odds",
    "image_folder_frames",
    "load_epfl_sequence",
    "log_odds_table",
    "lookups_from_cameras",
    "max_log_ratio",
    "person_score_map",
    "read_epfl_detections",
    "read_mot_detections",
    "camera_instants",
    "recording_frames",
    "subtraction_window",
    "wildtrack_frames",
]
