"""Evaluation against ground truth."""

from ._detection import DetectionScores, detection_scores, match_detections

__all__ = [
    "DetectionScores",
    "detection_scores",
    "match_detections",
]
