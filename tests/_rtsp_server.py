"""A small RTSP server for loopback tests: JPEG frames as RTP/JPEG streams (test-only code).

Written from the RFCs: RTSP 1.0 (RFC 2326: OPTIONS, DESCRIBE, SETUP, PLAY, GET_PARAMETER, TEARDOWN), an SDP
(RFC 4566) with the static payload type 26 (JPEG, 90 kHz), RTP (RFC 3550: random initial sequence number, time
stamp and SSRC) carrying RFC 2435 JPEG payloads (types 0/1, baseline, Q = 255: the frame's own quantisation tables
in band, so the decoded frames are the JPEGs' own), sent over the RTSP connection (``$``-framed interleaved,
RTP/AVP/TCP) or over UDP (RTP/AVP to the client's port), whichever the client's SETUP asks for.

``rtsp://HOST:PORT/<camera>`` streams that camera's frames paced at their times from PLAY, each with the RTP time
stamp of its time (90 kHz, from a random origin per connection). Faults as :class:`planefuse.live.MjpegServer`'s:
``stall_after`` frames then silence (connection open), ``close_after`` frames then the connection closes and the
stream is refused for ``down_s`` (a client that reconnects later gets the frames from where it stopped).
"""

from __future__ import annotations

import socket
import struct
import threading
import time
from collections.abc import Mapping, Sequence

import numpy as np

RTP_CLOCK_HZ = 90_000
PAYLOAD_TYPE_JPEG = 26
MAX_PAYLOAD_BYTES = 1400


def jpeg_scan(jpeg: bytes) -> tuple[int, int, int, bytes, bytes]:
    """A baseline JPEG's RFC 2435 type (0: 4:2:2, 1: 4:2:0), width and height [px], quantisation tables (luma then
    chroma, 64 bytes each in the JPEG's zig-zag order) and entropy-coded scan (without the EOI marker).

    Raises
    ------
    ValueError
        Not a JPEG RFC 2435 can carry this way (progressive, restart markers, 16-bit tables, other sampling).
    """
    if jpeg[:2] != b"\xff\xd8" or jpeg[-2:] != b"\xff\xd9":
        raise ValueError("not a JPEG (SOI ... EOI)")
    tables: dict[int, bytes] = {}
    sof = None
    i = 2
    while i < len(jpeg):
        if jpeg[i] != 0xFF:
            raise ValueError(f"JPEG: no marker at byte {i}")
        marker = jpeg[i + 1]
        length = int.from_bytes(jpeg[i + 2:i + 4], "big")
        body = jpeg[i + 4:i + 2 + length]
        if marker == 0xDB:  # DQT: one or more tables
            k = 0
            while k < len(body):
                pq, tq = body[k] >> 4, body[k] & 15
                if pq:
                    raise ValueError("JPEG: 16-bit quantisation table")
                tables[tq] = body[k + 1:k + 65]
                k += 65
        elif marker == 0xC0:
            sof = body
        elif marker in (0xC1, 0xC2, 0xC3, 0xDD):
            raise ValueError(f"JPEG: marker {marker:#x} (not baseline without restart markers)")
        elif marker == 0xDA:
            scan = jpeg[i + 2 + length:-2]
            break
        i += 2 + length
    else:
        raise ValueError("JPEG: no SOS")
    if sof is None or sof[5] != 3:
        raise ValueError("JPEG: a baseline 3-component frame is needed")
    height, width = int.from_bytes(sof[1:3], "big"), int.from_bytes(sof[3:5], "big")
    sampling = (sof[7], sof[10], sof[13])
    kinds = {(0x21, 0x11, 0x11): 0, (0x22, 0x11, 0x11): 1}
    if sampling not in kinds or (sof[8], sof[11], sof[14]) != (0, 1, 1):
        raise ValueError(f"JPEG: sampling {sampling} / tables not RFC 2435 type 0 or 1")
    if width % 8 or height % 8 or width > 2040 or height > 2040:
        raise ValueError(f"JPEG: {width}x{height} px is not a multiple of 8 up to 2040")
    return kinds[sampling], width, height, tables[0] + tables[1], scan


def rtp_jpeg_payloads(jpeg: bytes, max_payload: int = MAX_PAYLOAD_BYTES) -> list[bytes]:
    """The RFC 2435 payloads of one frame: each an 8-byte JPEG header (fragment offset, type, Q = 255, width / 8,
    height / 8), the first followed by the quantisation table header and tables, then a piece of the scan."""
    kind, width, height, qtables, scan = jpeg_scan(jpeg)
    out, off = [], 0
    while off < len(scan) or not out:
        head = struct.pack("!B", 0) + off.to_bytes(3, "big") + struct.pack("!BBBB", kind, 255, width // 8,
                                                                             height // 8)
        if off == 0:  # MBZ, precision (8-bit tables), length, the tables
            head += struct.pack("!BBH", 0, 0, len(qtables)) + qtables
        n = max_payload - len(head)
        out.append(head + scan[off:off + n])
        off += n
    return out


class RtspServer:
    """Serve JPEG frames as RTSP streams on ``host`` (a thread per connection).

    Parameters
    ----------
    frames : mapping of str -> (times_s (F,), sequence of bytes)
        Per camera, its frames' times [s] (increasing) and baseline JPEG bytes.
    host, port : str, int
        Interface; 0: any free port (:attr:`port` after :meth:`start`).
    transports : tuple of {"tcp", "udp"}
        Lower transports the server accepts; a SETUP asking for another is answered 461 Unsupported Transport.
    stall_after, close_after : mapping of str -> int, optional
        Per camera, frames sent before it goes silent (connection open) / before the connection closes.
    stall_s : float
        How long a stalled camera stays silent before it resumes [s] (``inf``: never).
    down_s : float
        After a ``close_after`` close, how long that camera's stream is refused (DESCRIBE answered 503) [s].
    loop : bool
        Start again from the first frame after the last, the times going on (one frame period after the last):
        an endless stream (benchmarks).
    seed : int
        Seeds the random RTP origins (sequence number, time stamp, SSRC) of the connections.

    Attributes
    ----------
    sent, connections : dict of str -> int
        Frames sent, connections that played, per camera.
    setups : list of str
        The ``Transport`` header of every SETUP received, in order.
    rtp_origins : dict of str -> list of int
        Per camera, each connection's initial RTP time stamp.
    """

    def __init__(self, frames: Mapping[str, tuple[Sequence[float], Sequence[bytes]]], host: str = "127.0.0.1",
                 port: int = 0, transports: tuple[str, ...] = ("tcp", "udp"),
                 stall_after: Mapping[str, int] | None = None, close_after: Mapping[str, int] | None = None,
                 stall_s: float = float("inf"), down_s: float = 0.0, loop: bool = False, seed: int = 0) -> None:
        self.frames = {k: (np.asarray(t, float), [rtp_jpeg_payloads(j) for j in jpgs])
                       for k, (t, jpgs) in frames.items()}
        self.host, self.port, self.transports = host, int(port), tuple(transports)
        self.stall_after, self.close_after = dict(stall_after or {}), dict(close_after or {})
        self.stall_s, self.down_s, self.loop = float(stall_s), float(down_s), bool(loop)
        self.down_until = {k: -np.inf for k in self.frames}
        self.refused = {k: 0 for k in self.frames}  # DESCRIBEs answered 503 while down
        self.rng = np.random.default_rng(seed)
        self.sent = {k: 0 for k in self.frames}
        self.connections = {k: 0 for k in self.frames}
        self.setups: list[str] = []
        self.rtp_origins: dict[str, list[int]] = {k: [] for k in self.frames}
        self._stop = threading.Event()
        self._lock = threading.Lock()
        self._sock: socket.socket | None = None
        self._clients: list[socket.socket] = []

    def url(self, camera: str) -> str:
        return f"rtsp://{self.host}:{self.port}/{camera}"

    def start(self) -> "RtspServer":
        self._sock = socket.create_server((self.host, self.port))
        self.port = self._sock.getsockname()[1]
        threading.Thread(target=self._accept, name="rtsp-accept", daemon=True).start()
        return self

    def stop(self) -> None:
        self._stop.set()
        if self._sock is not None:
            self._sock.close()
        for c in list(self._clients):
            _close(c)

    def _accept(self) -> None:
        while not self._stop.is_set():
            try:
                conn, _ = self._sock.accept()
            except OSError:
                return
            self._clients.append(conn)
            threading.Thread(target=_Connection(self, conn).serve, name="rtsp-conn", daemon=True).start()

    def _random_u32(self) -> int:
        with self._lock:
            return int(self.rng.integers(0, 2**32))


def _close(sock: socket.socket) -> None:
    try:
        sock.shutdown(socket.SHUT_RDWR)
    except OSError:
        pass
    sock.close()


class _Connection:
    """One client's RTSP session: requests read (and interleaved RTCP skipped) in this thread, RTP sent by a
    player thread after PLAY."""

    def __init__(self, server: RtspServer, sock: socket.socket) -> None:
        self.server, self.sock = server, sock
        self.camera: str | None = None
        self.channel: int | None = None           # interleaved RTP channel (TCP)
        self.udp: socket.socket | None = None     # RTP socket and the client's RTP address (UDP)
        self.udp_to: tuple[str, int] | None = None
        self.session = f"{server._random_u32():08X}"
        self.send_lock = threading.Lock()
        self.playing = threading.Event()
        self.closed = threading.Event()

    def serve(self) -> None:
        buf = b""
        try:
            while not self.closed.is_set():
                data = self.sock.recv(65536)
                if not data:
                    break
                buf += data
                while buf:
                    if buf[0] == 0x24:  # '$' channel length: interleaved data from the client (RTCP): skipped
                        if len(buf) < 4 or len(buf) < 4 + int.from_bytes(buf[2:4], "big"):
                            break
                        buf = buf[4 + int.from_bytes(buf[2:4], "big"):]
                        continue
                    end = buf.find(b"\r\n\r\n")
                    if end < 0:
                        break
                    lines = buf[:end].decode("latin-1").split("\r\n")
                    headers = {k.strip().lower(): v.strip() for k, _, v in (h.partition(":") for h in lines[1:])}
                    n = int(headers.get("content-length", 0))
                    if len(buf) < end + 4 + n:
                        break
                    buf = buf[end + 4 + n:]
                    method, url, _ = lines[0].split(" ", 2)
                    self._handle(method, url, headers)
        except OSError:
            pass
        finally:
            self.closed.set()
            _close(self.sock)
            if self.udp is not None:
                self.udp.close()

    def _reply(self, headers: dict, status: str = "200 OK", extra: dict | None = None, body: bytes = b"") -> None:
        lines = [f"RTSP/1.0 {status}", f"CSeq: {headers.get('cseq', '0')}"]
        lines += [f"{k}: {v}" for k, v in (extra or {}).items()]
        if body:
            lines.append(f"Content-Length: {len(body)}")
        with self.send_lock:
            self.sock.sendall(("\r\n".join(lines) + "\r\n\r\n").encode() + body)

    def _handle(self, method: str, url: str, headers: dict) -> None:
        srv = self.server
        session = {"Session": self.session}
        if method == "OPTIONS":
            self._reply(headers, extra={"Public": "OPTIONS, DESCRIBE, SETUP, PLAY, GET_PARAMETER, TEARDOWN"})
        elif method == "DESCRIBE":
            name = url.split("://", 1)[-1].split("/", 2)[1] if url.count("/") >= 3 else ""
            if name not in srv.frames:
                self._reply(headers, "404 Not Found")
                return
            if time.monotonic() < srv.down_until[name]:
                srv.refused[name] += 1
                self._reply(headers, "503 Service Unavailable")
                return
            self.camera = name
            times = srv.frames[name][0]
            fps = 1.0 / float(np.median(np.diff(times))) if len(times) > 1 else 25.0
            sdp = ("v=0\r\no=- 0 0 IN IP4 127.0.0.1\r\ns=planefuse test\r\nc=IN IP4 0.0.0.0\r\nt=0 0\r\n"
                   f"m=video 0 RTP/AVP {PAYLOAD_TYPE_JPEG}\r\na=rtpmap:{PAYLOAD_TYPE_JPEG} JPEG/{RTP_CLOCK_HZ}\r\n"
                   f"a=framerate:{fps:g}\r\na=control:track0\r\n").encode()
            self._reply(headers, extra={"Content-Type": "application/sdp", "Content-Base": f"{srv.url(name)}/"},
                        body=sdp)
        elif method == "SETUP":
            transport = headers.get("transport", "")
            srv.setups.append(transport)
            first = transport.split(",")[0]
            fields = dict(f.partition("=")[::2] for f in first.split(";"))
            if first.startswith("RTP/AVP/TCP") and "tcp" in srv.transports:
                a = int(fields.get("interleaved", "0-1").split("-")[0])
                self.channel = a
                self._reply(headers, extra={"Transport": f"RTP/AVP/TCP;unicast;interleaved={a}-{a + 1}", **session})
            elif not first.startswith("RTP/AVP/TCP") and "client_port" in fields and "udp" in srv.transports:
                client_rtp = int(fields["client_port"].split("-")[0])
                self.udp = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
                self.udp.bind((srv.host, 0))
                self.udp_to = (self.sock.getpeername()[0], client_rtp)
                port = self.udp.getsockname()[1]
                self._reply(headers, extra={"Transport": f"RTP/AVP;unicast;client_port={client_rtp}-{client_rtp + 1};"
                                                         f"server_port={port}-{port + 1}", **session})
            else:
                self._reply(headers, "461 Unsupported Transport")
        elif method == "PLAY":
            if self.camera is None or (self.channel is None and self.udp is None):
                self._reply(headers, "455 Method Not Valid in This State")
                return
            seq0, ts0, ssrc = srv._random_u32() & 0xFFFF, srv._random_u32(), srv._random_u32()
            srv.rtp_origins[self.camera].append(ts0)
            self._reply(headers, extra={"Range": "npt=0.000-", **session,
                                        "RTP-Info": f"url={srv.url(self.camera)}/track0;seq={seq0};rtptime={ts0}"})
            if not self.playing.is_set():
                self.playing.set()
                threading.Thread(target=self._play, args=(seq0, ts0, ssrc), name="rtsp-play", daemon=True).start()
        elif method == "GET_PARAMETER":
            self._reply(headers, extra=session)
        elif method == "TEARDOWN":
            self._reply(headers, extra=session)
            self.closed.set()
            _close(self.sock)
        else:
            self._reply(headers, "501 Not Implemented")

    def _send(self, packets: list[bytes]) -> None:
        """One frame's RTP packets: each a datagram (UDP), or all in one write on the connection (TCP: a write per
        packet would wait for the GIL at each, delaying frames where the process is busy)."""
        if self.udp is not None:
            for packet in packets:
                self.udp.sendto(packet, self.udp_to)
            return
        data = b"".join(struct.pack("!BBH", 0x24, self.channel, len(p)) + p for p in packets)
        with self.send_lock:
            self.sock.sendall(data)

    def _play(self, seq: int, ts0: int, ssrc: int) -> None:
        srv, name = self.server, self.camera
        times, frames = srv.frames[name]
        n = len(times)
        span = times[-1] - times[0] + (times[-1] - times[-2] if n > 1 else 1.0)

        def time_of(k: int) -> float:  # the k-th frame sent over all loops
            return float(times[k % n] + (k // n) * span)

        srv.connections[name] += 1
        i = srv.sent[name]  # a reconnecting client goes on where it stopped
        if i >= n and not srv.loop:
            return
        start, t_first = time.monotonic(), time_of(i)
        try:
            while (i < n or srv.loop) and not self.closed.is_set():
                if name in srv.close_after and srv.sent[name] == srv.close_after[name]:
                    srv.close_after.pop(name)
                    srv.down_until[name] = time.monotonic() + srv.down_s
                    self.closed.set()
                    _close(self.sock)
                    return
                if name in srv.stall_after and srv.sent[name] == srv.stall_after[name]:
                    srv.stall_after.pop(name)
                    if srv._stop.wait(None if np.isinf(srv.stall_s) else srv.stall_s):
                        return
                    start, t_first = time.monotonic(), time_of(i)
                wait = start + (time_of(i) - t_first) - time.monotonic()
                if wait > 0 and srv._stop.wait(wait):
                    return
                stamp = (ts0 + int(round((time_of(i) - times[0]) * RTP_CLOCK_HZ))) & 0xFFFFFFFF
                payloads = frames[i % n]
                packets = []
                for k, p in enumerate(payloads):
                    marker = 0x80 if k == len(payloads) - 1 else 0
                    packets.append(struct.pack("!BBHII", 0x80, marker | PAYLOAD_TYPE_JPEG, seq, stamp, ssrc) + p)
                    seq = (seq + 1) & 0xFFFF
                self._send(packets)
                srv.sent[name] += 1
                i += 1
        except OSError:
            return
