"""The run configuration: one YAML file, validated by pydantic models.

Every numeric field carries its unit in its name (``_m``, ``_s``, ``_hz``,
``_m_s``) and, in its field metadata, a human-readable ``unit`` and
``expected`` range; :func:`planefuse.config.load_config` quotes them in its
error messages and :func:`planefuse.config.example_yaml` writes them as
comments.
"""

from __future__ import annotations

from pathlib import Path
from typing import Annotated, Any, Literal

from pydantic import BaseModel, ConfigDict, Field, field_validator, model_validator

from ..grid import PlaneStack

__all__ = [
    "PlanesConfig",
    "CameraSensorConfig",
    "LaserSensorConfig",
    "SoundSensorConfig",
    "SensorsConfig",
    "FilterModelConfig",
    "DetectionModelConfig",
    "ModelsConfig",
    "OutputsConfig",
    "RunConfig",
]


def _field(default: Any = ..., *, description: str, unit: str = "", expected: str = "", **kw: Any) -> Any:
    """A pydantic Field whose metadata holds the unit and expected range quoted in errors and comments."""
    extra = {"unit": unit, "expected": expected}
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

    heights_m: list[Annotated[float, Field(ge=0.0, le=10.0)]] = _field(
        [0.1, 0.5, 1.0, 1.5],
        description="Heights of the planes above the ground plane pi_ref (z = 0)",
        unit="m",
        expected="at least one height, each in [0, 10], strictly increasing",
        min_length=1,
    )
    x_range_m: tuple[float, float] = _field(
        (0.0, 10.0), description="World X extent of the grid (min, max)", unit="m", expected="min < max"
    )
    y_range_m: tuple[float, float] = _field(
        (0.0, 10.0), description="World Y extent of the grid (min, max)", unit="m", expected="min < max"
    )
    cell_size_m: float = _field(
        0.1, description="Side of a square grid cell", unit="m", expected="in (0, 5]", gt=0.0, le=5.0
    )

    @field_validator("heights_m")
    @classmethod
    def _heights(cls, v: list[float]) -> list[float]:
        for i in range(1, len(v)):
            if v[i] <= v[i - 1]:
                raise item_error(i, f"{v[i]} m is not above the previous height {v[i - 1]} m")
        return v

    @field_validator("x_range_m", "y_range_m")
    @classmethod
    def _range(cls, v: tuple[float, float]) -> tuple[float, float]:
        if not v[0] < v[1]:
            raise ValueError(f"range min {v[0]} m must be below max {v[1]} m")
        return v

    @model_validator(mode="after")
    def _cells(self) -> "PlanesConfig":
        n = ((self.x_range_m[1] - self.x_range_m[0]) / self.cell_size_m) * (
            (self.y_range_m[1] - self.y_range_m[0]) / self.cell_size_m
        )
        if n * len(self.heights_m) > 50_000_000:
            raise ValueError(
                f"the grid would have {n * len(self.heights_m):.3g} cells (> 5e7); increase cell_size_m"
            )
        return self

    def to_stack(self) -> PlaneStack:
        """The :class:`~planefuse.grid.PlaneStack` this section describes."""
        return PlaneStack.from_extent(self.heights_m, self.x_range_m, self.y_range_m, self.cell_size_m)


class CameraSensorConfig(_Model):
    """Cameras: background subtraction, then registration of the foreground on the planes (planefuse.vision)."""

    enabled: bool = _field(True, description="Use the cameras")
    foreground_method: Literal["MOG2", "KNN"] = _field(
        "KNN", description="OpenCV background subtractor", expected="MOG2 or KNN"
    )
    history_frames: int = _field(
        500, description="Frames in the background model's history", unit="frames", expected=">= 1", ge=1
    )
    var_threshold: float | None = _field(
        None,
        description="MOG2 varThreshold (squared Mahalanobis distance) or KNN dist2Threshold; null = OpenCV's default",
        expected="null or > 0",
        gt=0.0,
    )
    detect_shadows: bool = _field(True, description="Let the subtractor mark shadows (then treated as background)")
    p_foreground_given_occupied: float = _field(
        0.9, description="Sensor model P(foreground | cell occupied)", expected="in (0, 1)", gt=0.0, lt=1.0
    )
    p_foreground_given_free: float = _field(
        0.2, description="Sensor model P(foreground | cell free)", expected="in (0, 1)", gt=0.0, lt=1.0
    )
    sensor_model: Literal["cell", "generative"] = _field(
        "cell",
        description="Cameras' evidence on the planes: per cell (each cell scored on its own) or generative (people "
                    "on the grid explain each whole foreground image, Fleuret et al. 2008; docs/cameras.md)",
        expected="cell or generative",
    )


class LaserSensorConfig(_Model):
    """Laser range finders: hits become evidence on the plane whose height band holds them (planefuse.laser)."""

    enabled: bool = _field(True, description="Use the laser range finders")
    p_occupied_hit: float = _field(
        0.9, description="Inverse sensor model: P(occupied) of a cell holding a beam's end point",
        expected="in (0.5, 1)", gt=0.5, lt=1.0,
    )
    p_occupied_free: float = _field(
        0.45, description="Inverse sensor model: P(occupied) of a cell a beam crossed before its end",
        expected="in (0, 0.5)", gt=0.0, lt=0.5,
    )
    no_return_free_m: float | None = _field(
        None, description="Free space along a beam with no return, up to this range; null = the scanner's range_max",
        unit="m", expected="null or > 0", gt=0.0,
    )


class SoundSensorConfig(_Model):
    """Binaural microphones: Bayesian azimuth saliency registered as wedges on the planes (planefuse.audio)."""

    enabled: bool = _field(True, description="Use the binaural microphone pair")
    block_length_s: float = _field(
        0.5, description="Length of the audio blocks localised one at a time", unit="s", expected="in (0, 10]",
        gt=0.0, le=10.0,
    )
    model_path: Path | None = _field(
        None, description="Calibrated sensor model (planefuse audio calibrate); null = the spherical-head model",
        expected="null or a file path",
    )


class SensorsConfig(_Model):
    """Which modalities take part, and their front-end parameters."""

    cameras: CameraSensorConfig = _field(CameraSensorConfig(), description="Cameras")
    laser: LaserSensorConfig = _field(LaserSensorConfig(), description="Laser range finders")
    sound: SoundSensorConfig = _field(SoundSensorConfig(), description="Binaural microphone pair")

    @model_validator(mode="after")
    def _any(self) -> "SensorsConfig":
        if not (self.cameras.enabled or self.laser.enabled or self.sound.enabled):
            raise ValueError("at least one of cameras, laser, sound must be enabled")
        return self


class FilterModelConfig(_Model):
    """Bayesian Occupancy Filter per plane (planefuse.tracking.BOFParams) and its time handling."""

    n_velocities_per_axis: int = _field(
        7, description="Velocity hypotheses per axis (odd: the set includes v = 0)", expected="odd, in [1, 15]",
        ge=1, le=15,
    )
    velocity_max_m_s: float = _field(
        1.5, description="Largest velocity hypothesis per axis", unit="m/s", expected="in (0, 10]", gt=0.0, le=10.0
    )
    prior_occupancy: float = _field(
        0.05, description="Prior occupancy probability of a cell", expected="in (0, 1)", gt=0.0, lt=1.0
    )
    decay_rate_hz: float = _field(
        0.5, description="Rate at which an unobserved cell's occupancy returns to the prior", unit="1/s",
        expected=">= 0", ge=0.0,
    )
    velocity_noise_rate_hz: float = _field(
        1.0, description="Rate of velocity changes (mixing between neighbouring velocity hypotheses)", unit="1/s",
        expected=">= 0", ge=0.0,
    )
    merge_tolerance_s: float = _field(
        0.05, description="Evidence messages closer in time than this are fused in one update", unit="s",
        expected="in [0, 1]", ge=0.0, le=1.0,
    )
    window_s: float = _field(
        0.2, description="Re-ordering window for out-of-order messages", unit="s", expected="in [0, 10]",
        ge=0.0, le=10.0,
    )
    output_period_s: float = _field(
        0.2, description="Time between output steps (occupancy, detections, tracks)", unit="s",
        expected="in (0, 10]", gt=0.0, le=10.0,
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
        1.5, description="Column log-odds above which a cluster is a person hypothesis", expected="> 0", gt=0.0
    )
    person_radius_m: float = _field(
        0.3, description="Radius of a person's footprint", unit="m", expected="in (0, 2]", gt=0.0, le=2.0
    )
    min_separation_m: float = _field(
        0.4, description="Closest two people may stand", unit="m", expected="in (0, 5]", gt=0.0, le=5.0
    )
    gate_m: float = _field(
        0.75, description="Largest distance between a track's prediction and the cluster it is associated with",
        unit="m", expected="> 0", gt=0.0,
    )
    confirm_hits: int = _field(3, description="Associations before a track is reported", expected=">= 1", ge=1)
    max_misses: int = _field(
        10, description="Output steps a track may go unobserved before it is ended", unit="steps",
        expected=">= 0", ge=0,
    )
    match_distance_m: float = _field(
        0.5, description="Evaluation: largest distance of a correct detection from the truth", unit="m",
        expected="> 0", gt=0.0,
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
    zarr: bool = _field(True, description="Write per-plane occupancy over time to occupancy.zarr")
    chunk_steps: int = _field(
        50, description="Time steps per zarr chunk; a re-run resumes at the first unfinished chunk",
        unit="steps", expected="in [1, 10000]", ge=1, le=10_000,
    )
    figures: bool = _field(True, description="Write PNG figures to figures/")
    animation: Literal["none", "gif", "mp4"] = _field(
        "gif", description="Animation of the plane stack over time", expected="none, gif or mp4"
    )
    report: bool = _field(True, description="Write the self-contained report.html")
    rerun: bool = _field(False, description="Write a rerun recording (planefuse.rrd) for the rerun viewer")
    figure_dpi: int = _field(100, description="Resolution of the figures", unit="dpi", expected="in [30, 600]",
                             ge=30, le=600)


class RunConfig(_Model):
    """One planefuse run."""

    recording: Path = _field(
        description="Recording folder holding scene.yaml (relative paths are relative to this file)",
        expected="a folder path",
    )
    planes: PlanesConfig = _field(PlanesConfig(), description="Plane stack and grid")
    sensors: SensorsConfig = _field(SensorsConfig(), description="Sensors")
    models: ModelsConfig = _field(ModelsConfig(), description="Models")
    outputs: OutputsConfig = _field(OutputsConfig(), description="Outputs")

    def resolved(self, base_dir: Path) -> "RunConfig":
        """Copy with ``recording`` and ``outputs.out_dir`` made absolute against ``base_dir``."""
        rec = self.recording if self.recording.is_absolute() else (base_dir / self.recording)
        out = self.outputs.out_dir
        out = out if out.is_absolute() else (base_dir / out)
        return self.model_copy(
            update={
                "recording": rec.resolve(),
                "outputs": self.outputs.model_copy(update={"out_dir": out.resolve()}),
            }
        )
