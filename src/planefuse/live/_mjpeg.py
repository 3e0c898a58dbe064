"""Frames served as live MJPEG streams over HTTP (loopback tests, demos): :class:`MjpegServer`.

``GET /<camera>.mjpg`` streams that camera's frames as ``multipart/x-mixed-replace`` JPEG parts, each with its
``X-Timestamp`` [s] (the frame's time, as mjpg-streamer sends one), paced at the frames' times from the moment
the client connected. Faults can be injected per camera to test a live run: ``stall_after`` frames then silence
(the connection stays open), ``close_after`` frames then the connection closes (a reconnecting client gets the
stream again from the frame it stopped at).
"""

from __future__ import annotations

import threading
import time
from collections.abc import Mapping, Sequence
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer

import cv2
import numpy as np

__all__ = ["MjpegServer", "recording_jpeg_frames"]

BOUNDARY = "planefuseframe"


def recording_jpeg_frames(rec, quality: int = 90, n_frames: int | None = None
                          ) -> dict[str, tuple[np.ndarray, list[bytes]]]:
    """Each camera's frames of ``rec`` as JPEG bytes: name -> (times [s] (F,), JPEG of each frame) (the first
    ``n_frames`` where given)."""
    out = {}
    for cam in rec.cameras:
        s = rec.camera(cam.name)
        n = len(s) if n_frames is None else min(len(s), int(n_frames))
        jpgs = []
        for i in range(n):
            ok, buf = cv2.imencode(".jpg", s.frame(i), [cv2.IMWRITE_JPEG_QUALITY, int(quality)])
            if not ok:
                raise ValueError(f"camera {cam.name!r} frame {i}: JPEG encoding failed")
            jpgs.append(buf.tobytes())
        out[cam.name] = (np.asarray(s.times_s[:n], float), jpgs)
    return out


class MjpegServer:
    """Serve JPEG frames as MJPEG streams on ``host`` (a thread per client).

    Parameters
    ----------
    frames : mapping of str -> (times_s (F,), sequence of bytes)
        Per camera, its frames' times [s] (increasing) and JPEG bytes.
    host : str
        Interface (``127.0.0.1`` by default).
    port : int
        0: any free port (:attr:`port` after :meth:`start`).
    speed : float
        Playback speed (1: the frames' own rate).
    stall_after, close_after : mapping of str -> int, optional
        Per camera, frames sent before it goes silent (connection open) / before the connection closes.
    stall_s : float
        How long a stalled camera stays silent before it resumes [s] (``inf``: never).
    loop : bool
        Start again from the first frame after the last, the times going on (one frame period after the last):
        an endless stream (soak tests).
    """

    def __init__(self, frames: Mapping[str, tuple[Sequence[float], Sequence[bytes]]], host: str = "127.0.0.1",
                 port: int = 0, speed: float = 1.0, stall_after: Mapping[str, int] | None = None,
                 close_after: Mapping[str, int] | None = None, stall_s: float = float("inf"),
                 loop: bool = False) -> None:
        self.frames = {k: (np.asarray(t, float), list(j)) for k, (t, j) in frames.items()}
        self.host, self.port, self.speed = host, int(port), float(speed)
        self.stall_after = dict(stall_after or {})
        self.close_after = dict(close_after or {})
        self.stall_s = float(stall_s)
        self.loop = bool(loop)
        self.sent = {k: 0 for k in self.frames}   # frames sent per camera (over all its connections)
        self.connections = {k: 0 for k in self.frames}
        self._stop = threading.Event()
        self._server: ThreadingHTTPServer | None = None

    def url(self, camera: str) -> str:
        return f"http://{self.host}:{self.port}/{camera}.mjpg"

    def start(self) -> "MjpegServer":
        server = self

        class Handler(BaseHTTPRequestHandler):
            def log_message(self, *args):  # quiet
                pass

            def do_GET(self):  # noqa: N802 - http.server's name
                name = self.path.strip("/").removesuffix(".mjpg")
                if name not in server.frames:
                    self.send_error(404)
                    return
                server._stream(self, name)

        self._server = ThreadingHTTPServer((self.host, self.port), Handler)
        self._server.daemon_threads = True
        self.port = self._server.server_address[1]
        threading.Thread(target=self._server.serve_forever, name="planefuse-mjpeg", daemon=True).start()
        return self

    def stop(self) -> None:
        self._stop.set()
        if self._server is not None:
            self._server.shutdown()
            self._server.server_close()

    def _stream(self, handler: BaseHTTPRequestHandler, name: str) -> None:
        times, jpgs = self.frames[name]
        self.connections[name] += 1
        first = self.sent[name]  # a reconnecting client goes on where it stopped
        handler.send_response(200)
        handler.send_header("Content-Type", f"multipart/x-mixed-replace; boundary={BOUNDARY}")
        handler.send_header("Cache-Control", "no-cache")
        handler.end_headers()
        n = len(jpgs)
        span = (times[-1] - times[0] + (times[-1] - times[-2] if n > 1 else 1.0)) if n else 0.0

        def time_of(k: int) -> float:  # the k-th frame sent over all loops
            return float(times[k % n] + (k // n) * span)

        start, t_first = time.monotonic(), (time_of(first) if first < n or self.loop else 0.0)
        try:
            i = first
            while i < n or (self.loop and n):
                if self._stop.is_set():
                    return
                if name in self.close_after and self.sent[name] == self.close_after[name]:
                    self.close_after.pop(name)
                    return  # the connection closes
                if name in self.stall_after and self.sent[name] == self.stall_after[name]:
                    self.stall_after.pop(name)
                    if self._stop.wait(None if np.isinf(self.stall_s) else self.stall_s):
                        return
                    start, t_first = time.monotonic(), time_of(i)
                t = time_of(i)
                wait = start + (t - t_first) / self.speed - time.monotonic()
                if wait > 0 and self._stop.wait(wait):
                    return
                jpg = jpgs[i % n]
                head = (f"--{BOUNDARY}\r\nContent-Type: image/jpeg\r\nContent-Length: {len(jpg)}\r\n"
                        f"X-Timestamp: {t!r}\r\n\r\n").encode()
                handler.wfile.write(head + jpg + b"\r\n")
                handler.wfile.flush()
                self.sent[name] += 1
                i += 1
            # the end of the frames: the stream stays open and silent until the server stops
            self._stop.wait()
        except (BrokenPipeError, ConnectionResetError):
            return
