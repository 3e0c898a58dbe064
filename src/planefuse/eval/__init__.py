"""Evaluation against ground truth."""

from ._attitude import AttitudeScores, rest_mask, score_attitude
from ._detection import DetectionScores, detection_scores, match_detections
from ._system import EVAL_WARMUP_S, run_counts, system_metrics
from ._tracking import tracking_metrics

__all__ = [
    "AttitudeScores",
    "rest_mask",
    "score_attitude",
    "DetectionScores",
    "detection_scores",
    "match_detections",
    "run_counts",
    "system_metrics",
    "EVAL_WARMUP_S",
    "tracking_metrics",
]
