"""The cameras' evidence from frames that arrive (a live run), not read from a recording.

:func:`arriving_camera_source` is :func:`~planefuse.pipeline.camera_source` with the synchronised instants
given by the caller as they come (``planefuse.live`` forms them from network streams): the same front ends,
registration, fusion and detector, so a live run on the frames of a recording, at the recording's times,
computes exactly the evidence of the offline run. The instants' times are not known in advance: the source's
``items`` yield each one when the caller's iterable gives it, and block until then.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Callable, Iterable, Iterator, Sequence

import numpy as np

from ..grid import Evidence, PlaneStack
from ..io import Recording
from ._streams import EvidenceSource, ModalityReport, _background_or_none

__all__ = ["arriving_camera_source"]


def arriving_camera_source(rec: Recording, stack: PlaneStack, params, report: ModalityReport,
                           frames: Iterable[tuple[float, Sequence[np.ndarray | None]]], *,
                           occluder_boxes_m=None, correlation_s: float = 0.0,
                           tracked_xy: Callable[[float], np.ndarray] | None = None,
                           keep_detections: bool = False) -> EvidenceSource:
    """All cameras' instants as ``frames`` gives them: ``(time_s, images)`` per instant, ``images`` one per camera
    of ``rec`` in its order (``None``: the camera gave no frame for that instant, e.g. a stalled stream: it is
    unobserved there, its cells get no evidence from it, :func:`planefuse.vision.camera_detections`).

    ``rec`` gives the calibrations (and each camera's empty-scene plate, which primes its background model as in
    the offline run); its frames are not read. Cameras that follow an IMU are refused (their attitude is read
    from the recording's IMU log). ``keep_detections``: append every instant's camera detections to
    ``report.camera_detections`` (the offline run does; a long live run would grow without bound, so off by
    default; without it ``report.camera.person_boxes`` keeps each camera's latest boxes only).

    Raises
    ------
    ValueError
        A camera of ``rec`` follows its IMU.
    """
    from ..registration import CameraRegistration
    from ..vision import CameraReport, camera_detections

    names = [c.name for c in rec.cameras]
    if report.camera is None:
        report.camera = CameraReport()
    registration = CameraRegistration.from_recording(rec, stack, params.registration, occluder_boxes_m)
    if registration.tracks:
        raise ValueError(f"cameras {sorted(registration.tracks)} follow their IMU: a live run takes fixed cameras "
                         "only (sensors.cameras.attitude_source: calibration)")
    lookups = registration.lookups_at(0.0)
    backgrounds = [_background_or_none(rec.camera(n)) for n in names]
    pending: deque = deque()

    def taken() -> Iterator[tuple[float, Sequence[np.ndarray | None]]]:
        while True:  # one instant per computed message, put there by items() just before
            yield pending.popleft()

    instants = camera_detections(taken(), lookups, stack, params, names=names, report=report.camera,
                                 backgrounds=backgrounds, registration=registration, correlation_s=correlation_s,
                                 tracked_xy=tracked_xy)

    def compute() -> Evidence:
        ev, det = next(instants)
        if keep_detections:
            report.camera_detections.append(det)
        else:  # each camera's person boxes of its latest instant only (bounded over a long run)
            for items in report.camera.person_boxes.values():
                del items[:-1]
        return ev

    def items() -> Iterator[tuple[float, Callable[[], Evidence]]]:
        for time_s, images in frames:
            pending.append((float(time_s), list(images)))
            yield float(time_s), compute

    report.camera_registration = registration
    return EvidenceSource("cameras", items(), 0)
