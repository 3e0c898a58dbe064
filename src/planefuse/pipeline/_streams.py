"""Every modality of a recording turned into time-stamped :class:`~planefuse.grid.Evidence` on the plane stack.

Each generator reads its stream lazily (chunk by chunk) and yields evidence in
time order; :func:`merged_evidence` interleaves them by time stamp, which is what
the Bayesian Occupancy Filter consumes (seed eq. 7: one product of sensor models
per fused time step).
"""

from __future__ import annotations

import heapq
from collections.abc import Iterator
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from ..grid import Evidence, GroundDetections, PlaneStack
from ..io import Recording

if TYPE_CHECKING:
    from ..vision import CameraReport

__all__ = ["ModalityReport", "camera_evidence", "laser_evidence", "sound_evidence", "merged_evidence"]


@dataclass
class ModalityReport:
    """What each modality produced and what it had to report (missing frames, invalid returns...)."""

    camera: "CameraReport | None" = None
    camera_detections: list[GroundDetections] = field(default_factory=list)
    n_laser_scans: int = 0
    n_laser_invalid_beams: int = 0
    laser_points_world: list[np.ndarray] = field(default_factory=list)
    laser_points_times_s: list[float] = field(default_factory=list)
    n_sound_blocks: int = 0
    sound_times_s: list[float] = field(default_factory=list)
    sound_map_azimuth_rad: list[float] = field(default_factory=list)
    sound_saliency: list[np.ndarray] = field(default_factory=list)
    sound_azimuth_grid_rad: np.ndarray | None = None
    T_world_head: np.ndarray | None = None

    @property
    def n_camera_frames(self) -> int:
        """Synchronised camera instants processed."""
        return self.camera.instants if self.camera is not None else 0

    @property
    def n_missing_camera_frames(self) -> int:
        """Frames missing at those instants, over all cameras (see ``camera.missing_frames``)."""
        return self.camera.n_missing if self.camera is not None else 0


def camera_evidence(rec: Recording, stack: PlaneStack, params, report: ModalityReport) -> Iterator[Evidence]:
    """Background subtraction (primed with the empty-scene image where the stream has one), registration
    on every plane and multi-view fusion (planefuse.vision)."""
    from ..vision import CameraReport, camera_detections, lookups_from_cameras, recording_frames

    cams = rec.cameras
    names = [c.name for c in cams]
    lookups = lookups_from_cameras(cams, stack)
    report.camera = CameraReport()
    # empty-scene calibration plates prime the background models (no ghosts of people already in view)
    backgrounds = [_background_or_none(rec.camera(n)) for n in names]
    for ev, det in camera_detections(recording_frames(rec), lookups, stack, params,
                                     names=names, report=report.camera, backgrounds=backgrounds):
        report.camera_detections.append(det)
        yield ev


def _background_or_none(stream) -> np.ndarray | None:
    """The stream's empty-scene image, or None where it has none."""
    try:
        return stream.background()
    except ValueError:
        return None


def laser_evidence(rec: Recording, stack: PlaneStack, model, report: ModalityReport,
                   keep_points_every: int = 40) -> Iterator[Evidence]:
    """Every scan of every laser registered with free space on every plane (planefuse.laser).

    The recording format writes NaN for "no return within range"; such beams free space up to the
    maximum range (``scans_from_arrays(nan_is_no_return=True)``).
    """
    from ..laser import LaserRegistrar, scans_from_arrays
    from ..sim import tilting_unit_from_model

    for name in rec.lasers:
        ls = rec.laser(name)
        unit = tilting_unit_from_model(ls.model)
        registrar = LaserRegistrar(stack, unit, model, sensor=name)
        sc = unit.scanner
        for chunk in ls.chunks():
            scans = scans_from_arrays(chunk.times_s, chunk.angles_rad, chunk.ranges_m, chunk.tilt_rad,
                                      ls.T_world_base, sc.range_min_m, sc.range_max_m)
            for scan in scans:
                reg = registrar.register(scan)
                report.n_laser_scans += 1
                report.n_laser_invalid_beams += reg.n_invalid
                if report.n_laser_scans % keep_points_every == 1:
                    report.laser_points_world.append(reg.points_world)
                    report.laser_points_times_s.append(scan.time_s)
                yield reg.evidence


def sound_evidence(rec: Recording, stack: PlaneStack, report: ModalityReport, block_s: float = 0.5,
                   model=None) -> Iterator[Evidence]:
    """Bayesian binaural localisation per block, registered as a wedge on every plane (planefuse.audio)."""
    from ..audio import default_sensor_model, evidence_from_saliency, localize

    for name in rec.audio:
        au = rec.binaural(name)
        m = model if model is not None else default_sensor_model(float(au.fs_hz))
        n = int(round(block_s * au.fs_hz))
        for t0, x in au.blocks(n):
            if len(x) < n // 2:
                continue
            loc = localize(x, float(au.fs_hz), m)
            t = t0 + 0.5 * len(x) / au.fs_hz
            report.n_sound_blocks += 1
            report.sound_times_s.append(t)
            report.sound_map_azimuth_rad.append(loc.map_azimuth_rad)
            report.sound_saliency.append(loc.saliency)
            report.sound_azimuth_grid_rad = loc.azimuth_rad
            report.T_world_head = au.T_world_head
            yield evidence_from_saliency(loc.saliency, loc.azimuth_rad, au.T_world_head, stack, t, sensor=name)


def merged_evidence(*streams: Iterator[Evidence]) -> Iterator[Evidence]:
    """Interleave time-ordered evidence streams by time stamp."""
    return heapq.merge(*streams, key=lambda e: e.time_s)
