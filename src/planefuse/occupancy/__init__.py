"""Generative multi-view occupancy (Fleuret et al. 2008): silhouettes, mean-field marginals, POM files.

Public API (stable): :class:`Silhouettes`, :func:`silhouettes_from_cameras` (boxes projected from calibrated
cameras, :class:`PersonVolume`), :class:`GenerativeParams`, :class:`MeanFieldSolver` /
:func:`occupancy_marginals`, and the ``.pom`` readers/writers.
"""

from ._meanfield import GenerativeParams, MeanFieldResult, MeanFieldSolver, Silhouettes, occupancy_marginals
from ._pom import PomConfig, pom_frame_path, read_pom, read_pom_masks, run_pom, write_pom, write_pom_result
from ._silhouettes import PersonVolume, locations_from_stack, silhouettes_from_cameras

__all__ = [
    "GenerativeParams",
    "MeanFieldResult",
    "MeanFieldSolver",
    "PersonVolume",
    "PomConfig",
    "Silhouettes",
    "locations_from_stack",
    "occupancy_marginals",
    "pom_frame_path",
    "read_pom",
    "read_pom_masks",
    "run_pom",
    "silhouettes_from_cameras",
    "write_pom",
    "write_pom_result",
]
