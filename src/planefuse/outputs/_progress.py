"""Progress of the long steps of a run (simulate, register, filter, evaluate).

Three modes, one API:

* ``"rich"`` -- live bars with count, rate and ETA on the terminal (stderr);
* ``"json"`` -- one JSON object per line on stderr (``start``, throttled
  ``progress``, ``end`` / ``interrupted``, ``message``, and ``warning`` for every Python warning raised inside the
  context), for scripts and log collectors: every line of the stream parses as JSON;
* ``"quiet"`` -- nothing.

Usage::

    with progress_steps(mode) as progress:
        with progress.step("filter", total=n_frames, unit="frames") as advance:
            for frame in frames:
                ...
                advance(1)
"""

from __future__ import annotations

import contextlib
import json
import sys
import time
import warnings
from collections.abc import Callable, Iterator
from typing import IO, Literal

from rich.console import Console
from rich.progress import (
    BarColumn,
    MofNCompleteColumn,
    Progress,
    ProgressColumn,
    Task,
    TaskProgressColumn,
    TextColumn,
    TimeElapsedColumn,
    TimeRemainingColumn,
)
from rich.text import Text

__all__ = ["ProgressMode", "ProgressReporter", "progress_mode", "progress_steps"]

ProgressMode = Literal["rich", "json", "quiet"]


class _RateColumn(ProgressColumn):
    """Items per second, with the step's unit."""

    def render(self, task: Task) -> Text:
        speed = task.finished_speed or task.speed
        unit = task.fields.get("unit", "it")
        return Text("-" if speed is None else f"{speed:,.1f} {unit}/s", style="progress.data.speed")


class ProgressReporter:
    """Reports the progress of named steps; create it with :func:`progress_steps`.

    Parameters
    ----------
    mode : {"rich", "json", "quiet"}
    stream : text stream
        Where JSON lines (and rich bars) go; stderr by default so stdout stays clean.
    json_interval_s : float
        Smallest interval between two ``progress`` lines of one step in JSON mode [s].
    """

    def __init__(self, mode: ProgressMode = "rich", stream: IO[str] | None = None, json_interval_s: float = 1.0):
        if mode not in ("rich", "json", "quiet"):
            raise ValueError(f"progress mode must be 'rich', 'json' or 'quiet', got {mode!r}")
        self.mode = mode
        self.stream = stream if stream is not None else sys.stderr
        self.json_interval_s = float(json_interval_s)
        self._progress: Progress | None = None
        if mode == "rich":
            self._progress = Progress(
                TextColumn("[bold]{task.description:<10}"),
                BarColumn(),
                MofNCompleteColumn(),
                TaskProgressColumn(),
                _RateColumn(),
                TimeElapsedColumn(),
                TextColumn("ETA"),
                TimeRemainingColumn(),
                console=Console(file=self.stream),
                transient=False,
            )

    def event(self, event: str, **fields: object) -> None:
        """Emit one JSON log line (JSON mode only); ``fields`` must be JSON-serialisable."""
        if self.mode == "json":
            rec = {"time_unix_s": round(time.time(), 3), "event": event, **fields}
            self.stream.write(json.dumps(rec) + "\n")
            self.stream.flush()

    def message(self, text: str) -> None:
        """A one-line note: printed above the bars in rich mode, a ``message`` event in JSON mode."""
        if self._progress is not None:
            self._progress.console.print(text)
        self.event("message", text=text)

    @contextlib.contextmanager
    def step(self, name: str, total: int | None, unit: str = "frames",
             completed: int = 0) -> Iterator[Callable[[int], None]]:
        """Track one step; yields ``advance(n)`` to call as work completes.

        Parameters
        ----------
        name : str
            Step name (``"simulate"``, ``"register"``, ``"filter"``, ``"evaluate"``...).
        total : int or None
            Number of items, if known (needed for an ETA); an estimate, corrected to the items done when the step
            ends.
        unit : str
            What an item is (``"frames"``, ``"chunks"``...), shown with the rate.
        completed : int
            Items already done (a resumed run), counted in the bar but not in the rate.
        """
        t0 = time.perf_counter()
        state = {"done": int(completed), "last": 0.0}
        self.event("start", step=name, total=total, unit=unit, completed=int(completed))
        task = None
        if self._progress is not None:
            task = self._progress.add_task(name, total=total, completed=completed, unit=unit)

        def advance(n: int = 1) -> None:
            state["done"] += n
            if task is not None:
                self._progress.advance(task, n)
            if self.mode == "json":
                now = time.perf_counter()
                if now - state["last"] >= self.json_interval_s or (total is not None and state["done"] >= total):
                    state["last"] = now
                    rate = (state["done"] - completed) / max(now - t0, 1e-9)
                    eta = None if (total is None or rate <= 0) else round((total - state["done"]) / rate, 2)
                    self.event("progress", step=name, done=state["done"], total=total,
                               rate_per_s=round(rate, 3), eta_s=eta)

        try:
            yield advance
        except KeyboardInterrupt:
            self.event("interrupted", step=name, done=state["done"], total=total,
                       elapsed_s=round(time.perf_counter() - t0, 3))
            raise
        else:
            self.event("end", step=name, done=state["done"], total=total,
                       elapsed_s=round(time.perf_counter() - t0, 3))
            if task is not None and total is not None and state["done"] != total:
                # a total that was an estimate (output steps from the recording's duration): the finished bar
                # shows what was done, not 600/601
                self._progress.update(task, total=state["done"])
        finally:
            if task is not None:
                self._progress.stop_task(task)


@contextlib.contextmanager
def progress_steps(mode: ProgressMode = "rich", stream: IO[str] | None = None,
                   json_interval_s: float = 1.0) -> Iterator[ProgressReporter]:
    """Context in which a run reports its steps; see the module docstring for an example.

    ``mode`` is usually chosen from the CLI flags: ``--quiet`` gives
    ``"quiet"``, ``--log-json`` gives ``"json"``, neither gives ``"rich"``.
    """
    reporter = ProgressReporter(mode, stream, json_interval_s)
    if reporter.mode == "json":
        # every line on the stream is JSON: a warning raised inside is a "warning" event, not a line of text
        with warnings.catch_warnings():
            warnings.showwarning = lambda message, category, *_, **__: reporter.event(
                "warning", category=category.__name__, message=" ".join(str(message).split()))
            yield reporter
        return
    if reporter._progress is None:
        yield reporter
        return
    with reporter._progress:
        yield reporter


def progress_mode(quiet: bool, log_json: bool) -> ProgressMode:
    """The mode selected by the ``--quiet`` / ``--log-json`` CLI flags (``--log-json`` wins)."""
    return "json" if log_json else ("quiet" if quiet else "rich")
