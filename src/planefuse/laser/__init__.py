"""Laser range finders: scanner models, simulation, registration onto the plane stack, readers."""

from ._raycast import HIT_CYLINDER, HIT_FLOOR, HIT_NONE, HIT_SPHERE, HIT_WALL, raycast
from ._scanner import (
    LaserScan,
    LaserScannerSpec,
    R_y,
    TiltingUnit,
    origins_world_from_scan,
    points_laser_from_scan,
    points_world_from_scan,
)
from ._simulate import ScanTruth, simulate_nodding_sweep, simulate_scan

__all__ = [
    "HIT_CYLINDER",
    "HIT_FLOOR",
    "HIT_NONE",
    "HIT_SPHERE",
    "HIT_WALL",
    "raycast",
    "LaserScan",
    "LaserScannerSpec",
    "R_y",
    "TiltingUnit",
    "origins_world_from_scan",
    "points_laser_from_scan",
    "points_world_from_scan",
    "ScanTruth",
    "simulate_nodding_sweep",
    "simulate_scan",
]
