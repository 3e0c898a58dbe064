"""The run configuration: one YAML file, validated by pydantic models.

Every numeric field carries its unit in its name (``_m``, ``_s``, ``_hz``, ``_m_s``) and, in its field
metadata, a human-readable ``unit`` and ``expected`` range; :func:`planefuse.config.load_config` quotes
them in its error messages and :func:`planefuse.config.example_yaml` writes them as comments.

Most fields stand for one attribute of the library's parameters (:class:`planefuse.pipeline.SystemParams`,
:class:`planefuse.outputs.OutputSettings`), named in the field's ``library`` metadata: the field's default
is that attribute's default, :meth:`RunConfig.system_params` sets it, and the rules it must follow are
the library's own (``__post_init__``), reported by :func:`~planefuse.config.load_config` at the field's
line. The models here check only what is the configuration's own: types, names, the size of the grid.
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path
from typing import Annotated, Any, Iterator, Literal

from pydantic import BaseModel, ConfigDict, Field, field_validator

from ..outputs import OutputSettings
from ..pipeline import RunPlan, SystemParams

__all__ = [
    "PlanesConfig",
    "SceneConfig",
    "CameraSensorConfig",
    "LaserSensorConfig",
    "SoundSensorConfig",
    "SensorsConfig",
    "FilterModelConfig",
    "DetectionModelConfig",
    "ModelsConfig",
    "OutputsConfig",
    "RunConfig",
    "library_fields",
]

#: The library values the configuration stands for, at their defaults: ``system.*`` and ``outputs.*``.
_LIBRARY_DEFAULTS = {"system": SystemParams(), "outputs": OutputSettings()}


def _library_value(path: str) -> Any:
    obj: Any = _LIBRARY_DEFAULTS
    for i, part in enumerate(path.split(".")):
        obj = obj[part] if i == 0 else getattr(obj, part)
    return obj


def _field(default: Any = ..., *, description: str, unit: str = "", expected: str = "", library: str = "",
           **kw: Any) -> Any:
    """A pydantic Field whose metadata holds the unit and expected range quoted in errors and comments, and
    the library attribute (``system.tracking.tracker.gate_m``) it sets; a library field's default is the
    library's (``default`` is then left out, or given only to convert the library's value)."""
    extra = {"unit": unit, "expected": expected, "library": library}
    if library and default is ...:
        default = _library_value(library)
        if isinstance(default, tuple) and "heights" in library:
            default = list(default)
    return Field(default, description=description, json_schema_extra=extra, **kw)


def item_error(index: int, message: str) -> ValueError:
    """A validator error about item ``index`` of a list field; the loader appends ``[index]`` to the field path."""
    return ValueError(f"{ITEM_MARK}{index}: {message}")


#: Prefix of a validator message that names a list item (see :func:`item_error`).
ITEM_MARK = "@item "


class _Model(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True, validate_default=True)


class PlanesConfig(_Model):
    """The stack of horizontal planes z = h_0..h_{L-1} and their common XY grid."""

    heights_m: list[float] = _field(
        description="Heights of the planes above the ground plane pi_ref (z = 0)", unit="m",
        expected="at least one height, each in [0, 10], strictly increasing", library="system.heights_m",
    )
    x_range_m: tuple[float, float] | None = _field(
        description="World X extent of the grid (min, max); null = the recording's room less wall_margin_m",
        unit="m", expected="null or min < max", library="system.x_range_m",
    )
    y_range_m: tuple[float, float] | None = _field(
        description="World Y extent of the grid (min, max); null = the recording's room less wall_margin_m",
        unit="m", expected="null or min < max", library="system.y_range_m",
    )
    wall_margin_m: float = _field(
        description="Margin kept from the room's walls when the extent comes from the recording", unit="m",
        expected=">= 0", library="system.wall_margin_m",
    )
    cell_size_m: float = _field(
        description="Side of a square grid cell", unit="m", expected="in (0, 5]", library="system.cell_size_m"
    )


class SceneConfig(_Model):
    """What is known of the installation's static scene (issue 17): its occluders."""

    occluder_boxes_m: list[tuple[float, float, float, float, float, float]] = _field(
        [], description="Static occluders (pillars, shelves, counters), axis-aligned boxes [x_min, x_max, y_min, "
        "y_max, z_min, z_max] in the world frame: each camera leaves the cells they hide from it unobserved, and "
        "the cells they fill hold no person (planefuse.grid.cells_hidden_by_occluders); cameras' sensor_model cell",
        unit="m", expected="each minimum below its maximum", library="system.occluder_boxes_m",
    )


class CameraSensorConfig(_Model):
    """Cameras: background subtraction, then registration of the foreground on the planes (planefuse.vision)."""

    enabled: bool = _field(description="Use the cameras", library="system.cameras")
    foreground_method: Literal["knn", "mog2", "cnt", "mean", "none"] = _field(
        description="Background subtractor: OpenCV's knn, mog2 or cnt (opencv-contrib), or mean (a running-average "
        "background per pixel, numba: 13x cheaper than knn per frame, for steady lighting; it does not follow a "
        "real camera's exposure changes), or none (no subtraction: the person_detector's boxes alone)",
        expected="knn, mog2, cnt, mean or none",
        library="system.camera_params.foreground.method",
    )
    history_frames: int = _field(
        description="Frames in the background model's history", unit="frames", expected="an integer >= 1",
        library="system.camera_params.foreground.history",
    )
    var_threshold: float | None = _field(
        description="MOG2 varThreshold (squared Mahalanobis distance) or KNN dist2Threshold; null = OpenCV's default",
        expected="null or > 0", library="system.camera_params.foreground.threshold",
    )
    detect_shadows: bool = _field(
        description="Let the subtractor mark shadows (then treated as background)",
        library="system.camera_params.foreground.detect_shadows",
    )
    p_foreground_given_occupied: float = _field(
        description="Sensor model P(foreground | cell occupied)", expected="in (0, 1)",
        library="system.camera_params.fusion.p_detect",
    )
    p_foreground_given_free: float = _field(
        description="Sensor model P(foreground | cell free)", expected="in (0, 1), below p_foreground_given_occupied",
        library="system.camera_params.fusion.p_false_alarm",
    )
    attitude_source: Literal["calibration", "imu"] = _field(
        description="Where each camera's attitude comes from: its calibration (fixed) or its IMU (followed over time)",
        expected="calibration or imu", library="system.camera_params.registration.attitude_source",
    )
    attitude_tolerance_px: float = _field(
        description="With imu: the map that brings a turned camera's frames back to its calibrated view is rebuilt "
                    "when its attitude moved an image point by more",
        unit="px", expected="> 0", library="system.camera_params.registration.tolerance_px",
    )
    imu_filter: Literal["imufusion", "madgwick", "mahony", "ekf"] = _field(
        description="With imu: attitude filter (planefuse.geometry.attitude_from_imu method; imufusion with its "
                    "selected settings by default, docs/results.md)",
        expected="imufusion, madgwick, mahony or ekf",
        library="system.camera_params.registration.imu_filter",
    )
    ignore_rects_px: list[tuple[str, int, int, int, int]] = _field(
        [], description="Image regions that are not scene evidence, besides the recording's own (planefuse import "
        "--ignore-rect): [camera, u_min, v_min, u_max, v_max] each, max exclusive (a watermark, a TV, a privacy "
        "zone found after the import)", unit="px", expected="camera name and 0 <= u_min < u_max, 0 <= v_min < v_max",
        library="system.camera_ignore_rects_px",
    )
    sensor_model: Literal["cell", "generative"] = _field(
        description="Cameras' evidence on the planes: per cell (each cell scored on its own) or generative (people "
                    "on the grid explain each whole foreground image, Fleuret et al. 2008; docs/cameras.md)",
        expected="cell or generative", library="system.camera_params.sensor_model",
    )
    # --- foreground front end on real video (issue 14): illumination, shadows, relearning, clean-up ---
    learning_rate: float = _field(
        description="Background model's learning rate per frame; -1 = automatic (1 / frames seen, then 1 / "
        "history_frames)", expected="-1 or in [0, 1]", library="system.camera_params.foreground.learning_rate",
    )
    primed_rate: Literal["steady", "automatic"] = _field(
        description="How an automatic background model learns after the recording's empty-scene image primed it: "
        "steady (1 / history_frames: a real empty scene) or automatic (OpenCV's fast start goes on: an estimated "
        "scene, `planefuse import --background-median-s`)", expected="steady or automatic",
        library="system.camera_params.foreground.primed_rate",
    )
    shadow_likelihood: float = _field(
        description="Foreground likelihood of a shadow-labelled pixel (detect_shadows): low = background lit "
        "differently; 0.5 = unknown (dark clothes on a light floor are labelled shadow)", expected="in [0, 1]",
        library="system.camera_params.foreground.shadow_likelihood",
    )
    gain_compensation: bool = _field(
        description="Divide each frame by its per-channel gain against a learnt reference background before "
        "subtraction (automatic exposure, white balance, clouds)",
        library="system.camera_params.foreground.gain_compensation",
    )
    gain_blocks: tuple[int, int] = _field(
        description="With gain_compensation: (rows, cols) of blocks of the gain field; (1, 1) = one gain per "
        "channel", expected="two integers >= 1", library="system.camera_params.foreground.gain_blocks",
    )
    gain_rate: float = _field(
        description="With gain_compensation: running-average rate of the reference background", unit="1/frame",
        expected="in (0, 1]", library="system.camera_params.foreground.gain_rate",
    )
    relearn_fraction: float | None = _field(
        description="A frame with more than this share of its pixels foreground is a sudden global change: no "
        "evidence, fast relearning; null = off", expected="null or in (0, 1)",
        library="system.camera_params.foreground.relearn_fraction",
    )
    relearn_frames: int = _field(
        description="Frames of fast relearning after a sudden change", unit="frames", expected="an integer >= 1",
        library="system.camera_params.foreground.relearn_frames",
    )
    relearn_rate: float = _field(
        description="Learning rate while relearning", unit="1/frame", expected="in (0, 1]",
        library="system.camera_params.foreground.relearn_rate",
    )
    selective_update: bool = _field(
        description="Keep the silhouettes of the people the cameras' model found at the previous instant out of the "
        "background model (people who stand still do not fade into it); knn only",
        library="system.camera_params.foreground.selective_update",
    )
    selective_source: Literal["model", "detector"] = _field(
        description="With selective_update: what is kept out of the background model, the people the cameras' model "
        "found at the previous instant (model) or the person_detector's boxes of the previous frame (detector)",
        expected="model or detector", library="system.camera_params.foreground.selective_source",
    )
    selective_max_frames: int = _field(
        description="With selective_update: a pixel is kept out for at most this many consecutive frames, then "
        "learnt (a ghost of a background object that moved still heals)", unit="frames",
        expected="an integer >= 1", library="system.camera_params.foreground.selective_max_frames",
    )
    person_detector: Literal["hog", "yolox"] | None = _field(
        description="A person detector beside the background subtraction: 'yolox' = a pretrained YOLOX ONNX model "
        "(person_model; docs/cameras.md), 'hog' = OpenCV's HOG people detector (in opencv-contrib from OpenCV 5); "
        "its boxes are the people's silhouettes (foreground); null = none",
        expected="null, 'hog' or 'yolox'", library="system.camera_params.foreground.person_detector",
    )
    person_model: str | None = _field(
        description="With person_detector yolox: the ONNX file of a YOLOX export (Nano, Tiny, S, ... from the YOLOX "
        "project's releases; planefuse never downloads it), relative to this file", expected="a path or null",
        library="system.camera_params.foreground.person_model",
    )
    person_engine: Literal["auto", "opencv", "onnxruntime"] = _field(
        description="With person_detector yolox: what runs the model: 'onnxruntime' (pip install "
        "'planefuse[onnxruntime]'; about half the cost on one core), 'opencv' (OpenCV's DNN module, always there), "
        "'auto' = onnxruntime where installed, else opencv (metrics.json says which ran)",
        expected="'auto', 'opencv' or 'onnxruntime'", library="system.camera_params.foreground.person_engine",
    )
    person_input_px: tuple[int, int] | None = _field(
        description="With person_detector yolox: (width, height) of the canvas each frame is letterboxed into; null "
        "= fitted to the frame (its own size, or its longer side reduced to 416, each side up to a multiple of 32)",
        unit="px", expected="null or two multiples of 32",
        library="system.camera_params.foreground.person_input_px",
    )
    person_upscale: float = _field(
        description="With person_detector hog: enlargement of the frame before detection (the detector's window is "
        "128 px tall)", expected="> 0", library="system.camera_params.foreground.person_upscale",
    )
    person_min_score: float | None = _field(
        description="With person_detector: smallest score of a kept box (yolox: person probability, null = 0.5; "
        "hog: SVM margin, null = 0.3)", expected="null or a finite number (yolox: in [0, 1])",
        library="system.camera_params.foreground.person_min_score",
    )
    person_nms_iou: float = _field(
        description="With person_detector yolox: a box overlapping a better one by more than this IoU is dropped",
        expected="in (0, 1]", library="system.camera_params.foreground.person_nms_iou",
    )
    person_likelihood: float | None = _field(
        description="With person_detector: foreground likelihood at least given to a detected person's box; 0 = the "
        "boxes leave the foreground as it is; null = the detector's default (hog 0.9, yolox 0: its boxes reach the "
        "planes as evidence, box_free_log_odds)", expected="null or in [0, 1]",
        library="system.camera_params.foreground.person_likelihood",
    )
    box_log_odds: float | None = _field(
        description="With person_detector: peak log-odds each box adds around its foot point on the ground, on every "
        "plane up to the head (one view places a person; docs/detector.md); 0 = no foot points; null = the "
        "detector's default (yolox 1, chosen on the EPFL terrace's tuning frames; hog 0)",
        expected="null or >= 0", library="system.camera_params.boxes.log_odds",
    )
    box_foot_std_frac: float = _field(
        description="With box_log_odds: standard deviation of a box's foot pixel in each image direction, as a share "
        "of the box's height (mapped to the ground: grows with distance)", expected="> 0",
        library="system.camera_params.boxes.foot_std_frac",
    )
    box_free_log_odds: float | None = _field(
        description="With person_detector: log-odds (<= 0) each camera gives a ground cell it sees outside every one "
        "of its boxes, on every plane (the detector found nobody there; cells inside a box, hidden behind a detected "
        "person, get none); 0 = none; null = the detector's default (yolox -3, chosen on the EPFL terrace's tuning "
        "frames; hog 0)", expected="null or <= 0", library="system.camera_params.boxes.free_log_odds",
    )
    box_override: bool = _field(
        description="With box_log_odds: where a box's bump lies, the sensor model's evidence against a person is "
        "dropped (a detected person who stands still has faded from the background model)",
        library="system.camera_params.boxes.override",
    )
    box_min_std_m: float = _field(
        description="With box_log_odds: standard deviation added to a foot point in every ground direction", unit="m",
        expected="> 0", library="system.camera_params.boxes.min_std_m",
    )
    person_outside_weight: float = _field(
        description="With person_detector: the background subtraction's foreground outside every box is scaled by "
        "this towards foreground_floor (1 = unchanged, 0 = only the boxes)", expected="in [0, 1]",
        library="system.camera_params.foreground.person_outside_weight",
    )
    open_px: int = _field(
        description="Side of the morphological opening removing speckle from the foreground; 0 = none", unit="px",
        expected="an integer >= 0", library="system.camera_params.foreground.open_px",
    )
    close_px: int = _field(
        description="Side of the morphological closing filling holes in the foreground; 0 = none", unit="px",
        expected="an integer >= 0", library="system.camera_params.foreground.close_px",
    )
    blur_px: int = _field(
        description="Side of the box filter softening the foreground into a likelihood; 0 = none", unit="px",
        expected="an integer >= 0", library="system.camera_params.foreground.blur_px",
    )
    foreground_floor: float = _field(
        description="Foreground likelihood of a background pixel (no pixel is certain)", expected="in [0, 1], "
        "below foreground_ceiling", library="system.camera_params.foreground.floor",
    )
    foreground_ceiling: float = _field(
        description="Foreground likelihood of a foreground pixel", expected="in [0, 1]",
        library="system.camera_params.foreground.ceiling",
    )
    subtraction_downscale: int = _field(
        description="Subtract the background on frames reduced by this factor per direction (faster: 2 = a quarter "
        "of the pixels), the likelihood interpolated back to full size; 1 = full resolution",
        expected="an integer >= 1", library="system.camera_params.foreground.downscale",
    )
    plate_frames: int | None = _field(
        description="Times the empty-scene plate primes the background model (with primed_rate automatic also its "
        "weight); null = the method's own need (10; CNT twice cnt_min_stability)", unit="frames",
        expected="an integer >= 1 or null", library="system.camera_params.foreground.plate_frames",
    )
    knn_samples: int = _field(
        description="KNN background samples kept per pixel (OpenCV's nSamples; fewer are faster, 3 = 17 % less "
        "KNN time than 7)", expected="an integer >= 2", library="system.camera_params.foreground.knn_samples",
    )
    cnt_min_stability: int = _field(
        description="CNT: frames a pixel must keep its grey level to become background (OpenCV's "
        "minPixelStability)", unit="frames", expected="an integer >= 1, below history_frames",
        library="system.camera_params.foreground.cnt_min_stability",
    )
    mean_foreground_rate: float = _field(
        description="mean: rate of learning foreground and shadow pixels into the background, relative to the "
        "learning rate (0 = never, 1 = like background pixels)", expected="in [0, 1]",
        library="system.camera_params.foreground.mean_foreground_rate",
    )
    frame_stride: int = _field(
        description="Process every k-th synchronised camera instant (the others are not read; the background "
        "models learn from the processed frames); 1 = every frame",
        expected="an integer >= 1", library="system.camera_params.frame_stride",
    )
    max_rate_hz: float | None = _field(
        description="Process at most this many camera instants per second (the first at or after each multiple of "
        "its period), the others not read: frame_stride in time, for recordings of any frame rate; null = every "
        "instant; the default is the default output rate (models.filter.output_period_s 0.2 s)", unit="Hz",
        expected="null or > 0", library="system.camera_params.max_rate_hz",
    )
    # --- generative sensor model (sensor_model: generative; planefuse.vision.GenerativeSensorParams) ---
    generative_people_per_m2: float = _field(
        description="Generative model: prior density of people", unit="1/m^2", expected="> 0",
        library="system.camera_params.generative.people_per_m2",
    )
    generative_sigma: float = _field(
        description="Generative model: scale of the image pseudo-distance (larger = images trusted less)",
        expected="> 0", library="system.camera_params.generative.sigma",
    )
    generative_radius_m: float = _field(
        description="Generative model: radius of a person's cylinder", unit="m", expected="> 0",
        library="system.camera_params.generative.radius_m",
    )
    generative_height_range_m: tuple[float, float] | None = _field(
        description="Generative model: bottom and top of a person's cylinder; null = the stack's height bands",
        unit="m", expected="null or (bottom, top)", library="system.camera_params.generative.height_range_m",
    )
    generative_max_log_odds: float = _field(
        description="Generative model: bound on one instant's evidence per cell", expected="> 0",
        library="system.camera_params.generative.max_log_odds",
    )
    generative_detection_mass: float = _field(
        description="Generative model (per frame): a person is reported where the expected number of people "
        "within radius reaches this", expected="> 0", library="system.camera_params.generative.detection_mass",
    )
    generative_foreground_threshold: float | None = _field(
        description="Generative model: likelihoods at or above this are foreground, the rest background; null = "
        "keep the likelihoods", expected="null or in [0, 1]",
        library="system.camera_params.generative.foreground_threshold",
    )
    generative_evidence_prior: float | Literal["detection"] | None = _field(
        description="Generative model: the filter's evidence is the marginal's log-odds against this probability; "
        "null = against the model's prior; detection = the value at which one frame's evidence of a person the "
        "per-frame detector just reports (generative_detection_mass) reaches models.detection.column_threshold "
        "(planefuse.vision.detection_evidence_prior)", expected="null, detection or in (0, 1)",
        library="system.camera_params.generative.evidence_prior",
    )
    generative_hidden_unknown: bool = _field(
        description="Generative model, with generative_evidence_prior: log-odds between the model's prior and "
        "generative_evidence_prior give no evidence, so that a cell hidden behind other people in every view "
        "(marginals left at the prior) is unknown to the filter rather than evidence against a body",
        expected="true or false", library="system.camera_params.generative.hidden_unknown",
    )
    generative_max_iterations: int = _field(
        description="Generative model: most mean-field iterations per instant (they set its cost: the solver's "
        "relative tolerance rarely stops it earlier on real images)", expected="an integer >= 1",
        library="system.camera_params.generative.max_iterations",
    )
    generative_track_prior_ratio: float = _field(
        description="Generative model, with the filter: a ground location within generative_track_prior_radius_m of "
        "a tracked person's predicted position starts from this times the prior (the evidence is measured against "
        "it, so the filter does not count the tracks twice); 1 = every instant on its own",
        expected=">= 1", library="system.camera_params.generative.track_prior_ratio",
    )
    generative_track_prior_radius_m: float = _field(
        description="Generative model: radius of the disc around each tracked person's predicted position where "
        "generative_track_prior_ratio applies", unit="m", expected="> 0",
        library="system.camera_params.generative.track_prior_radius_m",
    )

    @field_validator("foreground_method", mode="before")
    @classmethod
    def _lower(cls, v: Any) -> Any:
        return v.lower() if isinstance(v, str) else v


class LaserSensorConfig(_Model):
    """Laser range finders: hits become evidence on the plane whose height band holds them (planefuse.laser)."""

    enabled: bool = _field(description="Use the laser range finders", library="system.laser")
    p_occupied_hit: float = _field(
        description="Inverse sensor model: P(occupied) of a cell holding a beam's end point",
        expected="in (0.5, 1)", library="system.laser_model.p_occupied_hit",
    )
    p_occupied_free: float = _field(
        description="Inverse sensor model: P(occupied) of a cell a beam crossed before its end",
        expected="in (0, 0.5)", library="system.laser_model.p_occupied_free",
    )
    no_return_free_m: float | None = _field(
        description="Free space along a beam with no return, up to this range; null = the scanner's range_max",
        unit="m", expected="null or > 0", library="system.laser_model.no_return_free_m",
    )


class SoundSensorConfig(_Model):
    """Binaural microphones: Bayesian azimuth saliency registered as wedges on the planes (planefuse.audio)."""

    enabled: bool = _field(description="Use the binaural microphone pair", library="system.sound")
    block_length_s: float = _field(
        description="Length of the audio blocks localised one at a time", unit="s", expected="> 0",
        library="system.sound_block_s",
    )
    model_path: Path | None = _field(
        description="Calibrated sensor model (planefuse audio calibrate); null = the spherical-head model "
        "(relative paths are relative to this file)",
        expected="null or a sensor model file", library="system.sound_model_path",
    )


class SensorsConfig(_Model):
    """Which modalities take part, and their front-end parameters."""

    cameras: CameraSensorConfig = _field(CameraSensorConfig(), description="Cameras")
    laser: LaserSensorConfig = _field(LaserSensorConfig(), description="Laser range finders")
    sound: SoundSensorConfig = _field(SoundSensorConfig(), description="Binaural microphone pair")


class FilterModelConfig(_Model):
    """Bayesian Occupancy Filter per plane (planefuse.tracking.BOFParams) and its time handling."""

    enabled: bool = _field(
        description="Filter over time; false = each output step is the current evidence alone (an ablation)",
        library="system.use_filter",
    )
    n_velocities_per_axis: int = _field(
        description="Velocity hypotheses per axis (odd: the set includes v = 0)", expected="odd, >= 1",
        library="system.tracking.bof.n_velocities_per_axis",
    )
    velocity_max_m_s: float = _field(
        description="Largest velocity hypothesis per axis", unit="m/s", expected="in [0, 10]",
        library="system.tracking.bof.velocity_max_m_s",
    )
    prior_occupancy: float = _field(
        description="Prior occupancy probability of a cell", expected="in (0, 1)",
        library="system.tracking.bof.prior_occupancy",
    )
    decay_rate_hz: float = _field(
        description="Rate at which an unobserved cell's occupancy returns to the prior", unit="1/s",
        expected=">= 0", library="system.tracking.bof.decay_rate_hz",
    )
    velocity_noise_rate_hz: float = _field(
        description="Rate of velocity changes (mixing between neighbouring velocity hypotheses)", unit="1/s",
        expected=">= 0", library="system.tracking.bof.velocity_noise_rate_hz",
    )
    merge_tolerance_s: float = _field(
        description="Evidence messages closer in time than this are fused in one update", unit="s",
        expected=">= 0", library="system.tracking.merge_tolerance_s",
    )
    window_s: float = _field(
        description="Re-ordering window for out-of-order messages", unit="s", expected=">= 0",
        library="system.tracking.window_s",
    )
    camera_correlation_s: float = _field(
        description="Correlation time of each camera's evidence errors: a camera's frame counts "
        "min(1, dt / this) of an independent observation, dt the time since that camera's previous live frame; "
        "0 = every frame fully", unit="s", expected=">= 0", library="system.camera_correlation_s",
    )
    laser_correlation_s: float = _field(
        description="The same for each laser's scans", unit="s", expected=">= 0",
        library="system.laser_correlation_s",
    )
    sound_correlation_s: float = _field(
        description="The same for each binaural head's blocks", unit="s", expected=">= 0",
        library="system.sound_correlation_s",
    )
    output_period_s: float = _field(
        description="Time between output steps (occupancy, detections, tracks)", unit="s", expected="> 0",
        library="system.output_period_s",
    )

    @field_validator("n_velocities_per_axis")
    @classmethod
    def _odd(cls, v: int) -> int:
        if v % 2 == 0:
            raise ValueError(f"must be odd so that v = 0 is a hypothesis, got {v}")
        return v


class DetectionModelConfig(_Model):
    """From occupancy to people: column clustering and track management (planefuse.tracking)."""

    column_threshold: float = _field(
        description="Column evidence (mean capped log-odds per observed body plane) above which a cluster is a "
        "person hypothesis", expected="finite", library="system.tracking.cluster.threshold",
    )
    person_radius_m: float = _field(
        description="Radius of a person's footprint (clustering; MOTChallenge boxes)", unit="m", expected=">= 0",
        library="system.tracking.cluster.person_radius_m",
    )
    min_separation_m: float = _field(
        description="Closest two people may stand", unit="m", expected=">= 0",
        library="system.tracking.cluster.min_separation_m",
    )
    gate_m: float = _field(
        description="Largest distance between a track's prediction and the cluster it is associated with",
        unit="m", expected="> 0", library="system.tracking.tracker.gate_m",
    )
    confirm_hits: int = _field(description="Associations before a track is reported", expected="an integer >= 1",
                               library="system.tracking.tracker.confirm_hits")
    max_misses: int = _field(
        description="Output steps a track may go unobserved before it is ended", unit="steps",
        expected="an integer >= 0", library="system.tracking.tracker.max_misses",
    )
    max_coast_report: int = _field(
        description="Output steps a confirmed track without a cluster is still reported (at its prediction)",
        unit="steps", expected="an integer >= 0", library="system.tracking.tracker.max_coast_report",
    )
    birth_exclusion_m: float = _field(
        description="No track is started on a cluster closer than this to a confirmed track", unit="m",
        expected=">= 0", library="system.tracking.tracker.birth_exclusion_m",
    )
    gate_chi2: float = _field(
        description="Mahalanobis gate of a track's position innovation (chi-square, 2 degrees of freedom; 9.21 = "
        "99 %)", expected="> 0", library="system.tracking.tracker.gate_chi2",
    )
    position_std_m: float = _field(
        description="Standard deviation of a cluster's position per axis (Kalman tracker measurement)", unit="m",
        expected="> 0", library="system.tracking.tracker.position_std_m",
    )
    velocity_std_m_s: float = _field(
        description="Standard deviation added to a cluster's BOF velocity variance per axis (Kalman tracker "
        "measurement)", unit="m/s", expected="> 0", library="system.tracking.tracker.velocity_std_m_s",
    )
    acceleration_std_m_s2: float = _field(
        description="White-noise acceleration of the tracks' constant-velocity model", unit="m/s^2",
        expected=">= 0", library="system.tracking.tracker.acceleration_std_m_s2",
    )
    clutter_density_per_m2: float = _field(
        description="Density of false clusters (multi-view ghosts, trails) per step, against which the tracker "
        "weighs each track-to-cluster pairing (with a detection probability of 0.9)", unit="1/m^2",
        expected="> 0", library="system.tracking.tracker.clutter_density_per_m2",
    )
    support_threshold: float | None = _field(
        description="Column evidence near a confirmed track's prediction that keeps it reported without a cluster "
        "(the filter still holds the person below column_threshold: partly hidden, a camera gone); null = none",
        expected="null or finite", library="system.tracking.tracker.support_threshold",
    )
    reacquire_speed_m_s: float | None = _field(
        description="A track lost for a step or more takes a cluster no track took within its covariance gate and "
        "gate_m + this x the time it has been lost (tentative again, under its own id); null = never", unit="m/s",
        expected="null or >= 0", library="system.tracking.tracker.reacquire_speed_m_s",
    )
    velocity_decorrelation: bool = _field(
        description="Count the filter's cluster velocities once per the filter's velocity memory in the tracks' "
        "Kalman update (they repeat the same evidence from step to step); false: each step's velocity is new",
        library="system.tracking.tracker.velocity_decorrelation",
    )
    position_from_step_evidence: bool = _field(
        description="Take each person's position from the evidence fused since the previous output step, by "
        "mean-shift from the filter's mode (the filter's own mode lags a walker and runs on at a stop or a turn); "
        "false: the filter's mode", library="system.tracking.cluster.position_from_step_evidence",
    )
    appearance_weight: float | None = _field(
        description="Weight of the appearance distance (colour of upper and lower body in every camera, 0..1) in the "
        "tracker's pairing cost, in -2 ln likelihood-ratio units per unit distance; null = position and velocity "
        "alone (docs/identities.md)", expected="null or >= 0", library="system.tracking.tracker.appearance_weight",
    )
    appearance_reference_distance: float = _field(
        description="Appearance distance at which a pairing is as likely the same person as not", expected="0..1",
        library="system.tracking.tracker.appearance_reference_distance",
    )
    appearance_update_rate: float = _field(
        description="Rate at which a track's appearance model takes in each new view (a passer-by moves it by at "
        "most this)", expected="in (0, 1]", library="system.tracking.tracker.appearance_update_rate",
    )
    reid_max_s: float | None = _field(
        description="A track lost for at most this long is re-identified by appearance when its person comes back "
        "(a new track confirmed near its last position takes its identity); null = no re-identification",
        unit="s", expected="null or >= 0", library="system.tracking.tracker.reid_max_s",
    )
    reid_max_distance_m: float = _field(
        description="Largest distance between a lost track's last position and a new track for re-identification",
        unit="m", expected=">= 0", library="system.tracking.tracker.reid_max_distance_m",
    )
    reid_max_appearance_distance: float = _field(
        description="Largest appearance distance between a lost track and a new track for re-identification",
        expected="0..1", library="system.tracking.tracker.reid_max_appearance_distance",
    )
    stitch: bool = _field(
        description="After the run, join tracklets across gaps by time, space and appearance (offline; a run into a "
        "folder writes the live tracks as they were, the stitched ones to tracks_stitched.csv, scored under "
        "'stitched'; a run in memory gives the stitched identities)",
        library="system.stitch.enabled",
    )
    stitch_max_gap_s: float = _field(
        description="Longest gap between a tracklet's end and the start of the one that continues it (stitching)",
        unit="s", expected="> 0", library="system.stitch.max_gap_s",
    )
    stitch_fill_gap_s: float | None = _field(
        description="After the stitching, place each identity on the steps of a gap of at most this long between "
        "two of its reports, on the straight line between them (offline); null = no filling",
        unit="s", expected="null or > 0", library="system.stitch.max_fill_gap_s",
    )
    stitch_smooth_s: float | None = _field(
        description="After the stitching and filling, each identity's positions smoothed in time by a Gaussian of "
        "this standard deviation (offline); null = as reported",
        unit="s", expected="null or > 0", library="system.stitch.smooth_sigma_s",
    )
    stitch_split_s: float | None = _field(
        description="Before the stitching joins tracklets, each is cut where the colours of the views it took change "
        "(two people exchanged by the tracker): the span of views compared on each side (offline); null = no cutting",
        unit="s", expected="null or > 0", library="system.stitch.split_window_s",
    )
    match_distance_m: float = _field(
        description="Evaluation: largest distance of a correct detection or track from the truth", unit="m",
        expected="> 0", library="system.match_distance_m",
    )


class ModelsConfig(_Model):
    """Filter and detection parameters."""

    filter: FilterModelConfig = _field(FilterModelConfig(), description="Bayesian Occupancy Filter")
    detection: DetectionModelConfig = _field(DetectionModelConfig(), description="Detection and tracking")


class OutputsConfig(_Model):
    """What a run writes and where."""

    out_dir: Path = _field(
        Path("planefuse-out"), description="Output folder (relative paths are relative to this file)",
        expected="a folder path",
    )
    zarr: bool = _field(description="Write per-plane occupancy over time to occupancy.zarr (needed to resume)",
                        library="outputs.zarr")
    chunk_steps: int = _field(
        description="Time steps per zarr chunk; a re-run resumes at the first unfinished chunk", unit="steps",
        expected="an integer >= 1", library="outputs.chunk_steps",
    )
    figures: bool = _field(description="Write PNG figures to figures/", library="outputs.figures")
    animation: Literal["none", "gif", "mp4"] = _field(
        description="Animation of the plane stack over time", expected="none, gif or mp4", library="outputs.animation"
    )
    report: bool = _field(description="Write the self-contained report.html", library="outputs.report")
    rerun: bool = _field(description="Write a rerun recording (planefuse.rrd) for the rerun viewer",
                         library="outputs.rerun")
    figure_dpi: int = _field(description="Resolution of the figures", unit="dpi", expected="an integer >= 1",
                             library="outputs.figure_dpi")
    animation_max_frames: int | None = _field(
        description="The animation shows at most this many output steps, evenly spaced (a longer run is subsampled "
        "and a warning says so); null = every step", unit="steps", expected="null or an integer >= 1",
        library="outputs.animation_max_frames",
    )
    camera_videos: bool = _field(
        description="Also write figures/camera_<name>_tracks.mp4 per camera: its frame at each output step with the "
        "tracks drawn from the feet to the head (at most animation_max_frames steps)", library="outputs.camera_videos",
    )
    mcap: bool = _field(description="Write planefuse.mcap: tracks, detections and occupancy grids in Foxglove's "
                        "schemas (opens in Foxglove)", library="outputs.mcap")
    ros2_bag: bool = _field(description="Write ros2_bag/: people_msgs/People, MarkerArray, PoseArray and an "
                            "OccupancyGrid per plane in a ROS 2 bag", library="outputs.ros2_bag")


def library_fields(model: type[BaseModel] | None = None, prefix: str = "") -> Iterator[tuple[str, str]]:
    """``(config field path, library attribute path)`` of every configuration field that sets a library value,
    e.g. ``("models.detection.gate_m", "system.tracking.tracker.gate_m")``."""
    model = RunConfig if model is None else model
    for name, info in model.model_fields.items():
        ann = info.annotation
        if isinstance(ann, type) and issubclass(ann, BaseModel):
            yield from library_fields(ann, f"{prefix}{name}.")
            continue
        extra = info.json_schema_extra if isinstance(info.json_schema_extra, dict) else {}
        if extra.get("library"):
            yield f"{prefix}{name}", str(extra["library"])


def _config_value(cfg: BaseModel, path: str) -> Any:
    obj: Any = cfg
    for part in path.split("."):
        obj = getattr(obj, part)
    return obj


def _with_values(obj: Any, values: dict[tuple[str, ...], Any]) -> Any:
    """``obj`` (a frozen dataclass) with the attributes at the given paths replaced, each object rebuilt once
    (children first), so that rules between its fields see the final values together."""
    direct = {k[0]: v for k, v in values.items() if len(k) == 1}
    children: dict[str, dict[tuple[str, ...], Any]] = {}
    for k, v in values.items():
        if len(k) > 1:
            children.setdefault(k[0], {})[k[1:]] = v
    for name, sub in children.items():
        direct[name] = _with_values(getattr(obj, name), sub)
    return replace(obj, **direct) if direct else obj


class RunConfig(_Model):
    """One planefuse run."""

    recording: Path = _field(
        description="Recording folder holding scene.yaml (relative paths are relative to this file)",
        expected="a folder path",
    )
    planes: PlanesConfig = _field(PlanesConfig(), description="Plane stack and grid")
    scene: SceneConfig = _field(SceneConfig(), description="Known static scene")
    sensors: SensorsConfig = _field(SensorsConfig(), description="Sensors")
    models: ModelsConfig = _field(ModelsConfig(), description="Models")
    outputs: OutputsConfig = _field(OutputsConfig(), description="Outputs")

    def resolved(self, base_dir: Path) -> "RunConfig":
        """Copy with ``recording``, ``outputs.out_dir``, ``sensors.sound.model_path`` and
        ``sensors.cameras.person_model`` made absolute against ``base_dir``."""

        def absolute(p: Path) -> Path:
            return (p if p.is_absolute() else base_dir / p).resolve()

        sound = self.sensors.sound
        if sound.model_path is not None:
            sound = sound.model_copy(update={"model_path": absolute(sound.model_path)})
        cameras = self.sensors.cameras
        if cameras.person_model is not None:
            cameras = cameras.model_copy(update={"person_model": str(absolute(Path(cameras.person_model)))})
        return self.model_copy(update={
            "recording": absolute(self.recording),
            "outputs": self.outputs.model_copy(update={"out_dir": absolute(self.outputs.out_dir)}),
            "sensors": self.sensors.model_copy(update={"sound": sound, "cameras": cameras}),
        })

    def _library_values(self, root: str) -> dict[tuple[str, ...], Any]:
        values = {}
        for field_path, lib in library_fields():
            head, _, rest = lib.partition(".")
            if head == root:
                v = _config_value(self, field_path)
                values[tuple(rest.split("."))] = tuple(v) if isinstance(v, list) else v
        if root == "system" and self.sensors.cameras.generative_evidence_prior == "detection":
            from ..vision import detection_evidence_prior

            values[("camera_params", "generative", "evidence_prior")] = detection_evidence_prior(
                self.sensors.cameras.generative_detection_mass, self.models.detection.column_threshold)
        return values

    def _library(self, root: str) -> Any:
        return _with_values(_LIBRARY_DEFAULTS[root], self._library_values(root))

    def library_errors(self) -> list[ValueError]:
        """Every library rule this configuration breaks: each parameter class is built on its own from its
        fields (so that one error does not hide another), then the whole, for the rules between classes."""
        errors: list[ValueError] = []
        for root in _LIBRARY_DEFAULTS:
            values = self._library_values(root)
            groups: dict[tuple[str, ...], dict[tuple[str, ...], Any]] = {}
            for path, v in values.items():
                groups.setdefault(path[:-1], {})[path[-1:]] = v
            n = len(errors)
            for parent, group in groups.items():
                obj = _LIBRARY_DEFAULTS[root]
                for part in parent:
                    obj = getattr(obj, part)
                try:
                    _with_values(obj, group)
                except ValueError as err:
                    errors.append(err)
            if len(errors) == n:
                try:
                    _with_values(_LIBRARY_DEFAULTS[root], values)
                except ValueError as err:
                    errors.append(err)
        return errors

    def system_params(self) -> SystemParams:
        """The :class:`~planefuse.pipeline.SystemParams` this configuration runs with (raises ``ValueError``
        naming ``Class.attribute`` where a library rule is broken; :func:`~planefuse.config.load_config`
        reports it at the configuration field)."""
        return self._library("system")

    def output_settings(self) -> OutputSettings:
        """The :class:`~planefuse.outputs.OutputSettings` of the ``outputs`` section."""
        return self._library("outputs")

    def plan(self, *, resume: bool = True) -> RunPlan:
        """The :class:`~planefuse.pipeline.RunPlan` of this configuration (paths as they are: load the file
        with :func:`~planefuse.config.load_config` to have them resolved)."""
        from ._load import config_hash, config_yaml

        return RunPlan(self.system_params(), self.outputs.out_dir, self.output_settings(), config_yaml(self),
                       config_hash(self), resume)
