"""Timestamp checks shared by all stream readers, and a chunked CSV reader that names file and line."""

from __future__ import annotations

import io
import warnings
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

__all__ = ["Gap", "TimeChecker", "read_csv_chunks", "write_csv"]


@dataclass(frozen=True)
class Gap:
    """Samples missing between ``after_s`` and ``before_s`` (about ``missing`` at the nominal rate)."""

    after_s: float
    before_s: float
    missing: int


@dataclass
class TimeChecker:
    """Checks a stream's timestamps chunk by chunk: finite, strictly increasing (no duplicates), and
    reports gaps longer than 1.5 nominal periods in :attr:`gaps` (and one warning per stream).

    Parameters
    ----------
    source : str
        File name used in error messages.
    rate_hz : float
        Nominal rate; 0 disables gap detection.
    """

    source: str
    rate_hz: float = 0.0
    gaps: list[Gap] = field(default_factory=list)
    _last: float = -np.inf
    _warned: bool = False

    def check(self, times_s: np.ndarray, first_line: int | None = None) -> None:
        """Check the next chunk. Errors name sample ``i`` as ``line first_line + i`` of a text file, or as
        ``time_s[i]`` (the array field) when ``first_line`` is None."""
        t = np.asarray(times_s, dtype=float)

        def at(i: int) -> str:
            return f"line {first_line + i}" if first_line is not None else f"time_s[{i}]"

        bad = np.nonzero(~np.isfinite(t))[0]
        if bad.size:
            raise ValueError(f"{self.source}: {at(bad[0])}: time_s is not finite ({t[bad[0]]})")
        if t.size == 0:
            return
        prev = np.concatenate([[self._last], t[:-1]])
        back = np.nonzero(t < prev)[0]
        dup = np.nonzero(t == prev)[0]
        if back.size and (not dup.size or back[0] < dup[0]):
            i = back[0]
            raise ValueError(
                f"{self.source}: {at(i)}: time_s {float(t[i])!r} goes backwards (previous {float(prev[i])!r}); "
                "timestamps must increase"
            )
        if dup.size:
            i = dup[0]
            raise ValueError(f"{self.source}: {at(i)}: duplicate time_s {float(t[i])!r}; timestamps must increase")
        if self.rate_hz > 0:
            dt = t - prev
            big = np.nonzero(np.isfinite(prev) & (dt > 1.5 / self.rate_hz))[0]
            for i in big:
                self.gaps.append(Gap(float(prev[i]), float(t[i]), int(round(dt[i] * self.rate_hz)) - 1))
            if big.size and not self._warned:
                self._warned = True
                warnings.warn(
                    f"{self.source}: gap in timestamps after {prev[big[0]]:.6f} s "
                    f"(see the stream's .gaps for all of them)",
                    stacklevel=3,
                )
        self._last = float(t[-1])


def read_csv_chunks(path: Path, columns: list[str], max_rows: int = 100_000) -> Iterator[tuple[np.ndarray, int]]:
    """Stream a numeric CSV with a header line, ``max_rows`` rows at a time.

    Yields
    ------
    rows : ndarray, shape (n, len(columns)), float64
    first_line : int
        1-based line number of ``rows[0]`` in the file.

    Raises
    ------
    ValueError
        Missing file, wrong header, or a malformed/truncated line (the message names file and line).
    """
    if not path.is_file():
        raise ValueError(f"{path}: file not found (missing stream)")
    with open(path, newline="") as fh:
        header = fh.readline().strip()
        got = [c.strip() for c in header.split(",")]
        if got != columns:
            raise ValueError(f"{path}:1: header must be {','.join(columns)!r}, got {header!r}")
        line = 2
        while True:
            lines = []
            for _ in range(max_rows):
                s = fh.readline()
                if not s:
                    break
                lines.append(s)
            if not lines:
                return
            rows = _parse(lines, len(columns), path, line)
            yield rows, line
            line += len(lines)


def _parse(lines: list[str], ncol: int, path: Path, first_line: int) -> np.ndarray:
    try:
        rows = np.loadtxt(io.StringIO("".join(lines)), delimiter=",", ndmin=2)
        if rows.shape[1] == ncol and len(rows) == len(lines):
            return rows
    except ValueError:
        pass
    # Slow path only to name the offending line.
    for k, s in enumerate(lines):
        parts = s.strip().split(",")
        msg = None
        if not s.endswith("\n") and k == len(lines) - 1 and len(parts) != ncol:
            msg = f"truncated line (expected {ncol} fields, got {len(parts)})"
        elif len(parts) != ncol:
            msg = f"expected {ncol} comma-separated fields, got {len(parts)}"
        else:
            try:
                [float(x) for x in parts]
            except ValueError:
                msg = f"not a number in {s.strip()!r}"
        if msg:
            raise ValueError(f"{path}:{first_line + k}: {msg}")
    raise ValueError(f"{path}:{first_line}: could not parse lines {first_line}-{first_line + len(lines) - 1}")


def write_csv(path: Path, columns: list[str], rows: np.ndarray, fmt: str = "%.17g") -> None:
    """Write a numeric table with a header; ``%.17g`` makes float64 round-trip exactly."""
    path.parent.mkdir(parents=True, exist_ok=True)
    np.savetxt(path, np.asarray(rows, dtype=float).reshape(-1, len(columns)), delimiter=",", fmt=fmt,
               header=",".join(columns), comments="")
