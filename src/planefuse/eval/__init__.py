"""Evaluation against ground truth."""

from ._tracking import tracking_metrics

__all__ = ["tracking_metrics"]
