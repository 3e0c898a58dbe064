"""Names and paths that come from data: one rule for every manifest path and every name that becomes a file name.

* :func:`check_name` -- a sensor (or figure) name is ``[A-Za-z0-9][A-Za-z0-9_.-]*``, at most 64 characters: no
  ``/``, no ``..``, nothing a file system or a shell reads specially.
* :func:`resolve_inside` -- a relative path from a manifest (or a CSV inside a recording), resolved and checked to
  lie inside its folder. Absolute paths, ``..`` that climbs out and symbolic links that point out are refused.
* :class:`PathArray` -- many file paths (a stream's frame files) in one bytes array instead of a Path each.

This module sits at the bottom of the library (it imports nothing from planefuse), so every layer may call it.
"""

from __future__ import annotations

import os
import re
from collections.abc import Iterable, Sequence
from pathlib import Path, PurePosixPath, PureWindowsPath

import numpy as np

__all__ = ["NAME_PATTERN", "PathArray", "check_name", "resolve_inside"]

NAME_PATTERN = re.compile(r"[A-Za-z0-9][A-Za-z0-9_.-]{0,63}")


def check_name(name: str, what: str = "name") -> str:
    """Return ``name`` if it is safe as a file name, else raise ``ValueError`` naming ``what``.

    Parameters
    ----------
    name : str
        E.g. a camera's name, used in ``figures/camera_<name>.png`` and ``cameras/<name>/``.
    what : str
        What the name belongs to, for the error message (e.g. ``"camera name"``).
    """
    if not isinstance(name, str) or not NAME_PATTERN.fullmatch(name) or ".." in name:
        raise ValueError(f"{what} {name!r} must match {NAME_PATTERN.pattern} (letters, digits, '_', '-', '.'; "
                         "no '/', no '..'; at most 64 characters)")
    return name


def resolve_inside(folder: str | Path, relpath: str | Path, what: str) -> Path:
    """``folder / relpath`` resolved, checked to lie inside ``folder``.

    Parameters
    ----------
    folder : str or Path
        The folder the path is relative to (a recording folder).
    relpath : str or Path
        A relative path read from data (manifest field, CSV cell).
    what : str
        The field it came from, named in the error (e.g. ``"times_file of camera 'cam0'"``).

    Returns
    -------
    Path
        The resolved absolute path (it need not exist; callers check that and say what is missing).

    Raises
    ------
    ValueError
        If ``relpath`` is empty, absolute (POSIX or Windows form), or resolves outside ``folder`` -- through ``..``
        or through a symbolic link. The message names ``what`` and the offending path, never the content of the
        file it points to.
    """
    rel = str(relpath)
    if not rel.strip():
        raise ValueError(f"{what}: empty path")
    if "\x00" in rel:
        raise ValueError(f"{what}: path {rel!r} contains a NUL byte")
    if PurePosixPath(rel).is_absolute() or PureWindowsPath(rel).is_absolute() or PureWindowsPath(rel).drive:
        raise ValueError(f"{what}: path {rel!r} must be relative to the recording folder {folder}")
    base = Path(folder).resolve()
    target = (base / rel).resolve()
    if not target.is_relative_to(base):
        raise ValueError(f"{what}: path {rel!r} points outside the recording folder {folder}")
    return target


class PathArray(Sequence[Path]):
    """File paths kept as one array of their bytes (``os.fsencode``), each a :class:`~pathlib.Path` when read.

    A recording lists one file per frame and camera (30 000 for four cameras over 300 s at 25 Hz); a ``Path``
    object each costs ~0.7 kB of Python objects, which made a run's memory grow with the length of its
    recording. Here a path costs its length in bytes.
    """

    def __init__(self, paths: Iterable[str | Path]) -> None:
        encoded = [os.fsencode(p) for p in paths]
        self._paths = np.array(encoded, dtype=bytes) if encoded else np.zeros(0, dtype="S1")

    def __len__(self) -> int:
        return len(self._paths)

    def fspath(self, i: int) -> str:
        """Path ``i`` as a str (what file functions take; no :class:`~pathlib.Path` object made)."""
        return os.fsdecode(self._paths[i])

    def __getitem__(self, i):  # type: ignore[override]
        if isinstance(i, slice):
            return [Path(os.fsdecode(b)) for b in self._paths[i]]
        return Path(os.fsdecode(self._paths[i]))
