"""Plane stack specification, evidence grids and ground detections."""

from ._evidence import (
    LOG_ODDS_CLIP,
    Evidence,
    GroundDetections,
    log_odds_from_probability,
    probability_from_log_odds,
)
from ._occluders import cells_filled_by_occluders, cells_hidden_by_occluders, check_occluder_boxes
from ._stack import PlaneStack, disc_offsets

__all__ = [
    "LOG_ODDS_CLIP",
    "Evidence",
    "GroundDetections",
    "PlaneStack",
    "cells_filled_by_occluders",
    "cells_hidden_by_occluders",
    "check_occluder_boxes",
    "disc_offsets",
    "log_odds_from_probability",
    "probability_from_log_odds",
]
