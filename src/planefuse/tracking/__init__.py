"""Bayesian Occupancy Filter per plane, asynchronous multi-sensor fusion, clustering and tracking."""

from ._bof import (
    BayesianOccupancyFilter,
    BOFParams,
    BOFState,
    bof_initial_state,
    bof_predict,
    bof_update,
    transition_probabilities,
    velocity_grid_mps,
)
from ._bof_numpy import bof_predict_numpy, bof_update_numpy

__all__ = [
    "BOFParams",
    "BOFState",
    "BayesianOccupancyFilter",
    "bof_initial_state",
    "bof_predict",
    "bof_predict_numpy",
    "bof_update",
    "bof_update_numpy",
    "transition_probabilities",
    "velocity_grid_mps",
]
