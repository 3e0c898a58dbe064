"""Cameras end to end: frames -> foreground -> per-plane evidence -> people on the ground."""

from __future__ import annotations

import warnings
from dataclasses import dataclass, field
from typing import Callable, Iterable, Iterator, Literal, Sequence

import cv2
import numpy as np

from .._params import check_fields
from ..geometry import H_plane_image_calibrated, PinholeCamera
from ..grid import Evidence, GroundDetections, PlaneStack
from ..occupancy import PersonVolume, silhouettes_from_cameras
from ..registration import CameraRegistration, ImagePlaneLookup, RegistrationParams
from ._boxes import BoxEvidenceParams, box_evidence, combine_box_evidence
from ._foreground import BackgroundSubtractor, ForegroundParams
from ._fusion import NEUTRAL_FOREGROUND, NEUTRAL_LEVEL, CameraFusion, FusionParams, max_log_ratio, quantise_foreground
from ._generative import GenerativeCameraSensor, GenerativeSensorParams
from ._persons import PersonParams, ground_detections_from_log_odds

__all__ = ["CameraFrontEnd", "CameraParams", "CameraReport", "camera_detections", "camera_foregrounds",
           "frame_is_dead", "lookups_from_cameras", "subtraction_window"]

#: A frame whose mean grey level is at most this is black (a camera that lost its signal).
DEAD_FRAME_MAX_MEAN = 8.0


def frame_is_dead(image: np.ndarray, previous: np.ndarray | None) -> bool:
    """True for a frame a failed camera delivers: black (mean level <= ``DEAD_FRAME_MAX_MEAN``) or frozen
    (bit-identical to the camera's previous frame, which sensor noise makes impossible for a live camera)."""
    # the exact integer sum of the levels (OpenCV, per channel) against the mean's bound: np.mean's decision
    # without its float64 copy of the frame
    if sum(cv2.sumElems(image)) <= DEAD_FRAME_MAX_MEAN * image.size:
        return True
    # a live frame differs from the previous one within its first row almost always: the whole frame is compared
    # only where that row is the same
    return previous is not None and previous.shape == image.shape and np.array_equal(image[:1], previous[:1]) \
        and np.array_equal(image, previous)


def lookups_from_cameras(cameras: Sequence[PinholeCamera], stack: PlaneStack,
                         route: str = "camera",
                         ignore_masks: Sequence[np.ndarray | None] | None = None) -> list[ImagePlaneLookup]:
    """One image -> plane-stack lookup per calibrated camera.

    Parameters
    ----------
    cameras : sequence of PinholeCamera
    stack : PlaneStack
    route : {"camera", "projection", "imu"}
        ``"camera"``: project every cell centre through the full camera model
        (lens distortion included; for raw frames). ``"projection"`` / ``"imu"``:
        per-plane homographies from the projection matrix (Khan & Shah) or from
        the IMU attitude (seed eq. 1); these ignore lens distortion, so frames
        must be undistorted first. Planes at or above a camera raise
        ``ValueError``.
    ignore_masks : sequence of (ndarray (height_px, width_px) bool or None), optional
        Per camera, pixels that are not scene evidence: the cells they see are unobserved by that camera
        (:meth:`ImagePlaneLookup.without_pixels`), so its sensor model gives them no evidence either way.

    Returns
    -------
    list of ImagePlaneLookup
    """
    if route not in ("camera", "projection", "imu"):
        raise ValueError(f"route must be 'camera', 'projection' or 'imu', got {route!r}")
    if ignore_masks is not None and len(ignore_masks) != len(cameras):
        raise ValueError(f"ignore_masks: expected {len(cameras)} entries (None where absent), got {len(ignore_masks)}")
    out = []
    for c, cam in enumerate(cameras):
        if route == "camera":
            lk = ImagePlaneLookup.from_camera(cam, stack)
        else:
            H_image_plane = np.stack([np.linalg.inv(H_plane_image_calibrated(cam, h, route=route))
                                      for h in stack.heights_m])
            lk = ImagePlaneLookup.from_homographies(H_image_plane, cam.intrinsics.width_px,
                                                    cam.intrinsics.height_px, stack)
        if ignore_masks is not None and ignore_masks[c] is not None:
            lk = lk.without_pixels(ignore_masks[c])
        out.append(lk)
    return out


@dataclass(frozen=True)
class CameraParams:
    """Everything the camera pipeline needs besides geometry.

    Attributes
    ----------
    foreground : ForegroundParams or None
        Background subtraction applied to every frame; ``None`` when the frames
        already are foreground likelihoods (masks, rendered boxes).
    fusion : FusionParams
        Multi-view sensor model.
    person : PersonParams
        Multi-plane person model and peak extraction.
    registration : RegistrationParams
        Where each camera's attitude comes from (calibration or IMU) when registering a recording.
    sensor_model : {"cell", "generative"}
        The cameras' evidence on the stack: ``"cell"`` scores every cell of every plane on its own
        (``fusion``, ``person``); ``"generative"`` explains each whole foreground image by people standing on
        the grid's cells (``generative``; Fleuret et al. 2008, docs/cameras.md).
    generative : GenerativeSensorParams
        The generative model's parameters (used when ``sensor_model == "generative"``).
    boxes : BoxEvidenceParams
        The person detector's boxes (``foreground.person_detector``) as evidence on every plane, added to the sensor
        model's (:func:`planefuse.vision.box_evidence`): free space where a camera sees the ground outside every box
        (``free_log_odds``; YOLOX's default -3), and each box's foot point with its body up to the head
        (``log_odds``; YOLOX's default 1). docs/detector.md.
    frame_stride : int
        Process every ``frame_stride``-th synchronised camera instant of a recording, from the first
        (:func:`planefuse.vision.camera_instants`); the others are not read. 1 = every frame. The background
        models learn from the processed frames only (``ForegroundParams.history`` counts those), and the filter
        weighs each camera message by the time since the previous one (``SystemParams.camera_correlation_s``),
        so the cameras' total weight per second does not change. Roughly divides the cameras' share of a run's
        CPU time (decoding, background subtraction, fusion, person extraction) by ``frame_stride``.
    max_rate_hz : float or None
        Process at most this many camera instants per second [Hz] (:func:`planefuse.vision.camera_instants`: the
        first instant at or after each multiple of ``1 / max_rate_hz``); the others are not read, as with
        ``frame_stride`` but in time rather than frames, so one value serves recordings of any frame rate (EPFL
        terrace, 25 Hz video: 5 Hz, the rate its configuration was chosen at). None: every instant. Default 5 Hz,
        the default output rate (``SystemParams.output_period_s`` 0.2 s): one camera instant per output step, which
        halves the default run's CPU time (docs/benchmarks.md) and is level or ahead of every instant on the
        simulated tuning scenes (docs/results.md, "Cameras at 5 Hz").
    """

    foreground: ForegroundParams | None = field(default_factory=ForegroundParams)
    fusion: FusionParams = field(default_factory=FusionParams)
    person: PersonParams = field(default_factory=PersonParams)
    registration: RegistrationParams = field(default_factory=RegistrationParams)
    sensor_model: Literal["cell", "generative"] = "cell"
    generative: GenerativeSensorParams = field(default_factory=GenerativeSensorParams)
    boxes: BoxEvidenceParams = field(default_factory=BoxEvidenceParams)
    frame_stride: int = 1
    max_rate_hz: float | None = 5.0

    def __post_init__(self) -> None:
        if self.sensor_model not in ("cell", "generative"):
            raise ValueError(f"CameraParams.sensor_model must be 'cell' or 'generative', got {self.sensor_model!r}")
        check_fields(self, frame_stride="int>=1", max_rate_hz="?>0")


@dataclass
class CameraReport:
    """What happened to the inputs of :func:`camera_detections` (filled while iterating).

    Attributes
    ----------
    instants : int
        Instants processed.
    missing_frames : dict
        Camera name -> list of ``time_s`` at which it had no frame (the other
        cameras were fused without it).
    blind_cameras : list of str
        Cameras that see no cell of the stack.
    person_boxes : dict
        Camera name -> list of ``(time_s, PersonBoxes)``: the person detector's boxes at each processed instant
        (``ForegroundParams.person_detector``; empty without one).
    """

    instants: int = 0
    missing_frames: dict[str, list[float]] = field(default_factory=dict)
    blind_cameras: list[str] = field(default_factory=list)
    person_boxes: dict[str, list] = field(default_factory=dict)

    @property
    def n_missing(self) -> int:
        """Total number of missing frames over all cameras."""
        return sum(len(v) for v in self.missing_frames.values())


#: Per camera and instant, what the front end made of the frame: a foreground likelihood, no frame, or a frame
#: a failed camera delivered (black or frozen).
OK, NO_FRAME, DEAD_FRAME = "ok", "no frame", "a black or frozen frame"


class CameraFrontEnd:
    """One camera's front end, frame after frame: dead-frame check and background subtraction.

    Stateful (the previous frame, the background model): feed it every frame of one camera in time order. It
    runs wherever the frames are (this process, or a dask worker per camera: ``planefuse run --workers``) and
    gives the same foregrounds anywhere (the background model's random draws are seeded per frame).

    Parameters
    ----------
    width_px, height_px : int
        The camera's image size.
    foreground : ForegroundParams or None
        Background subtraction; None when the frames already are foreground likelihoods (then passed through).
    name : str
    background : ndarray, optional
        Empty-scene image priming the background model.
    quantise : bool
        Give foregrounds as uint8 ``0..255`` (what :class:`CameraFusion` quantises them to; a quarter of the
        bytes to send from a worker, and no float image at all where the subtractor has no blur or resize)
        instead of float32. :func:`camera_detections` quantises for the per-cell sensor model.
    window : (row0, row1, col0, col1) or None
        Subtract the background in these rows and columns of the image only [px, half-open]
        (:func:`subtraction_window`: the part the per-cell fusion reads, with the cleaning's reach); the
        foreground elsewhere is the neutral likelihood (unobserved). None: the whole image.
    """

    def __init__(self, width_px: int, height_px: int, foreground: ForegroundParams | None, name: str,
                 background: np.ndarray | None = None, quantise: bool = False,
                 window: tuple[int, int, int, int] | None = None) -> None:
        self.name, self.quantise = name, bool(quantise)
        self.width_px, self.height_px = int(width_px), int(height_px)
        self.window = None if foreground is None or window is None else _checked_window(window, width_px, height_px)
        if self.window is not None:
            r0, r1, c0, c1 = self.window
            self._crop = (slice(r0, r1), slice(c0, c1))
            width_px, height_px = c1 - c0, r1 - r0
            if background is not None:
                background = self._cropped(background, "background")
        self.subtractor = None if foreground is None else BackgroundSubtractor(width_px, height_px, foreground, name)
        if self.subtractor is not None and background is not None:
            self.subtractor.prime(background)
        self._previous: np.ndarray | None = None

    def _cropped(self, img: np.ndarray, what: str = "frame") -> np.ndarray:
        """``img`` inside :attr:`window`, after checking that it has the camera's size."""
        if np.shape(img)[:2] != (self.height_px, self.width_px):
            raise ValueError(f"{self.name}: {what} must be {self.height_px}x{self.width_px} (rows x cols) as in the "
                             f"camera's calibration, got shape {np.shape(img)}")
        return img[self._crop]

    def check(self, img: np.ndarray | None) -> str:
        """The frame's status (:data:`OK`, :data:`NO_FRAME` or :data:`DEAD_FRAME`); call once per frame, in time
        order (a frozen frame is one bit-identical to the previous one)."""
        if img is None:
            return NO_FRAME
        if self.subtractor is None:
            return OK
        dead = frame_is_dead(img, self._previous)
        self._previous = img
        return DEAD_FRAME if dead else OK

    def learn(self, img: np.ndarray) -> None:
        """Update the background model with a checked frame only (an instant a resumed run skips)."""
        if self.subtractor is not None:
            self.subtractor.update(img if self.window is None else self._cropped(img))

    def foreground(self, img: np.ndarray) -> np.ndarray:
        """The foreground likelihood of a checked frame (float32 in [0, 1], or uint8 when quantising)."""
        if self.subtractor is None:
            fg = img
        elif self.window is None:
            fg = self.subtractor.apply(img, quantised=self.quantise)
        else:
            inside = self.subtractor.apply(self._cropped(img), quantised=self.quantise)
            neutral = NEUTRAL_LEVEL if inside.dtype == np.uint8 else NEUTRAL_FOREGROUND
            fg = np.full((self.height_px, self.width_px), neutral, inside.dtype)
            fg[self._crop] = inside
        if self.quantise and fg.dtype != np.uint8:
            fg = quantise_foreground(fg)
        return fg

    @property
    def last_boxes(self):
        """The person detector's boxes in the last frame given to :meth:`foreground` (frame pixels), or None
        without a detector (:attr:`ForegroundParams.person_detector`)."""
        return None if self.subtractor is None else self.subtractor.person_boxes

    def protect(self, people: np.ndarray) -> None:
        """Keep the pixels ``people`` (height_px, width_px) bool out of the background model at the next frame
        (:meth:`BackgroundSubtractor.protect`, ``ForegroundParams.selective_update``)."""
        if self.subtractor is not None:
            self.subtractor.protect(people)

    def replay(self, img: np.ndarray | None) -> None:
        """Check ``img`` and, if it is a live frame, only learn from it (an instant a resumed run skips)."""
        if self.check(img) == OK:
            self.learn(img)

    def process(self, img: np.ndarray | None) -> tuple[np.ndarray | None, str, object]:
        """``(foreground, status, boxes)``: status :data:`OK` with :meth:`foreground` and :attr:`last_boxes`, else
        :data:`NO_FRAME` / :data:`DEAD_FRAME` with None and None."""
        status = self.check(img)
        if status != OK:
            return None, status, None
        return self.foreground(img), status, self.last_boxes


def _checked_window(window, width_px: int, height_px: int) -> tuple[int, int, int, int]:
    r0, r1, c0, c1 = (int(v) for v in window)
    if not (0 <= r0 < r1 <= height_px and 0 <= c0 < c1 <= width_px):
        raise ValueError(f"window (row0, row1, col0, col1) = {tuple(window)} px must lie in the "
                         f"{height_px}x{width_px} image and hold at least one pixel")
    return r0, r1, c0, c1


def subtraction_window(lookup: ImagePlaneLookup, camera: CameraParams) -> tuple[int, int, int, int] | None:
    """The rows and columns ``(row0, row1, col0, col1)`` [px, half-open] of a camera's image that its background
    subtraction must cover (:class:`CameraFrontEnd` ``window``), or None for the whole image.

    The per-cell fusion reads one pixel per cell (``lookup``); a pixel's foreground depends on its own history
    and, through the cleaning (opening, closing, blur, the reduced resolution), on the pixels within its reach.
    The window is the bounding box of the pixels read, grown by that reach (at reduced resolution, on the whole
    image's grid of model pixels). None where the subtraction uses the whole image: the generative sensor model
    (it reads whole silhouettes), a person detector, gain compensation, the relearning share of foreground pixels,
    or the selective update (the people's silhouettes); without background subtraction; where no pixel is read.
    Inside the window the foreground is what the whole image gives, but for OpenCV KNN's random update phases,
    drawn per pixel in image order.
    """
    params = camera.foreground
    if camera.sensor_model != "cell" or params is None or params.person_detector is not None \
            or params.gain_compensation or params.relearn_fraction is not None or params.selective_update:
        return None
    idx = lookup.pixel_index[lookup.visible]
    if idx.size == 0:
        return None
    w, h, d = lookup.width_px, lookup.height_px, params.downscale
    rows, cols = idx // w, idx % w
    # the cleaning's reach [px]: opening and closing (each an erosion and a dilation) at the model's resolution,
    # the resize back, the blur; one more model pixel for the rounding of the reduced size
    side_open, side_close = int(params.open_px / d + 0.5), int(params.close_px / d + 0.5)
    reach = d * (2 * (side_open // 2) + 2 * (side_close // 2) + 2) + params.blur_px // 2 + 1

    def span(lo: int, hi: int, n: int) -> tuple[int, int]:
        # on the whole image's grid of d x d model pixels: a start and a length that are multiples of d
        a = max(lo - reach, 0)
        a -= a % d
        b = min(hi + reach + 1, n)
        return a, min(a + -(-(b - a) // d) * d, n)

    return span(int(rows.min()), int(rows.max()), h) + span(int(cols.min()), int(cols.max()), w)


def camera_foregrounds(frames: Iterable[tuple[float, Sequence[np.ndarray | None]]],
                       front_ends: Sequence[CameraFrontEnd], replay: int = 0,
                       registration: CameraRegistration | None = None,
                       ) -> Iterator[tuple[float, list[np.ndarray | None], list[str], list]]:
    """The front ends of all cameras, in this process: ``(time_s, foregrounds, statuses, boxes)`` per instant of
    ``frames`` after the first ``replay`` (which only update the background models); ``boxes`` holds each camera's
    person boxes (:attr:`CameraFrontEnd.last_boxes`; None without a frame or a person detector).

    With ``registration``, every live frame (replayed ones included) is first brought back to its camera's
    calibrated view (:meth:`CameraRegistration.stabilise`); black or frozen frames are told from the raw frames.
    The pixels of the calibrated view a turned camera does not see (:meth:`CameraRegistration.unseen`) get the
    foreground likelihood :data:`NEUTRAL_FOREGROUND`: unobserved, no evidence either way.
    """
    n = len(front_ends)
    for i, (time_s, images) in enumerate(frames):
        images = list(images)
        if len(images) != n:
            raise ValueError(f"instant t={time_s}: expected {n} images (None for missing), got {len(images)}")
        status = [fe.check(img) for fe, img in zip(front_ends, images)]
        if registration is not None:  # cameras that turned: their images back in the calibrated view
            images = registration.stabilise([img if s == OK else None for img, s in zip(images, status)], time_s)
        if i < replay:
            for fe, img, s in zip(front_ends, images, status):
                if s == OK:
                    fe.learn(img)
            continue
        fgs = [fe.foreground(img) if s == OK else None for fe, img, s in zip(front_ends, images, status)]
        boxes = [fe.last_boxes if s == OK else None for fe, s in zip(front_ends, status)]
        if registration is not None:
            for c, fg in enumerate(fgs):
                unseen = registration.unseen(c) if fg is not None else None
                if unseen is not None:
                    fgs[c] = fg = fg.copy()
                    fg[unseen] = NEUTRAL_LEVEL if fg.dtype == np.uint8 else NEUTRAL_FOREGROUND
        yield time_s, fgs, status, boxes


def camera_detections(
    frames: Iterable[tuple[float, Sequence[np.ndarray | None]]],
    lookups: Sequence[ImagePlaneLookup],
    stack: PlaneStack,
    params: CameraParams = CameraParams(),
    *,
    names: Sequence[str] | None = None,
    report: CameraReport | None = None,
    backgrounds: Sequence[np.ndarray | None] | None = None,
    replay: int = 0,
    registration: CameraRegistration | None = None,
    cameras: Sequence[PinholeCamera] | None = None,
    ignore_masks: Sequence[np.ndarray | None] | None = None,
    foregrounds: Iterable[tuple[float, Sequence[np.ndarray | None], Sequence[str]]] | None = None,
    correlation_s: float = 0.0,
    last_live_s: Sequence[float | None] | None = None,
    tracked_xy: Callable[[float], np.ndarray] | None = None,
) -> Iterator[tuple[Evidence, GroundDetections]]:
    """Run the camera pipeline over a synchronised recording.

    Parameters
    ----------
    frames : iterable of (time_s, images)
        ``images`` holds one entry per camera (same order as ``lookups``): a
        frame (uint8 grey/BGR) when ``params.foreground`` is set, otherwise a
        foreground likelihood (float in [0, 1] or uint8 0..255); ``None`` marks
        a missing frame (warned, recorded in ``report``, the other cameras still
        fuse that instant).
    lookups : sequence of ImagePlaneLookup
        One per camera (see :func:`lookups_from_cameras`).
    stack : PlaneStack
    params : CameraParams
    names : sequence of str, optional
        Camera names (``cam0``...).
    report : CameraReport, optional
        Filled with counts of missing frames and blind cameras.
    backgrounds : sequence of (ndarray or None), optional
        One empty-scene image per camera (``None`` where a camera has none) that
        primes its background model (:meth:`BackgroundSubtractor.prime`); ignored
        without ``params.foreground``.
    replay : int
        The first ``replay`` instants only update the background models: nothing is registered, fused,
        yielded or reported for them. A run resumed after ``replay`` instants gets the exact background
        models (OpenCV cannot save them) and so the exact outputs of an uninterrupted run.
    registration : CameraRegistration, optional
        Cameras that follow their attitude: at every instant (replayed ones included) their images are
        brought back to the calibrated view (:meth:`CameraRegistration.stabilise`) before anything else
        (``lookups`` must be its lookups).
    cameras : sequence of PinholeCamera, optional
        The calibrated cameras (same order as ``lookups``); needed by ``params.sensor_model == "generative"``
        (taken from ``registration`` when given).
    ignore_masks : sequence of (bool ndarray or None), optional
        Per camera, pixels that are not scene evidence, for the generative model (taken from ``registration``
        when given; the per-cell model has them in its lookups).
    foregrounds : iterable of (time_s, foregrounds, statuses, boxes), optional
        The cameras' front ends computed elsewhere (per-camera streams on dask workers: ``planefuse.batch.
        remote_foregrounds``): per instant, each camera's :meth:`CameraFrontEnd.process`. ``frames``,
        ``backgrounds`` and ``replay`` are then not used. Not with ``params.foreground.selective_update``, whose
        front ends take each instant's people back from this process.
    correlation_s : float
        Correlation time ``tau`` [s] >= 0 of each camera's errors (per-cell sensor model only): camera ``c``'s
        log-likelihood ratios at an instant ``t`` are weighted by ``w_c = min(1, (t - t_c) / tau)``, ``t_c`` the
        time of its previous live frame (:mod:`planefuse.tracking._async`, "Temporally correlated sensor
        errors", applied per camera): a camera's frame counts its share of the time since *its* previous one,
        so one back from a dropout (black, frozen, frames lost) counts as a fresh observation, and a camera's
        silence does not change the others' weights. 0: every frame counts fully. The detections are computed
        from the unweighted evidence.
    last_live_s : sequence of (float or None), optional
        Per camera, the time [s] of its last live frame before the first instant of ``frames`` (a resumed run;
        None: none yet, its next frame counts fully).
    tracked_xy : callable, optional
        ``tracked_xy(time_s)`` -> (N, 2) [m, world]: the people tracked so far, predicted to the instant, asked
        for every computed instant. With the generative sensor model and ``params.generative.track_prior_ratio``
        > 1 they are its location prior (:meth:`GenerativeCameraSensor.location_prior`); the evidence is then
        measured against that prior and the detections are the prior's too. Not used otherwise.

    Yields
    ------
    (Evidence, GroundDetections)
        Per-plane fused log-odds ``(L, ny, nx)`` (sensor ``"cameras"``) and the
        people found on the ground, both stamped ``time_s``.

    Notes
    -----
    With ``params.foreground.selective_update`` the people found at an instant are fed back to the front ends:
    their silhouettes in each camera (the generative model's person volume, ``params.generative``, projected
    from ``cameras``) are kept out of the background models at the next frame. Replayed instants are then
    computed in full (not yielded), so that a resumed run still gets the exact background models.

    Raises
    ------
    ValueError
        A frame whose size differs from its camera's calibration, or an instant
        with the wrong number of images.
    """
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        fusion = CameraFusion(lookups, stack, params.fusion, names)
    for w in caught:
        warnings.warn(w.message, stacklevel=2)
    generative = None
    if registration is not None:
        cameras, ignore_masks = registration.cameras, registration.ignore_masks
    # the camera model's people fed back to the front ends (a detector's boxes stay inside each front end)
    selective = params.foreground is not None and params.foreground.selective_update and \
        params.foreground.selective_source == "model"
    if selective and (cameras is None or foregrounds is not None):
        raise ValueError("foreground selective_update needs the calibrated cameras (cameras= or registration=) and "
                         "the front ends in this process (not foregrounds=)")
    if params.sensor_model == "generative":
        if cameras is None:
            raise ValueError("sensor_model 'generative' needs the calibrated cameras (cameras= or registration=)")
        generative = GenerativeCameraSensor(cameras, stack, params.generative, ignore_masks, fusion.names)
    if report is not None:
        report.blind_cameras = list(fusion.blind_cameras)
    if foregrounds is None:
        if backgrounds is not None and params.foreground is not None and len(backgrounds) != fusion.n_cameras:
            raise ValueError(f"backgrounds: expected {fusion.n_cameras} images (None where absent), "
                             f"got {len(backgrounds)}")
        bgs = backgrounds if backgrounds is not None and params.foreground is not None else [None] * fusion.n_cameras
        # the per-cell fusion reads 256 levels (the front ends give them: no float image in between) at its lookups'
        # pixels only (each subtractor covers those: its window)
        front_ends = [CameraFrontEnd(lk.width_px, lk.height_px, params.foreground, name, bg,
                                     quantise=generative is None,
                                     window=subtraction_window(lk, params))
                      for lk, name, bg in zip(lookups, fusion.names, bgs)]
        foregrounds = camera_foregrounds(frames, front_ends, 0 if selective else replay, registration)
        person = params.generative.person(stack)
    track_prior = tracked_xy is not None and generative is not None and params.generative.track_prior_ratio != 1.0
    if selective and replay and track_prior:
        raise ValueError("a resumed run cannot replay selective_update's people with the tracks' prior "
                         "(generative_track_prior_ratio > 1): the tracks of the replayed instants are not kept")
    if correlation_s < 0 or not np.isfinite(correlation_s):
        raise ValueError(f"correlation_s must be finite and >= 0 s, got {correlation_s}")
    if correlation_s > 0 and generative is not None:
        raise ValueError("correlation_s weights each camera of the per-cell sensor model; the generative model's "
                         "evidence does not split by camera (weight its message: evidence_correlation_s)")
    last = [None] * fusion.n_cameras if last_live_s is None else list(last_live_s)
    if len(last) != fusion.n_cameras:
        raise ValueError(f"last_live_s: expected {fusion.n_cameras} times (None where none), got {len(last)}")
    detector = None if params.foreground is None else params.foreground.person_detector
    box_params = params.boxes.for_detector(detector)
    if detector is not None and box_params.log_odds > 0 and cameras is None:
        raise ValueError("CameraParams.boxes.log_odds registers the boxes' foot points: it needs the calibrated "
                         "cameras (cameras= or registration=)")
    for i, (time_s, fgs, status, boxes) in enumerate(foregrounds):
        replayed = selective and i < replay
        for c, what in enumerate(status if not replayed else ()):
            if what != OK:
                warnings.warn(f"{fusion.names[c]}: {what} at t={time_s} s; fusing the other cameras",
                              stacklevel=2)
                if report is not None:
                    report.missing_frames.setdefault(fusion.names[c], []).append(float(time_s))
        if generative is None:
            evidence = fusion.evidence(fgs, time_s)
            detections = ground_detections_from_log_odds(evidence.log_odds, fusion.cameras_seeing(fusion.active),
                                                         stack, time_s, max_log_ratio(params.fusion), params.person)
            if correlation_s > 0:
                evidence = _weighted(fusion, fgs, evidence, last, correlation_s)
        else:
            prior = None
            if track_prior:  # never on a replayed instant: refused above
                prior = generative.location_prior(tracked_xy(float(time_s)))
            q = generative.marginals(fgs, prior)
            evidence = Evidence(float(time_s), "cameras", generative.log_odds_from_marginals(q, prior))
            detections = generative.detections(q, time_s, params.person.nms_radius_m)
        if report is not None and not replayed:
            for name, found in zip(fusion.names, boxes):
                if found is not None:
                    report.person_boxes.setdefault(name, []).append((float(time_s), found))
        if box_params.active and any(found is not None for found in boxes):
            bumps = box_evidence(cameras, boxes, stack, box_params, ignore_masks, lookups)
            evidence = Evidence(float(time_s), "cameras", combine_box_evidence(evidence.log_odds, bumps, box_params),
                                copy=False)
        if selective:
            for fe, people in zip(front_ends, people_masks(cameras, detections.xy_m, person)):
                fe.protect(people)
        if replayed:
            continue
        if report is not None:
            report.instants += 1
        yield evidence, detections


def _weighted(fusion: CameraFusion, fgs: Sequence[np.ndarray | None], evidence: Evidence, last: list,
              correlation_s: float) -> Evidence:
    """``evidence`` with each live camera ``c`` weighted by ``min(1, (t - last[c]) / correlation_s)``; updates
    ``last`` [s] in place (:func:`camera_detections` ``correlation_s``)."""
    t = float(evidence.time_s)
    w = np.ones(fusion.n_cameras)
    for c, fg in enumerate(fgs):
        if fg is not None:
            if last[c] is not None:
                w[c] = min(1.0, max(t - last[c], 0.0) / correlation_s)
            last[c] = t
    live = w[fusion.active]
    if not live.size or np.all(live == 1.0):
        return evidence
    if np.all(live == live[0]):  # the usual instant: every live camera's previous frame at the same time
        return Evidence(t, evidence.sensor, evidence.log_odds * np.float32(live[0]), copy=False)
    return fusion.evidence(fgs, t, evidence.sensor, weights=w)


def people_masks(cameras: Sequence[PinholeCamera], xy_m: np.ndarray, person: PersonVolume) -> list[np.ndarray]:
    """Per camera, the pixels (height_px, width_px) bool covered by the silhouette boxes of people standing at
    ``xy_m`` (N, 2) [m, world] (:func:`planefuse.occupancy.silhouettes_from_cameras`)."""
    masks = [np.zeros((c.intrinsics.height_px, c.intrinsics.width_px), bool) for c in cameras]
    if len(xy_m):
        boxes = silhouettes_from_cameras(cameras, np.asarray(xy_m, float).reshape(-1, 2), person).boxes_px
        for m, cam_boxes in zip(masks, boxes):
            for x0, y0, x1, y1 in cam_boxes[cam_boxes[:, 0] >= 0]:
                m[y0:y1 + 1, x0:x1 + 1] = True
    return masks
