"""The run's output folder: occupancy (zarr), detections and tracks (CSV + MOTChallenge), metrics, report.

Layout of ``out_dir``::

    run_state.json      config hash, chunk size, finished chunks, status (the commit record)
    config.yaml         the configuration of the run
    occupancy.zarr/     group: occupancy (T, L, ny, nx) float32 P(occupied), time_s (T,) float64
    detections.csv      step,time_s,x_m,y_m,height_m,confidence,source
    tracks.csv          step,time_s,track_id,x_m,y_m,vx_m_s,vy_m_s
    detections_mot.txt  MOTChallenge rows (see :func:`mot_rows`)
    tracks_mot.txt      MOTChallenge rows
    checkpoint.npz      the run's state at the last finished chunk (optional; what a re-run resumes from)
    checkpoint.prev.npz the one before (kept so that a kill between a checkpoint and the commit record
                        still leaves a checkpoint matching the record)
    metrics.json
    figures/*.png, animation.gif|mp4, report.html, planefuse.rrd

Work is committed one chunk of ``chunk_steps`` time steps at a time: the zarr
chunk, the CSV files and the checkpoint are written (each atomically), then
``run_state.json`` records the chunk as finished. A re-run with the same
configuration hash resumes at the first unfinished chunk; a different hash
starts afresh. Interrupting (Ctrl-C) flushes the partial chunk so every file is
valid, but does not mark it finished.
"""

from __future__ import annotations

import contextlib
import csv
import io
import json
import os
import shutil
import tempfile
import zipfile
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import zarr

from ..grid import GroundDetections, PlaneStack
from ._atomic import TMP_MARK, atomic_open, atomic_write_json, atomic_write_text, remove_stale_temporaries
from ._lock import LOCK_FILE, OutputLock, lock_holder

__all__ = ["OutputWriter", "DETECTION_COLUMNS", "TRACK_COLUMNS", "mot_rows", "read_table", "rows_by_step",
           "out_dir_problem", "FIGURES_WRITTEN"]

DETECTION_COLUMNS = ("step", "time_s", "x_m", "y_m", "height_m", "confidence", "source")
TRACK_COLUMNS = ("step", "time_s", "track_id", "x_m", "y_m", "vx_m_s", "vy_m_s")
#: ``camera_boxes.csv``: each camera's person boxes [px, the frame's pixels: u right, v down] at each output step.
BOX_COLUMNS = ("step", "time_s", "camera", "left_px", "top_px", "width_px", "height_px", "score")
STATE_FILE = "run_state.json"
CHECKPOINT_FILE = "checkpoint.npz"
PREVIOUS_CHECKPOINT_FILE = "checkpoint.prev.npz"
_OWNED = ("occupancy.zarr", "detections.csv", "tracks.csv", "detections_mot.txt", "tracks_mot.txt",
          CHECKPOINT_FILE, PREVIOUS_CHECKPOINT_FILE, "metrics.json", "figures", "report.html", "animation.gif",
          "animation.mp4", "planefuse.rrd", "planefuse.mcap", "ros2_bag", "config.yaml", STATE_FILE,
          "tracks_stitched.csv", "tracks_stitched_mot.txt", "live_report.json")
#: Each camera's person boxes as a MOTChallenge 2-D file: ``boxes_<camera>_mot.txt`` (owned like ``_OWNED``).
_BOX_FILE_PREFIX, _BOX_FILE_SUFFIX = "boxes_", "_mot.txt"


def _owned(name: str) -> bool:
    """True for an entry of an output folder that a run writes."""
    return name in _OWNED or name == "camera_boxes.csv" or (
        name.startswith(_BOX_FILE_PREFIX) and name.endswith(_BOX_FILE_SUFFIX))


#: In ``figures/``: the names of the figures planefuse wrote there (the only files of it a new run deletes).
FIGURES_WRITTEN = ".planefuse-figures"


def _foreign_entries(out_dir: Path, owned_by_a_run: bool) -> list[str]:
    """Entries of ``out_dir`` no planefuse run wrote (all of them in a folder without a run's state)."""
    names = [p.name for p in out_dir.iterdir() if TMP_MARK not in p.name and p.name != LOCK_FILE]
    if not owned_by_a_run:
        return sorted(names)
    foreign = [n for n in names if not _owned(n)]
    figures = out_dir / "figures"
    if figures.is_dir():
        ours = _written_figures(figures)
        foreign += [f"figures/{p.name}" for p in figures.iterdir()
                    if p.name not in ours and p.name != FIGURES_WRITTEN and TMP_MARK not in p.name]
    return sorted(foreign)


def _written_figures(figures: Path) -> set[str]:
    try:
        return set((figures / FIGURES_WRITTEN).read_text(encoding="utf-8").split())
    except OSError:
        return set()


def out_dir_problem(out_dir: Path | str, *, config_hash: str, resume: bool = True, force: bool = False,
                    protected: Path | str | None = None) -> str | None:
    """Why a run with ``config_hash`` must not write into ``out_dir`` (None when it may), without writing.

    Refused: a folder equal to or inside ``protected`` (the recording); a path that is a file, lies below a
    file or cannot be written; a folder another planefuse run is writing into (its lock, :mod:`._lock`, is held;
    whatever ``force`` says); a folder holding files no planefuse run wrote (unless ``force``: they are kept);
    a folder holding another run's results -- a different configuration or recording (unless ``force``, or
    ``resume=False``: ``--fresh`` starts afresh and replaces them).
    """
    out = Path(out_dir).absolute()
    if protected is not None:
        rec = Path(protected).resolve()
        if out.resolve() == rec or rec in out.resolve().parents:
            return (f"out_dir {out} is {'the' if out.resolve() == rec else 'inside the'} recording folder {rec}: "
                    "outputs would mix with the recording; choose another folder (outputs.out_dir)")
    for p in (out, *out.parents):
        if p.exists():
            if not p.is_dir():
                return f"out_dir {out}: {p} is a file, not a folder"
            try:  # os.access says yes to root everywhere: try it (read-only file systems, /proc, ...)
                os.rmdir(tempfile.mkdtemp(prefix=f".planefuse-probe{TMP_MARK}", dir=p))
            except OSError as exc:
                return f"out_dir {out}: cannot write in {p} ({exc.strerror or exc})"
            break
    if not out.is_dir():
        return None
    holder = lock_holder(out)
    if holder is not None:
        return (f"out_dir {out} is being written by another planefuse run ({holder}): wait for it to end, or choose "
                "another folder (outputs.out_dir)")
    state_path = out / STATE_FILE
    state = None
    if state_path.exists():
        try:
            state = json.loads(state_path.read_text(encoding="utf-8"))
        except (OSError, ValueError):
            state = None
    if force:
        return None
    foreign = _foreign_entries(out, isinstance(state, dict))
    if foreign:
        shown = ", ".join(foreign[:5]) + (" ..." if len(foreign) > 5 else "")
        return (f"out_dir {out} holds files planefuse did not write ({shown}): choose an empty folder, or pass "
                "--force to write beside them (they are kept)")
    if resume and isinstance(state, dict) and state.get("config_hash") != config_hash:
        return (f"out_dir {out} holds the results of another run (a different configuration, recording or person "
                f"model, "
                f"{state.get('status', '?')}): choose another folder, or pass --fresh (or --force) to replace them")
    return None


def open_locked(out_dir: Path, open_fn: Callable[[], None]) -> OutputLock:
    """Create ``out_dir``, take its lock (:class:`OutputLock`) before anything in it is read or changed, and call
    ``open_fn()`` holding it; returns the lock, released again where the creation or ``open_fn`` fails."""
    out_dir = Path(out_dir)
    try:
        out_dir.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise ValueError(f"out_dir {out_dir}: cannot create the folder ({exc.strerror or exc})") from None
    lock = OutputLock(out_dir)
    lock.acquire()
    try:
        open_fn()
    except BaseException:
        lock.release()
        raise
    return lock


#: ``numpy.savetxt`` formats of :func:`mot_rows`' columns (metres to 0.1 mm).
MOT_FORMAT = ["%d", "%d", "%.4f", "%.4f", "%.4f", "%.4f", "%.4f", "%.4f", "%.4f", "%d"]


def mot_rows(steps, ids, xy_m, confidence, person_radius_m: float) -> np.ndarray:
    """MOTChallenge rows ``frame, id, bb_left, bb_top, bb_width, bb_height, conf, x, y, z`` on the floor plan.

    Frames are 1-based (``step + 1``). The "bounding box" is the person's
    square footprint on the ground plane in metres (``x - r, y - r, 2r, 2r``),
    so motmetrics' IoU distance works on the floor plan; ``x, y`` are the
    world position [m] and ``z`` is -1. Detections use id -1.

    Returns
    -------
    ndarray, shape (N, 10), float64
    """
    steps = np.asarray(steps, dtype=float).reshape(-1)
    xy = np.asarray(xy_m, dtype=float).reshape(-1, 2)
    n = len(steps)
    r = float(person_radius_m)
    out = np.empty((n, 10))
    out[:, 0] = steps + 1
    out[:, 1] = np.asarray(ids, dtype=float).reshape(-1) if np.ndim(ids) else float(ids)
    out[:, 2] = xy[:, 0] - r
    out[:, 3] = xy[:, 1] - r
    out[:, 4] = 2 * r
    out[:, 5] = 2 * r
    out[:, 6] = np.asarray(confidence, dtype=float).reshape(-1) if np.ndim(confidence) else float(confidence)
    out[:, 7:9] = xy
    out[:, 9] = -1
    return out


def rows_by_step(table: Mapping[str, np.ndarray], n_steps: int, *columns: str) -> list[np.ndarray]:
    """The rows of a detections/tracks table (column arrays with a ``step`` column) grouped by step.

    Returns
    -------
    list of ndarray, shape (N_k, len(columns)), float
        One array per step ``0 .. n_steps - 1`` with the given columns of that step's rows (empty where the
        step has none).
    """
    order = np.argsort(table["step"], kind="stable")
    bounds = np.searchsorted(table["step"][order], np.arange(n_steps + 1))
    rows = np.stack([np.asarray(table[c], dtype=float)[order] for c in columns], axis=-1).reshape(-1, len(columns))
    return [rows[a:b] for a, b in zip(bounds[:-1], bounds[1:])]


def read_table(path: Path | str) -> dict[str, np.ndarray]:
    """Read a ``detections.csv`` / ``tracks.csv`` written by :class:`OutputWriter` into column arrays."""
    with open(path, newline="", encoding="utf-8") as f:
        rows = list(csv.reader(f))
    if not rows:
        raise ValueError(f"{path}: empty file (expected a header row)")
    return _columns(tuple(rows[0]), rows[1:])


@dataclass
class _Table:
    columns: tuple[str, ...]
    rows: list[tuple] = field(default_factory=list)

    def truncate(self, step: int) -> None:
        self.rows = [r for r in self.rows if r[0] < step]

    def upto(self, step: int) -> list[tuple]:
        """The rows of the steps before ``step`` (rows come in step order)."""
        n = len(self.rows)
        while n and self.rows[n - 1][0] >= step:
            n -= 1
        return self.rows[:n]

    def csv_text(self, rows: list[tuple]) -> str:
        buf = io.StringIO()
        w = csv.writer(buf, lineterminator="\n")
        w.writerow(self.columns)
        w.writerows(rows)
        return buf.getvalue()


class OutputWriter:
    """Writes everything a run produces into ``out_dir``, resumably and atomically.

    Parameters
    ----------
    out_dir : path-like
        Output folder (created).
    stack : PlaneStack
        The plane stack; occupancy arrays are ``(L, ny, nx)`` on it.
    config_hash : str
        Identifies the configuration (:func:`planefuse.config.config_hash`);
        finished chunks of a previous run are reused only if it matches.
    chunk_steps : int
        Time steps per chunk (the unit of commit and resume).
    write_zarr : bool
        Keep occupancy on disk (``occupancy.zarr``); if False it is kept in
        memory for the figures only and a run cannot resume.
    config_text : str
        YAML of the configuration, copied to ``config.yaml`` and the report.
    person_radius_m : float
        Footprint radius [m] used for the MOTChallenge boxes.
    resume : bool
        False: start afresh even where a previous run of the same configuration left finished chunks
        (they are deleted).
    force : bool
        Write into a folder holding another run's results (replaced) or files no run wrote (kept).
    protected : path-like, optional
        A folder the outputs must not go into (the recording).

    Raises
    ------
    ValueError
        ``out_dir`` is refused (:func:`out_dir_problem`), cannot be created, or another run holds its lock.

    Notes
    -----
    One writer per folder: the writer holds the folder's lock (:class:`~planefuse.outputs._lock.OutputLock`,
    ``.planefuse.lock``) from its creation until :meth:`finish` (status ``"finished"``), :meth:`mark_finished`,
    the end of its ``with`` block or its deletion; a lock left by a killed run is taken over with a warning.

    Attributes
    ----------
    resume_step : int
        First time step the pipeline must compute (0 for a fresh run).
    resumed : bool
        True when finished chunks of a previous run were kept.
    """

    def __init__(
        self,
        out_dir: Path | str,
        stack: PlaneStack,
        *,
        config_hash: str,
        chunk_steps: int = 50,
        write_zarr: bool = True,
        config_text: str = "",
        person_radius_m: float = 0.3,
        resume: bool = True,
        force: bool = False,
        protected: Path | str | None = None,
    ):
        if int(chunk_steps) < 1:
            raise ValueError(f"chunk_steps must be >= 1, got {chunk_steps}")
        problem = out_dir_problem(out_dir, config_hash=str(config_hash), resume=resume, force=force,
                                  protected=protected)
        if problem is not None:
            raise ValueError(problem)
        self.out_dir = Path(out_dir)
        self.stack = stack
        self.config_hash = str(config_hash)
        self.chunk_steps = int(chunk_steps)
        self.write_zarr = bool(write_zarr)
        self.config_text = config_text
        self.person_radius_m = float(person_radius_m)
        self.metrics: dict[str, Any] = {}
        self._lock = open_locked(self.out_dir, lambda: self._open(resume))

    def _open(self, resume: bool) -> None:
        remove_stale_temporaries(self.out_dir)

        state = self._read_state()
        self.resumed = bool(
            resume and state and self.write_zarr and state.get("config_hash") == self.config_hash
            and state.get("chunk_steps") == self.chunk_steps and state.get("n_chunks_done", 0) > 0
            and (self.out_dir / "occupancy.zarr").exists()
        )
        self.n_chunks_done = int(state["n_chunks_done"]) if self.resumed else 0
        self.resume_step = self.n_chunks_done * self.chunk_steps
        if not self.resumed:
            self._clear()
        self._dets = _Table(DETECTION_COLUMNS)
        self._tracks = _Table(TRACK_COLUMNS)
        self._boxes = _Table(BOX_COLUMNS)
        self._tables_dirty = True  # the files do not hold these (empty or truncated) tables yet
        self._open_zarr()
        if self.resumed:
            for table, name in ((self._dets, "detections.csv"), (self._tracks, "tracks.csv"),
                                (self._boxes, "camera_boxes.csv")):
                if (self.out_dir / name).exists():
                    cols = read_table(self.out_dir / name)
                    table.rows = list(zip(*(cols[c].tolist() for c in table.columns)))
                    table.truncate(self.resume_step)
        if self.config_text:
            atomic_write_text(self.out_dir / "config.yaml", self.config_text)
        self._buffer: dict[int, tuple[float, np.ndarray]] = {}
        self._steps_written = self.resume_step
        self._write_state("running")
        self.rerun = None

    def attach_rerun(self, logger) -> None:
        """Log occupancy, detections and tracks to ``logger`` (a :class:`~planefuse.viz.RerunLogger` opened in
        the folder after the writer, which clears stale temporary files) as they are written; a resumed run
        logs the kept steps again first. :attr:`rerun` is it, for the pipeline's own logging; the writer
        closes it."""
        self.rerun = logger
        if self.resumed:
            self._relog_finished_steps()

    def _relog_finished_steps(self) -> None:
        """A resumed run's recording starts anew: log the kept steps again from the folder."""
        times = self.times_s()
        dets = rows_by_step(self.detections_table(), len(times), "x_m", "y_m")
        tracks = rows_by_step(self.tracks_table(), len(times), "track_id", "x_m", "y_m")
        for step, (t, d, tr) in enumerate(zip(times, dets, tracks)):
            self.rerun.set_time(step, float(t))
            self.rerun.log_occupancy(self._occ[step])
            self.rerun.log_detections(d)
            self.rerun.log_tracks(tr[:, 0].astype(np.int64), tr[:, 1:3])

    # -- state ---------------------------------------------------------------------------------------------------
    def _read_state(self) -> dict | None:
        p = self.out_dir / STATE_FILE
        try:
            return json.loads(p.read_text(encoding="utf-8"))
        except (OSError, ValueError):
            return None

    def _state(self, status: str, error: str | None = None) -> dict[str, Any]:
        state = {
            "status": status,
            "config_hash": self.config_hash,
            "chunk_steps": self.chunk_steps,
            "n_chunks_done": self.n_chunks_done,
            "n_steps_finished": self.n_chunks_done * self.chunk_steps,
            "n_steps_written": self._steps_written,
        }
        if error:
            state["error"] = error
        return state

    def _write_state(self, status: str, error: str | None = None) -> None:
        atomic_write_json(self.out_dir / STATE_FILE, self._state(status, error))

    def record_end(self, status: str, error: str | None = None) -> None:
        """Record that the run ended without finishing (``"interrupted"``, ``"failed"``, with the error's first
        300 characters): after a flush of what is buffered where the disk allows, else by overwriting
        ``run_state.json`` in place, which needs no new disk block (a full disk, ENOSPC, refuses the atomic write of
        a new file). Never raises."""
        error = None if error is None else " ".join(error.split())[:300]
        try:
            self.flush(status)
            if error:
                self._write_state(status, error)
            return
        except Exception:  # noqa: BLE001 - the disk is full or gone: fall back to the state alone
            pass
        text = json.dumps(self._state(status, error), indent=2) + "\n"
        with contextlib.suppress(OSError):
            fd = os.open(self.out_dir / STATE_FILE, os.O_WRONLY | os.O_CREAT, 0o644)
            try:
                os.write(fd, text.encode())
                os.ftruncate(fd, len(text.encode()))
            finally:
                os.close(fd)

    def _clear(self) -> None:
        """Delete what an earlier run wrote here; in ``figures/`` only the figures it listed (the user's own
        files there are kept)."""
        figures = self.out_dir / "figures"
        if figures.is_dir():
            for name in _written_figures(figures) | {FIGURES_WRITTEN}:
                (figures / name).unlink(missing_ok=True)
            with contextlib.suppress(OSError):
                figures.rmdir()  # only when empty
        for name in [*_OWNED, *(n for n in os.listdir(self.out_dir) if _owned(n) and n not in _OWNED)]:
            p = self.out_dir / name
            if name == "figures":
                continue
            if p.is_dir():
                shutil.rmtree(p)
            elif p.exists():
                p.unlink()

    def _open_zarr(self) -> None:
        L, ny, nx = self.stack.shape
        store = zarr.storage.LocalStore(self.out_dir / "occupancy.zarr") if self.write_zarr \
            else zarr.storage.MemoryStore()
        if self.resumed:
            self._group = zarr.open_group(store, mode="r+")
            self._occ = self._group["occupancy"]
            self._time = self._group["time_s"]
            self._occ.resize((self.resume_step, L, ny, nx))
            self._time.resize((self.resume_step,))
            return
        g = zarr.open_group(store, mode="w")
        g.attrs.update({
            "heights_m": list(self.stack.heights_m), "x_min_m": self.stack.x_min_m, "y_min_m": self.stack.y_min_m,
            "cell_size_m": self.stack.cell_size_m, "config_hash": self.config_hash,
            "convention": "occupancy[t, l, iy, ix] = P(occupied) of the cell centred at x_min_m+(ix+0.5)*cell, "
                          "y_min_m+(iy+0.5)*cell on the plane z = heights_m[l]",
        })
        self._occ = g.create_array("occupancy", shape=(0, L, ny, nx), chunks=(self.chunk_steps, 1, ny, nx),
                                   dtype="float32", fill_value=np.nan)
        self._time = g.create_array("time_s", shape=(0,), chunks=(self.chunk_steps,), dtype="float64",
                                    fill_value=np.nan)
        self._group = g

    # -- writing ---------------------------------------------------------------------------------------------------
    def write_occupancy(self, step: int, time_s: float, occupancy,
                        checkpoint: Callable[[], Mapping[str, np.ndarray]] | None = None) -> bool:
        """Record the posterior occupancy of every plane at one time step.

        Parameters
        ----------
        step : int
            Time-step index, counted from 0; steps must arrive in order starting at :attr:`resume_step`.
        time_s : float
            Time of the step [s].
        occupancy : ndarray, shape (L, ny, nx)
            P(occupied) per cell, in [0, 1].
        checkpoint : callable, optional
            Returns the filter state (name -> array) to save when this step
            completes a chunk; called only then. :meth:`load_checkpoint` gives it back on resume.

        Returns
        -------
        bool
            True when this step completed (and committed) a chunk.
        """
        occ = np.asarray(occupancy, dtype=np.float32)
        if occ.shape != self.stack.shape:
            raise ValueError(f"occupancy must have shape {self.stack.shape} (L, ny, nx), got {occ.shape}")
        expected = self._steps_written + len(self._buffer)
        if int(step) != expected:
            raise ValueError(f"step {step} out of order: expected step {expected}")
        if not np.isfinite(time_s):
            raise ValueError(f"time_s must be finite, got {time_s}")
        self._buffer[int(step)] = (float(time_s), occ)
        if self.rerun is not None:
            self.rerun.set_time(step, time_s)
            self.rerun.log_occupancy(occ)
        if len(self._buffer) == self.chunk_steps:
            self._flush_buffer()
            self._commit(checkpoint)
            return True
        return False

    def write_detections(self, step: int, detections: GroundDetections) -> None:
        """Record the people detected at ``step`` (positions on the ground plane [m]).

        Call it before the ``write_occupancy`` of the same step: that call may commit the step's chunk.
        """
        self._check_open_step(step)
        if self.rerun is not None:
            self.rerun.set_time(step, detections.time_s)
            self.rerun.log_detections(detections.xy_m)
        for (x, y), h, c in zip(detections.xy_m, detections.height_m, detections.confidence):
            self._dets.rows.append((int(step), float(detections.time_s), float(x), float(y), float(h), float(c),
                                    detections.source))
            self._tables_dirty = True

    def write_tracks(self, step: int, time_s: float, track_ids, xy_m, velocity_m_s=None) -> None:
        """Record the confirmed tracks at ``step``.

        Parameters
        ----------
        track_ids : array-like of int, shape (N,)
        xy_m : array-like, shape (N, 2)
            Positions on the ground plane [m].
        velocity_m_s : array-like, shape (N, 2), optional
            Velocities [m/s]; NaN when omitted.

        Call it before the ``write_occupancy`` of the same step: that call may commit the step's chunk.
        """
        self._check_open_step(step)
        ids = np.asarray(track_ids, dtype=np.int64).reshape(-1)
        xy = np.asarray(xy_m, dtype=float).reshape(-1, 2)
        v = np.full_like(xy, np.nan) if velocity_m_s is None else np.asarray(velocity_m_s, float).reshape(-1, 2)
        if not (len(ids) == len(xy) == len(v)):
            raise ValueError(f"track_ids {ids.shape}, xy_m {xy.shape}, velocity_m_s {v.shape} disagree on N")
        if self.rerun is not None:
            self.rerun.set_time(step, time_s)
            self.rerun.log_tracks(ids, xy)
        for i, p, vv in zip(ids, xy, v):
            self._tracks.rows.append((int(step), float(time_s), int(i), *map(float, p), *map(float, vv)))
            self._tables_dirty = True

    def write_camera_boxes(self, step: int, time_s: float, camera: str, ltwh_px, score) -> None:
        """Record a camera's person boxes at ``step`` (the detector's, at the camera instant ``time_s`` [s]).

        Parameters
        ----------
        camera : str
        ltwh_px : array-like, shape (K, 4)
            ``left, top, width, height`` [px] in the frame's pixels.
        score : array-like, shape (K,)
            The detector's score of each box.

        Call it before the ``write_occupancy`` of the same step: that call may commit the step's chunk.
        """
        self._check_open_step(step)
        b = np.asarray(ltwh_px, float).reshape(-1, 4)
        sc = np.asarray(score, float).reshape(-1)
        if len(b) != len(sc):
            raise ValueError(f"camera {camera!r}: ltwh_px {b.shape} and score {sc.shape} disagree on K")
        for (left, top, w, h), c in zip(b, sc):
            self._boxes.rows.append((int(step), float(time_s), str(camera), float(left), float(top), float(w),
                                     float(h), float(c)))
            self._tables_dirty = True

    def _check_open_step(self, step: int) -> None:
        if int(step) < self._steps_written:
            raise ValueError(
                f"step {step} is already written (its chunk was flushed or committed by write_occupancy); write "
                "a step's detections and tracks before its occupancy"
            )

    def write_metrics(self, metrics: Mapping[str, Any]) -> None:
        """Write ``metrics.json`` (scalars, and lists for per-step series); merges with earlier calls."""
        self.metrics.update(metrics)
        atomic_write_json(self.out_dir / "metrics.json", self.metrics)

    def _flush_buffer(self) -> None:
        if not self._buffer:
            return
        steps = sorted(self._buffer)
        a, b = steps[0], steps[-1] + 1
        L, ny, nx = self.stack.shape
        try:
            self._occ.resize((b, L, ny, nx))
            self._time.resize((b,))
            self._occ[a:b] = np.stack([self._buffer[s][1] for s in steps])
            self._time[a:b] = np.array([self._buffer[s][0] for s in steps])
        except OSError as exc:  # a full disk (ENOSPC), a folder gone: name what could not be written
            raise OSError(exc.errno, f"cannot write {self.out_dir / 'occupancy.zarr'}: "
                          f"{exc.strerror or exc}") from exc
        self._steps_written = b
        self._buffer.clear()
        self._write_tables()

    def _write_tables(self) -> None:
        if not self._tables_dirty:
            return  # flush, finish and chunk commits may follow each other without new rows
        # only the steps whose occupancy is written: an interruption between a step's tables and its occupancy
        # (Ctrl-C) must not leave the tables one step ahead of the store and run_state.json
        dets, tracks = self._dets.upto(self._steps_written), self._tracks.upto(self._steps_written)
        boxes = self._boxes.upto(self._steps_written)
        atomic_write_text(self.out_dir / "detections.csv", self._dets.csv_text(dets))
        atomic_write_text(self.out_dir / "tracks.csv", self._tracks.csv_text(tracks))
        if self._boxes.rows:  # a person detector ran: its boxes, and one MOTChallenge 2-D file per camera
            atomic_write_text(self.out_dir / "camera_boxes.csv", self._boxes.csv_text(boxes))
            for camera in sorted({r[2] for r in self._boxes.rows}):
                rows = [(r[0] + 1, -1, *r[3:8], -1, -1, -1) for r in boxes if r[2] == camera]
                with atomic_open(self.out_dir / f"{_BOX_FILE_PREFIX}{camera}{_BOX_FILE_SUFFIX}", "w") as f:
                    np.savetxt(f, np.asarray(rows, float).reshape(-1, 10),
                               fmt=["%d", "%d", "%.2f", "%.2f", "%.2f", "%.2f", "%.4f", "%d", "%d", "%d"],
                               delimiter=",")
        for name, table_rows, id_col in (("detections_mot.txt", dets, None), ("tracks_mot.txt", tracks, 2)):
            rows = np.asarray([(r[0], -1 if id_col is None else r[id_col], r[2 if id_col is None else 3],
                                r[3 if id_col is None else 4], r[5] if id_col is None else 1.0)
                               for r in table_rows], dtype=float).reshape(-1, 5)
            mot = mot_rows(rows[:, 0], rows[:, 1], rows[:, 2:4], rows[:, 4], self.person_radius_m)
            with atomic_open(self.out_dir / name, "w") as f:
                np.savetxt(f, mot, fmt=MOT_FORMAT, delimiter=",")
        # rows held back (their step's occupancy not yet written) are written with their step
        self._tables_dirty = len(dets) < len(self._dets.rows) or len(tracks) < len(self._tracks.rows) \
            or len(boxes) < len(self._boxes.rows)

    def _commit(self, checkpoint: Callable[[], Mapping[str, np.ndarray]] | None) -> None:
        if checkpoint is not None:
            state = dict(checkpoint())
            current, previous = self.out_dir / CHECKPOINT_FILE, self.out_dir / PREVIOUS_CHECKPOINT_FILE
            # the checkpoint of the chunk run_state.json still names is kept until the record moves on, so
            # that a kill between the two writes leaves a checkpoint matching the record either way
            if current.exists():
                os.replace(current, previous)
            with atomic_open(current, "wb") as f:
                np.savez(f, step=self._steps_written, **state)
        self.n_chunks_done = self._steps_written // self.chunk_steps
        self._write_state("running")

    def load_checkpoint(self) -> dict[str, np.ndarray] | None:
        """The state saved with the last finished chunk of a resumed run (None on a fresh run, or when no
        checkpoint of that chunk is there).

        Raises
        ------
        ValueError
            A checkpoint file cannot be read (it names the file).
        """
        if not self.resumed:
            return None
        for p in (self.out_dir / CHECKPOINT_FILE, self.out_dir / PREVIOUS_CHECKPOINT_FILE):
            if not p.exists():
                continue
            try:
                with np.load(p, allow_pickle=False) as z:
                    state = {k: z[k] for k in z.files}
            except (OSError, ValueError, EOFError, zipfile.BadZipFile) as exc:
                raise ValueError(f"{p}: cannot read the checkpoint (corrupt file?): {exc}") from None
            if "step" not in state:
                raise ValueError(f"{p}: the checkpoint has no 'step' entry")
            if int(state.pop("step")) == self.resume_step:
                return state
        return None

    def flush(self, status: str = "interrupted") -> None:
        """Write the steps buffered so far (a partial chunk) so all files are valid; the chunk stays unfinished."""
        self._flush_buffer()
        self._write_tables()
        self._write_state(status)

    # -- reading back ----------------------------------------------------------------------------------------------
    @property
    def n_steps(self) -> int:
        """Time steps written to the occupancy store."""
        return self._steps_written

    def occupancy(self) -> np.ndarray:
        """All occupancy written so far, shape (T, L, ny, nx) float32, in memory (see :meth:`occupancy_array`)."""
        return self._occ[:]

    def occupancy_array(self):
        """The occupancy written so far as the store's array, shape (T, L, ny, nx) float32: indexing it reads
        only the steps asked for (from ``occupancy.zarr`` when the run keeps it on disk)."""
        return self._occ

    def times_s(self) -> np.ndarray:
        """Times [s] of the written steps, shape (T,)."""
        return self._time[:]

    def detections_table(self) -> dict[str, np.ndarray]:
        """Detections recorded so far as column arrays (:data:`DETECTION_COLUMNS`)."""
        return _columns(self._dets.columns, self._dets.rows)

    def camera_boxes_table(self) -> dict[str, np.ndarray]:
        """Every camera's person boxes written so far (:data:`BOX_COLUMNS`)."""
        return _columns(self._boxes.columns, self._boxes.rows)

    def tracks_table(self) -> dict[str, np.ndarray]:
        """Tracks recorded so far as column arrays (:data:`TRACK_COLUMNS`)."""
        return _columns(self._tracks.columns, self._tracks.rows)

    # -- ending ----------------------------------------------------------------------------------------------------
    def finish(self, status: str = "finished") -> None:
        """Flush the last steps and the tables, record ``status`` and close the rerun recording.

        Figures, animation and report are built from the folder by the pipeline
        (:func:`planefuse.pipeline.run_to_folder`), not here: it finishes with ``status="presenting"`` and
        calls :meth:`mark_finished` when they are written, so that ``finished`` is the last thing written.
        """
        self._flush_buffer()
        self._write_tables()
        # only full chunks count as finished: a re-run of the same configuration recomputes the short tail
        self.n_chunks_done = self._steps_written // self.chunk_steps
        self._write_state(status)
        if self.rerun is not None:
            self.rerun.close()
            self.rerun = None
        if status == "finished":
            self._lock.release()

    def close(self) -> None:
        """Release the folder's lock (and close the rerun recording) without writing anything: a writer opened only
        to look at a folder, or one whose run is given up. The writer must not be written to afterwards."""
        if self.rerun is not None:
            with contextlib.suppress(Exception):
                self.rerun.close()
            self.rerun = None
        self._lock.release()

    def mark_finished(self) -> None:
        """Record the run as finished (after everything else is written) and release the folder's lock."""
        self._write_state("finished")
        self._lock.release()

    def summary(self) -> dict[str, Any]:
        """Counts for the report: steps, planes, grid, detections, tracks, resume information."""
        tr = self._tracks.rows
        return {
            "time steps": self._steps_written,
            "planes (heights m)": ", ".join(f"{h:g}" for h in self.stack.heights_m),
            "grid (ny x nx, cell m)": f"{self.stack.ny} x {self.stack.nx}, {self.stack.cell_size_m:g}",
            "detections": len(self._dets.rows),
            "track points": len(tr),
            "distinct tracks": len({r[2] for r in tr}),
            "resumed at step": self.resume_step if self.resumed else "no (fresh run)",
            "config hash": self.config_hash[:16],
        }

    def __enter__(self) -> "OutputWriter":
        return self

    def __exit__(self, exc_type, exc, tb) -> None:
        try:
            if exc_type is not None:
                interrupted = issubclass(exc_type, KeyboardInterrupt)
                self.record_end("interrupted" if interrupted else "failed",
                                None if interrupted else f"{exc_type.__name__}: {exc}")
            if self.rerun is not None:
                with contextlib.suppress(Exception):
                    self.rerun.close()
                self.rerun = None
        finally:
            self._lock.release()


_COLUMN_DTYPES = {"step": np.int64, "track_id": np.int64, "source": object, "camera": object}


def _columns(columns: tuple[str, ...], rows: list) -> dict[str, np.ndarray]:
    return {name: np.asarray([r[j] for r in rows], dtype=_COLUMN_DTYPES.get(name, float))
            for j, name in enumerate(columns)}
