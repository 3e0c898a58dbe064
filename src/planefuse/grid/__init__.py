"""Plane stack specification, evidence grids and ground detections."""

from ._evidence import (
    LOG_ODDS_CLIP,
    Evidence,
    GroundDetections,
    log_odds_from_probability,
    probability_from_log_odds,
)
from ._stack import PlaneStack

__all__ = [
    "LOG_ODDS_CLIP",
    "Evidence",
    "GroundDetections",
    "PlaneStack",
    "log_odds_from_probability",
    "probability_from_log_odds",
]
