"""One writer per output folder: a lock file that a second run finds held, and a dead run's left-over lock.

``out_dir/.planefuse.lock`` holds the writer's process id, host and start time; the writer holds an exclusive
``flock`` on it while it writes, which the operating system releases when the process ends however it ends
(Ctrl-C, a kill, a crash). A second run finds the lock held and is refused, naming the holder; a run that finds a
lock file nobody holds (its writer was killed) takes it over with a warning. Where ``flock`` is unavailable
(Windows, some network file systems) the process id alone decides: a lock of a process still running on this
host is held.
"""

from __future__ import annotations

import contextlib
import os
import socket
import time
import warnings
from pathlib import Path

try:
    import fcntl
except ImportError:  # Windows
    fcntl = None

__all__ = ["OutputLock", "LOCK_FILE", "lock_holder"]

#: The lock file's name in an output folder.
LOCK_FILE = ".planefuse.lock"


def _describe(text: str) -> str:
    """``PID 123 on host, since 2026-12-07 08:00:00`` from a lock file's text (what is readable of it)."""
    parts = text.split()
    if len(parts) >= 2 and parts[0].isdigit():
        since = " ".join(parts[2:4]) if len(parts) >= 4 else ""
        return f"PID {parts[0]} on {parts[1][:64]}" + (f", since {since}" if since else "")
    return "a process that left no id"


def _pid_alive(text: str) -> bool:
    """Whether the lock's process runs on this host (False where the text names none or another host)."""
    parts = text.split()
    if len(parts) < 2 or not parts[0].isdigit() or parts[1] != socket.gethostname():
        return False
    try:
        os.kill(int(parts[0]), 0)
    except ProcessLookupError:
        return False
    except (PermissionError, OverflowError):
        return True
    return True


def _read(fd: int) -> str:
    with contextlib.suppress(OSError):
        os.lseek(fd, 0, os.SEEK_SET)
        return os.read(fd, 512).decode("utf-8", "replace")
    return ""


def lock_holder(folder: Path | str) -> str | None:
    """Who holds ``folder``'s lock (``PID ... on host, since ...``), or None when nobody does; takes nothing."""
    path = Path(folder) / LOCK_FILE
    try:
        fd = os.open(path, os.O_RDONLY)
    except OSError:
        return None
    try:
        text = _read(fd)
        if fcntl is not None:
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except BlockingIOError:
                return _describe(text)
            except OSError:
                pass  # flock unsupported here: the process id decides
            else:
                return None  # closing the descriptor releases it
        return _describe(text) if _pid_alive(text) and int(text.split()[0]) != os.getpid() else None
    finally:
        os.close(fd)


class OutputLock:
    """The exclusive lock of an output folder (:data:`LOCK_FILE`), held from :meth:`acquire` to :meth:`release`.

    Parameters
    ----------
    folder : path-like
        The output folder (must exist).

    Raises
    ------
    ValueError
        From :meth:`acquire`: another run holds the lock (named), or the lock file cannot be created.
    """

    def __init__(self, folder: Path | str):
        self.path = Path(folder) / LOCK_FILE
        self._fd: int | None = None

    @property
    def held(self) -> bool:
        return self._fd is not None

    def acquire(self) -> None:
        """Take the lock; a lock file left by a dead run is taken over with a warning (``UserWarning``)."""
        if self._fd is not None:
            return
        for _ in range(10):  # retried when a holder released (unlinked) the file between our open and our flock
            try:
                fd = os.open(self.path, os.O_RDWR | os.O_CREAT, 0o644)
            except OSError as exc:
                raise ValueError(f"out_dir {self.path.parent}: cannot create the lock file {LOCK_FILE} "
                                 f"({exc.strerror or exc})") from None
            text = _read(fd)
            locked = False
            if fcntl is not None:
                try:
                    fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
                    locked = True
                except BlockingIOError:
                    os.close(fd)
                    raise ValueError(self._refusal(text)) from None
                except OSError:
                    pass  # flock unsupported on this file system: the process id decides
            if not locked and _pid_alive(text) and int(text.split()[0]) != os.getpid():
                os.close(fd)
                raise ValueError(self._refusal(text))
            try:
                same = os.fstat(fd).st_ino == os.stat(self.path).st_ino
            except OSError:
                same = False
            if not same:
                os.close(fd)
                continue
            break
        else:
            raise ValueError(f"out_dir {self.path.parent}: the lock file {LOCK_FILE} keeps being replaced by another "
                             "run")
        if text.strip() and text.split()[0] != str(os.getpid()):
            warnings.warn(f"out_dir {self.path.parent}: took over the lock of a planefuse run that is no longer "
                          f"running ({_describe(text)}): that run was interrupted or killed", stacklevel=3)
        mine = f"{os.getpid()} {socket.gethostname()} {time.strftime('%Y-%m-%d %H:%M:%S')}\n".encode()
        try:
            os.ftruncate(fd, 0)
            os.lseek(fd, 0, os.SEEK_SET)
            os.write(fd, mine)
        except OSError:
            pass  # a full disk: the flock still holds; the file names no holder
        self._fd = fd

    def _refusal(self, text: str) -> str:
        return (f"out_dir {self.path.parent} is being written by another planefuse run ({_describe(text)}): wait for "
                "it to end, or choose another folder (outputs.out_dir)")

    def release(self) -> None:
        """Remove the lock file and release the lock (nothing where it is not held)."""
        fd, self._fd = self._fd, None
        if fd is None:
            return
        with contextlib.suppress(OSError):
            self.path.unlink()
        with contextlib.suppress(OSError):
            os.close(fd)

    def __del__(self) -> None:
        self.release()
