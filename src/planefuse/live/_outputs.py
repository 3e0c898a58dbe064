"""Live outputs for programs: tracks as JSON lines, ``tracks.csv`` and ``tracks_mot.txt``, written (and flushed) at
every output step."""

from __future__ import annotations

import csv
import json
import sys
from pathlib import Path
from typing import IO

import numpy as np

from ..outputs import MOT_FORMAT, mot_rows
from ..tracking import ClusterParams, TrackerOutput

__all__ = ["LiveOutputs", "TRACKS_CSV_COLUMNS", "track_records"]

#: The columns of ``tracks.csv``, as the offline run writes it (docs/outputs.md).
TRACKS_CSV_COLUMNS = ("step", "time_s", "track_id", "x_m", "y_m", "vx_m_s", "vy_m_s")


def track_records(out: TrackerOutput) -> list[dict]:
    """One JSON-ready dict per reported track of ``out``: ``id``, ``x_m``, ``y_m`` (world) [m], ``vx_m_s``,
    ``vy_m_s`` [m/s], ``misses`` (consecutive steps coasting on the prediction)."""
    t = out.tracks
    return [{"id": int(i), "x_m": float(xy[0]), "y_m": float(xy[1]), "vx_m_s": float(v[0]), "vy_m_s": float(v[1]),
             "misses": int(m)} for i, xy, v, m in zip(t.ids, t.xy_m, t.velocity_m_s, t.misses)]


class LiveOutputs:
    """Where a live run writes its tracks as they come.

    Parameters
    ----------
    out_dir : path or None
        Folder of ``tracks.csv`` and ``tracks_mot.txt`` (the offline run's formats, docs/outputs.md; created) and,
        at the end, ``live_report.json``. None: no folder.
    jsonl : str, path or None
        ``"-"``: JSON lines on standard output; a path: JSON lines in that file; None: none. A line per output
        step: ``{"step", "time_s", "latency_s", "tracks": [track_records...]}``.
    append : bool
        Append to the files (a resumed run, :class:`~planefuse.live.LiveFolder`) instead of replacing them.
    person_radius_m : float
        The footprint radius of the MOTChallenge rows [m] (the run's ``tracking.cluster.person_radius_m``, as the
        recording run writes them; None: :class:`~planefuse.tracking.ClusterParams`' default).
    """

    def __init__(self, out_dir: str | Path | None = None, jsonl: str | Path | None = None, *,
                 person_radius_m: float | None = None, append: bool = False) -> None:
        self.person_radius_m = float(ClusterParams().person_radius_m if person_radius_m is None else person_radius_m)
        self.out_dir = None if out_dir is None else Path(out_dir)
        self._csv_file: IO | None = None
        self._mot_file: IO | None = None
        self._jsonl: IO | None = None
        self._own_jsonl = False
        if self.out_dir is not None:
            self.out_dir.mkdir(parents=True, exist_ok=True)
            path = self.out_dir / "tracks.csv"
            header = not (append and path.is_file() and path.stat().st_size > 0)
            self._csv_file = open(path, "a" if append else "w", newline="")
            self._csv = csv.writer(self._csv_file)
            if header:
                self._csv.writerow(TRACKS_CSV_COLUMNS)
            self._csv_file.flush()
            self._mot_file = open(self.out_dir / "tracks_mot.txt", "a" if append else "w")
        if jsonl == "-":
            self._jsonl = sys.stdout
        elif jsonl is not None:
            Path(jsonl).parent.mkdir(parents=True, exist_ok=True)
            self._jsonl, self._own_jsonl = open(jsonl, "a" if append else "w"), True

    def write(self, step: int, out: TrackerOutput, latency_s: float | None) -> None:
        """Append output step ``step`` (its tracks) and flush."""
        records = track_records(out)
        if self._csv_file is not None:
            for r in records:
                self._csv.writerow((step, repr(float(out.time_s)), r["id"], repr(r["x_m"]), repr(r["y_m"]),
                                    repr(r["vx_m_s"]), repr(r["vy_m_s"])))
            self._csv_file.flush()
            t = out.tracks
            mot = mot_rows(np.full(len(t), step), t.ids, t.xy_m, np.ones(len(t)), self.person_radius_m)
            np.savetxt(self._mot_file, mot, fmt=MOT_FORMAT, delimiter=",")
            self._mot_file.flush()
        if self._jsonl is not None:
            self._jsonl.write(json.dumps({"step": step, "time_s": float(out.time_s),
                                          "latency_s": None if latency_s is None else round(latency_s, 6),
                                          "tracks": records}) + "\n")
            self._jsonl.flush()

    def close(self, report: dict | None = None) -> None:
        """Flush and close; write ``report`` as ``live_report.json`` in the folder."""
        for f in (self._csv_file, self._mot_file):
            if f is not None:
                f.close()
        self._csv_file = self._mot_file = None
        if self._jsonl is not None:
            self._jsonl.flush()
            if self._own_jsonl:
                self._jsonl.close()
            self._jsonl = None
        if report is not None and self.out_dir is not None:
            (self.out_dir / "live_report.json").write_text(json.dumps(report, indent=2, default=_jsonable) + "\n")


def _jsonable(v):
    if isinstance(v, np.generic):
        return v.item()
    raise TypeError(f"not JSON-serialisable: {type(v).__name__}")
