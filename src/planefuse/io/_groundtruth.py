"""Ground truth: people's positions and heights over time, their body shapes, sound sources' positions
and azimuths in the binaural head frame. Stored as CSV under ``groundtruth/``."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..grid import GroundDetections
from ._paths import resolve_inside
from ._timestamps import read_csv_chunks, write_csv

__all__ = ["PeopleTruth", "SoundTruth", "GroundTruth", "PEOPLE_COLUMNS", "BODY_COLUMNS", "SOUND_COLUMNS"]

PEOPLE_COLUMNS = ["time_s", "person_id", "x_m", "y_m", "heading_rad", "speed_m_s", "height_m"]
BODY_COLUMNS = ["person_id", "height_m", "hip_height_m", "leg_radius_m", "leg_spacing_m", "torso_radius_m",
                "head_radius_m"]
SOUND_COLUMNS = ["time_s", "person_id", "speaking", "x_m", "y_m", "z_m", "azimuth_rad", "elevation_rad"]


@dataclass(frozen=True)
class PeopleTruth:
    """Where every person is.

    Attributes
    ----------
    times_s : ndarray (T,)
    person_ids : ndarray (P,) int
    xy_m : ndarray (T, P, 2)
        Body centre on the ground plane (world, metres); NaN where a person is absent.
    heading_rad : ndarray (T, P)
        Facing direction, counter-clockwise from world +x.
    speed_m_s : ndarray (T, P)
    height_m : ndarray (P,)
    """

    times_s: np.ndarray
    person_ids: np.ndarray
    xy_m: np.ndarray
    heading_rad: np.ndarray
    speed_m_s: np.ndarray
    height_m: np.ndarray

    def index_at(self, time_s: float) -> int:
        """Index of the ground-truth sample nearest to ``time_s``."""
        return int(np.argmin(np.abs(self.times_s - time_s)))

    def xy_at(self, times_s) -> np.ndarray:
        """Positions (T, P, 2) [m] linearly interpolated at ``times_s`` (T,), clamped to the sampled span;
        NaN where a person is absent at either neighbouring sample."""
        t = np.atleast_1d(np.asarray(times_s, dtype=float))
        if len(self.times_s) == 1:
            return np.broadcast_to(self.xy_m[0], (len(t),) + self.xy_m.shape[1:]).copy()
        k = np.clip(np.searchsorted(self.times_s, t, side="right") - 1, 0, len(self.times_s) - 2)
        w = np.clip((t - self.times_s[k]) / (self.times_s[k + 1] - self.times_s[k]), 0.0, 1.0)[:, None, None]
        return self.xy_m[k] * (1 - w) + self.xy_m[k + 1] * w

    def detections_at(self, time_s: float) -> GroundDetections:
        """Ground truth at ``time_s`` (interpolated) as :class:`~planefuse.grid.GroundDetections` (confidence 1)."""
        xy = self.xy_at([time_s])[0]
        ok = np.isfinite(xy).all(axis=1)
        return GroundDetections(float(time_s), xy[ok], np.ones(int(ok.sum())), self.height_m[ok], source="groundtruth")

    def rows(self) -> np.ndarray:
        T, P = self.xy_m.shape[:2]
        r = np.zeros((T, P, 7))
        r[..., 0] = self.times_s[:, None]
        r[..., 1] = self.person_ids[None]
        r[..., 2:4] = self.xy_m
        r[..., 4] = self.heading_rad
        r[..., 5] = self.speed_m_s
        r[..., 6] = self.height_m[None]
        return r.reshape(-1, 7)

    @classmethod
    def from_rows(cls, rows: np.ndarray, source: str) -> PeopleTruth:
        times, inv = np.unique(rows[:, 0], return_inverse=True)
        ids, pinv = np.unique(rows[:, 1].astype(int), return_inverse=True)
        T, P = len(times), len(ids)
        xy = np.full((T, P, 2), np.nan)
        hd = np.full((T, P), np.nan)
        sp = np.full((T, P), np.nan)
        xy[inv, pinv] = rows[:, 2:4]
        hd[inv, pinv] = rows[:, 4]
        sp[inv, pinv] = rows[:, 5]
        h = np.full(P, np.nan)
        h[pinv] = rows[:, 6]
        if len(np.unique(inv * P + pinv)) != len(rows):
            raise ValueError(f"{source}: a (time_s, person_id) pair appears twice")
        return cls(times, ids, xy, hd, sp, h)


@dataclass(frozen=True)
class SoundTruth:
    """Sound sources (the speakers' mouths) over time.

    Attributes
    ----------
    times_s : ndarray (T,)
    person_ids : ndarray (Q,) int
        The people who speak at some point.
    speaking : ndarray (T, Q) bool
    position_m : ndarray (T, Q, 3)
        Source position in the world [m].
    azimuth_rad, elevation_rad : ndarray (T, Q)
        Direction in the binaural head frame (azimuth ``atan2(y, x)``, 0 ahead, positive to the left).
    """

    times_s: np.ndarray
    person_ids: np.ndarray
    speaking: np.ndarray
    position_m: np.ndarray
    azimuth_rad: np.ndarray
    elevation_rad: np.ndarray

    def rows(self) -> np.ndarray:
        T, Q = self.speaking.shape
        r = np.zeros((T, Q, 8))
        r[..., 0] = self.times_s[:, None]
        r[..., 1] = self.person_ids[None]
        r[..., 2] = self.speaking
        r[..., 3:6] = self.position_m
        r[..., 6] = self.azimuth_rad
        r[..., 7] = self.elevation_rad
        return r.reshape(-1, 8)

    @classmethod
    def from_rows(cls, rows: np.ndarray, source: str) -> SoundTruth:
        times, inv = np.unique(rows[:, 0], return_inverse=True)
        ids, qinv = np.unique(rows[:, 1].astype(int), return_inverse=True)
        T, Q = len(times), len(ids)
        if T * Q != len(rows) or len(np.unique(inv * Q + qinv)) != len(rows):
            raise ValueError(f"{source}: expected one row per (time_s, person_id), got {len(rows)} rows for "
                             f"{T} times x {Q} sources")
        out = np.zeros((T, Q, 6))
        out[inv, qinv] = rows[:, 2:8]
        return cls(times, ids, out[..., 0] > 0.5, out[..., 1:4], out[..., 4], out[..., 5])


@dataclass(frozen=True)
class GroundTruth:
    """All ground truth of a recording. ``bodies`` is a (P, 7) table with :data:`BODY_COLUMNS`."""

    people: PeopleTruth | None = None
    bodies: np.ndarray | None = None
    sound: SoundTruth | None = None

    def write(self, root: Path) -> dict[str, str]:
        """Write the CSV files under ``root/groundtruth``; returns the manifest's ``groundtruth`` fields."""
        out = {}
        if self.people is not None:
            write_csv(root / "groundtruth/people.csv", PEOPLE_COLUMNS, self.people.rows())
            out["people_file"] = "groundtruth/people.csv"
        if self.bodies is not None:
            write_csv(root / "groundtruth/bodies.csv", BODY_COLUMNS, self.bodies)
            out["bodies_file"] = "groundtruth/bodies.csv"
        if self.sound is not None:
            write_csv(root / "groundtruth/sound_sources.csv", SOUND_COLUMNS, self.sound.rows())
            out["sound_sources_file"] = "groundtruth/sound_sources.csv"
        return out

    @classmethod
    def read(cls, root: Path, people_file: str | None, bodies_file: str | None,
             sound_sources_file: str | None) -> GroundTruth:
        """Read (and check) the ground-truth files named in the manifest."""

        def table(rel: str | None, cols: list[str], timed: bool) -> np.ndarray | None:
            if rel is None:
                return None
            path = resolve_inside(root, rel, "groundtruth file")
            parts = []
            last = -np.inf
            for rows, line in read_csv_chunks(path, cols):
                if timed:
                    # Rows are grouped by time: check the times of the groups, not of every row.
                    t = rows[:, 0]
                    back = np.nonzero(t < np.concatenate([[last], t[:-1]]))[0]
                    if back.size:
                        i = back[0]
                        raise ValueError(f"{path}:{line + i}: time_s {t[i]!r} goes backwards; rows must be sorted by time")
                    last = t[-1]
                parts.append(rows)
            return np.concatenate(parts) if parts else np.zeros((0, len(cols)))

        p = table(people_file, PEOPLE_COLUMNS, True)
        b = table(bodies_file, BODY_COLUMNS, False)
        s = table(sound_sources_file, SOUND_COLUMNS, True)
        return cls(
            None if p is None else PeopleTruth.from_rows(p, str(root / people_file)),
            b,
            None if s is None else SoundTruth.from_rows(s, str(root / sound_sources_file)),
        )
