"""Within one recording: the cameras' front end as per-camera streams on dask workers.

Each camera's front end (decoding its frames, the dead-frame check, background subtraction:
:class:`planefuse.vision.CameraFrontEnd`) is stateful and sequential in time, but independent of the other
cameras. :func:`remote_foregrounds` runs one :class:`CameraStream` per camera on the cluster's workers (a dask
actor that reads the recording folder itself) and gives the foregrounds back in time order, a few chunks ahead
of what the run consumes; the run's own process registers and fuses them and runs the sequential filter and
tracker on them, exactly as the serial run does. The front end seeds the background model's random draws per
frame, so its foregrounds, and so the run's tables and metrics, are identical to the serial run's.
"""

from __future__ import annotations

import threading
from collections import deque
from collections.abc import Iterator, Sequence

import numpy as np

__all__ = ["CameraStream", "remote_foregrounds"]


class CameraStream:
    """One camera's front end over a recording folder, chunk after chunk of camera instants (a dask actor).

    Parameters
    ----------
    root : str
        Recording folder (read on the worker: it must be reachable there under this path).
    name : str
        The camera.
    foreground : ForegroundParams or None
        Background subtraction (None: the frames are foreground likelihoods already).
    start : int
        Camera instants the run skips (a resumed run); their frames are replayed into the background model.
    quantise : bool
        Foregrounds as uint8 levels (what the per-cell fusion uses) instead of float32.
    chunk : int
        Camera instants per chunk.
    stride : int
        Every ``stride``-th camera instant only (``CameraParams.frame_stride``; ``start`` counts those).
    max_rate_hz : float or None
        At most this many camera instants per second [Hz] (``CameraParams.max_rate_hz``).
    window : (row0, row1, col0, col1) or None
        The image part the background subtraction covers [px] (:class:`~planefuse.vision.CameraFrontEnd`).
    """

    def __init__(self, root: str, name: str, foreground, start: int, quantise: bool, chunk: int,
                 stride: int = 1, max_rate_hz: float | None = None,
                 window: tuple[int, int, int, int] | None = None) -> None:
        from ..io import read_recording
        from ..pipeline._streams import _background_or_none
        from ..vision import CameraFrontEnd, camera_instants
        from ._jobs import threads_from_environment

        threads_from_environment()
        rec = read_recording(root)
        cams = {c.name: c for c in rec.cameras}
        if name not in cams:
            raise ValueError(f"{root}: no camera {name!r} (it has {sorted(cams)})")
        self.stream = rec.camera(name)
        size = cams[name].intrinsics
        background = _background_or_none(self.stream) if foreground is not None else None
        self.front_end = CameraFrontEnd(size.width_px, size.height_px, foreground, name, background, quantise,
                                        window)
        times = camera_instants(rec, stride, max_rate_hz)
        self._replay = times[:start] if foreground is not None else times[:0]
        self.times = times[start:]
        self.chunk_size = int(chunk)
        self._next = 0
        self._done: dict[int, list] = {}
        self._lock = threading.Lock()

    def _frame(self, time_s: float):
        from ..vision._datasets import frame_at

        j = frame_at(self.stream, time_s)
        return None if j is None else self.stream.frame(j)

    def chunk(self, k: int) -> list[tuple[np.ndarray | None, str, object]]:
        """``(foreground, status, boxes)`` per camera instant of chunk ``k`` (:meth:`CameraFrontEnd.process`); chunks are
        computed in order whatever order the calls arrive in."""
        with self._lock:
            while self._next <= k:
                if self._next == 0:
                    for t in self._replay:
                        self.front_end.replay(self._frame(t))
                n = self.chunk_size
                self._done[self._next] = [self.front_end.process(self._frame(t))
                                          for t in self.times[self._next * n:(self._next + 1) * n]]
                self._next += 1
            return self._done.pop(k)


def remote_foregrounds(client, root, names: Sequence[str], foreground, times_s: np.ndarray, start: int = 0,
                       quantise: bool = True, chunk: int = 10, ahead: int = 3, stride: int = 1,
                       max_rate_hz: float | None = None, windows: Sequence | None = None,
                       ) -> Iterator[tuple[float, list[np.ndarray | None], list[str], list]]:
    """Every camera's front end on the cluster, in time order: what :func:`planefuse.vision.camera_foregrounds`
    gives in this process.

    Parameters
    ----------
    client : distributed.Client
    root : path
        The recording folder (reachable by the workers under this path).
    names : sequence of str
        Cameras, in the recording's order.
    foreground : ForegroundParams or None
    times_s : ndarray, shape (T,)
        The run's camera instants after ``start`` (:func:`planefuse.vision.camera_instants` with ``stride`` and
        ``max_rate_hz``) [s].
    start : int
        Instants skipped at the start (a resumed run).
    quantise : bool
        Foregrounds as uint8 levels (for the per-cell fusion).
    chunk, ahead : int
        Instants per message, and chunks requested ahead of the one consumed (per camera).
    stride : int
        Every ``stride``-th camera instant of the recording (``CameraParams.frame_stride``).
    max_rate_hz : float or None
        At most this many camera instants per second [Hz] (``CameraParams.max_rate_hz``).
    windows : sequence of ((row0, row1, col0, col1) or None), optional
        Per camera, the image part its background subtraction covers [px]
        (:func:`planefuse.vision.subtraction_window`); None: the whole image.

    Yields
    ------
    (time_s, foregrounds, statuses, boxes)
        Per camera instant, each camera's :meth:`~planefuse.vision.CameraFrontEnd.process`.
    """
    if root is None:
        raise ValueError("per-camera streams on dask workers need a recording folder (the workers read the "
                         "frames themselves); this recording is in memory")
    workers = sorted(client.scheduler_info()["workers"])
    if not workers:
        raise ValueError("the dask cluster has no workers")
    windows = [None] * len(names) if windows is None else list(windows)
    futures = [client.submit(CameraStream, str(root), name, foreground, int(start), bool(quantise), int(chunk),
                             int(stride), max_rate_hz, windows[c], actor=True, workers=[workers[c % len(workers)]],
                             pure=False)
               for c, name in enumerate(names)]
    actors = [f.result() for f in futures]
    n_chunks = -(-len(times_s) // chunk)
    pending = [deque(a.chunk(k) for k in range(min(ahead, n_chunks))) for a in actors]
    try:
        for k in range(n_chunks):
            results = [p.popleft().result() for p in pending]
            if k + ahead < n_chunks:
                for a, p in zip(actors, pending):
                    p.append(a.chunk(k + ahead))
            for i, t in enumerate(times_s[k * chunk:(k + 1) * chunk]):
                yield float(t), [r[i][0] for r in results], [r[i][1] for r in results], [r[i][2] for r in results]
    finally:
        del actors, pending
        client.cancel(futures)
