"""Plane stack specification and per-plane occupancy grids."""

from ._stack import PlaneStack

__all__ = ["PlaneStack"]
