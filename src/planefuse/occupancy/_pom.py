"""POM configuration files (``.pom``): read, run with planefuse's solver, write.

The format is the one of the Probabilistic Occupancy Map program (Fleuret et al. 2008), as its README describes
it: one keyword per line, ``#`` starts a comment line::

    ROOM <view width> <view height> <number of cameras> <number of locations>    (-1 -1: sizes from CAMERA)
    CAMERA <camera number> <view width> <view height>
    RECTANGLE <camera number> <location number> notvisible | <xmin> <ymin> <xmax> <ymax>   (pixels, inclusive)
    INPUT_VIEW_FORMAT / RESULT_VIEW_FORMAT / RESULT_FORMAT / CONVERGENCE_VIEW_FORMAT <format>   (%c %f %i)
    PRIOR <p>   SIGMA_IMAGE_DENSITY <s>   MAX_NB_SOLVER_ITERATIONS <n>   PROBA_IGNORED <p>
    PROCESS <first frame> <number of frames>

Relative file names are taken relative to the ``.pom`` file's folder (POM takes them relative to the working
directory; the two agree when it is run from there). Results are written as POM writes them:
``proba-f<frame>.dat`` (``RESULT_FORMAT``) holds one ``<location> <probability>`` line per location, the
probability printed with 6 significant digits.
"""

from __future__ import annotations

import os
from itertools import chain, compress
from operator import methodcaller, not_
from dataclasses import dataclass, field
from pathlib import Path
from typing import Iterable, Iterator, Sequence

import cv2
import numpy as np
from numba import njit

from ._meanfield import GenerativeParams, MeanFieldResult, MeanFieldSolver, Silhouettes

__all__ = ["PomConfig", "pom_frame_path", "read_pom", "read_pom_masks", "run_pom", "write_pom", "write_pom_result"]

_FORMAT_KEYS = ("INPUT_VIEW_FORMAT", "RESULT_VIEW_FORMAT", "RESULT_FORMAT", "CONVERGENCE_VIEW_FORMAT")
_KEYS = ("ROOM", "CAMERA", "RECTANGLE", *_FORMAT_KEYS, "PRIOR", "SIGMA_IMAGE_DENSITY", "MAX_NB_SOLVER_ITERATIONS",
         "PROBA_IGNORED", "PROCESS")


@dataclass(frozen=True)
class PomConfig:
    """A parsed ``.pom`` file.

    Attributes
    ----------
    path : Path
        The file read (relative formats are resolved against its folder).
    camera_ids : tuple of int
        POM camera numbers, in the order of :attr:`silhouettes`' cameras.
    silhouettes : Silhouettes
        The RECTANGLE lines (not visible where absent or ``notvisible``).
    params : GenerativeParams
        PRIOR, SIGMA_IMAGE_DENSITY, MAX_NB_SOLVER_ITERATIONS and PROBA_IGNORED (POM's defaults where absent).
    formats : dict of str -> str
        The ``*_FORMAT`` lines given, by keyword.
    process : tuple of (int, int)
        ``(first frame, number of frames)`` of each PROCESS line.
    format_lines : dict of str -> int
        Line of each ``*_FORMAT`` keyword (for error messages).
    """

    path: Path
    camera_ids: tuple[int, ...]
    silhouettes: Silhouettes
    params: GenerativeParams
    formats: dict[str, str] = field(default_factory=dict)
    process: tuple[tuple[int, int], ...] = ()
    format_lines: dict[str, int] = field(default_factory=dict)

    @property
    def frames(self) -> list[int]:
        """Every frame number the PROCESS lines ask for, in order."""
        return [f for first, n in self.process for f in range(first, first + n)]


def pom_frame_path(cfg: PomConfig, key: str, frame: int, camera: int | None = None, iteration: int = 0) -> Path:
    """File name of ``key`` (e.g. ``"INPUT_VIEW_FORMAT"``) for a frame and POM camera number, resolved."""
    if key not in cfg.formats:
        raise ValueError(f"{cfg.path}: no {key} line")
    name = cfg.formats[key].replace("%f", str(frame)).replace("%i", str(iteration))
    if camera is not None:
        name = name.replace("%c", str(camera))
    p = Path(name)
    return p if p.is_absolute() else cfg.path.parent / p


def read_pom(path: str | os.PathLike) -> PomConfig:
    """Parse a ``.pom`` file.

    Raises
    ------
    ValueError
        ``<file>:<line>: <what>`` for an unknown keyword, a wrong number or type of fields, a camera or location
        out of range, a rectangle outside its camera's image, a missing ROOM or CAMERA.
    FileNotFoundError
        The file does not exist.
    """
    path = Path(path)
    text = path.read_text(encoding="utf-8", errors="replace")
    span = _rectangle_run(text)
    if span is not None:  # the usual layout: one run of RECTANGLE lines between a header and a trailer
        start, end = span
        head, tail = text[:start].splitlines(), text[end + 1:].splitlines()
        n_run = text.count("\n", start, end) + 1
        numbered = chain(enumerate(head, start=1), enumerate(tail, start=len(head) + n_run + 1))
        bulk = _bulk_rectangles(text[start:end], n_run)
    else:
        lines = text.splitlines()
        is_rect = list(map(methodcaller("startswith", _BULK_PREFIX), lines))
        chosen = list(compress(lines, is_rect))
        numbered = compress(enumerate(lines, start=1), map(not_, is_rect))
        bulk = _bulk_rectangles("\n".join(chosen), len(chosen))
    if bulk is not None:
        try:
            return _parse(path, numbered, bulk)
        except _NotBulk:
            pass
    return _parse(path, enumerate(text.splitlines(), start=1), None)


class _NotBulk(Exception):
    """The bulk-read RECTANGLE lines need the line-by-line check (for its error message, or an unusual line)."""


_BULK_PREFIX = "RECTANGLE "
#: characters other than "\n" that ``str.splitlines`` takes for line breaks (ASCII ones; a non-ASCII text is read
#: line by line)
_OTHER_BREAKS = ("\r", "\v", "\f", "\x1c", "\x1d", "\x1e")


def _rectangle_run(text: str) -> tuple[int, int] | None:
    """``(start, end)`` of the run of whole lines that all start with ``"RECTANGLE "`` and hold every such line
    (``end``: the position of the newline after the last, or the end of the text), found with a few whole-text
    searches instead of a test per line; None where there is no such run (RECTANGLE lines interleaved with others)
    or the text has line breaks other than ``"\n"``: the caller then sorts the lines one by one."""
    start = 0 if text.startswith(_BULK_PREFIX) else text.find("\n" + _BULK_PREFIX) + 1
    if start == 0 and not text.startswith(_BULK_PREFIX):
        return None
    last = text.rfind("\n" + _BULK_PREFIX, start) + 1 or start
    end = text.find("\n", last)
    end = len(text) if end < 0 else end
    if not text.isascii() or any(ch in text for ch in _OTHER_BREAKS):
        return None
    if text.count("\n" + _BULK_PREFIX, start, end) != text.count("\n", start, end):
        return None
    return start, end


def _bulk_rectangles(body: str, n_lines: int) -> tuple[np.ndarray, np.ndarray] | None:
    """``n_lines`` lines starting with ``"RECTANGLE "`` (joined by newlines) read at once: (N, 6) int64 rows of
    camera, location, box (-1 where ``notvisible``) and (N,) bool ``notvisible``. None where one of them is not
    written the plain way (``RECTANGLE <int> <int> notvisible|<int> <int> <int> <int>``, single spaces, integers of
    at most 9 digits): the file is then read line by line, which accepts other spellings or names the line."""
    if not n_lines:
        return np.zeros((0, 6), np.int64), np.zeros(0, bool)
    rows = np.empty((n_lines, 6), np.int64)
    hidden = np.empty(n_lines, np.bool_)
    if not body.isascii() or not _scan_rectangles(np.frombuffer(body.encode("ascii"), np.uint8), rows, hidden):
        return None
    return rows, hidden


@njit(cache=True)
def _scan_rectangles(text, rows, hidden):  # pragma: no cover - compiled
    # rows[i], hidden[i] from line i of ``text`` (ASCII bytes); False at the first byte off the plain grammar or
    # where the number of lines differs from len(rows)
    prefix = b"RECTANGLE"
    notvisible = b"notvisible"
    n, pos = len(text), 0
    for i in range(rows.shape[0]):
        for j in range(9):
            if pos >= n or text[pos] != prefix[j]:
                return False
            pos += 1
        hidden[i] = False
        for f in range(6):
            if pos >= n or text[pos] != 32:  # one space before each field
                return False
            pos += 1
            if f == 2 and pos < n and text[pos] == 110:  # "n": notvisible
                for j in range(10):
                    if pos >= n or text[pos] != notvisible[j]:
                        return False
                    pos += 1
                hidden[i] = True
                rows[i, 2:] = -1
                break
            sign = 1
            if pos < n and text[pos] == 45:  # "-"
                sign = -1
                pos += 1
            v, digits = 0, 0
            while pos < n and 48 <= text[pos] <= 57:
                v = 10 * v + (text[pos] - 48)
                pos += 1
                digits += 1
            if digits == 0 or digits > 9:
                return False
            rows[i, f] = sign * v
        if pos < n:
            if text[pos] != 10 or i == rows.shape[0] - 1:
                return False
            pos += 1
    return pos == n


def _parse(path: Path, numbered: Iterable[tuple[int, str]], bulk: tuple[np.ndarray, np.ndarray] | None) -> PomConfig:
    """Read the ``.pom`` lines ``(1-based number, text)``; ``bulk``: the ``"RECTANGLE "`` lines, left out of
    ``numbered`` and read by :func:`_bulk_rectangles` (their checks vectorised: raises _NotBulk where one fails,
    for the line-by-line reading to name it)."""
    room = None  # (w, h, n_cam, n_loc)
    cams: dict[int, tuple[int, int, int]] = {}  # id -> (w, h, line)
    rects: list[tuple[int, int, int, list[int] | None]] = []  # (line, cam, loc, box)
    scalars: dict[str, float] = {}
    formats: dict[str, str] = {}
    format_lines: dict[str, int] = {}
    process: list[tuple[int, int]] = []

    def fail(n: int, msg: str) -> ValueError:
        return ValueError(f"{path}:{n}: {msg}")

    def ints(n: int, key: str, vals: list[str], count: int) -> list[int]:
        if len(vals) != count:
            raise fail(n, f"{key} takes {count} integers, got {len(vals)} fields: {' '.join(vals)!r}")
        try:
            return [int(v) for v in vals]
        except ValueError:
            raise fail(n, f"{key} takes integers, got {' '.join(vals)!r}") from None

    for n, raw in numbered:
        line = raw.strip()
        if not line or line.startswith("#"):
            continue
        key, *vals = line.split()
        if key not in _KEYS:
            raise fail(n, f"unknown keyword {key!r} (expected one of {', '.join(_KEYS)})")
        if key == "ROOM":
            if room is not None:
                raise fail(n, "second ROOM line")
            w, h, nc, nl = ints(n, key, vals, 4)
            if nc <= 0 or nl <= 0:
                raise fail(n, f"ROOM needs positive numbers of cameras and locations, got {nc} and {nl}")
            if (w, h) != (-1, -1) and (w <= 0 or h <= 0):
                raise fail(n, f"ROOM view size must be positive (or -1 -1 with CAMERA lines), got {w}x{h}")
            room = (w, h, nc, nl)
        elif key == "CAMERA":
            cid, w, h = ints(n, key, vals, 3)
            if cid < 0 or w <= 0 or h <= 0:
                raise fail(n, f"CAMERA needs a camera number >= 0 and a positive size, got {' '.join(vals)}")
            if cid in cams:
                raise fail(n, f"camera {cid} already defined on line {cams[cid][2]}")
            cams[cid] = (w, h, n)
        elif key == "RECTANGLE":
            if len(vals) == 3 and vals[2] == "notvisible":
                cid, loc = ints(n, key, vals[:2], 2)
                rects.append((n, cid, loc, None))
            else:
                if len(vals) != 6:
                    raise fail(n, f"RECTANGLE takes <camera> <location> notvisible|<xmin> <ymin> <xmax> <ymax>, "
                                  f"got {' '.join(vals)!r}")
                cid, loc, *box = ints(n, key, vals, 6)
                rects.append((n, cid, loc, box))
        elif key in _FORMAT_KEYS:
            if len(vals) != 1:
                raise fail(n, f"{key} takes one file name format, got {len(vals)} fields")
            formats[key] = vals[0]
            format_lines[key] = n
        elif key == "PROCESS":
            first, count = ints(n, key, vals, 2)
            if count < 0:
                raise fail(n, f"PROCESS needs a number of frames >= 0, got {count}")
            process.append((first, count))
        else:
            if len(vals) != 1:
                raise fail(n, f"{key} takes one number, got {len(vals)} fields")
            try:
                v = int(vals[0]) if key == "MAX_NB_SOLVER_ITERATIONS" else float(vals[0])
            except ValueError:
                raise fail(n, f"{key} takes a number, got {vals[0]!r}") from None
            ok = {"PRIOR": 0 < v < 1, "SIGMA_IMAGE_DENSITY": v > 0, "MAX_NB_SOLVER_ITERATIONS": v >= 1,
                  "PROBA_IGNORED": 0 < v <= 1}[key]
            if not ok:
                raise fail(n, f"{key} out of range: {vals[0]}")
            scalars[key] = v
    if room is None:
        raise ValueError(f"{path}: no ROOM line")
    w, h, n_cam, n_loc = room
    if (w, h) == (-1, -1):
        if len(cams) != n_cam:
            raise ValueError(f"{path}: ROOM -1 -1 needs {n_cam} CAMERA lines, found {len(cams)}")
        ids = list(cams)  # in the order of the CAMERA lines
        sizes = tuple((cams[i][1], cams[i][0]) for i in ids)
    else:
        ids = list(range(n_cam))
        for cid, (cw, ch, line) in cams.items():
            if cid >= n_cam:
                raise fail(line, f"camera {cid} outside ROOM's {n_cam} cameras (0..{n_cam - 1})")
            if (cw, ch) != (w, h):
                raise fail(line, f"camera {cid} size {cw}x{ch} differs from ROOM's {w}x{h}")
        sizes = tuple((h, w) for _ in ids)
    index = {cid: i for i, cid in enumerate(ids)}
    boxes = np.full((n_cam, n_loc, 4), -1, dtype=np.int32)
    if bulk is not None:
        if rects:  # RECTANGLE lines of another spelling (leading blanks, tabs): all read line by line
            raise _NotBulk
        _fill_bulk(boxes, bulk, index, sizes)
    for line, cid, loc, box in rects:
        if cid not in index:
            raise fail(line, f"camera {cid} is not defined (cameras: {ids})")
        if not 0 <= loc < n_loc:
            raise fail(line, f"location {loc} outside ROOM's {n_loc} locations (0..{n_loc - 1})")
        if box is None:
            boxes[index[cid], loc] = -1
            continue
        ch, cw = sizes[index[cid]]
        x0, y0, x1, y1 = box
        if not (0 <= x0 <= x1 < cw and 0 <= y0 <= y1 < ch):
            raise fail(line, f"rectangle {x0} {y0} {x1} {y1} of camera {cid} is empty or outside its {cw}x{ch} "
                             f"image (pixels 0..{cw - 1} x 0..{ch - 1}, inclusive)")
        boxes[index[cid], loc] = box
    defaults = GenerativeParams()
    params = GenerativeParams(
        prior=float(scalars.get("PRIOR", defaults.prior)),
        sigma=float(scalars.get("SIGMA_IMAGE_DENSITY", defaults.sigma)),
        max_iterations=int(scalars.get("MAX_NB_SOLVER_ITERATIONS", defaults.max_iterations)),
        # rounded: 1 - 0.99 is 0.010000000000000009 in binary, which would leave out every location still at
        # PRIOR 0.01 on the first iteration; POM keeps them (its first iterate, docs/results.md)
        ignored_below=round(1.0 - float(scalars.get("PROBA_IGNORED", 1.0)), 12),
        damping=defaults.damping, tolerance=defaults.tolerance,
    )
    return PomConfig(path, tuple(ids), Silhouettes(boxes, sizes), params, formats, tuple(process), format_lines)


def _fill_bulk(boxes: np.ndarray, bulk: tuple[np.ndarray, np.ndarray], index: dict[int, int],
               sizes: tuple[tuple[int, int], ...]) -> None:
    """Write the RECTANGLE lines into ``boxes`` (C, K, 4) at once, the later of two lines for the same camera and
    location winning, as line by line; raises _NotBulk where a line would fail a check."""
    n_cam, n_loc = boxes.shape[:2]
    rows, hidden = bulk
    if not len(rows):
        return
    ids = np.array(sorted(index), np.int64)
    cam = np.searchsorted(ids, rows[:, 0])
    if (cam >= len(ids)).any() or (ids[np.minimum(cam, len(ids) - 1)] != rows[:, 0]).any():
        raise _NotBulk
    cam = np.array([index[int(i)] for i in ids], np.int64)[cam]
    loc, box = rows[:, 1], rows[:, 2:]
    if ((loc < 0) | (loc >= n_loc)).any():
        raise _NotBulk
    hw = np.array(sizes, np.int64)[cam]
    shown = ~hidden
    bad = shown & ~((box[:, 0] >= 0) & (box[:, 0] <= box[:, 2]) & (box[:, 2] < hw[:, 1])
                    & (box[:, 1] >= 0) & (box[:, 1] <= box[:, 3]) & (box[:, 3] < hw[:, 0]))
    if bad.any():
        raise _NotBulk
    # the last line of each (camera, location) wins
    key = cam * n_loc + loc
    _, last = np.unique(key[::-1], return_index=True)
    last = len(key) - 1 - last
    boxes[cam[last], loc[last]] = box[last]


def read_pom_masks(cfg: PomConfig, frame: int) -> list[np.ndarray]:
    """The INPUT_VIEW_FORMAT images of one frame as float foreground in [0, 1] (grey level / 255), one per camera.

    Raises
    ------
    ValueError
        No INPUT_VIEW_FORMAT line, a missing or unreadable image, or one of the wrong size (naming the file and
        the ``.pom`` line).
    """
    return [img.astype(np.float64) / 255.0 for img in _read_grey_masks(cfg, frame)]


def _read_grey_masks(cfg: PomConfig, frame: int) -> list[np.ndarray]:
    """The INPUT_VIEW_FORMAT images of one frame, uint8 grey levels (the solver scales them by 1 / 255 as
    :func:`read_pom_masks` does: the same foreground)."""
    if "INPUT_VIEW_FORMAT" not in cfg.formats:
        raise ValueError(f"{cfg.path}: no INPUT_VIEW_FORMAT line: cannot find the input masks")
    line = cfg.format_lines["INPUT_VIEW_FORMAT"]
    out = []
    for cid, (h, w) in zip(cfg.camera_ids, cfg.silhouettes.image_sizes):
        p = pom_frame_path(cfg, "INPUT_VIEW_FORMAT", frame, cid)
        if not p.is_file():
            raise ValueError(f"{cfg.path}:{line}: INPUT_VIEW_FORMAT: mask of camera {cid}, frame {frame} not "
                             f"found: {p}")
        img = cv2.imread(str(p), cv2.IMREAD_GRAYSCALE)
        if img is None:
            raise ValueError(f"{cfg.path}:{line}: INPUT_VIEW_FORMAT: cannot read image {p}")
        if img.shape != (h, w):
            raise ValueError(f"{cfg.path}:{line}: {p} is {img.shape[1]}x{img.shape[0]}, camera {cid} is {w}x{h}")
        out.append(img)
    return out


def write_pom_result(path: str | os.PathLike, marginals: np.ndarray) -> None:
    """Write marginals the way POM's RESULT_FORMAT does: ``<location> <probability>`` per line, 6 digits."""
    q = np.asarray(marginals, dtype=float).ravel()
    # one format over every line (40 % faster than a format per line at 40 000 locations: the same text)
    fields: list[float | int] = [0] * (2 * len(q))
    fields[::2] = range(len(q))
    fields[1::2] = q.tolist()
    Path(path).write_text(("%d %g\n" * len(q)) % tuple(fields), encoding="ascii")


def run_pom(cfg: PomConfig, frames: Sequence[int] | None = None, write: bool = True,
            params: GenerativeParams | None = None, threads: int = 1) -> Iterator[tuple[int, MeanFieldResult]]:
    """Run planefuse's mean-field solver on a POM configuration's masks, frame by frame.

    Parameters
    ----------
    cfg : PomConfig
    frames : sequence of int, optional
        Frames to process (default: the PROCESS lines').
    write : bool
        Write ``RESULT_FORMAT`` files (``proba-f<frame>.dat``) where the configuration has that line.
    params : GenerativeParams, optional
        Overrides the configuration's solver parameters.
    threads : int
        Threads of the solver (:class:`MeanFieldSolver`; the same marginals on any number).

    Yields
    ------
    (frame, MeanFieldResult)
    """
    solver = MeanFieldSolver(cfg.silhouettes, params or cfg.params, threads=threads)
    for frame in (cfg.frames if frames is None else frames):
        result = solver.solve(_read_grey_masks(cfg, frame))
        if write and "RESULT_FORMAT" in cfg.formats:
            out = pom_frame_path(cfg, "RESULT_FORMAT", frame)
            out.parent.mkdir(parents=True, exist_ok=True)
            write_pom_result(out, result.marginals)
        yield frame, result


def write_pom(path: str | os.PathLike, silhouettes: Silhouettes, params: GenerativeParams = GenerativeParams(),
              *, input_view_format: str | None = None, result_format: str | None = None,
              process: tuple[int, int] | None = None, camera_ids: Sequence[int] | None = None,
              comment: str = "") -> None:
    """Write a ``.pom`` file POM reads (sizes per camera through ``ROOM -1 -1`` and CAMERA lines).

    ``camera_ids`` are the POM camera numbers (default 0..C-1); PROBA_IGNORED is ``1 - params.ignored_below``.
    """
    C, K = silhouettes.n_cameras, silhouettes.n_locations
    ids = list(range(C)) if camera_ids is None else [int(i) for i in camera_ids]
    if len(ids) != C:
        raise ValueError(f"camera_ids has {len(ids)} entries for {C} cameras")
    lines = [f"# {c}" for c in comment.splitlines()] if comment else []
    lines.append(f"ROOM -1 -1 {C} {K}")
    lines += [f"CAMERA {cid} {w} {h}" for cid, (h, w) in zip(ids, silhouettes.image_sizes)]
    # float(): the repr of a numpy scalar ("np.float64(0.01)") is no number to POM
    lines += [f"PRIOR {float(params.prior)!r}", f"SIGMA_IMAGE_DENSITY {float(params.sigma)!r}",
              f"MAX_NB_SOLVER_ITERATIONS {int(params.max_iterations)}",
              f"PROBA_IGNORED {round(1.0 - float(params.ignored_below), 12)!r}"]
    if input_view_format:
        lines.append(f"INPUT_VIEW_FORMAT {input_view_format}")
    if result_format:
        lines.append(f"RESULT_FORMAT {result_format}")
    for c, cid in enumerate(ids):
        for k, b in enumerate(silhouettes.boxes_px[c]):
            lines.append(f"RECTANGLE {cid} {k} notvisible" if b[0] < 0
                         else f"RECTANGLE {cid} {k} {b[0]} {b[1]} {b[2]} {b[3]}")
    if process is not None:
        lines.append(f"PROCESS {int(process[0])} {int(process[1])}")
    Path(path).write_text("\n".join(lines) + "\n", encoding="ascii")

