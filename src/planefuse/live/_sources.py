"""Live sensor sources: frames read as they stream, stamped on one clock, retried when the stream fails.

A :class:`LiveSource` runs in its own thread and hands every measurement to a sink with two stamps on the run's
clock (seconds since the live run started, ``time.monotonic``): when it arrived, and the time it stands for
(the arrival itself, or the stream's own presentation time where the run uses it). Cameras are the only kind
this version reads; a laser, IMU or binaural source is another subclass feeding its own sink.

A stream that fails (cannot be opened, stops delivering for ``stall_s``, closes) is retried with exponential
back-off (``retry_min_s`` doubling up to ``retry_max_s``); a file played at its own rate ends at its end, and a
frame the camera's calibration does not fit (its size) stops the source with an error: neither is retried.
Every transition is reported (:attr:`LiveSource.on_event`) and counted (:class:`SourceHealth`).
"""

from __future__ import annotations

import http.client
import sys
import threading
import time
from collections import deque
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from urllib.parse import urlsplit

import cv2
import numpy as np

__all__ = ["CameraSource", "LiveSource", "SourceHealth", "camera_reader", "device_path", "mjpeg_frames",
           "source_kind", "PRESENTATION_KINDS", "SOURCE_KINDS", "SOURCE_STATES"]

#: A source's states: opening its stream, delivering, waiting to retry after a failure (no frame for ``stall_s``,
#: closed, refused), finished (a file's end), stopped with an error (not retried), stopped by the run.
SOURCE_STATES = ("connecting", "live", "retrying", "ended", "error", "stopped")

#: Frames kept to measure a source's received rate (the last this many arrival times).
RATE_WINDOW_FRAMES = 50


@dataclass
class SourceHealth:
    """What a source did so far (updated by its thread, read by the run and the live page).

    Attributes
    ----------
    state : str
        One of :data:`SOURCE_STATES`.
    received : int
        Frames received from the stream.
    used, skipped, dropped, late : int
        Frames given to the system; not taken because the run's rate is below the stream's (as an offline run
        with ``max_rate_hz``); taken but dropped, the oldest first, because the system fell behind
        (``queue_frames``); arrived after their instant was processed. Counted by the synchroniser.
    reconnects : int
        Times the stream was opened again after a failure.
    stalls : int
        Times the stream stopped delivering for ``stall_s`` or failed.
    last_error : str
        The last failure, "" if none.
    last_arrival_s : float or None
        Arrival of the newest frame [s, run clock].
    lag_s : float or None
        Newest instant's processing lag for this camera: when the system took its frame, less its arrival [s].
    """

    name: str
    state: str = "connecting"
    received: int = 0
    used: int = 0
    skipped: int = 0
    dropped: int = 0
    late: int = 0
    reconnects: int = 0
    stalls: int = 0
    last_error: str = ""
    last_arrival_s: float | None = None
    lag_s: float | None = None
    _arrivals: deque = field(default_factory=lambda: deque(maxlen=RATE_WINDOW_FRAMES), repr=False)

    def rate_hz(self, now_s: float) -> float:
        """Frames received per second over the last :data:`RATE_WINDOW_FRAMES` frames (0 where the newest is more
        than 2 s old or fewer than 2 arrived)."""
        a = self._arrivals
        if len(a) < 2 or now_s - a[-1] > 2.0:
            return 0.0
        return (len(a) - 1) / max(a[-1] - a[0], 1e-9)

    def as_dict(self, now_s: float) -> dict:
        """The counters as JSON-ready values (``rate_hz`` and ``age_s`` of the newest frame at ``now_s``)."""
        return {"name": self.name, "state": self.state, "rate_hz": round(self.rate_hz(now_s), 2),
                "received": self.received, "used": self.used, "skipped": self.skipped, "dropped": self.dropped,
                "late": self.late, "reconnects": self.reconnects, "stalls": self.stalls,
                "last_error": self.last_error,
                "age_s": None if self.last_arrival_s is None else round(now_s - self.last_arrival_s, 3),
                "lag_s": None if self.lag_s is None else round(self.lag_s, 4)}


class _Stop(Exception):
    """The run stops the source."""


class LiveSource:
    """One sensor read as it streams, in a thread of its own: the base of every live source.

    Subclasses implement :meth:`_open` (the stream's measurements, an iterator of ``(data, presentation_s or
    None)``; it raises ``ConnectionError``/``OSError``/``TimeoutError`` where the stream fails, and ends where a
    finite stream ends) and :meth:`_check` (refuse a measurement the sensor's calibration does not fit).

    Parameters
    ----------
    name : str
        The sensor's name in the recording that holds its calibration.
    sink : callable
        ``sink(data, arrival_s, presentation_s)`` for every measurement, from the source's thread; it may raise
        ``ValueError`` to refuse one (the source stops with that error).
    clock : callable
        The run's clock [s] (``time.monotonic() - start``).
    stall_s, retry_min_s, retry_max_s : float
        No measurement for this long [s] marks the stream stalled and reopens it; back-off before a retry [s],
        doubling from ``retry_min_s`` up to ``retry_max_s`` (reset by a measurement).
    retry : bool
        False: a failed stream is not reopened (a file ends).
    on_event : callable, optional
        ``on_event(message)`` for every change of state.
    """

    kind = "sensor"

    def __init__(self, name: str, sink: Callable, clock: Callable[[], float], *, stall_s: float = 2.0,
                 retry_min_s: float = 0.5, retry_max_s: float = 8.0, retry: bool = True,
                 on_event: Callable[[str], None] | None = None) -> None:
        if not (stall_s > 0 and 0 < retry_min_s <= retry_max_s):
            raise ValueError(f"source {name!r}: stall_s > 0 and 0 < retry_min_s <= retry_max_s are needed, got "
                             f"{stall_s}, {retry_min_s}, {retry_max_s}")
        self.name, self.sink, self.clock = name, sink, clock
        self.stall_s, self.retry_min_s, self.retry_max_s, self.retry = stall_s, retry_min_s, retry_max_s, retry
        self.on_event = on_event or (lambda message: None)
        self.health = SourceHealth(name)
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None

    @property
    def running(self) -> bool:
        """Whether the source may still deliver (not ended, failed for good or stopped)."""
        return self.health.state not in ("ended", "error", "stopped")

    @property
    def delivering(self) -> bool:
        """Whether the source is delivering now (worth waiting a moment for its next measurement)."""
        h = self.health
        return h.state == "live" and h.last_arrival_s is not None and self.clock() - h.last_arrival_s < self.stall_s

    def start(self) -> None:
        """Start reading in a daemon thread."""
        self._thread = threading.Thread(target=self._loop, name=f"planefuse-live-{self.name}", daemon=True)
        self._thread.start()

    def request_stop(self) -> None:
        """Ask the thread to stop, without waiting."""
        self._stop.set()

    def stop(self, timeout_s: float = 2.0) -> None:
        """Ask the thread to stop and wait for it at most ``timeout_s`` [s] (a read blocked in a library call
        ends at its own time-out; the thread is a daemon)."""
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout_s)
        if self.running:
            self.health.state = "stopped"

    def _set(self, state: str, message: str = "") -> None:
        if state != self.health.state:
            self.health.state = state
            self.on_event(f"{self.kind} {self.name!r}: {state}" + (f" ({message})" if message else ""))

    def _loop(self) -> None:
        backoff = self.retry_min_s
        while not self._stop.is_set():
            self._set("connecting")
            try:
                for data, presentation_s in self._open():
                    if self._stop.is_set():
                        raise _Stop
                    arrival = self.clock()
                    h = self.health
                    h.received += 1
                    h.last_arrival_s = arrival
                    h._arrivals.append(arrival)
                    self._check(data)
                    self.sink(data, arrival, presentation_s)
                    self._set("live")
                    backoff = self.retry_min_s
                if self._stop.is_set():
                    break
                if not self.retry:
                    self._set("ended", "end of stream")
                    return
                raise ConnectionError("the stream closed")
            except _Stop:
                break
            except ValueError as exc:  # a measurement the calibration does not fit: not retried
                self.health.last_error = str(exc)
                self._set("error", str(exc))
                return
            except (OSError, ConnectionError, TimeoutError, http.client.HTTPException) as exc:
                if self._stop.is_set():
                    break
                h = self.health
                h.stalls += 1
                h.last_error = f"{type(exc).__name__}: {exc}"
                if not self.retry:
                    self._set("error", h.last_error)
                    return
                self._set("retrying", f"{h.last_error}; retry in {backoff:g} s")
                if self._stop.wait(backoff):
                    break
                backoff = min(2 * backoff, self.retry_max_s)
                h.reconnects += 1
        if self.running:
            self.health.state = "stopped"

    def _open(self) -> Iterator[tuple[object, float | None]]:
        raise NotImplementedError

    def _check(self, data) -> None:
        """Raise ``ValueError`` for a measurement the sensor's calibration does not fit."""


def mjpeg_frames(url: str, timeout_s: float) -> Iterator[tuple[bytes, float | None]]:
    """The JPEG parts of an HTTP(S) ``multipart/x-mixed-replace`` (MJPEG) stream, each with its ``X-Timestamp``
    header [s] where the server sends one (mjpg-streamer does), else None.

    Raises
    ------
    ConnectionError
        An HTTP status other than 200, or a response that is not multipart.
    ValueError
        A part without ``Content-Length``.
    TimeoutError / OSError
        No byte for ``timeout_s`` [s] (a stalled stream), or the connection failed.
    """
    parts = urlsplit(url)
    conn_cls = http.client.HTTPSConnection if parts.scheme == "https" else http.client.HTTPConnection
    conn = conn_cls(parts.hostname, parts.port, timeout=timeout_s)
    try:
        conn.request("GET", (parts.path or "/") + (f"?{parts.query}" if parts.query else ""))
        resp = conn.getresponse()
        if resp.status != 200:
            raise ConnectionError(f"HTTP {resp.status} {resp.reason}")
        ctype = resp.getheader("Content-Type", "")
        if "multipart" not in ctype or "boundary=" not in ctype:
            raise ConnectionError(f"not an MJPEG stream (Content-Type {ctype!r})")
        # the parts start at a line "--" + boundary (some servers declare the boundary with its dashes)
        token = ctype.split("boundary=", 1)[1].split(";")[0].strip().strip('"').lstrip("-").encode()
        while True:
            line = resp.readline()
            if not line:
                return  # the server closed the stream
            if not line.strip().lstrip(b"-").startswith(token):
                continue
            headers: dict[str, str] = {}
            while True:
                h = resp.readline()
                if not h:
                    return
                h = h.strip()
                if not h:
                    break
                k, _, v = h.decode("latin-1").partition(":")
                headers[k.strip().lower()] = v.strip()
            n = headers.get("content-length")
            if n is None:  # a stream this reader cannot split: not retried
                raise ValueError(f"{url}: MJPEG part without a Content-Length header (not supported)")
            data = resp.read(int(n))
            if len(data) < int(n):
                return
            ts = headers.get("x-timestamp")
            yield data, (float(ts) if ts else None)
    finally:
        conn.close()


#: What a camera's stream is (:func:`source_kind`): an HTTP(S) MJPEG stream, a video file played at its own rate, a
#: local device, or another URL opened by OpenCV's FFmpeg (RTSP).
SOURCE_KINDS = ("mjpeg", "file", "device", "ffmpeg")

#: The kinds whose frames carry a presentation time on a clock the cameras can share (``clock: presentation``):
#: MJPEG's ``X-Timestamp`` (the server's clock) and a file's own times (a recording played back). OpenCV gives an
#: RTSP stream's RTP times counted from each connection's first frame, whatever the stream's RTP origin
#: (tests/test_live_rtsp.py), and a device's frames none.
PRESENTATION_KINDS = ("mjpeg", "file")


def source_kind(source: str | int) -> str:
    """One of :data:`SOURCE_KINDS`: ``http(s)://`` is MJPEG; an int or ``/dev/video...`` a local device; a path or
    ``file://`` URL a video file; any other URL (``rtsp://``, ``rtmp://``, ...) goes to OpenCV's FFmpeg."""
    if isinstance(source, int):
        return "device"
    if source.startswith(("http://", "https://")):
        return "mjpeg"
    if source.startswith("/dev/video"):
        return "device"
    if source.startswith("file://") or "://" not in source:
        return "file"
    return "ffmpeg"


def device_path(source: str | int) -> Path | None:
    """The device node of a local device source on Linux (``/dev/videoN`` for index N; the path itself), None
    elsewhere (an index is then OpenCV's to resolve)."""
    if isinstance(source, str):
        return Path(source)
    return Path(f"/dev/video{int(source)}") if sys.platform.startswith("linux") else None


def camera_reader(source: str | int, timeout_s: float) -> Callable[[], Iterator[tuple[np.ndarray, float | None]]]:
    """A function that opens ``source`` and iterates its frames ``(image (H, W, 3) uint8 BGR, presentation_s)``.

    By :func:`source_kind`: ``http(s)://`` an MJPEG stream (:func:`mjpeg_frames`, presentation time from
    ``X-Timestamp``); a path or ``file://`` URL: a video file played at its own rate (its frames' times; ends at its
    end); an int or ``/dev/videoN``: a local device; ``rtsp://`` (or any other URL OpenCV's FFmpeg opens) through
    ``cv2.VideoCapture(url, CAP_FFMPEG)`` with open and read time-outs of ``timeout_s`` [s]. Devices and FFmpeg
    URLs give no presentation time (None; :data:`PRESENTATION_KINDS`).

    RTSP: OpenCV asks FFmpeg for RTP over the RTSP connection first (``rtsp_flags=prefer_tcp``) and falls back to
    UDP where the camera refuses; setting the environment variable ``OPENCV_FFMPEG_CAPTURE_OPTIONS`` (for any
    option) replaces that default with FFmpeg's (UDP first), unless it says ``rtsp_transport;tcp``.

    A device whose node does not exist when it is first opened raises ``ValueError`` (not retried: a wrong name);
    one that disappears later (unplugged) is retried as a stream that failed.
    """
    kind = source_kind(source)
    if kind == "mjpeg":
        def read_mjpeg():
            for data, pts in mjpeg_frames(source, timeout_s):
                img = cv2.imdecode(np.frombuffer(data, np.uint8), cv2.IMREAD_COLOR)
                if img is None:
                    raise ConnectionError("an MJPEG part is not a decodable JPEG")
                yield img, pts
        return read_mjpeg
    if kind == "file":
        path = Path(source[len("file://"):] if source.startswith("file://") else source)

        def read_file():
            if not path.is_file():
                raise ValueError(f"{path}: video file not found")
            cap = cv2.VideoCapture(str(path))
            try:
                if not cap.isOpened():
                    raise ValueError(f"{path}: OpenCV cannot open this video")
                start = time.monotonic()
                while True:
                    ok, img = cap.read()
                    if not ok or img is None:
                        return
                    pts = float(cap.get(cv2.CAP_PROP_POS_MSEC)) / 1e3
                    wait = start + pts - time.monotonic()
                    if wait > 0:  # played at its own rate
                        time.sleep(wait)
                    yield img, pts
            finally:
                cap.release()
        return read_file

    opened = []  # whether the source was ever opened (a device missing from the start is a wrong name)

    def read_capture():
        if kind == "device":
            node = device_path(source)
            if node is not None and not node.exists():
                if not opened:
                    raise ValueError(f"device {source!r}: {node} does not exist (no such camera on this machine)")
                raise ConnectionError(f"device {node} is gone")
            cap = cv2.VideoCapture(source)
        else:
            ms = int(timeout_s * 1e3)
            cap = cv2.VideoCapture(source, cv2.CAP_FFMPEG,
                                   [cv2.CAP_PROP_OPEN_TIMEOUT_MSEC, ms, cv2.CAP_PROP_READ_TIMEOUT_MSEC, ms])
        try:
            if not cap.isOpened():
                raise ConnectionError(f"OpenCV cannot open {source!r}")
            opened.append(True)
            while True:
                ok, img = cap.read()
                if not ok or img is None:
                    raise ConnectionError("no frame (stream ended or timed out)")
                yield img, None
        finally:
            cap.release()
    return read_capture


class CameraSource(LiveSource):
    """A camera read as it streams (:func:`camera_reader`), its frames checked against its calibration's size.

    Parameters
    ----------
    name : str
    source : str or int
        URL, device, or video file (:func:`camera_reader`).
    width_px, height_px : int
        The calibration's image size; a frame of another size stops the source with an error.
    **kwargs
        :class:`LiveSource`'s (a file is not retried at its end).
    """

    kind = "camera"

    def __init__(self, name: str, source: str | int, width_px: int, height_px: int, sink: Callable,
                 clock: Callable[[], float], **kwargs) -> None:
        kwargs.setdefault("retry", source_kind(source) != "file")
        super().__init__(name, sink, clock, **kwargs)
        self.source, self.width_px, self.height_px = source, int(width_px), int(height_px)
        self._reader = camera_reader(source, self.stall_s)

    def _open(self):
        return self._reader()

    def _check(self, img) -> None:
        if img.shape[:2] != (self.height_px, self.width_px):
            raise ValueError(f"camera {self.name!r}: frame is {img.shape[1]}x{img.shape[0]} px, its calibration "
                             f"{self.width_px}x{self.height_px} px")
