"""The whole system on cameras as they stream: :class:`LiveRun`.

The run's own :class:`~planefuse.pipeline.SystemRun` (registration, filter, tracker) is fed the synchronised
instants :class:`~planefuse.live.FrameSynchroniser` forms from the cameras' frames as they arrive, and each
output step is written (tracks as JSON lines, ``tracks.csv``) and shown on the live page as soon as it is made.

Latency: the tracker releases a batch of evidence once no later message can join it (its merge tolerance); the
live run knows when that is from the instants' slots (every later instant is stamped at or after
:meth:`FrameSynchroniser.next_stamp_bound_s`), so at 5 Hz an instant is fused and its tracks given at once,
not one instant later as the re-ordering window of a recording would. The batches, and so the tracks, are those
of the offline run.
"""

from __future__ import annotations

import base64
import itertools
import math
import resource
import threading
import time
import warnings
from collections import deque
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field, replace
from pathlib import Path

import cv2
import numpy as np

from ..eval import EVAL_WARMUP_S
from ..io import Recording
from ..pipeline import SystemParams, SystemRun, stack_for_recording
from ..tracking import TrackerOutput
from ._outputs import LiveOutputs, track_records
from ._page import LivePage
from ._resume import LiveFolder, live_key
from ._sources import PRESENTATION_KINDS, CameraSource, source_kind
from ._sync import FrameSynchroniser, LiveInstant

__all__ = ["LiveSettings", "LiveRun", "LiveSummary", "CLOCKS"]

#: ``"arrival"``: every frame stands for when it arrived (``time.monotonic``, one clock for all cameras);
#: ``"presentation"``: for the stream's own time stamp (MJPEG ``X-Timestamp``, a file's presentation time), for
#: cameras whose clocks are one (synchronised by NTP/PTP, or a recording played back); refused for RTSP streams
#: and devices (:data:`~planefuse.live.PRESENTATION_KINDS`).
CLOCKS = ("arrival", "presentation")


@dataclass(frozen=True)
class LiveSettings:
    """How a live run reads its cameras and what it serves and writes; the one place their defaults live.

    Attributes
    ----------
    cameras : mapping of str -> str or int
        Camera name (as in the recording holding the calibrations) -> its stream: ``rtsp://...``,
        ``http(s)://...`` MJPEG, a device index or ``/dev/videoN``, or a video file played at its own rate
        (:func:`planefuse.live.camera_reader`). Every camera of the recording needs one.
    clock : {"arrival", "presentation"}
        :data:`CLOCKS`.
    queue_frames : int
        Frames each camera's queue holds while the system is busy; beyond, the oldest are dropped (counted).
    sync_wait_s : float or None
        Longest wait [s] for the other cameras' frames of an instant after its first (None: one instant's period).
    stall_s : float
        A stream that gives no frame for this long [s] is reopened (and is unobserved meanwhile).
    retry_min_s, retry_max_s : float
        Back-off before reopening a failed stream [s]: from ``retry_min_s``, doubling, at most ``retry_max_s``.
    serve : bool
        Serve the live page.
    host : str
        Interface the page binds to: ``127.0.0.1`` (this machine only) unless another is asked for explicitly.
    port : int
        The page's TCP port (0: any free one).
    page_rate_hz : float
        States sent to the page per second at most (camera images are the heavy part).
    trail_s : float
        Length of the tracks' trails on the page [s].
    page_width_px : int
        Width of the camera images on the page [px].
    checkpoint_steps : int
        With an output folder, the tracker's state is saved every this many output steps (and at the end) for
        the next session to resume from (:class:`~planefuse.live.LiveFolder`; 50: 10 s at 5 Hz, a write of a
        few MB).
    """

    cameras: Mapping[str, str | int] = field(default_factory=dict)
    clock: str = "arrival"
    queue_frames: int = 2
    sync_wait_s: float | None = None
    stall_s: float = 2.0
    retry_min_s: float = 0.5
    retry_max_s: float = 8.0
    serve: bool = True
    host: str = "127.0.0.1"
    port: int = 8765
    page_rate_hz: float = 5.0
    trail_s: float = 5.0
    page_width_px: int = 320
    checkpoint_steps: int = 50

    def __post_init__(self) -> None:
        if self.clock not in CLOCKS:
            raise ValueError(f"LiveSettings.clock must be one of {CLOCKS}, got {self.clock!r}")
        for name in ("queue_frames", "page_width_px", "checkpoint_steps"):
            v = getattr(self, name)
            if not (isinstance(v, int) and v >= 1):
                raise ValueError(f"LiveSettings.{name} must be an integer >= 1, got {v!r}")
        if not (isinstance(self.port, int) and 0 <= self.port <= 65535):
            raise ValueError(f"LiveSettings.port must be an integer in 0..65535 (0: any free port), got {self.port!r}")
        for name in ("stall_s", "retry_min_s", "retry_max_s", "page_rate_hz", "trail_s"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v > 0):
                raise ValueError(f"LiveSettings.{name} must be finite and > 0, got {v!r}")
        if self.retry_max_s < self.retry_min_s:
            raise ValueError(f"LiveSettings.retry_max_s ({self.retry_max_s}) must be >= retry_min_s "
                             f"({self.retry_min_s})")
        if self.sync_wait_s is not None and not (math.isfinite(self.sync_wait_s) and self.sync_wait_s >= 0):
            raise ValueError(f"LiveSettings.sync_wait_s must be finite and >= 0 [s] or None, got {self.sync_wait_s!r}")


#: A live run keeps this many of the latest latencies, memory samples and events, so that a run of days stays
#: bounded (a few MiB; 20 000 instants are 67 min at 5 Hz).
KEPT = 20_000


def _kept() -> deque:
    return deque(maxlen=KEPT)


@dataclass
class LiveSummary:
    """What a live run did: per camera its counters, the outputs given and the latency of each (the latest
    :data:`KEPT` of each series)."""

    outputs: int = 0
    instants: int = 0
    interrupted: bool = False
    #: per instant: (its first output's emission [s, run clock], latency [s]: that emission less the arrival of
    #: the instant's last frame, whether the run had warmed up)
    latencies_s: deque = field(default_factory=_kept)
    #: per output step: the latency [s] of its newest instant (what its JSON line says), whether warmed up
    step_latencies_s: deque = field(default_factory=_kept)
    #: (run clock [s], resident set size [MiB]) sampled every output second
    rss_mib: deque = field(default_factory=_kept)
    health: list[dict] = field(default_factory=list)
    events: deque = field(default_factory=_kept)

    def latency_ms(self, q: float, warm: bool = True) -> float | None:
        """The ``q``-th percentile [ms] of the instants' latencies once warmed up (``warm=False``: all of them, the
        first instants' set-up included); None without such outputs."""
        lat = [v for _, v, w in self.latencies_s if w or not warm]
        return float(np.percentile(lat, q) * 1e3) if lat else None

    def step_latency_ms(self, q: float) -> float | None:
        """The ``q``-th percentile [ms] of the output steps' latencies (each its newest instant's) once warmed up."""
        lat = [v for v, w in self.step_latencies_s if w]
        return float(np.percentile(lat, q) * 1e3) if lat else None

    def as_dict(self) -> dict:
        return {"outputs": self.outputs, "instants": self.instants, "interrupted": self.interrupted,
                "latency_ms_p50": self.latency_ms(50), "latency_ms_p95": self.latency_ms(95),
                "latency_ms_max": self.latency_ms(100), "latency_ms_max_with_start": self.latency_ms(100, False),
                "step_latency_ms_p50": self.step_latency_ms(50), "step_latency_ms_p95": self.step_latency_ms(95),
                "cameras": self.health, "events": list(self.events), "rss_mib": list(self.rss_mib)}


def _rss_mib() -> float:
    """The process's resident set size now [MiB] (Linux /proc; the peak from getrusage elsewhere)."""
    try:
        with open("/proc/self/statm") as f:
            return int(f.read().split()[1]) * resource.getpagesize() / 2**20
    except OSError:
        return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024


class LiveRun:
    """The whole system on live cameras (module docstring).

    Parameters
    ----------
    rec : Recording
        The calibrations (cameras, planes, monitored area; each camera's empty-scene plate where it has one);
        its frames are not read. Lasers and binaural heads stay recording-only in this version: they are not
        fused live (announced).
    params : SystemParams
        What to run (the camera rate ``camera_params.max_rate_hz`` is the live instants' rate; None: every frame).
    settings : LiveSettings
    out_dir : path, optional
        Where ``tracks.csv``, ``tracks_mot.txt``, ``live_report.json`` and the checkpoint go: a folder holding a
        live run of the same configuration, recording and clock is resumed (:class:`~planefuse.live.LiveFolder`).
    jsonl : str or path, optional
        ``"-"`` (standard output) or a file for the tracks as JSON lines (appended to when the run resumes).
    resume, force : bool
        As ``planefuse run``'s ``--fresh`` (``resume=False``: start afresh) and ``--force`` treat the folder.
    config_key : str
        What identifies the configuration for resuming (:func:`planefuse.config.config_hash`; "": a hash of
        ``params``).
    on_event : callable, optional
        ``on_event(message)`` for every announcement (sources' states, warm-up, the end).
    on_output : callable, optional
        ``on_output(output, latency_s)`` for every output step.

    Raises
    ------
    ValueError
        A camera of the recording without a stream in ``settings.cameras``, or a stream for a camera the
        recording does not calibrate; ``clock: presentation`` with a stream that has no shared clock; the folder
        refused (another run's results, files planefuse did not write, another run writing there); the system's
        own refusals (:class:`~planefuse.pipeline.SystemRun`).
    """

    def __init__(self, rec: Recording, params: SystemParams, settings: LiveSettings, *,
                 out_dir: str | Path | None = None, jsonl: str | Path | None = None,
                 on_event: Callable[[str], None] | None = None,
                 on_output: Callable[[TrackerOutput, float], None] | None = None, resume: bool = True,
                 force: bool = False, config_key: str = "") -> None:
        names = [c.name for c in rec.cameras]
        if not names:
            raise ValueError("the recording calibrates no camera: a live run needs cameras")
        missing = [n for n in names if n not in settings.cameras]
        unknown = [n for n in settings.cameras if n not in names]
        if missing or unknown:
            raise ValueError(f"live cameras: the recording calibrates {names}; "
                             + (f"no stream given for {missing}" if missing else "")
                             + ("; " if missing and unknown else "")
                             + (f"streams given for unknown cameras {unknown}" if unknown else ""))
        if not params.cameras:
            raise ValueError("sensors.cameras.enabled is false: a live run fuses the cameras")
        if settings.clock == "presentation":
            unclocked = [n for n in names if source_kind(settings.cameras[n]) not in PRESENTATION_KINDS]
            if unclocked:
                raise ValueError(f"clock: presentation: cameras {unclocked} give no time stamps on a clock the cameras "
                                 "share (RTSP through OpenCV: RTP times from each connection's first frame; a "
                                 "device: none); use clock: arrival")
        self.start_s = time.monotonic()
        self.events: deque[str] = _kept()
        self._on_event = on_event
        dropped = [m for m, on, have in (("laser", params.laser, rec.lasers), ("sound", params.sound, rec.audio))
                   if on and have]
        params = replace(params, laser=False, sound=False)
        if dropped:
            self.announce(f"{' and '.join(dropped)}: recording-only in this version, not fused live")
        if params.stitch.enabled:  # the offline pass needs the whole run; live, its views would only pile up
            params = replace(params, stitch=replace(params.stitch, enabled=False))
            self.announce("models.detection.stitch: an offline pass after a recording's run, not run live "
                          "(the live tracks are the online tracker's)")
        self.rec, self.params, self.settings, self.names = rec, params, settings, names
        self.stack = stack_for_recording(rec, params)
        frame_s = 1.0 / max(rec.camera(n).rate_hz for n in names)
        self.sync = FrameSynchroniser(names, frame_s, params.camera_params.max_rate_hz, settings.queue_frames,
                                      settings.sync_wait_s, delivering=self._delivering, clock=self.clock,
                                      stamp="earliest" if settings.clock == "presentation" else "slot")
        self.sources = []
        for c, name in enumerate(names):
            cam = rec.camera(name).camera
            src = CameraSource(name, settings.cameras[name], cam.intrinsics.width_px, cam.intrinsics.height_px,
                               self._sink(c), self.clock, stall_s=settings.stall_s, retry_min_s=settings.retry_min_s,
                               retry_max_s=settings.retry_max_s, on_event=self._source_event)
            src.health = self.sync.health[c]
            self.sources.append(src)
        self.sync.finished = lambda: not any(s.running for s in self.sources)
        self.system = SystemRun(rec, params, self.stack, camera_frames=self._frames())
        self.resumed_at_step = 0
        self.tolerance_s = self.system.tracker.params.merge_tolerance_s
        self.folder = None
        if out_dir is not None:
            self.folder = LiveFolder(out_dir, live_key(rec, params, settings.clock, config_key), resume=resume,
                                     force=force, protected=rec.root)
        try:
            if self.folder is not None and self.folder.resumed:
                self._resume()
            self.outputs = LiveOutputs(out_dir, jsonl, person_radius_m=params.tracking.cluster.person_radius_m,
                                       append=self.folder is not None and self.folder.resumed)
        except BaseException:
            if self.folder is not None:
                self.folder.close()
            raise
        self.on_output = on_output
        self.page = LivePage(settings.host, settings.port) if settings.serve else None
        self.summary = LiveSummary(events=self.events)
        self._instant: LiveInstant | None = None
        self._latest: list = [None] * len(names)  # each camera's latest fused frame (the page's)
        self._last_output: TrackerOutput | None = None
        self._pending: deque[LiveInstant] = deque()  # instants pushed, not yet in an output
        self._trails: dict[int, deque] = {}
        self._last_page_s = -math.inf
        self._warm_until: float | None = None
        self._warm = False
        self._stop = threading.Event()
        self._lock = threading.Lock()

    def clock(self) -> float:
        """The run's clock [s]: ``time.monotonic()`` since the run was made (a resumed run's goes on from the previous
        session's, :class:`~planefuse.live.LiveFolder`)."""
        return time.monotonic() - self.start_s

    def _resume(self) -> None:
        """Continue the folder's previous session: its tracker's state restored (steps and identities moved on past
        every row written), the clock going on from its own (the time between the sessions unobserved: the first
        instant's prediction spans it), frames stamped before its last output refused."""
        folder, tracker = self.folder, self.system.tracker
        tracker.load_state_dict(folder.tracker_state(tracker.state_dict()))
        self.resumed_at_step = tracker.n_outputs
        self.start_s -= folder.clock_s
        last = [t for t in (tracker.bof.time_s, tracker.tracker.time_s) if t is not None]
        if last:
            self.sync.after_s = max(last)
        self.announce(f"resuming {folder.out_dir} at step {folder.next_step} (track identities from "
                      f"{tracker.tracker.state_dict()['next_id']}; run clock {folder.clock_s:.1f} s, the time since "
                      "the previous session unobserved)" + ("" if folder.checkpoint is not None else
                                                         "; no checkpoint: filter and tracks start afresh"))

    def announce(self, message: str) -> None:
        """Record ``message`` and pass it to ``on_event``."""
        self.events.append(f"{self.clock():8.2f} s  {message}")
        if self._on_event is not None:
            self._on_event(message)

    def _source_event(self, message: str) -> None:
        self.announce(message)
        self.sync.wake()

    def _delivering(self, c: int) -> bool:
        src = self.sources[c]
        # a camera still opening its stream for the first time is waited for (at most sync_wait_s an instant)
        return src.delivering or (src.health.state == "connecting" and src.health.received == 0)

    def _sink(self, c: int) -> Callable:
        presentation = self.settings.clock == "presentation"
        name = self.names[c]

        def sink(image: np.ndarray, arrival_s: float, presentation_s: float | None) -> None:
            if presentation:
                if presentation_s is None:
                    raise ValueError(f"camera {name!r}: its stream gives no presentation time (clock: presentation "
                                     "needs one; use clock: arrival)")
                stamp = presentation_s
            else:
                stamp = arrival_s
            self.sync.put(c, image, stamp, arrival_s)
        return sink

    def _frames(self):
        for inst in self.sync.instants():
            self._instant = inst
            for c, f in enumerate(inst.frames):
                if f is not None:
                    self._latest[c] = f
            yield inst.time_s, inst.images

    def stop(self) -> None:
        """End the run from another thread (as Ctrl-C does in the run's own): outputs are flushed."""
        self._stop.set()
        self.sync.close()

    def run(self, duration_s: float | None = None) -> LiveSummary:
        """Run until the sources end, ``duration_s`` [s] has passed, :meth:`stop` or Ctrl-C (KeyboardInterrupt,
        caught: the run ends cleanly); every output is written and flushed, the sources stopped, the summary
        returned (and written as ``live_report.json`` where there is an output folder)."""
        if self.page is not None:
            self.page.start()
            self.announce(f"live page on {self.page.url}")
        self._publish_idle("warming up")
        self.warm_up()
        self._publish_idle("waiting for the cameras")
        primed = all(self.rec.camera(n).has_background for n in self.names)
        self.announce("background models: primed with the empty-scene plates" if primed else
                      "background models: learning from the first frames")
        for s in self.sources:
            s.start()
        timer = None
        if duration_s is not None:
            timer = threading.Timer(duration_s, self.stop)
            timer.daemon = True
            timer.start()
        step = self.system.n_outputs
        try:
            with warnings.catch_warnings():
                # a camera without a frame at an instant is counted in its health, not warned about each time
                warnings.filterwarnings("ignore", message=r".*: (no frame|a black or frozen frame) at t=")
                for ev in self.system.evidence:
                    inst = self._instant
                    self._pending.append(inst)
                    self.summary.instants += 1
                    self._warming(inst)
                    until = self.sync.next_stamp_bound_s(inst.slot) - self.tolerance_s - 1e-9
                    for out in self.system.tracker.push(ev, until_s=until):
                        self._emit(step, out)
                        step += 1
                    if self._stop.is_set():
                        break
        except KeyboardInterrupt:
            self.summary.interrupted = True
            self.announce("interrupted (Ctrl-C): flushing the outputs")
        finally:
            if timer is not None:
                timer.cancel()
            for s in self.sources:  # all asked at once, then each waited for
                s.request_stop()
            for s in self.sources:
                s.stop(0.5)
            self.sync.close()
            try:
                for out in self.system.tracker.flush():
                    self._emit(step, out)
                    step += 1
                if self.folder is not None:  # what the next session continues from
                    self.folder.save_checkpoint(self.system.tracker.state_dict(), self.system.n_outputs, self.clock(),
                                                "interrupted" if self.summary.interrupted else "ended")
            finally:
                now = self.clock()
                self.summary.health = [s.health.as_dict(now) for s in self.sources]
                self.announce(f"ended: {self.summary.outputs} output steps from {self.summary.instants} instants; "
                              + ", ".join(f"{h['name']} dropped {h['dropped']}" for h in self.summary.health))
                self.outputs.close({**self.summary.as_dict(), "resumed_at_step": self.resumed_at_step})
                if self.folder is not None:
                    self.folder.close()
                self._publish_final()
        return self.summary

    def warm_up(self) -> float:
        """Run the system once on a few instants of blank frames (each camera's empty-scene plate, else grey) in
        a throw-away :class:`~planefuse.pipeline.SystemRun`, so that its compiled kernels (numba) are built before
        the first live frame, which would otherwise wait seconds; announce when ready. Returns the time it took
        [s]."""
        t = time.perf_counter()
        blank = []
        for n in self.names:
            s = self.rec.camera(n)
            cam = s.camera.intrinsics
            blank.append(s.background() if s.has_background else
                         np.full((cam.height_px, cam.width_px, 3), 128, np.uint8))
        period = self.sync.period_s
        frames = [(k * period, [b.copy() for b in blank]) for k in range(3)]
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            dry = SystemRun(self.rec, self.params, self.stack, camera_frames=iter(frames))
            for _ in dry.outputs():
                pass
        took = time.perf_counter() - t
        self.announce(f"system ready: compiled and run on blank frames in {took:.1f} s")
        return took

    def close(self) -> None:
        """Stop the live page (it keeps showing the last state after :meth:`run` until then); release the output
        folder where :meth:`run` did not."""
        if self.page is not None:
            self.page.stop()
        if self.folder is not None:
            self.folder.close()

    def _warming(self, inst: LiveInstant) -> None:
        if self._warm:
            return
        if self._warm_until is None:
            self._warm_until = inst.time_s + EVAL_WARMUP_S
        if inst.time_s >= self._warm_until - 1e-9:
            self._warm = True
            self.announce(f"warmed up: background models and filter have {EVAL_WARMUP_S:g} s of frames; tracks "
                          "from now on are the system's steady output")

    def _emit(self, step: int, out: TrackerOutput) -> None:
        now = self.clock()
        self._last_output = out
        # the output holds the evidence of every pushed instant stamped up to its time (and its merge tolerance):
        # each instant's latency is from its last frame's arrival to the first output holding it
        newest = None
        while self._pending and self._pending[0].time_s <= out.time_s + self.tolerance_s + 1e-9:
            newest = self._pending.popleft()
            self.summary.latencies_s.append((now, now - newest.arrival_s, self._warm))
        latency = None if newest is None else now - newest.arrival_s
        if latency is not None:
            self.summary.step_latencies_s.append((latency, self._warm))
        s = self.summary
        s.outputs += 1
        if not s.rss_mib or now - s.rss_mib[-1][0] >= 1.0:
            s.rss_mib.append((round(now, 3), round(_rss_mib(), 2)))
        self.outputs.write(step, out, latency)
        if self.folder is not None and (step + 1) % self.settings.checkpoint_steps == 0:
            # the tracker's state is complete while an output is handled
            self.folder.save_checkpoint(self.system.tracker.state_dict(), step + 1, now)
        if self.on_output is not None:
            self.on_output(out, latency)
        self._update_trails(out)
        if self.page is not None and now - self._last_page_s >= 1.0 / self.settings.page_rate_hz:
            self._last_page_s = now
            self.page.publish(self._state(out, now))

    def _update_trails(self, out: TrackerOutput) -> None:
        t = float(out.time_s)
        for i, xy in zip(out.tracks.ids, out.tracks.xy_m):
            self._trails.setdefault(int(i), deque()).append((t, float(xy[0]), float(xy[1])))
        for i in list(self._trails):
            trail = self._trails[i]
            while trail and trail[0][0] < t - self.settings.trail_s:
                trail.popleft()
            if not trail:
                del self._trails[i]

    def _recent_latency_ms(self, q: float) -> float | None:
        lat = [v for _, v, _ in itertools.islice(reversed(self.summary.latencies_s), 100)]
        return float(np.percentile(lat, q) * 1e3) if lat else None

    def _state(self, out: TrackerOutput | None, now: float) -> dict:
        """The page's state (JSON-ready)."""
        tracks = []
        if out is not None:
            for r in track_records(out):
                r["trail"] = [[round(x, 3), round(y, 3)] for _, x, y in self._trails.get(r["id"], ())]
                tracks.append(r)
        occ_png = None
        if out is not None:
            top = np.flipud(out.occupancy.max(axis=0))  # row 0 at the largest world Y (north up)
            img = np.clip(255.0 * (1.0 - top), 0, 255).astype(np.uint8)
            ok, buf = cv2.imencode(".png", cv2.applyColorMap(img, cv2.COLORMAP_BONE))
            occ_png = base64.b64encode(buf).decode() if ok else None
        # each camera's latest fused frame, with the step's detections and tracks
        cams = {n: None if f is None else self._camera_jpeg(c, f.image, out)
                for c, (n, f) in enumerate(zip(self.names, self._latest))}
        x0, x1, y0, y1 = self.stack.extent_m
        return {"time_s": 0.0 if out is None else float(out.time_s), "clock_s": round(now, 3),
                "status": "interrupted" if self.summary.interrupted else ("running" if not self._stop.is_set()
                                                                           else "ended"),
                "warm_up": "warmed up" if self._warm else "warming up",
                "extent_m": [x0, x1, y0, y1], "tracks": tracks,
                "detections": [] if out is None else [[round(float(x), 3), round(float(y), 3)]
                                                      for x, y in np.asarray(out.detections.xy_m).reshape(-1, 2)], "occupancy_png": occ_png, "cameras": cams,
                "health": [s.health.as_dict(now) for s in self.sources],
                "latency_ms_p50": self._recent_latency_ms(50), "latency_ms_p95": self._recent_latency_ms(95),
                "outputs": self.summary.outputs, "instants": self.summary.instants}

    def _camera_jpeg(self, c: int, image: np.ndarray, out: TrackerOutput | None) -> str | None:
        """Camera ``c``'s frame with the step's detections (white crosses at the feet) and tracks drawn (a line from
        the feet to 1.7 m, the identity), scaled to the page's width, as base64 JPEG."""
        cam = self.rec.cameras[c]
        img = image.copy()
        if out is not None and len(out.detections):  # the step's detections (the filter's clusters): white crosses
            xy = np.asarray(out.detections.xy_m, float).reshape(-1, 2)
            for p in cam.project(np.column_stack([xy, np.zeros(len(xy))])):
                if np.isfinite(p).all():
                    cv2.drawMarker(img, tuple(int(round(v)) for v in p), (255, 255, 255), cv2.MARKER_CROSS, 12, 2)
        if out is not None and len(out.tracks):
            xy = np.asarray(out.tracks.xy_m, float)
            feet = cam.project(np.column_stack([xy, np.zeros(len(xy))]))
            head = cam.project(np.column_stack([xy, np.full(len(xy), 1.7)]))
            for i, a, b in zip(out.tracks.ids, feet, head):
                if not (np.isfinite(a).all() and np.isfinite(b).all()):
                    continue
                colour = _COLOURS_BGR[int(i) % len(_COLOURS_BGR)]
                p, q = tuple(int(round(v)) for v in a), tuple(int(round(v)) for v in b)
                cv2.line(img, p, q, colour, 2)
                cv2.circle(img, p, 4, colour, -1)
                cv2.putText(img, str(int(i)), (q[0] + 4, q[1]), cv2.FONT_HERSHEY_SIMPLEX, 0.6, colour, 2)
        scale = self.settings.page_width_px / img.shape[1]
        if scale < 1:
            img = cv2.resize(img, (self.settings.page_width_px, int(round(img.shape[0] * scale))),
                             interpolation=cv2.INTER_AREA)
        ok, buf = cv2.imencode(".jpg", img, [cv2.IMWRITE_JPEG_QUALITY, 75])
        return base64.b64encode(buf).decode() if ok else None

    def _publish_idle(self, status: str) -> None:
        if self.page is not None:
            st = self._state(None, self.clock())
            st["status"] = status
            self.page.publish(st)

    def _publish_final(self) -> None:
        if self.page is None:
            return
        self._stop.set()
        self.page.publish(self._state(self._last_output, self.clock()))


#: Track colours on the camera images (BGR), the page's palette.
_COLOURS_BGR = [(75, 25, 230), (75, 180, 60), (216, 99, 67), (49, 130, 245), (180, 30, 145), (244, 212, 66),
                (230, 50, 240), (36, 99, 154), (153, 153, 70), (0, 0, 128)]
