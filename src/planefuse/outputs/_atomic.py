"""Atomic file writes: a reader (or a killed writer) never sees a half-written file.

Data goes to a temporary file in the destination's folder, is flushed and
fsync'ed, then ``os.replace`` renames it over the destination, which POSIX
and Windows make atomic within one file system.
"""

from __future__ import annotations

import contextlib
import io
import json
import os
import shutil
import tempfile
from collections.abc import Iterator
from pathlib import Path
from typing import IO, Any

import numpy as np

__all__ = ["atomic_open", "atomic_write_bytes", "atomic_write_text", "atomic_write_json", "TMP_MARK",
           "remove_stale_temporaries"]

def _file_mode() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return 0o666 & ~mask


_FILE_MODE = _file_mode()  # mkstemp creates 0600 files; give the final file the usual permissions

#: Temporary files carry this in their name; :func:`remove_stale_temporaries` deletes leftovers of killed runs.
TMP_MARK = ".pf-tmp-"


@contextlib.contextmanager
def atomic_open(path: Path | str, mode: str = "w", encoding: str | None = "utf-8") -> Iterator[IO[Any]]:
    """Open a temporary file that replaces ``path`` when the ``with`` block ends without error.

    On an exception (including ``KeyboardInterrupt``) the temporary file is
    removed and ``path`` is left as it was.
    """
    path = Path(path)
    if mode not in ("w", "wb"):
        raise ValueError(f"mode must be 'w' or 'wb', got {mode!r}")
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(prefix=f".{path.name}{TMP_MARK}", dir=path.parent)
    except OSError as exc:
        raise _naming(exc, path) from exc
    try:
        os.fchmod(fd, _FILE_MODE)
        with os.fdopen(fd, mode, encoding=None if "b" in mode else encoding,
                       newline=None if "b" in mode else "") as f:
            yield f
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, path)
    except BaseException as exc:
        with contextlib.suppress(FileNotFoundError):
            os.unlink(tmp)
        if isinstance(exc, OSError):
            raise _naming(exc, path) from exc
        raise


def _naming(exc: OSError, path: Path) -> OSError:
    """``exc`` with ``path`` in its message (a full disk's ``[Errno 28] No space left on device`` names no file)."""
    if exc.errno is None:
        return OSError(f"cannot write {path}: {exc}")
    return OSError(exc.errno, f"cannot write {path}: {exc.strerror or exc}")


def atomic_write_bytes(path: Path | str, data: bytes) -> None:
    """Write ``data`` to ``path`` atomically."""
    with atomic_open(path, "wb") as f:
        f.write(data)


def atomic_write_text(path: Path | str, text: str) -> None:
    """Write UTF-8 ``text`` to ``path`` atomically."""
    with atomic_open(path, "w") as f:
        f.write(text)


def _json_default(obj: Any) -> Any:
    if isinstance(obj, np.ndarray):
        return obj.tolist()
    if isinstance(obj, np.generic):
        return obj.item()
    if isinstance(obj, Path):
        return str(obj)
    raise TypeError(f"cannot write {type(obj).__name__} as JSON")


def atomic_write_json(path: Path | str, obj: Any) -> None:
    """Write ``obj`` (numpy arrays and scalars allowed) as indented JSON to ``path`` atomically.

    NaN and infinities are written as ``null`` so the file stays strict JSON.
    """
    def clean(o: Any) -> Any:
        if isinstance(o, dict):
            return {str(k): clean(v) for k, v in o.items()}
        if isinstance(o, (list, tuple)):
            return [clean(v) for v in o]
        if isinstance(o, np.ndarray):
            return clean(o.tolist())
        if isinstance(o, (float, np.floating)):
            return float(o) if np.isfinite(o) else None
        return o

    buf = io.StringIO()
    json.dump(clean(obj), buf, indent=2, default=_json_default, allow_nan=False)
    atomic_write_text(path, buf.getvalue() + "\n")


def remove_stale_temporaries(folder: Path | str) -> int:
    """Delete temporary files (and bag folders) left in ``folder`` (not recursive) by a killed writer; return how
    many."""
    n = 0
    for p in Path(folder).glob(f".*{TMP_MARK}*"):
        with contextlib.suppress(FileNotFoundError):
            if p.is_dir():  # a ROS 2 bag folder being written (planefuse.outputs.write_run_ros2_bag)
                shutil.rmtree(p)
            else:
                p.unlink()
            n += 1
    return n
