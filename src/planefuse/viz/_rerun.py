"""Recorded (and optionally live) view of a run in the rerun viewer.

Entity paths (world frame: z up, metres; timelines ``time`` [s] and ``step``)::

    world                               view coordinates (right-handed, Z up)
    world/planes/z_<h>m/outline         static outline of each plane's grid
    world/planes/z_<h>m/occupied        cells with P(occupied) >= threshold, as 3-D points coloured by P
    planes/z_<h>m                       each plane's occupancy as a 2-D image (row 0 = lowest world Y)
    world/cameras/<name>                camera pose (Transform3D) and intrinsics (Pinhole)
    world/cameras/<name>/image          frames, where logged
    world/laser/<name>                  laser hits (3-D points)
    world/sound/<name>                  direction-of-arrival wedge on the ground plane
    world/detections                    ground-plane detections
    world/tracks                        track positions, labelled with their ids

Open the file with ``rerun planefuse.rrd``.
"""

from __future__ import annotations

import uuid
from collections.abc import Sequence
from pathlib import Path

import matplotlib
import numpy as np

try:
    import rerun as rr
except ImportError:  # rerun-sdk is the optional "viz" extra
    rr = None

from ..geometry import PinholeCamera
from ..grid import PlaneStack
from ..outputs._atomic import TMP_MARK

__all__ = ["RerunLogger", "plane_entity", "rrd_entity_paths"]


def plane_entity(height_m: float) -> str:
    """Entity-path component of the plane at ``height_m`` [m], e.g. ``z_0.50m``."""
    return f"z_{height_m:.2f}m"


class RerunLogger:
    """Logs a run to a rerun recording file (and optionally a live viewer).

    Parameters
    ----------
    path : path-like or None
        ``.rrd`` file to write; it is written to a temporary name and renamed
        on :meth:`close`, so a file at ``path`` is always complete.
    stack : PlaneStack
    spawn : bool
        Also stream to a newly started rerun viewer (needs a display).
    occupied_threshold : float
        Cells at or above this P(occupied) are logged as 3-D points.
    """

    def __init__(self, path: Path | str | None, stack: PlaneStack, *, spawn: bool = False,
                 occupied_threshold: float = 0.5, application_id: str = "planefuse"):
        if rr is None:
            raise ImportError("the rerun recording needs rerun-sdk: pip install 'planefuse[viz]'")
        self.stack = stack
        self.occupied_threshold = float(occupied_threshold)
        self.path = None if path is None else Path(path)
        self.rec = rr.RecordingStream(application_id, recording_id=uuid.uuid4())
        self._tmp = None
        if self.path is not None:
            self.path.parent.mkdir(parents=True, exist_ok=True)
            self._tmp = self.path.with_name(f".{self.path.stem}{TMP_MARK}{self.path.suffix}")
            self.rec.save(self._tmp)
        if spawn:
            self.rec.spawn(connect=True)
        self._centers = stack.cell_centers_world()
        self._log_static()

    def _log_static(self) -> None:
        self.rec.log("world", rr.ViewCoordinates.RIGHT_HAND_Z_UP, static=True)
        x0, x1, y0, y1 = self.stack.extent_m
        for h in self.stack.heights_m:
            ring = np.array([[x0, y0, h], [x1, y0, h], [x1, y1, h], [x0, y1, h], [x0, y0, h]])
            self.rec.log(f"world/planes/{plane_entity(h)}/outline", rr.LineStrips3D([ring], radii=0.01),
                         static=True)

    def set_time(self, step: int, time_s: float) -> None:
        """Set the ``step`` and ``time`` [s] timelines for what is logged next."""
        self.rec.set_time("step", sequence=int(step))
        self.rec.set_time("time", duration=float(time_s))

    def log_cameras(self, cameras: Sequence[PinholeCamera]) -> None:
        """Log each camera's pose and intrinsics (static)."""
        for cam in cameras:
            ent = f"world/cameras/{cam.name}"
            self.rec.log(ent, rr.Transform3D(translation=cam.center_world, mat3x3=cam.R_world_cam), static=True)
            self.rec.log(ent, rr.Pinhole(image_from_camera=cam.K, resolution=[cam.intrinsics.width_px,
                                                                              cam.intrinsics.height_px]),
                         static=True)

    def log_camera_image(self, name: str, image) -> None:
        """Log one frame (H, W) or (H, W, 3) uint8 of camera ``name`` at the current time."""
        self.rec.log(f"world/cameras/{name}/image", rr.Image(np.asarray(image)))

    def log_occupancy(self, occupancy) -> None:
        """Log every plane's occupancy (L, ny, nx), P(occupied) in [0, 1], at the current time."""
        occ = np.asarray(occupancy, dtype=np.float32)
        if occ.shape != self.stack.shape:
            raise ValueError(f"occupancy must have shape {self.stack.shape}, got {occ.shape}")
        cmap = matplotlib.colormaps["magma"]
        for l, h in enumerate(self.stack.heights_m):
            name = plane_entity(h)
            p = np.nan_to_num(occ[l], nan=0.0)
            self.rec.log(f"planes/{name}", rr.Image(cmap(p[::-1], bytes=True)[..., :3]))
            m = p >= self.occupied_threshold
            self.rec.log(f"world/planes/{name}/occupied", rr.Points3D(
                self._centers[l][m], colors=cmap(p[m], bytes=True)[:, :3],
                radii=0.5 * self.stack.cell_size_m))

    def log_laser(self, name: str, points_world) -> None:
        """Log laser hits (N, 3) in the world frame [m] at the current time."""
        self.rec.log(f"world/laser/{name}", rr.Points3D(np.asarray(points_world, float).reshape(-1, 3),
                                                        colors=[230, 40, 40], radii=0.02))

    def log_sound_wedge(self, name: str, origin_world, azimuth_min_rad: float, azimuth_max_rad: float,
                        range_m: float = 5.0, n_arc: int = 24) -> None:
        """Log a direction-of-arrival wedge on the ground plane.

        Parameters
        ----------
        origin_world : array-like, shape (3,)
            Microphone pair centre [m]; the wedge is drawn at z = 0.
        azimuth_min_rad, azimuth_max_rad : float
            Bounds of the wedge, world azimuth (from +X towards +Y) [rad].
        range_m : float
            Radius of the drawn wedge [m].
        """
        o = np.asarray(origin_world, float).reshape(3)
        a = np.linspace(azimuth_min_rad, azimuth_max_rad, n_arc)
        arc = np.stack([o[0] + range_m * np.cos(a), o[1] + range_m * np.sin(a), np.zeros_like(a)], -1)
        base = np.array([[o[0], o[1], 0.0]])
        self.rec.log(f"world/sound/{name}", rr.LineStrips3D([np.concatenate([base, arc, base])],
                                                            colors=[60, 160, 255], radii=0.02))

    def log_detections(self, xy_m) -> None:
        """Log ground-plane detections (N, 2) [m] at the current time."""
        xy = np.asarray(xy_m, float).reshape(-1, 2)
        self.rec.log("world/detections", rr.Points3D(np.c_[xy, np.zeros(len(xy))], colors=[0, 220, 220],
                                                     radii=0.08))

    def log_tracks(self, track_ids, xy_m) -> None:
        """Log track positions (N, 2) [m] with their integer ids at the current time."""
        ids = np.asarray(track_ids, dtype=np.int64).reshape(-1)
        xy = np.asarray(xy_m, float).reshape(-1, 2)
        self.rec.log("world/tracks", rr.Points3D(np.c_[xy, np.zeros(len(xy))], class_ids=ids,
                                                 labels=[f"track {i}" for i in ids], radii=0.15))

    def close(self) -> Path | None:
        """Flush and close the recording; return the ``.rrd`` path (renamed into place)."""
        self.rec.flush()
        self.rec.disconnect()
        if self._tmp is not None and self._tmp.exists():
            self._tmp.replace(self.path)
        return self.path


def rrd_entity_paths(path: Path | str) -> set[str]:
    """Entity paths (with leading ``/``) stored in a ``.rrd`` file, read back with rerun's chunk reader."""
    from rerun.chunk import RrdReader

    return {chunk.entity_path for chunk in RrdReader(str(path)).stream()}
