"""A live run's output folder, resumable: :class:`LiveFolder`.

The folder follows the recording run's rule (:func:`planefuse.outputs.out_dir_problem`, the same lock and
``run_state.json``): a folder holding a live run of the same key (configuration, recording, clock) is resumed; one
holding another run's results, or files planefuse did not write, is refused in one line unless ``resume=False``
(``--fresh``: start afresh, replacing them) or ``force``.

What a session leaves for the next is the tracker's checkpoint (:meth:`planefuse.tracking.EvidenceTracker.
state_dict`, the state a recording run checkpoints, in ``checkpoint.npz``), written every ``checkpoint_steps``
output steps and at the end of the session, with the run clock and the wall-clock time it was taken at. The next
session restores it and continues: the run clock goes on from the checkpoint's by the wall-clock time elapsed (the
gap between the sessions is time without frames: unobserved, no evidence), the output steps and track identities
continue (never reused: above every step and identity in ``tracks.csv``, also after a kill that left rows newer than
the last checkpoint), and ``tracks.csv`` / ``tracks_mot.txt`` are appended to.
"""

from __future__ import annotations

import csv
import hashlib
import json
import time
import zipfile
from collections.abc import Mapping
from pathlib import Path

import numpy as np

from .._state import StateDict, sub_state, with_prefix
from ..io import Recording
from ..outputs import atomic_open, atomic_write_json, out_dir_problem, remove_stale_temporaries
from ..outputs._writer import CHECKPOINT_FILE, STATE_FILE, open_locked
from ..pipeline import RunPlan, SystemParams, resume_key

__all__ = ["LiveFolder", "live_key", "LIVE_FILES"]

#: What a live run writes in its folder (a fresh run deletes them; ``live_report.json`` is the last session's).
LIVE_FILES = ("tracks.csv", "tracks_mot.txt", "live_report.json", CHECKPOINT_FILE)

#: Version of a live checkpoint's content (the tracker's state and the clock).
LIVE_CHECKPOINT_FORMAT = 1


def live_key(rec: Recording, params: SystemParams, clock: str, config_key: str = "") -> str:
    """The key under which a live run resumes (16 hex digits): the recording run's :func:`~planefuse.pipeline.
    resume_key` of ``params`` (or ``config_key``) on ``rec``, with the clock and the mark of a live run (so that
    a recording run's folder is not taken for a live one)."""
    base = resume_key(RunPlan(params=params, config_key=config_key), rec)
    return hashlib.sha256(f"live\n{base}\n{clock}".encode()).hexdigest()[:16]


class LiveFolder:
    """The output folder of a live run, opened for a session (module docstring).

    Parameters
    ----------
    out_dir : path
    key : str
        :func:`live_key`.
    resume : bool
        False: start afresh where the folder holds a live run of the same key (or another run's results).
    force : bool
        Write into a folder holding another run's results (replaced) or files no run wrote (kept).
    protected : path, optional
        A folder the outputs must not go into (the recording).

    Raises
    ------
    ValueError
        One line: the folder is refused (:func:`~planefuse.outputs.out_dir_problem`), another run holds it, or its
        checkpoint cannot be read.

    Attributes
    ----------
    resumed : bool
        A previous session is continued.
    checkpoint : dict or None
        The tracker's state saved by the previous session (its ``tracker.`` entries), None on a fresh run.
    next_step, next_id : int
        The first output step and the lowest track identity this session may give (above every one in
        ``tracks.csv``; 0: no constraint beyond the tracker's own).
    clock_s : float
        Where this session's run clock starts [s]: 0 on a fresh run, else the previous session's clock at its
        checkpoint plus the wall-clock time since, and after its last row.
    """

    def __init__(self, out_dir: str | Path, key: str, *, resume: bool = True, force: bool = False,
                 protected: str | Path | None = None) -> None:
        problem = out_dir_problem(out_dir, config_hash=key, resume=resume, force=force, protected=protected)
        if problem is not None:
            raise ValueError(problem)
        self.out_dir, self.key = Path(out_dir), key
        self._lock = open_locked(self.out_dir, lambda: self._open(resume))

    def _open(self, resume: bool) -> None:
        remove_stale_temporaries(self.out_dir)
        state = self._read_state()
        self.resumed = bool(resume and state and state.get("config_hash") == self.key and state.get("kind") == "live")
        self.checkpoint: StateDict | None = None
        self.next_step, self.next_id, self.clock_s = 0, 0, 0.0
        if not self.resumed:
            for name in LIVE_FILES + (STATE_FILE,):
                (self.out_dir / name).unlink(missing_ok=True)
            self.save_state("running")
            return
        clock_s = float(state.get("clock_s", 0.0)) + max(0.0, time.time() - float(state.get("wall_s", time.time())))
        step = int(state.get("n_outputs", 0))
        path = self.out_dir / CHECKPOINT_FILE
        if path.exists():
            try:
                with np.load(path, allow_pickle=False) as z:
                    ck = {k: z[k] for k in z.files}
            except (OSError, ValueError, EOFError, zipfile.BadZipFile) as exc:
                raise ValueError(f"{path}: cannot read the checkpoint (corrupt file?): {exc}") from None
            if int(ck.get("format", -1)) != LIVE_CHECKPOINT_FORMAT:
                raise ValueError(f"{path}: live checkpoint format {ck.get('format')}, this version reads "
                                 f"{LIVE_CHECKPOINT_FORMAT}: pass --fresh to start afresh")
            self.checkpoint = sub_state(ck, "tracker")
            step = max(step, int(self.checkpoint["n_outputs"]))
        # rows written after the last checkpoint (a session killed between two) are kept: go on after them
        last_step, last_id, last_time_s = _last_rows(self.out_dir / "tracks.csv")
        self.next_step = max(step, last_step + 1)
        self.next_id = max(self.next_id, last_id + 1)
        self.clock_s = max(clock_s, last_time_s)
        self.save_state("running")

    def _read_state(self) -> dict | None:
        try:
            state = json.loads((self.out_dir / STATE_FILE).read_text(encoding="utf-8"))
        except (OSError, ValueError):
            return None
        return state if isinstance(state, dict) else None

    def tracker_state(self, fresh: Mapping[str, np.ndarray]) -> StateDict:
        """The state a resumed session's tracker loads: the checkpoint (or, without one, the ``fresh`` tracker's
        own state), its output count and next identity moved on to :attr:`next_step` and :attr:`next_id`."""
        state = dict(self.checkpoint if self.checkpoint is not None else fresh)
        state["n_outputs"] = np.asarray(self.next_step, dtype=np.int64)
        state["tracker.next_id"] = np.asarray(max(int(state["tracker.next_id"]), self.next_id), dtype=np.int64)
        return state

    def save_state(self, status: str, n_outputs: int | None = None, clock_s: float | None = None) -> None:
        """Write ``run_state.json``: the key, ``status``, the output steps given and the run clock [s] with the
        wall-clock time now."""
        atomic_write_json(self.out_dir / STATE_FILE, {
            "status": status, "kind": "live", "config_hash": self.key,
            "n_outputs": self.next_step if n_outputs is None else int(n_outputs),
            "clock_s": self.clock_s if clock_s is None else float(clock_s), "wall_s": time.time()})

    def save_checkpoint(self, tracker_state: Mapping[str, np.ndarray], n_outputs: int, clock_s: float,
                        status: str = "running") -> None:
        """Write the tracker's state (taken while an output is handled, or after the flush at the end) as
        ``checkpoint.npz`` (atomically), then ``run_state.json`` naming it."""
        with atomic_open(self.out_dir / CHECKPOINT_FILE, "wb") as f:
            np.savez(f, format=LIVE_CHECKPOINT_FORMAT, **with_prefix("tracker", tracker_state))
        self.save_state(status, n_outputs, clock_s)

    def close(self) -> None:
        """Release the folder's lock."""
        self._lock.release()


def _last_rows(path: Path) -> tuple[int, int, float]:
    """The largest step, track identity and time [s] in a ``tracks.csv`` (-1, -1, 0.0 where it has no row)."""
    step, ident, t = -1, -1, 0.0
    if not path.is_file():
        return step, ident, t
    with open(path, newline="", encoding="utf-8") as f:
        for row in csv.DictReader(f):
            try:
                step, ident = max(step, int(row["step"])), max(ident, int(row["track_id"]))
                t = max(t, float(row["time_s"]))
            except (KeyError, TypeError, ValueError):
                raise ValueError(f"{path}: not a tracks.csv planefuse wrote (row {row})") from None
    return step, ident, t
