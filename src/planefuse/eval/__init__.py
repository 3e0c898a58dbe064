"""Evaluation against ground truth."""

from ._detection import DetectionScores, detection_scores, match_detections
from ._system import system_metrics
from ._tracking import tracking_metrics

__all__ = [
    "DetectionScores",
    "detection_scores",
    "match_detections",
    "system_metrics",
    "tracking_metrics",
]
