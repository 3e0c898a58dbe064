"""Laser range finders: scanner models, simulation, registration onto the plane stack, readers."""

from ._occupancy import (
    CELL_FREE,
    CELL_OCCUPIED,
    CELL_UNKNOWN,
    P_REF_FROM_WORLD,
    LaserSensorModel,
    ScanRegistration,
    register_points,
    register_scan,
    traverse_beams,
    xy_ref_from_points_laser,
)
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
    "CELL_FREE",
    "CELL_OCCUPIED",
    "CELL_UNKNOWN",
    "P_REF_FROM_WORLD",
    "LaserSensorModel",
    "ScanRegistration",
    "register_points",
    "register_scan",
    "traverse_beams",
    "xy_ref_from_points_laser",
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
