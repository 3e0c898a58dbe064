"""Per-camera foreground likelihood in [0, 1]: background subtraction, masks, person boxes.

Every foreground source here returns a ``float32`` image of shape
``(height_px, width_px)`` whose value is the probability that the pixel shows a
moving person (1) rather than the static background (0). The multi-view fusion
(:mod:`._fusion`) reads it as a soft observation.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np
from .._params import check_fields, require
from ._fusion import quantise_foreground
from ._gain import block_gain_medians, divide_by_gain
from ._mean_background import MeanBackground
from ._yolox import PERSON_ENGINES, PersonBoxes, YoloxDetector, check_input_size, fitted_input_size

__all__ = [
    "BackgroundSubtractor",
    "ForegroundParams",
    "GainCompensator",
    "PersonDetector",
    "foreground_from_boxes",
    "foreground_from_mask",
    "read_mot_detections",
]

#: OpenCV's default KNN ``dist2Threshold`` (squared distance in grey levels); on frames reduced by ``downscale`` the
#: default is this divided by ``downscale`` (ForegroundParams.threshold).
_KNN_THRESHOLD = 400.0
#: Rate per frame of the running average of the background that protected pixels are compared with (selective
#: update): the gain compensator's reference rate, a time constant of 20 frames.
_MEAN_RATE = 0.05
# Values written by OpenCV's MOG2/KNN subtractors into their masks.
_CV_FOREGROUND = 255
_CV_SHADOW = 127


@dataclass(frozen=True)
class ForegroundParams:
    """Background subtraction settings.

    Attributes
    ----------
    method : {"knn", "mog2", "cnt", "mean"}
        OpenCV subtractor (``createBackgroundSubtractorKNN`` / ``...MOG2`` / ``cv2.bgsegm.create...CNT``), or
        ``"mean"``: one running-average background colour per pixel in one numba pass
        (:class:`~planefuse.vision._mean_background.MeanBackground`), KNN's decision (squared colour distance
        against ``threshold``) and shadow rule against that mean; 13x cheaper than KNN per frame and at or above
        it on the simulator (steady lighting), but on real video (EPFL terrace, tuning frames 0-1499) it calls
        20-70 % of the image foreground where KNN calls 1-10 %: its slow average does not follow a real
        camera's exposure and light (docs/results.md, "A running-average subtractor").
        CNT (Zeevi's background subtraction by counting, in ``opencv-contrib``) works on the grey frame: a pixel
        is background once it has kept the grey level of its history (within OpenCV's fixed 30 levels) for more
        than ``cnt_min_stability`` frames; it has no threshold to set and no shadow label.
    history : int
        Frames in the background model (CNT: its ``maxPixelStability``, the most frames of credit a pixel's
        background colour can collect).
    threshold : float
        MOG2 ``varThreshold`` (squared Mahalanobis distance) or KNN
        ``dist2Threshold`` (squared distance; ``"mean"``: the same, to the
        mean); ``None`` = OpenCV's default (16 for MOG2, 400 for KNN and
        ``"mean"``), for KNN and ``"mean"`` divided by ``downscale`` (an
        average of ``downscale**2`` pixels is less noisy but blurs a person's
        edges; 200 at ``downscale`` 2 was the best of 100-400 on the default
        scene's tuning seeds 1-3, docs/results.md "Cameras").
    detect_shadows : bool
        Let OpenCV mark shadows (value 127) instead of foreground.
    shadow_likelihood : float
        Foreground likelihood given to shadow pixels (low: shadows are most
        likely background lit differently, not a person).
    open_px, close_px : int
        Side of the square structuring elements of the morphological opening
        (removes speckle) and closing (fills holes) [px]; 0 disables.
    blur_px : int
        Side of the box filter that turns the cleaned mask into a smooth
        likelihood [px] (odd; 0 or 1 disables).
    floor, ceiling : float
        The likelihood is mapped affinely to ``[floor, ceiling]`` so that no pixel
        is certain: a subtractor's "background" still leaves ``floor`` chance of
        a person (camouflage), its "foreground" ``1 - ceiling`` of noise.
    learning_rate : float
        OpenCV learning rate (-1 = automatic from ``history``).
    primed_rate : {"steady", "automatic"}
        How an automatic model (``learning_rate`` -1) learns after :meth:`BackgroundSubtractor.prime`: ``"steady"``
        at ``1 / history`` per frame, for a real image of the empty scene (people who stop are not absorbed);
        ``"automatic"`` goes on with the model's fast automatic start (OpenCV's ``1 / min(2 n, history)`` after ``n``
        frames, ``"mean"``'s ``1 / min(n, history)``, the plate's included; CNT has no rate), for an *estimated*
        plate (``planefuse import --background-median-s``), which may hold people and another light than the frames
        that follow, and has to be corrected quickly.
    plate_frames : int or None
        Times :meth:`BackgroundSubtractor.prime` feeds the empty-scene plate to the model (with ``primed_rate``
        ``"automatic"`` also the plate's weight: the fast start counts on from it). None: the method's own need,
        10 for KNN, MOG2 and ``"mean"``, twice ``cnt_min_stability`` for CNT (a pixel must keep its grey level
        that long before it is background). KNN's masks on the default scene (tuning seed 2, 4 cameras, 40 s,
        every 5th frame) have as few false foreground pixels after 5, 7 or 10 as after 20 or 30, and many more
        after 3 (its sample memory not yet filled); the system's scores on the demo scene's tuning seeds 1-3 are
        identical after 7, 10, 20 and 30 (docs/benchmarks.md, "Tenth session").
    gain_compensation : bool
        Divide every frame by a smooth per-channel gain field before the subtractor sees it, so that a camera's
        automatic exposure or white balance, or a cloud, does not turn the whole image into foreground. The
        field is the median ratio of the frame to a reference background (a running average of the
        compensated frames' background pixels, so it stays in the units the subtractor learnt) over
        ``gain_blocks`` blocks, interpolated between block centres.
    gain_blocks : tuple of int
        ``(rows, cols)`` of the gain field's blocks. One block (a global gain per channel) was the most robust on
        the EPFL terrace's tuning frames (0-1499; docs/results.md): with several, a person filling much of a
        block biases its median.
    gain_rate : float
        Rate of the reference background's running average, per frame, in (0, 1].
    relearn_fraction : float or None
        A frame (after compensation) with more than this share of its pixels foreground is a sudden global
        change the compensation could not follow (light switched, camera bumped): it gives no evidence (the
        likelihood is 0.5 everywhere, which the fusion reads as "unobserved") and the subtractor relearns
        the scene at ``relearn_rate`` for ``relearn_frames`` frames. ``None`` disables.
    relearn_frames : int
        Frames of fast relearning after a sudden change.
    relearn_rate : float
        Learning rate while relearning, in (0, 1].
    downscale : int
        Subtract the background on frames reduced by this factor in each direction (``cv2.INTER_AREA``; 2 = a
        quarter of the pixels, a sixth of KNN's time at 360x288), then bring the likelihood back to the
        camera's size by bilinear interpolation; the open/close sides are divided by it. 1 = full resolution.
        A different detector, not a speed-only change: docs/results.md, "Background subtraction at reduced
        resolution" (not the default: behind full resolution on the tuning seeds).
    selective_update : bool
        Conservative background update (KNN only): the pixels given to :meth:`BackgroundSubtractor.protect` before
        a frame -- the silhouettes of the people the camera model explains at the previous instant, fed back by the
        camera pipeline (:func:`planefuse.vision.camera_detections`) -- that were foreground (or shadow) at the
        previous frame are not learnt into the background model, so that people who stand still do not fade into
        it (the background inside a silhouette's box is learnt as usual). There the model is fed a running average
        of the background (rate 0.05 per frame over the pixels called background) instead of the frame, and the
        foreground decision is the squared colour distance of the frame to that average against the KNN threshold
        (no shadow label). Off: every pixel is learnt (OpenCV's blind update). Not kept for the EPFL terrace
        (frames 0-1499: a little better warm, worse from a cold start; docs/results.md).
    selective_source : {"model", "detector"}
        With ``selective_update``, whose pixels are kept out of the model: ``"model"``, the silhouettes of the people
        the camera model explains at the previous instant (fed back by :func:`planefuse.vision.camera_detections`);
        ``"detector"``, the boxes the ``person_detector`` found in the previous frame (the subtractor protects
        itself: a background object that moved -- a ghost -- is no person to a detector, so it heals at once, and
        the cold start needs no camera model).
    knn_samples : int
        KNN only: background samples kept per pixel (OpenCV's ``setNSamples``; its default, 7). A pixel is
        background once ``kNNSamples`` (2) of them are within the threshold, so the first samples usually decide
        and fewer cost little: 3 took 17 % less time per 360x288 frame than 7 (0.80 against 0.97 ms, one core,
        docs/benchmarks.md "Real-time factor") and scored no worse on the default scene's tuning seeds 1-3; not
        the default until judged on the EPFL terrace's tuning frames.
    cnt_min_stability : int
        CNT only: frames a pixel must keep its grey level before it is background (OpenCV's
        ``minPixelStability``; its default, 15); below ``history``.
    mean_foreground_rate : float
        ``"mean"`` only: rate at which pixels called foreground or shadow are learnt into the running average,
        relative to the learning rate, in [0, 1] (0 = never, a conservative update; 1 = blind, every pixel alike).
    selective_max_frames : int
        A pixel is kept out of the model for at most this many consecutive frames, then learnt again whatever the
        camera model says (until it leaves the protected region), so that a ghost -- a background object that
        moved, which the camera model may explain as a person -- still heals. Nothing is protected during the
        model's first ``selective_max_frames`` frames either: a cold model calls the scene itself foreground and
        learns the people then in view as background, and the camera model's "people" on those frames are its
        ghosts (EPFL terrace, frames 1000-1499 from a cold start: filtered MODA -0.08 with protection from the
        first frame; docs/results.md).
    person_detector : {None, "hog", "yolox"}
        A person detector run on every frame beside the subtractor; the boxes it finds are each person's
        silhouette in that view: the likelihood inside them is at least ``person_likelihood`` (a person who
        stands still and has faded into the background model is still foreground), and they reach the planes as
        :class:`~planefuse.vision.BoxEvidenceParams` evidence (``CameraParams.boxes``). ``"yolox"``: a pretrained
        YOLOX ONNX model (``person_model``; :class:`~planefuse.vision.YoloxDetector`), the whole box.
        ``"hog"``: OpenCV's HOG + linear SVM people detector (Dalal & Triggs 2005, trained on INRIA Person; its
        model ships inside OpenCV: the core module in OpenCV 4, ``opencv-contrib`` from OpenCV 5), the body of
        each box (the middle half of its width, the middle three quarters of its height: the detector's 64 x 128
        px window has that margin around the person). None: background subtraction alone.
    person_model : str or None
        ``"yolox"``: path of the ONNX file (a YOLOX export of the raw-head layout: Nano, Tiny, S, ...; the user
        downloads it from the YOLOX project's releases, planefuse never downloads anything).
    person_engine : str
        ``"yolox"``: what runs the model (:data:`~planefuse.vision.PERSON_ENGINES`): ``"auto"`` ONNX Runtime where
        its package is installed (``pip install 'planefuse[onnxruntime]'``), else OpenCV's DNN module;
        ``"opencv"``; ``"onnxruntime"``. Their boxes agree to float rounding (tests/test_vision_yolox.py); ONNX
        Runtime costs about half on one core (5.2 against 11.0 ms per terrace frame at the fitted 384 x 288 canvas,
        docs/benchmarks.md). A run's ``metrics.json`` (``person_engine``) says which ran.
    person_input_px : (int, int) or None
        ``"yolox"``: canvas (width, height) [px] the frame is letterboxed into, multiples of 32. None: fitted to the
        frame (:func:`~planefuse.vision.fitted_input_size`: its own size, or reduced to a longer side of 416 px, the
        Nano model's own input, never enlarged). Per camera on the EPFL terrace's tuning frames 0-1475 every 25th
        (both cameras, IoU 0.5, score 0.5) the fitted 384 x 288 against 416 x 416 (the frames enlarged 1.16 times):
        recall 0.821 / precision 0.879 against 0.833 / 0.936, 12.2 against 19.8 ms per frame on one core; the whole
        system scored the same or better with it (:func:`~planefuse.vision.fitted_input_size`).
    person_upscale : float
        ``"hog"``: factor the frame is enlarged by before detection: the detector's window is 128 px tall,
        people in a 288 px high frame are often 40-120 px.
    person_min_score : float or None
        Smallest score of a kept box: ``"yolox"`` its person probability in [0, 1] (None: 0.5, chosen on the
        terrace tuning frames above: recall 0.845 / precision 0.747 at 0.3, 0.836 / 0.892 at 0.4, 0.833 / 0.936
        at 0.5, 0.833 / 0.943 at 0.55), ``"hog"`` its SVM margin (None: 0.3).
    person_nms_iou : float
        ``"yolox"``: a box overlapping a better one by more than this IoU is suppressed (YOLOX's 0.45).
    person_likelihood : float or None
        Foreground likelihood at least given to a detected person's box, in [0, 1]; 0 leaves the foreground as it
        is (and ``person_outside_weight`` is not used). None: the detector's default, ``"hog"`` 0.9, ``"yolox"`` 0:
        YOLOX's boxes filled into the foreground the generative model explains were worse than the subtraction
        alone on the EPFL terrace's tuning frames (1000-1499 cold, filtered MODA 0.621 / 0.781 at 0.5 / 1.0 m
        against 0.696 / 0.895; the boxes alone, 0.638 / 0.808): a box holds the background beside the person, which
        the model explains by more people. YOLOX's boxes reach the planes as evidence of free space instead
        (:class:`~planefuse.vision.BoxEvidenceParams` ``free_log_odds``).
    person_outside_weight : float
        The subtractor's foreground outside every box, relative to ``floor``, is multiplied by this, in [0, 1]:
        foreground a detector does not explain counts less (a shadow, a lighting change), but a person the
        detector missed inside a group still leaves some. 1: unchanged.
    """

    method: str = "knn"
    history: int = 500
    threshold: float | None = None
    detect_shadows: bool = True
    shadow_likelihood: float = 0.1
    open_px: int = 0
    close_px: int = 5
    blur_px: int = 0
    floor: float = 0.02
    ceiling: float = 0.98
    learning_rate: float = -1.0
    primed_rate: str = "steady"
    plate_frames: int | None = None
    gain_compensation: bool = False
    gain_blocks: tuple[int, int] = (1, 1)
    gain_rate: float = 0.05
    relearn_fraction: float | None = None
    relearn_frames: int = 5
    relearn_rate: float = 0.2
    downscale: int = 1
    selective_update: bool = False
    selective_max_frames: int = 50
    selective_source: str = "model"
    knn_samples: int = 7
    cnt_min_stability: int = 15
    mean_foreground_rate: float = 0.2
    person_detector: str | None = None
    person_model: str | None = None
    person_engine: str = "auto"
    person_input_px: tuple[int, int] | None = None
    person_upscale: float = 2.0
    person_min_score: float | None = None
    person_nms_iou: float = 0.45
    person_likelihood: float | None = None
    person_outside_weight: float = 1.0

    def __post_init__(self) -> None:
        require(self.method in ("knn", "mog2", "cnt", "mean", "none"), self, "method",
                f"must be 'knn', 'mog2', 'cnt', 'mean' or 'none', got {self.method!r}")
        require(self.primed_rate in ("steady", "automatic"), self, "primed_rate",
                f"must be 'steady' or 'automatic', got {self.primed_rate!r}")
        check_fields(self, history="int>=1", plate_frames="?int>=1", threshold="?>0", shadow_likelihood="[0,1]",
                     floor="[0,1]", ceiling="[0,1]", open_px="int>=0", close_px="int>=0", blur_px="int>=0")
        require(self.floor < self.ceiling, self, "floor", f"must be below ceiling, got {self.floor}, {self.ceiling}")
        check_fields(self, gain_rate="(0,1]", relearn_rate="(0,1]", relearn_fraction="?(0,1)",
                     relearn_frames="int>=1", downscale="int>=1", selective_max_frames="int>=1",
                     knn_samples="int>=1", mean_foreground_rate="[0,1]")
        require(self.method != "cnt" or self.threshold is None, self, "threshold",
                f"must be None for method 'cnt' (OpenCV's CNT has fixed thresholds), got {self.threshold}")
        check_fields(self, cnt_min_stability="int>=1")
        require(self.method != "cnt" or self.cnt_min_stability < self.history, self, "cnt_min_stability",
                f"must be below history = {self.history} for method 'cnt', got {self.cnt_min_stability}")
        require(self.knn_samples >= 2, self, "knn_samples",
                f"must be >= 2 (a pixel is background when 2 samples match), got {self.knn_samples}")
        require(not self.selective_update or self.method == "knn", self, "selective_update",
                f"needs method 'knn' (the decision on protected pixels uses its dist2Threshold), got {self.method!r}")
        require(self.selective_source in ("model", "detector"), self, "selective_source",
                f"must be 'model' or 'detector', got {self.selective_source!r}")
        require(not self.selective_update or self.selective_source != "detector" or self.person_detector is not None,
                self, "selective_source", "'detector' with selective_update needs a person_detector")
        require(len(self.gain_blocks) == 2 and min(self.gain_blocks) >= 1, self, "gain_blocks",
                f"must be (rows, cols) >= 1, got {self.gain_blocks}")
        require(self.person_detector in (None, "hog", "yolox"), self, "person_detector",
                f"must be None, 'hog' or 'yolox', got {self.person_detector!r}")
        check_fields(self, person_upscale=">0", person_min_score="?finite", person_likelihood="?[0,1]",
                     person_nms_iou="(0,1]", person_outside_weight="[0,1]")
        require(self.person_detector != "yolox" or self.person_model is not None, self, "person_model",
                "must name the YOLOX ONNX file with person_detector 'yolox'")
        require(self.person_engine in PERSON_ENGINES, self, "person_engine",
                f"must be one of {', '.join(map(repr, PERSON_ENGINES))}, got {self.person_engine!r}")
        require(self.person_detector != "yolox" or self.person_min_score is None or
                0 <= self.person_min_score <= 1, self, "person_min_score",
                f"must lie in [0, 1] for 'yolox' (a probability), got {self.person_min_score}")
        if self.person_detector == "yolox" and self.person_input_px is not None:
            try:
                check_input_size(self.person_input_px)
            except ValueError as exc:
                require(False, self, "person_input_px", str(exc))
        require(self.method != "none" or self.person_detector is not None, self, "method",
                "'none' (no background subtraction) needs a person_detector: nothing else would see people")

    @property
    def person_level(self) -> float:
        """:attr:`person_likelihood`, or the detector's default (``"hog"`` 0.9, ``"yolox"`` 0)."""
        if self.person_likelihood is not None:
            return float(self.person_likelihood)
        return 0.9 if self.person_detector == "hog" else 0.0

    @property
    def min_person_score(self) -> float:
        """:attr:`person_min_score`, or the detector's default (``"yolox"`` 0.5, ``"hog"`` 0.3)."""
        if self.person_min_score is not None:
            return float(self.person_min_score)
        return 0.5 if self.person_detector == "yolox" else 0.3

    @property
    def n_plate_frames(self) -> int:
        """Times the empty-scene plate primes the model (:attr:`plate_frames`, or the method's own need)."""
        if self.plate_frames is not None:
            return self.plate_frames
        return 2 * self.cnt_min_stability if self.method == "cnt" else 10


class BackgroundSubtractor:
    """One camera's OpenCV background model turning frames into foreground likelihoods.

    Parameters
    ----------
    width_px, height_px : int
        Frame size the camera's calibration expects; other sizes are refused.
    params : ForegroundParams
    name : str
        Camera name used in error messages.
    """

    def __init__(self, width_px: int, height_px: int, params: ForegroundParams = ForegroundParams(),
                 name: str = "camera") -> None:
        self.width_px = int(width_px)
        self.height_px = int(height_px)
        self.params = params
        self.name = name
        if params.method == "none":
            self._model = _NoBackground()
        elif params.method == "mog2":
            self._model = cv2.createBackgroundSubtractorMOG2(
                history=params.history,
                varThreshold=16.0 if params.threshold is None else float(params.threshold),
                detectShadows=params.detect_shadows,
            )
        elif params.method == "cnt":
            self._model = _create_cnt(params)
        elif params.method == "mean":
            threshold = _KNN_THRESHOLD / params.downscale if params.threshold is None else float(params.threshold)
            self._model = MeanBackground(threshold, params.history, params.detect_shadows, params.mean_foreground_rate)
        else:
            threshold = _KNN_THRESHOLD / params.downscale if params.threshold is None else float(params.threshold)
            self._model = cv2.createBackgroundSubtractorKNN(
                history=params.history,
                dist2Threshold=threshold,
                detectShadows=params.detect_shadows,
            )
            self._model.setNSamples(params.knn_samples)
        # Mask value -> likelihood: 0 background, 127 shadow, 255 foreground.
        lut = np.zeros(256, dtype=np.float32)
        lut[_CV_SHADOW] = params.shadow_likelihood
        lut[_CV_FOREGROUND] = 1.0
        self._lut = lut
        #: the same likelihoods quantised to the fusion's 256 levels (``apply(quantised=True)``), a table where no
        #: blur or resize stands between the cleaned mask and them
        self._levels = None if params.blur_px > 1 or params.downscale > 1 else \
            quantise_foreground(_soften(lut.copy(), 0, params.floor, params.ceiling, own=True))
        d = params.downscale
        #: the subtractor's frame size (cols, rows) [px]: the camera's, reduced by ``params.downscale``
        self._model_size = (max(1, round(self.width_px / d)), max(1, round(self.height_px / d)))
        self._open = _kernel(int(params.open_px / d + 0.5))
        self._rate = params.learning_rate
        self._close = _kernel(int(params.close_px / d + 0.5))
        self._n_learned = 0
        self._gain = GainCompensator(params.gain_blocks, params.gain_rate) if params.gain_compensation else None
        self._relearn_left = 0
        #: Sudden global changes detected after the first ``relearn_frames`` frames (each gave no evidence and
        #: restarted a fast relearning).
        self.n_sudden_changes = 0
        # selective update: the pixels (model size) to keep out of the model at the next frame, and for how many
        # consecutive frames each pixel has been kept out
        self._protect: np.ndarray | None = None
        self._protected_for = np.zeros(self._model_size[::-1], np.uint16)
        #: the previous frame's foreground (OpenCV's decision, shadows included) at the model's size
        self._last_foreground = np.zeros(self._model_size[::-1], bool)
        #: running average of the frames' background pixels (model size, float32): the background protected
        #: pixels are fed and compared with
        self._mean_background: np.ndarray | None = None
        self._people = PersonDetector(params) if params.person_detector is not None else None

    def protect(self, people) -> None:
        """Keep the pixels ``people`` (height_px, width_px) bool -- where the camera model explains the image by
        people -- out of the background model at the next frame (:attr:`ForegroundParams.selective_update`;
        each pixel at most ``selective_max_frames`` frames in a row). Call before every frame: a frame without
        a call learns every pixel."""
        if not self.params.selective_update:
            raise ValueError(f"{self.name}: protect() needs ForegroundParams.selective_update")
        m = np.asarray(people)
        if m.shape != (self.height_px, self.width_px) or m.dtype != bool:
            raise ValueError(f"{self.name}: people mask must be a {self.height_px}x{self.width_px} bool image, got "
                             f"{m.dtype} {m.shape}")
        if self.params.downscale > 1:  # a model pixel is protected where any of its camera pixels is
            m = cv2.resize(m.astype(np.uint8), self._model_size, interpolation=cv2.INTER_AREA) > 0
        self._protect = m

    def prime(self, empty_frame, n_frames: int | None = None) -> None:
        """Initialise the background model with an image of the empty scene (calibration plate).

        Background subtraction that starts cold learns the people already in view as
        background (ghosts that last ``history`` frames); showing it the empty scene
        first, the usual calibration step, avoids that.

        Parameters
        ----------
        empty_frame : ndarray, shape (height_px, width_px) or (height_px, width_px, 3), uint8
            The scene without people, same format as the frames given to :meth:`apply`.
        n_frames : int, optional
            Times the plate is fed to the model (fills its sample memory); default
            :attr:`ForegroundParams.n_plate_frames`.

        Notes
        -----
        With ``params.learning_rate < 0`` (automatic) OpenCV learns at ``1 / frames seen``, fast at
        start so that a cold model converges; once primed the model already holds the background, so
        :meth:`apply` then learns at the steady ``1 / history`` instead (people standing still are not
        absorbed within a few frames), unless ``params.primed_rate`` is ``"automatic"`` (an estimated plate:
        OpenCV's fast start goes on, counting the plate's frames).
        """
        n_frames = self.params.n_plate_frames if n_frames is None else n_frames
        if n_frames < 1:
            raise ValueError(f"{self.name}: n_frames must be >= 1, got {n_frames}")
        img = self._check(empty_frame)
        for i in range(int(n_frames)):
            self._learn(img, 1.0 if i == 0 else -1.0)
        # CNT's rate is not a learning rate: a rate in (0, 1) scales its stability cap (maxPixelStability), so
        # its automatic mode (-1, the full cap) is its steady state
        if self.params.learning_rate < 0 and self.params.primed_rate == "steady" and self.params.method != "cnt":
            self._rate = 1.0 / self.params.history

    def _check(self, frame) -> np.ndarray:
        img = np.asarray(frame)
        if img.shape[:2] != (self.height_px, self.width_px) or img.ndim not in (2, 3):
            raise ValueError(
                f"{self.name}: frame must be {self.height_px}x{self.width_px} (rows x cols) as in the camera's "
                f"calibration, got shape {img.shape}"
            )
        if img.dtype != np.uint8:
            raise ValueError(f"{self.name}: frame must be uint8, got {img.dtype}")
        return img

    @property
    def person_boxes(self) -> PersonBoxes | None:
        """The person detector's boxes in the last frame :meth:`apply` saw (frame pixels; None without a
        detector)."""
        return None if self._people is None else self._people.last_boxes

    @property
    def protects_itself(self) -> bool:
        """True where the selective update keeps the person detector's boxes out of the model
        (:attr:`ForegroundParams.selective_source` ``"detector"``): nobody else calls :meth:`protect`."""
        return self.params.selective_update and self.params.selective_source == "detector"

    def update(self, frame) -> None:
        """Update the background model with ``frame`` as :meth:`apply` does, without computing the foreground
        (replaying the frames before a resumed run's first one; with :attr:`protects_itself` the detector still
        runs, so that the protected pixels are the same)."""
        img = self._check(frame)
        self._learn(img, self._rate)
        if self.protects_itself:
            self.protect(self._people.silhouettes(self._people.detect(img), self.height_px, self.width_px))

    def _learn(self, img: np.ndarray, rate: float) -> np.ndarray:
        # OpenCV's KNN model draws its per-pixel update phases (randu) from cv::theRNG, which every model
        # in the thread shares: seeding it from the model's own frame count makes the masks a function of
        # the frames alone (reproducible, and exactly replayed by a resumed run).
        cv2.setRNGSeed(_frame_seed(self._n_learned))
        self._n_learned += 1
        if self.params.downscale > 1:
            img = cv2.resize(img, self._model_size, interpolation=cv2.INTER_AREA)
        protect = self._take_protection() if self.params.selective_update else None
        relearning = self._relearn_left > 0
        if relearning:  # the scene is being relearnt: nothing is kept out
            rate = self.params.relearn_rate
            self._relearn_left -= 1
            protect = None
        compensated = img if self._gain is None else self._gain.compensate(img)
        if relearning and isinstance(self._model, MeanBackground):  # its foreground too, at the relearning rate
            mask = self._model.apply(compensated, learningRate=rate, foreground_rate=1.0)
        elif protect is None:
            mask = self._model.apply(compensated, learningRate=rate)
        else:
            mask = self._apply_selective(compensated, protect, rate)
        if self._gain is not None:
            self._gain.learn(compensated, mask == 0, self.params.relearn_rate if self._relearn_left else None)
        if self.params.selective_update:
            np.not_equal(mask, 0, out=self._last_foreground)
            self._learn_mean_background(compensated, mask)
        return mask

    def _take_protection(self) -> np.ndarray | None:
        """The pixels to keep out of the model at this frame (None: none), counting consecutive protected frames."""
        m, self._protect = self._protect, None
        count = self._protected_for
        if self._n_learned <= self.params.selective_max_frames:
            m = None  # a cold model: its "people" include the scene it has not learnt yet (see ForegroundParams)
        if m is None:
            count[:] = 0
            return None
        # only what the model calls foreground: the background around a person, or a false person's box, is
        # learnt as usual (else a false detection keeps its own box out of the model and so its foreground)
        m = m & self._last_foreground
        np.add(count, 1, out=count, where=m)
        count[~m] = 0
        np.minimum(count, self.params.selective_max_frames + 1, out=count)
        keep = m & (count <= self.params.selective_max_frames)
        return keep if keep.any() else None

    def _apply_selective(self, frame: np.ndarray, protect: np.ndarray, rate: float) -> np.ndarray:
        """OpenCV's mask of ``frame`` with the model fed the mean background on ``protect`` (ForegroundParams
        .selective_update); there the decision is the squared distance of ``frame`` to that mean."""
        mean = self._mean_background
        if mean is None:  # nothing learnt yet
            return self._model.apply(frame, learningRate=rate)
        fed = frame.copy()
        fed[protect] = np.round(mean[protect]).astype(np.uint8)
        mask = self._model.apply(fed, learningRate=rate)
        d = frame[protect].astype(np.float32) - mean[protect]
        dist2 = (d * d).sum(axis=-1) if d.ndim == 2 else d * d
        mask[protect] = np.where(dist2 > self._model.getDist2Threshold(), _CV_FOREGROUND, 0).astype(np.uint8)
        return mask

    def _learn_mean_background(self, frame: np.ndarray, mask: np.ndarray) -> None:
        """Running average (rate ``_MEAN_RATE`` per frame) of ``frame`` on the pixels ``mask`` calls background."""
        if self._mean_background is None:
            self._mean_background = frame.astype(np.float32)
            return
        w = (mask == 0).astype(np.float32) * _MEAN_RATE
        if frame.ndim == 3:
            w = w[..., None]
        self._mean_background += w * (frame.astype(np.float32) - self._mean_background)

    def apply(self, frame, quantised: bool = False) -> np.ndarray:
        """Update the background model with ``frame`` and return its foreground likelihood.

        Parameters
        ----------
        frame : ndarray, shape (height_px, width_px) or (height_px, width_px, 3), uint8
            Grey or BGR frame.
        quantised : bool
            Return the likelihood as the multi-view fusion's 256 levels, ``quantise_foreground(apply(frame))``
            (uint8), the same values computed without the float image where no blur or resize needs it.

        Returns
        -------
        ndarray, shape (height_px, width_px), float32 (uint8 when ``quantised``)
            Foreground likelihood in ``[floor, ceiling]``.
        """
        img = self._check(frame)
        like = self._subtract(img, quantised)
        if self._people is not None:
            self._people.mark(img, like, quantised)
            if self.protects_itself:  # the people it found stay out of the model at the next frame
                self.protect(self._people.silhouettes(self._people.last_boxes, self.height_px, self.width_px))
        return like

    def _subtract(self, img: np.ndarray, quantised: bool) -> np.ndarray:
        """The subtractor's likelihood of the checked frame ``img`` (:meth:`apply` without the person detector)."""
        relearning = self._relearn_left > 0
        mask = self._learn(img, self._rate)
        p = self.params
        # OpenCV's per-pixel operations, each the numpy expression it replaces (speed only, same values)
        hard = cv2.compare(mask, _CV_FOREGROUND, cv2.CMP_EQ)  # np.where(mask == 255, 255, 0)
        if p.relearn_fraction is not None and not relearning and cv2.countNonZero(hard) > \
                p.relearn_fraction * mask.size:
            self._relearn_left = p.relearn_frames
            # a cold model (OpenCV's KNN) calls its first few frames all foreground: not a change of the scene
            self.n_sudden_changes += int(self._n_learned > p.relearn_frames)
            relearning = True
        if relearning:  # the model is being rebuilt: no evidence either way
            like = np.full((self.height_px, self.width_px), 0.5, dtype=np.float32)
            return quantise_foreground(like) if quantised else like
        # Clean the hard decision (foreground only) before softening it.
        if self._open is not None:
            hard = cv2.morphologyEx(hard, cv2.MORPH_OPEN, self._open)
        if self._close is not None:
            hard = cv2.morphologyEx(hard, cv2.MORPH_CLOSE, self._close)
        # 255 where the cleaned decision is foreground, else 127 where OpenCV saw a shadow, else 0
        shadow = cv2.bitwise_and(cv2.compare(mask, _CV_SHADOW, cv2.CMP_EQ), _CV_SHADOW)
        if quantised and self._levels is not None:
            return cv2.LUT(cv2.max(hard, shadow), self._levels)
        like = cv2.LUT(cv2.max(hard, shadow), self._lut)
        if self.params.downscale > 1:
            like = cv2.resize(like, (self.width_px, self.height_px), interpolation=cv2.INTER_LINEAR)
        like = _soften(like, self.params.blur_px, self.params.floor, self.params.ceiling, own=True)
        return quantise_foreground(like) if quantised else like


class _NoBackground:
    """The subtractor of :attr:`ForegroundParams.method` ``"none"``: every pixel background."""

    def apply(self, image: np.ndarray, learningRate: float = -1.0) -> np.ndarray:  # noqa: N803 (OpenCV's name)
        return np.zeros(image.shape[:2], np.uint8)


class PersonDetector:
    """A person detector marking the people it finds in a foreground likelihood
    (:attr:`ForegroundParams.person_detector`: OpenCV's HOG people detector or a YOLOX model).

    Parameters
    ----------
    params : ForegroundParams
        ``person_*`` fields are used.

    Attributes
    ----------
    last_boxes : PersonBoxes
        The boxes of the last frame given to :meth:`mark` (frame pixels).
    """

    def __init__(self, params: ForegroundParams) -> None:
        self.params = params
        self.min_score = params.min_person_score
        if params.person_detector == "yolox":
            # one detector per canvas size (fitted to each frame size where person_input_px is None)
            self._yolox: dict[tuple[int, int], YoloxDetector] = {}
            if params.person_input_px is not None:
                self._yolox_for(params.person_input_px)
        else:
            if not hasattr(cv2, "HOGDescriptor"):
                raise ValueError(f"person_detector 'hog' needs OpenCV's HOG people detector, absent from this OpenCV "
                                 f"{cv2.__version__} (OpenCV 5 moved it to opencv-contrib-python-headless)")
            self._hog = cv2.HOGDescriptor()
            self._hog.setSVMDetector(cv2.HOGDescriptor_getDefaultPeopleDetector())
        self._level = params.person_level
        self._quantised_level = int(quantise_foreground(np.float32([self._level])).ravel()[0])
        self.last_boxes = PersonBoxes.empty()

    def _yolox_for(self, input_wh_px) -> YoloxDetector:
        wh = tuple(int(v) for v in input_wh_px)
        if wh not in self._yolox:
            # ONNX Runtime on as many threads as OpenCV (the run's --threads; OpenCV's DNN module uses them itself)
            self._yolox[wh] = YoloxDetector(self.params.person_model, wh, self.min_score, self.params.person_nms_iou,
                                            engine=self.params.person_engine, threads=max(1, cv2.getNumThreads()))
        return self._yolox[wh]

    def detect(self, frame: np.ndarray) -> PersonBoxes:
        """The people in ``frame`` (grey or BGR uint8): boxes in the frame's pixels and their scores."""
        if self.params.person_detector == "yolox":
            h, w = np.shape(frame)[:2]
            wh = self.params.person_input_px or fitted_input_size((w, h))
            return self._yolox_for(wh).detect(frame)
        k = self.params.person_upscale
        img = frame if k == 1 else cv2.resize(frame, None, fx=k, fy=k, interpolation=cv2.INTER_LINEAR)
        rects, scores = self._hog.detectMultiScale(img, winStride=(8, 8), padding=(8, 8), scale=1.05)
        rects = np.asarray(rects, dtype=float).reshape(-1, 4) / k
        scores = np.asarray(scores, dtype=float).reshape(-1)
        keep = scores >= self.min_score
        order = np.argsort(-scores[keep], kind="stable")
        return PersonBoxes(rects[keep][order], scores[keep][order])

    def boxes(self, frame: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """:meth:`detect` as ``(ltwh_px (K, 4), score (K,))``."""
        found = self.detect(frame)
        return found.ltwh_px, found.score

    def silhouettes(self, boxes: PersonBoxes, height_px: int, width_px: int) -> np.ndarray:
        """The pixels ``(height_px, width_px)`` bool of the people in ``boxes``: YOLOX's whole boxes, HOG's bodies
        (its window's margin left out)."""
        mask = np.zeros((height_px, width_px), bool)
        hog = self.params.person_detector == "hog"
        for x, y, bw, bh in boxes.ltwh_px:
            if hog:
                x, y, bw, bh = x + bw / 4, y + bh / 8, bw / 2, 3 * bh / 4
            c0, c1 = max(0, int(round(x))), min(width_px, int(round(x + bw)))
            r0, r1 = max(0, int(round(y))), min(height_px, int(round(y + bh)))
            mask[r0:r1, c0:c1] = True
        return mask

    def mark(self, frame: np.ndarray, like: np.ndarray, quantised: bool) -> None:
        """Raise ``like`` (the frame's foreground likelihood, float or quantised) to at least ``person_likelihood``
        on the people found in ``frame``, and scale what lies outside them by ``person_outside_weight`` towards
        ``floor``, in place (:attr:`last_boxes` only, where the level is 0)."""
        self.last_boxes = self.detect(frame)
        if self._level == 0:
            return
        h, w = like.shape
        inside = self.silhouettes(self.last_boxes, h, w)
        p = self.params
        if p.person_outside_weight < 1.0:
            outside = ~inside
            if quantised:
                floor = int(quantise_foreground(np.float32([p.floor])).ravel()[0])
                v = like[outside].astype(np.float32)
                like[outside] = np.round(floor + p.person_outside_weight * np.maximum(v - floor, 0)).astype(np.uint8)
            else:
                like[outside] = p.floor + p.person_outside_weight * np.maximum(like[outside] - p.floor, 0)
        level = self._quantised_level if quantised else self._level
        np.maximum(like, level, out=like, where=inside)


class GainCompensator:
    """Smooth per-channel gain of frames against a slowly learnt reference background.

    ``compensate(frame) = frame / G`` with ``G`` the per-block median of ``frame / reference`` over the pixels
    that were background in the previous frame (not too dark, not saturated), bilinearly interpolated
    between block centres; blocks with too few such pixels take the image's median. ``learn`` moves the
    reference towards the compensated frame on its background pixels at ``rate`` per frame, so the
    reference stays in the units of the first frame and a global exposure step is divided out at once.

    Parameters
    ----------
    blocks : (int, int)
        Rows and columns of the gain field's blocks.
    rate : float
        Running-average rate of the reference, per frame.
    """

    #: Pixels darker than this in the reference, or saturated in either image, say nothing about the gain [grey level].
    DARK, SATURATED = 16.0, 250.0
    #: Fewest background pixels (fraction of the image) the gain is measured on; below it all pixels are used.
    MIN_VALID = 0.05
    #: Bound on the gain of a block (and its inverse): beyond it the frame is not the same scene.
    MAX_GAIN = 4.0

    def __init__(self, blocks: tuple[int, int], rate: float) -> None:
        self.blocks = (int(blocks[0]), int(blocks[1]))
        self.rate = float(rate)
        self.reference: np.ndarray | None = None
        self._valid: np.ndarray | None = None

    def compensate(self, frame: np.ndarray) -> np.ndarray:
        """The frame (H, W[, C]) uint8 divided by its gain field, uint8."""
        if self.reference is None:
            self.reference = frame.astype(np.float32)
            return frame
        h, w = frame.shape[:2]
        img = frame.reshape(h, w, -1)
        ref = self.reference.reshape(h, w, -1)
        rows, cols = self.blocks
        ys, xs = np.linspace(0, h, rows + 1).astype(np.int64), np.linspace(0, w, cols + 1).astype(np.int64)
        use_valid = self._valid is not None
        valid = self._valid if use_valid else np.zeros((h, w), bool)
        medians = block_gain_medians(img, ref, valid, use_valid, self.DARK, self.SATURATED, self.MIN_VALID, ys, xs)
        gain = np.clip(medians, 1.0 / self.MAX_GAIN, self.MAX_GAIN)
        field = cv2.resize(gain, (w, h), interpolation=cv2.INTER_LINEAR).reshape(h, w, -1)
        return divide_by_gain(img, field).reshape(frame.shape)

    def learn(self, compensated: np.ndarray, background: np.ndarray, rate: float | None = None) -> None:
        """Update the reference with a compensated frame on its ``background`` (H, W) bool pixels (all pixels
        at ``rate`` when given: the scene is being relearnt)."""
        a = self.rate if rate is None else rate
        img = compensated.astype(np.float32)
        w = np.full(background.shape, a, np.float32) if rate is not None else background.astype(np.float32) * a
        w = w.reshape(w.shape + (1,) * (img.ndim - 2))
        self.reference += w * (img - self.reference)
        self._valid = background


@functools.lru_cache(maxsize=4096)
def _frame_seed(n: int) -> int:
    """A well-spread 31-bit seed for frame ``n`` (numpy's SeedSequence hash): OpenCV's multiply-with-carry
    generator seeded with consecutive small integers gives correlated draws. Cached: every camera asks for
    the same frame numbers."""
    return int(np.random.SeedSequence(n).generate_state(1, np.uint32)[0]) & 0x7FFFFFFF


def _create_cnt(params: ForegroundParams):
    """OpenCV's CNT subtractor (``cv2.bgsegm``, opencv-contrib) for ``params``: history on, ``history`` frames of
    credit at most, ``cnt_min_stability`` frames to become background."""
    if not hasattr(cv2, "bgsegm"):
        raise ValueError(f"foreground method 'cnt' needs cv2.bgsegm (opencv-contrib-python-headless), absent from "
                         f"this OpenCV {cv2.__version__}")
    # isParallel: rows split over OpenCV's threads (cv2.setNumThreads); every pixel is independent, so the mask
    # does not depend on the number of threads
    return cv2.bgsegm.createBackgroundSubtractorCNT(minPixelStability=params.cnt_min_stability, useHistory=True,
                                                    maxPixelStability=params.history, isParallel=True)


def _kernel(side_px: int):
    return None if side_px <= 1 else cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (side_px, side_px))


def _soften(like: np.ndarray, blur_px: int, floor: float, ceiling: float, *, own: bool = False) -> np.ndarray:
    """``floor + (ceiling - floor) * like`` (float32) after a box blur; computed in place in ``like`` where it is
    a float32 array of this call's own (``own``, or a blurred copy)."""
    if blur_px > 1:
        like, own = cv2.blur(like, (blur_px, blur_px), borderType=cv2.BORDER_REPLICATE), True
    if own and like.dtype == np.float32:
        np.multiply(like, np.float32(ceiling - floor), out=like)
        return np.add(like, np.float32(floor), out=like)
    return (floor + (ceiling - floor) * like).astype(np.float32)


def foreground_from_mask(mask, width_px: int | None = None, height_px: int | None = None, *,
                         blur_px: int = 0, floor: float = 0.02, ceiling: float = 0.98,
                         name: str = "mask") -> np.ndarray:
    """Foreground likelihood from an external binary or soft mask.

    Parameters
    ----------
    mask : ndarray, shape (H, W) or (H, W, C)
        ``bool``, ``uint8`` (0..255; 255 = foreground) or float in ``[0, 1]``.
        Multi-channel images must have equal channels (the first is used).
    width_px, height_px : int, optional
        Expected size; a mismatch raises ``ValueError``.
    blur_px : int
        Box-filter side [px] softening the edges (0 = none).
    floor, ceiling : float
        Affine mapping of ``[0, 1]`` to ``[floor, ceiling]`` (no certain pixel).

    Returns
    -------
    ndarray, shape (H, W), float32
    """
    m = np.asarray(mask)
    if m.ndim == 3:
        m = m[..., 0]
    if m.ndim != 2:
        raise ValueError(f"{name}: mask must be an (H, W) or (H, W, C) image, got shape {np.shape(mask)}")
    if width_px is not None and height_px is not None and m.shape != (height_px, width_px):
        raise ValueError(f"{name}: mask must be {height_px}x{width_px} (rows x cols), got {m.shape}")
    if m.dtype == bool:
        f = m.astype(np.float32)
    elif m.dtype == np.uint8:
        f = m.astype(np.float32) / 255.0
    else:
        f = m.astype(np.float32)
        if not np.isfinite(f).all() or f.min() < 0 or f.max() > 1:
            raise ValueError(f"{name}: a float mask must hold values in [0, 1]")
    return _soften(f, blur_px, floor, ceiling)


def foreground_from_boxes(boxes_ltwh, width_px: int, height_px: int, confidence=None, *,
                          floor: float = 0.02, ceiling: float = 0.98, blur_px: int = 0) -> np.ndarray:
    """Render person boxes as filled soft boxes: a foreground likelihood image.

    Parameters
    ----------
    boxes_ltwh : array_like, shape (N, 4)
        ``left, top, width, height`` in pixels (MOTChallenge layout; top-left
        origin, u right, v down).
    width_px, height_px : int
        Image size [px].
    confidence : array_like, shape (N,), optional
        Detector score in [0, 1] per box (1 if omitted); a pixel inside several
        boxes takes the largest.
    floor, ceiling : float
        Likelihood outside any box, and inside a box of confidence 1.
    blur_px : int
        Box-filter side [px] softening the box edges (0 = none).

    Returns
    -------
    ndarray, shape (height_px, width_px), float32
    """
    b = np.asarray(boxes_ltwh, dtype=float).reshape(-1, 4) if np.size(boxes_ltwh) else np.zeros((0, 4))
    if not np.isfinite(b).all():
        raise ValueError("boxes_ltwh has non-finite entries")
    conf = np.ones(len(b)) if confidence is None else np.asarray(confidence, dtype=float).reshape(-1)
    if conf.shape != (len(b),):
        raise ValueError(f"confidence must have shape ({len(b)},), got {conf.shape}")
    if len(conf) and (conf.min() < 0 or conf.max() > 1):
        raise ValueError("confidence must lie in [0, 1] (rescale detector scores first)")
    img = np.zeros((int(height_px), int(width_px)), dtype=np.float32)
    x0 = np.clip(np.floor(b[:, 0]), 0, width_px).astype(int)
    y0 = np.clip(np.floor(b[:, 1]), 0, height_px).astype(int)
    x1 = np.clip(np.ceil(b[:, 0] + b[:, 2]), 0, width_px).astype(int)
    y1 = np.clip(np.ceil(b[:, 1] + b[:, 3]), 0, height_px).astype(int)
    # Few boxes per frame: one slice assignment each.
    for i in np.argsort(conf):
        img[y0[i]:y1[i], x0[i]:x1[i]] = np.maximum(img[y0[i]:y1[i], x0[i]:x1[i]], conf[i])
    return _soften(img, blur_px, floor, ceiling)


def read_mot_detections(path) -> dict[int, np.ndarray]:
    """Read a MOTChallenge detection/ground-truth file.

    Rows: ``frame, id, left, top, width, height, conf, ...`` (comma-separated;
    extra columns ignored; frames as written in the file, usually 1-based).

    Returns
    -------
    dict
        ``frame -> ndarray (N, 5)`` of ``left, top, width, height, conf`` [px].
    """
    p = Path(path)
    try:
        a = np.loadtxt(p, delimiter=",", ndmin=2, usecols=range(7))
    except ValueError as exc:
        raise ValueError(f"{p}: expected MOTChallenge rows 'frame,id,left,top,width,height,conf,...': {exc}") from None
    if a.size == 0:
        return {}
    frames = a[:, 0].astype(int)
    out: dict[int, np.ndarray] = {}
    order = np.argsort(frames, kind="stable")
    splits = np.flatnonzero(np.diff(frames[order])) + 1
    for idx in np.split(order, splits):
        out[int(frames[idx[0]])] = a[idx][:, 2:7]
    return out
