"""Every modality of a recording turned into time-stamped :class:`~planefuse.grid.Evidence` on the plane stack.

Each sensor is an :class:`EvidenceSource`: its messages' time stamps, read cheaply from the recording, each
with the computation that turns it into evidence. :class:`MergedEvidence` interleaves the sources by time
stamp (what the Bayesian Occupancy Filter consumes, seed eq. 7: one product of sensor models per fused time
step) and computes a message only when it is taken, so it knows exactly how many messages each source has
given: a resumed run starts every source there (``start``) instead of recomputing the past.
"""

from __future__ import annotations

import heapq
import warnings
from collections.abc import Callable, Iterable, Iterator, Mapping
from dataclasses import dataclass, field
from functools import partial
from typing import TYPE_CHECKING

import numpy as np

from .._state import StateDict, get, pack_ragged, strings, unpack_ragged
from ..grid import Evidence, GroundDetections, PlaneStack
from ..io import Recording

if TYPE_CHECKING:
    from ..registration import CameraRegistration
    from ..vision import CameraReport

__all__ = ["DetectionLog", "EvidenceSource", "MergedEvidence", "ModalityReport", "camera_evidence", "camera_source",
           "laser_evidence", "laser_sources", "merged_evidence", "sound_evidence", "sound_sources"]


#: Laser scans whose points the report keeps for the figures: at first every ``LASER_POINTS_EVERY``-th, at most
#: ``LASER_POINTS_KEPT`` of them, evenly spaced over the run (:meth:`ModalityReport.keep_laser_points`).
LASER_POINTS_EVERY, LASER_POINTS_KEPT = 40, 64


class DetectionLog:
    """Every instant's :class:`~planefuse.grid.GroundDetections` of a run, kept as flat arrays.

    A run keeps the camera detector's own detections of every instant (the camera-only score, the per-frame
    rows of real-data experiments). One object per instant costs ~1 kB of Python and numpy headers; here an
    instant costs its time stamp, count and source index (20 bytes) and each detection its world XY [m],
    confidence and height [m] (32 bytes), in buffers that grow by doubling, so that a long run's memory and
    checkpoints grow by little more than the data. Values are stored exactly (float64).
    """

    def __init__(self, detections: Iterable[GroundDetections] = ()) -> None:
        self._n = self._n_det = 0
        self._times_s = np.zeros(64)
        self._counts = np.zeros(64, dtype=np.int64)
        self._source_index = np.zeros(64, dtype=np.int32)
        self._values = np.zeros((256, 4))  # x [m], y [m], confidence, height [m] per detection
        self._sources: list[str] = []
        for det in detections:
            self.append(det)

    def __len__(self) -> int:
        return self._n

    @property
    def times_s(self) -> np.ndarray:
        """Instants' time stamps [s], shape (T,) (a view: do not keep it across appends)."""
        return self._times_s[:self._n]

    def append(self, det: GroundDetections) -> None:
        """Add one instant's detections."""
        if self._n == len(self._times_s):
            size = 2 * self._n
            self._times_s = np.resize(self._times_s, size)
            self._counts = np.resize(self._counts, size)
            self._source_index = np.resize(self._source_index, size)
        k = len(det)
        if self._n_det + k > len(self._values):
            self._values = np.resize(self._values, (max(2 * len(self._values), self._n_det + k), 4))
        if det.source not in self._sources:
            self._sources.append(det.source)
        self._times_s[self._n] = det.time_s
        self._counts[self._n] = k
        self._source_index[self._n] = self._sources.index(det.source)
        v = self._values[self._n_det:self._n_det + k]
        v[:, :2], v[:, 2], v[:, 3] = det.xy_m, det.confidence, det.height_m
        self._n += 1
        self._n_det += k

    def __iter__(self) -> Iterator[GroundDetections]:
        """The instants in order, each a new :class:`~planefuse.grid.GroundDetections` (copies of the data)."""
        ends = np.cumsum(self._counts[:self._n])
        for i in range(self._n):
            v = self._values[ends[i] - self._counts[i]:ends[i]]
            yield GroundDetections(float(self._times_s[i]), v[:, :2].copy(), v[:, 2].copy(), v[:, 3].copy(),
                                   self._sources[self._source_index[i]])

    def state_dict(self) -> StateDict:
        """The log as arrays (see :mod:`planefuse._state`)."""
        n, v = self._n, self._values[:self._n_det]
        return {"camera_det_time_s": self._times_s[:n].copy(),
                "camera_det_source": strings([self._sources[i] for i in self._source_index[:n]]),
                "camera_det_count": self._counts[:n].copy(), "camera_det_xy_m": v[:, :2].copy(),
                "camera_det_confidence": v[:, 2].copy(), "camera_det_height_m": v[:, 3].copy()}

    @classmethod
    def from_state_dict(cls, state: Mapping[str, np.ndarray]) -> "DetectionLog":
        """Restore what :meth:`state_dict` saved."""
        def g(key):
            return get(state, key, "modality report")

        counts = g("camera_det_count")
        return cls(GroundDetections(float(t), xy, c, h, str(s)) for t, s, xy, c, h in zip(
            g("camera_det_time_s"), g("camera_det_source"), unpack_ragged(g("camera_det_xy_m"), counts),
            unpack_ragged(g("camera_det_confidence"), counts), unpack_ragged(g("camera_det_height_m"), counts)))


@dataclass
class ModalityReport:
    """What each modality produced and what it had to report (missing frames, invalid returns...)."""

    camera: "CameraReport | None" = None
    #: the camera detector's own detections of every instant (camera-only score, per-frame rows)
    camera_detections: DetectionLog = field(default_factory=DetectionLog)
    n_laser_scans: int = 0
    n_laser_invalid_beams: int = 0
    laser_points_world: list[np.ndarray] = field(default_factory=list)
    laser_points_times_s: list[float] = field(default_factory=list)
    #: every ``laser_points_stride``-th scan's points are kept (see :meth:`keep_laser_points`)
    laser_points_stride: int = LASER_POINTS_EVERY
    n_sound_blocks: int = 0
    sound_times_s: list[float] = field(default_factory=list)
    sound_map_azimuth_rad: list[float] = field(default_factory=list)
    sound_saliency: list[np.ndarray] = field(default_factory=list)
    sound_azimuth_grid_rad: np.ndarray | None = None
    T_world_head: np.ndarray | None = None
    #: The cameras' registration (attitude sources, stabilising map rebuilds per camera); rebuilt, not checkpointed,
    #: by a resumed run (which replays the attitudes of the instants it skips).
    camera_registration: "CameraRegistration | None" = None

    def __post_init__(self) -> None:
        if not isinstance(self.camera_detections, DetectionLog):  # any iterable of GroundDetections
            self.camera_detections = DetectionLog(self.camera_detections)

    def keep_laser_points(self, scan_index: int, time_s: float, points_world: np.ndarray) -> None:
        """Keep the points of laser scan ``scan_index`` (0-based, over all lasers) for the figures if it is on the
        current stride; past :data:`LASER_POINTS_KEPT` kept scans every other one is dropped and the stride
        doubles, so that the kept scans stay evenly spaced over the whole run and their memory bounded."""
        if scan_index % self.laser_points_stride:
            return
        self.laser_points_world.append(points_world)
        self.laser_points_times_s.append(float(time_s))
        if len(self.laser_points_world) > LASER_POINTS_KEPT:
            self.laser_points_world = self.laser_points_world[::2]
            self.laser_points_times_s = self.laser_points_times_s[::2]
            self.laser_points_stride *= 2

    @property
    def n_camera_frames(self) -> int:
        """Synchronised camera instants processed."""
        return self.camera.instants if self.camera is not None else 0

    @property
    def n_missing_camera_frames(self) -> int:
        """Frames missing at those instants, over all cameras (see ``camera.missing_frames``)."""
        return self.camera.n_missing if self.camera is not None else 0

    def state_dict(self) -> StateDict:
        """Everything reported so far, as arrays (see :mod:`planefuse._state`)."""
        pts, n_pts = pack_ragged(self.laser_points_world, (3,))
        cam = self.camera
        missing = [] if cam is None else [(n, t) for n, ts in cam.missing_frames.items() for t in ts]
        # the person boxes of camera instants computed but not yet written (a step's boxes are written with it)
        boxes = [] if cam is None else [(n, t, b) for n, items in cam.person_boxes.items() for t, b in items]
        sal = self.sound_saliency
        return {
            "has_camera": np.asarray(cam is not None),
            "camera_instants": np.asarray(0 if cam is None else cam.instants, dtype=np.int64),
            "camera_missing_name": strings([n for n, _ in missing]),
            "camera_missing_time_s": np.array([t for _, t in missing], dtype=float),
            "camera_blind": strings([] if cam is None else cam.blind_cameras),
            "camera_boxes_name": strings([n for n, _, _ in boxes]),
            "camera_boxes_time_s": np.array([t for _, t, _ in boxes], dtype=float),
            "camera_boxes_count": np.array([len(b) for _, _, b in boxes], dtype=np.int64),
            "camera_boxes_ltwh_px": np.concatenate([b.ltwh_px for _, _, b in boxes]).reshape(-1, 4) if boxes
            else np.zeros((0, 4)),
            "camera_boxes_score": np.concatenate([b.score for _, _, b in boxes]) if boxes else np.zeros(0),
            **self.camera_detections.state_dict(),
            "n_laser_scans": np.asarray(self.n_laser_scans, dtype=np.int64),
            "n_laser_invalid_beams": np.asarray(self.n_laser_invalid_beams, dtype=np.int64),
            "laser_points_count": n_pts, "laser_points_world": pts,
            "laser_points_times_s": np.array(self.laser_points_times_s, dtype=float),
            "laser_points_stride": np.asarray(self.laser_points_stride, dtype=np.int64),
            "n_sound_blocks": np.asarray(self.n_sound_blocks, dtype=np.int64),
            "sound_times_s": np.array(self.sound_times_s, dtype=float),
            "sound_map_azimuth_rad": np.array(self.sound_map_azimuth_rad, dtype=float),
            "sound_saliency": np.stack(sal) if sal else np.zeros((0, 0)),
            "sound_azimuth_grid_rad": (np.zeros(0) if self.sound_azimuth_grid_rad is None
                                       else np.asarray(self.sound_azimuth_grid_rad)),
            "T_world_head": np.zeros((0, 4)) if self.T_world_head is None else np.asarray(self.T_world_head),
        }

    def load_state_dict(self, state: Mapping[str, np.ndarray]) -> None:
        """Restore what :meth:`state_dict` saved."""
        from ..vision import CameraReport, PersonBoxes

        def g(key):
            return get(state, key, "modality report")

        self.camera = None
        if bool(g("has_camera")):
            missing: dict[str, list[float]] = {}
            for n, t in zip(g("camera_missing_name"), g("camera_missing_time_s")):
                missing.setdefault(str(n), []).append(float(t))
            self.camera = CameraReport(int(g("camera_instants")), missing, [str(n) for n in g("camera_blind")])
            ends = np.cumsum(g("camera_boxes_count"))
            ltwh, score = g("camera_boxes_ltwh_px"), g("camera_boxes_score")
            for n, t, a, b in zip(g("camera_boxes_name"), g("camera_boxes_time_s"), ends - g("camera_boxes_count"),
                                  ends):
                self.camera.person_boxes.setdefault(str(n), []).append(
                    (float(t), PersonBoxes(ltwh[a:b].reshape(-1, 4), score[a:b])))
        self.camera_detections = DetectionLog.from_state_dict(state)
        self.n_laser_scans = int(g("n_laser_scans"))
        self.n_laser_invalid_beams = int(g("n_laser_invalid_beams"))
        self.laser_points_world = unpack_ragged(g("laser_points_world"), g("laser_points_count"))
        self.laser_points_times_s = [float(t) for t in g("laser_points_times_s")]
        self.laser_points_stride = int(g("laser_points_stride"))
        self.n_sound_blocks = int(g("n_sound_blocks"))
        self.sound_times_s = [float(t) for t in g("sound_times_s")]
        self.sound_map_azimuth_rad = [float(a) for a in g("sound_map_azimuth_rad")]
        self.sound_saliency = list(g("sound_saliency"))
        grid, T = g("sound_azimuth_grid_rad"), g("T_world_head")
        self.sound_azimuth_grid_rad = grid if grid.size else None
        self.T_world_head = T if T.size else None


@dataclass
class EvidenceSource:
    """One sensor's messages in time order, each computed only when taken.

    Attributes
    ----------
    name : str
        Source name (unique in a run: ``"cameras"``, ``"laser:<name>"``, ``"sound:<name>"``).
    items : iterator of (float, callable)
        ``(time_s, compute)`` per message: the stamp [s] (cheap to read) and the function that computes the
        :class:`~planefuse.grid.Evidence` with that stamp. Messages must be computed in order.
    start : int
        Messages of the recording skipped at the start (a resumed run).
    """

    name: str
    items: Iterator[tuple[float, Callable[[], Evidence]]]
    start: int = 0

    def evidence(self) -> Iterator[Evidence]:
        """The messages, computed one after the other."""
        return (compute() for _, compute in self.items)


class MergedEvidence:
    """Interleave sources by time stamp (ties in source order), computing a message only when it is taken.

    Attributes
    ----------
    consumed : dict of str -> int
        Messages each source has given so far, counted from the start of the recording (skipped ones
        included): where a resumed run starts it.
    """

    def __init__(self, sources: Iterable[EvidenceSource]) -> None:
        self.sources = list(sources)
        names = [s.name for s in self.sources]
        if len(set(names)) != len(names):
            raise ValueError(f"evidence sources must have unique names, got {names}")
        self.consumed = {s.name: int(s.start) for s in self.sources}

    @property
    def n_computed(self) -> int:
        """Messages computed by this object (the skipped ones not counted)."""
        return sum(self.consumed.values()) - sum(int(s.start) for s in self.sources)

    def __iter__(self) -> Iterator[Evidence]:
        heap: list[tuple[float, int, Callable[[], Evidence]]] = []
        for i, src in enumerate(self.sources):
            self._advance(heap, i)
        while heap:
            t, i, compute = heapq.heappop(heap)
            src = self.sources[i]
            ev = compute()
            if ev.time_s != t:
                raise ValueError(f"source {src.name!r}: message announced at t={t!r} s was computed with "
                                 f"time_s={ev.time_s!r}")
            self.consumed[src.name] += 1
            yield ev
            self._advance(heap, i)

    def _advance(self, heap: list, i: int) -> None:
        item = next(self.sources[i].items, None)
        if item is not None:
            heapq.heappush(heap, (float(item[0]), i, item[1]))

    def state_dict(self) -> StateDict:
        """``source``: names, ``consumed``: messages given by each."""
        return {"source": strings(list(self.consumed)),
                "consumed": np.array(list(self.consumed.values()), dtype=np.int64)}


def consumed_from_state(state: Mapping[str, np.ndarray]) -> dict[str, int]:
    """Inverse of :meth:`MergedEvidence.state_dict`: source name -> messages already given."""
    return {str(n): int(c) for n, c in zip(get(state, "source", "sources"), get(state, "consumed", "sources"))}


def camera_source(rec: Recording, stack: PlaneStack, params, report: ModalityReport,
                  start: int = 0, client=None, occluder_boxes_m=None, correlation_s: float = 0.0,
                  tracked_xy: Callable[[float], np.ndarray] | None = None,
                  frame_tap: Callable[[float, list], None] | None = None) -> EvidenceSource:
    """All cameras' synchronised instants: background subtraction (primed with the empty-scene image where
    the stream has one), registration on every plane and multi-view fusion (planefuse.vision).

    With ``start > 0`` the first ``start`` instants are not computed, but their frames still update the
    background models (:func:`planefuse.vision.camera_detections` ``replay``), so that what follows is
    exactly what an uninterrupted run computes. With a dask ``client``, each camera's front end (decoding,
    dead frames, background subtraction) runs as a stream on the cluster's workers
    (:func:`planefuse.batch.remote_foregrounds`); the evidence is the same. ``occluder_boxes_m`` (B, 6) [m]:
    known static occluders, whose hidden cells each camera leaves unobserved
    (:class:`planefuse.registration.CameraRegistration`). ``correlation_s`` [s]: each camera's frames weighted by
    their share of the time since its previous live frame (:func:`planefuse.vision.camera_detections`); a resumed
    run takes each camera's last live frame before ``start`` from the restored report's missing frames.
    ``tracked_xy``: the people tracked so far, predicted to an instant [s] -> (N, 2) [m, world], asked when the
    instant is computed (the generative model's prior, :func:`planefuse.vision.camera_detections`).
    ``frame_tap(time_s, images)``: handed every instant's frames as read (one per camera, None where missing; the
    tracks' appearance, :class:`planefuse.tracking.AppearanceObserver`); not with cameras that follow their IMU
    (their frames are not in the calibrated view; warned, nothing handed) nor remote front ends (which then run in
    this process).
    """
    from ..registration import CameraRegistration
    from ..vision import CameraReport, camera_detections, camera_instants, recording_frames, subtraction_window

    cams = rec.cameras
    names = [c.name for c in cams]
    if report.camera is None:
        report.camera = CameraReport()
    replay = start if params.foreground is not None else 0
    stride, max_rate_hz = params.frame_stride, params.max_rate_hz
    all_times = camera_instants(rec, stride, max_rate_hz)
    times = all_times[start:]
    # each camera's last live frame before the first computed instant: the last instant it did not miss
    last_live_s = []
    for n in names:
        missed = set(report.camera.missing_frames.get(n, ()))
        last_live_s.append(next((float(t) for t in all_times[:start][::-1] if float(t) not in missed), None))

    def messages() -> Iterator[Evidence]:
        # cameras registered through their IMU: frames brought back to the calibrated view as they turn,
        # replayed through the instants a resumed run skips
        registration = CameraRegistration.from_recording(rec, stack, params.registration, occluder_boxes_m)
        lookups = registration.lookups_at(float(all_times[0]))
        # instants skipped without replay (replayed ones are stabilised as they come)
        registration.advance(all_times[1:start - replay])
        remote = client
        if remote is not None and registration.tracks:
            # stabilising a turning camera's frames needs its attitude track, which stays in this process
            warnings.warn(f"cameras {sorted(registration.tracks)} follow their IMU: their front ends run in this "
                          "process, not on the dask workers", stacklevel=2)
            remote = None
        tap = frame_tap
        if tap is not None and registration.tracks:
            warnings.warn(f"cameras {sorted(registration.tracks)} follow their IMU: the tracks' appearance is not "
                          "read from their frames", stacklevel=2)
            tap = None
        if remote is not None and tap is not None:
            warnings.warn("the tracks' appearance reads the cameras' frames: their front ends run in this process, "
                          "not on the dask workers", stacklevel=2)
            remote = None
        if remote is not None and params.foreground is not None and params.foreground.selective_update \
                and params.foreground.selective_source == "model":
            # the front ends keep each instant's people out of their background models: they need them at once
            warnings.warn("cameras' selective_update: their front ends run in this process, not on the dask "
                          "workers", stacklevel=2)
            remote = None
        if remote is not None:
            from ..batch import remote_foregrounds

            fgs = remote_foregrounds(remote, rec.root, names, params.foreground, times, start,
                                     quantise=params.sensor_model == "cell", stride=stride, max_rate_hz=max_rate_hz,
                                     windows=[subtraction_window(lk, params) for lk in lookups])
            instants = camera_detections((), lookups, stack, params, names=names, report=report.camera,
                                         registration=registration, foregrounds=fgs, correlation_s=correlation_s,
                                         last_live_s=last_live_s, tracked_xy=tracked_xy)
        else:
            # empty-scene calibration plates prime the background models (no ghosts of people already in view)
            backgrounds = [_background_or_none(rec.camera(n)) for n in names]
            frames = recording_frames(rec, start=start - replay, stride=stride, max_rate_hz=max_rate_hz)
            if tap is not None:
                frames = _tapped(frames, tap)
            instants = camera_detections(frames, lookups, stack, params, names=names, report=report.camera,
                                         backgrounds=backgrounds, replay=replay, registration=registration,
                                         correlation_s=correlation_s, last_live_s=last_live_s,
                                         tracked_xy=tracked_xy)
        report.camera_registration = registration
        for ev, det in instants:
            report.camera_detections.append(det)
            yield ev

    gen = messages()
    return EvidenceSource("cameras", ((float(t), partial(next, gen)) for t in times), start)


def _tapped(frames, tap: Callable[[float, list], None]):
    """``frames`` (time_s, images) as they are, each handed to ``tap`` first, with None for a camera's black or
    frozen frame (:func:`planefuse.vision.frame_is_dead`: a failed camera shows no one's colours)."""
    from ..vision import frame_is_dead

    previous: dict[int, np.ndarray] = {}
    for time_s, images in frames:
        live = []
        for c, img in enumerate(images):
            dead = img is not None and frame_is_dead(img, previous.get(c))
            if img is not None:
                previous[c] = img
            live.append(None if dead else img)
        tap(float(time_s), live)
        yield time_s, images


def _background_or_none(stream) -> np.ndarray | None:
    """The stream's empty-scene image, or None where it has none."""
    try:
        return stream.background()
    except ValueError:
        return None


def laser_sources(rec: Recording, stack: PlaneStack, model, report: ModalityReport,
                  start: Mapping[str, int] | None = None) -> list[EvidenceSource]:
    """One source per laser: every scan registered with free space on every plane (planefuse.laser).

    The recording format writes NaN for "no return within range"; such beams free space up to the
    maximum range (``scans_from_arrays(nan_is_no_return=True)``). ``start`` maps a source name to the
    scans to skip. A bounded, evenly spaced sample of the scans' points is kept in ``report`` for the figures
    (:meth:`ModalityReport.keep_laser_points`).
    """
    from ..laser import LaserRegistrar, scans_from_arrays, tilting_unit_from_device

    def register(registrar, scan) -> Evidence:
        reg = registrar.register(scan)
        report.keep_laser_points(report.n_laser_scans, scan.time_s, reg.points_world)
        report.n_laser_scans += 1
        report.n_laser_invalid_beams += reg.n_invalid
        return reg.evidence

    def items(ls, registrar, first: int):
        sc = registrar.unit.scanner
        for chunk in ls.chunks(start=first):
            for scan in scans_from_arrays(chunk.times_s, chunk.angles_rad, chunk.ranges_m, chunk.tilt_rad,
                                          ls.T_world_laser, sc.range_min_m, sc.range_max_m):
                yield scan.time_s, partial(register, registrar, scan)

    out = []
    for name in rec.lasers:
        ls = rec.laser(name)
        key = f"laser:{name}"
        first = int((start or {}).get(key, 0))
        registrar = LaserRegistrar(stack, tilting_unit_from_device(ls.model), model, sensor=name)
        out.append(EvidenceSource(key, items(ls, registrar, first), first))
    return out


def sound_sources(rec: Recording, stack: PlaneStack, report: ModalityReport, block_s: float = 0.5, model=None,
                  start: Mapping[str, int] | None = None) -> list[EvidenceSource]:
    """One source per binaural head: Bayesian localisation per block of ``block_s`` [s], registered as a
    wedge on every plane (planefuse.audio). A last block shorter than half a block is not used. ``start``
    maps a source name to the blocks to skip."""
    from ..audio import default_sensor_model, evidence_from_saliency, localize

    def compute(name, au, m, t, x) -> Evidence:
        loc = localize(x, float(au.fs_hz), m)
        report.n_sound_blocks += 1
        report.sound_times_s.append(t)
        report.sound_map_azimuth_rad.append(loc.map_azimuth_rad)
        report.sound_saliency.append(loc.saliency)
        report.sound_azimuth_grid_rad = loc.azimuth_rad
        report.T_world_head = au.T_world_head
        return evidence_from_saliency(loc.saliency, loc.azimuth_rad, au.T_world_head, stack, t, sensor=name)

    def items(name, au, m, n: int, first: int):
        for t0, x in au.blocks(n, start=first * n):
            if len(x) < n // 2:
                continue
            t = t0 + 0.5 * len(x) / au.fs_hz
            yield t, partial(compute, name, au, m, t, x)

    out = []
    for name in rec.audio:
        au = rec.binaural(name)
        m = model if model is not None else default_sensor_model(float(au.fs_hz))
        key = f"sound:{name}"
        first = int((start or {}).get(key, 0))
        out.append(EvidenceSource(key, items(name, au, m, int(round(block_s * au.fs_hz)), first), first))
    return out


def camera_evidence(rec: Recording, stack: PlaneStack, params, report: ModalityReport) -> Iterator[Evidence]:
    """The cameras' evidence (:func:`camera_source`) as one time-ordered stream."""
    return camera_source(rec, stack, params, report).evidence()


def laser_evidence(rec: Recording, stack: PlaneStack, model, report: ModalityReport) -> Iterator[Evidence]:
    """Every laser's evidence (:func:`laser_sources`) as one time-ordered stream."""
    return iter(MergedEvidence(laser_sources(rec, stack, model, report)))


def sound_evidence(rec: Recording, stack: PlaneStack, report: ModalityReport, block_s: float = 0.5,
                   model=None) -> Iterator[Evidence]:
    """Every binaural head's evidence (:func:`sound_sources`) as one time-ordered stream."""
    return iter(MergedEvidence(sound_sources(rec, stack, report, block_s, model)))


def merged_evidence(*streams: Iterable[Evidence]) -> Iterator[Evidence]:
    """Interleave time-ordered evidence streams by time stamp (each message computed before it is compared;
    :class:`MergedEvidence` computes them only when taken)."""
    return heapq.merge(*streams, key=lambda e: e.time_s)
