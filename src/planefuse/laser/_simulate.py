"""Simulated scans of a (tilting) 2-D laser scanner in the simulator's scene."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from ._raycast import raycast
from ._scanner import LaserScan, LaserScannerSpec, TiltingUnit, origins_world_from_scan

__all__ = ["ScanTruth", "simulate_scan", "simulate_nodding_sweep"]


@dataclass(frozen=True)
class ScanTruth:
    """Noise-free ray-cast result behind a simulated scan.

    Attributes
    ----------
    range_m : ndarray (N,)
        Exact distance to the first surface [m], ``inf`` if none within range.
    hit_kind : ndarray (N,) int8
        ``HIT_*`` code of :mod:`planefuse.laser._raycast`.
    hit_index : ndarray (N,) int64
        Row of the hit cylinder / sphere in the scene tables, -1 otherwise.
    """

    range_m: np.ndarray
    hit_kind: np.ndarray
    hit_index: np.ndarray


def _unit(scanner: TiltingUnit | LaserScannerSpec) -> TiltingUnit:
    if isinstance(scanner, TiltingUnit):
        return scanner
    if isinstance(scanner, LaserScannerSpec):
        return TiltingUnit.fixed(scanner)
    raise ValueError(f"scanner must be a TiltingUnit or LaserScannerSpec, got {type(scanner).__name__}")


def simulate_scan(
    scanner: TiltingUnit | LaserScannerSpec,
    T_world_laser,
    tilt_rad,
    cylinders,
    spheres,
    room_xy_m,
    wall_height_m: float,
    rng: np.random.Generator,
    *,
    time_s: float = 0.0,
    boxes=None,
    return_truth: bool = False,
):
    """Simulate one scan: ray-cast every beam and add Gaussian range noise.

    Parameters
    ----------
    scanner : TiltingUnit or LaserScannerSpec
        The unit (mechanical model + scanner); a bare spec means a fixed 2-D scanner.
    T_world_laser : array_like (4, 4)
        Pose of the unit frame {L} in the world.
    tilt_rad : float or array_like (n_beams,)
        Tilt of the unit per beam [rad] (per-beam values model nodding during the scan).
    cylinders, spheres, room_xy_m, wall_height_m
        The scene (see :func:`planefuse.laser.raycast`).
    rng : numpy.random.Generator
        Source of the range noise.
    time_s : float
        Time stamp given to the scan [s].
    boxes : array_like (B, 6), optional
        Static axis-aligned occluders (see :func:`planefuse.laser.raycast`).
    return_truth : bool
        Also return the noise-free :class:`ScanTruth`.

    Returns
    -------
    LaserScan
        ``ranges_m`` = true range + N(0, sigma^2); ``inf`` marks max-range readings (nothing
        within ``range_max_m``, or the noisy range at or beyond it); NaN marks returns
        closer than ``range_min_m`` (invalid, as a real device reports them).
    """
    unit = _unit(scanner)
    spec = unit.scanner
    angles = spec.angles_rad
    tilt = np.broadcast_to(np.asarray(tilt_rad, dtype=float), angles.shape)
    o_W, d_W = origins_world_from_scan(angles, tilt, T_world_laser, unit)
    r_true, kind, idx = raycast(o_W, d_W, cylinders, spheres, room_xy_m, wall_height_m, spec.range_max_m,
                                boxes=boxes, return_hits=True)
    r = r_true + spec.range_noise_sigma_m * rng.standard_normal(r_true.shape)
    r[r >= spec.range_max_m] = np.inf
    r[r < spec.range_min_m] = np.nan
    scan = LaserScan(float(time_s), angles, r, tilt, spec.range_min_m, spec.range_max_m,
                     np.asarray(T_world_laser, dtype=float))
    if return_truth:
        return scan, ScanTruth(r_true, kind, idx)
    return scan


def simulate_nodding_sweep(
    unit: TiltingUnit,
    T_world_laser: Any,
    scene: Any,
    times_s,
    rng: np.random.Generator,
    *,
    scan_duration_s: float = 0.025,
) -> list[LaserScan]:
    """Simulate the scans of a nodding unit at the given start times.

    Parameters
    ----------
    unit : TiltingUnit
        Nods as a triangle wave between ``tilt_min_rad`` and ``tilt_max_rad`` (``unit.tilt_at``).
    T_world_laser : array_like (4, 4) or callable
        Fixed unit pose, or ``time_s -> (4, 4)`` for a moving platform (evaluated at scan start).
    scene : object
        Anything with ``bodies_at(time_s) -> (cylinders, cylinder_ids, spheres, sphere_ids)``,
        ``room_xy_m`` and ``wall_height_m`` (``planefuse.sim``'s scene); its ``occluder_boxes_m``
        (B, 6), if it has them, stop beams too.
    times_s : array_like (K,)
        Start time of each scan [s].
    rng : numpy.random.Generator
        Range noise.
    scan_duration_s : float
        Time to sweep the beams of one scan [s] (25 ms for a UTM-30LX); beam ``i`` is taken
        at ``t + i / n_beams * scan_duration_s`` and gets the tilt of that instant.

    Returns
    -------
    list of LaserScan
        One per start time, with per-beam tilt and ``T_world_laser`` set.
    """
    times = np.asarray(times_s, dtype=float).reshape(-1)
    if not np.isfinite(times).all():
        raise ValueError("times_s has non-finite entries")
    pose_at: Callable[[float], Any] = T_world_laser if callable(T_world_laser) else (lambda _t: T_world_laser)
    frac = np.arange(unit.scanner.n_beams) / unit.scanner.n_beams
    boxes = getattr(scene, "occluder_boxes_m", None)
    scans = []
    for t in times:  # one ray-cast call per scan; the beams are vectorised inside it
        cylinders, _, spheres, _ = scene.bodies_at(float(t))
        tilt = unit.tilt_at(t + frac * scan_duration_s)
        scans.append(simulate_scan(unit, pose_at(float(t)), tilt, cylinders, spheres, scene.room_xy_m,
                                   scene.wall_height_m, rng, time_s=float(t), boxes=boxes))
    return scans
