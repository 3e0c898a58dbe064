"""Generative multi-view occupancy (Fleuret et al. 2008): silhouettes, mean-field marginals, POM files."""

from ._meanfield import GenerativeParams, MeanFieldResult, MeanFieldSolver, Silhouettes, occupancy_marginals

__all__ = ["GenerativeParams", "MeanFieldResult", "MeanFieldSolver", "Silhouettes", "occupancy_marginals"]
