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
        [0.0, 0.5, 1.0, 1.5],
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
        0.05, description="Side of a square grid cell", unit="m", expected="in (0, 5]", gt=0.0, le=5.0
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
    """Cameras: background subtraction, then registration of the foreground on the planes."""

    enabled: bool = _field(True, description="Use the cameras")
    names: list[str] | None = _field(
        None, description="Cameras to use (names in scene.yaml); null uses all", expected="null or names"
    )
    foreground_method: Literal["MOG2", "KNN"] = _field(
        "MOG2", description="OpenCV background subtractor", expected="MOG2 or KNN"
    )
    history_frames: int = _field(
        200, description="Frames in the background model's history", unit="frames", expected=">= 1", ge=1
    )
    var_threshold: float = _field(
        16.0,
        description="MOG2 varThreshold (squared Mahalanobis distance) or KNN dist2Threshold",
        expected="> 0",
        gt=0.0,
    )
    detect_shadows: bool = _field(False, description="Let the subtractor mark shadows (then treated as background)")
    p_foreground_given_occupied: float = _field(
        0.8, description="Sensor model P(foreground | cell occupied)", expected="in (0, 1)", gt=0.0, lt=1.0
    )
    p_foreground_given_free: float = _field(
        0.1, description="Sensor model P(foreground | cell free)", expected="in (0, 1)", gt=0.0, lt=1.0
    )


class LaserSensorConfig(_Model):
    """Laser range finders: hits become evidence on the plane whose height band holds them."""

    enabled: bool = _field(True, description="Use the laser range finders")
    max_range_m: float = _field(
        20.0, description="Ranges beyond this are treated as no return", unit="m", expected="in (0, 200]", gt=0.0,
        le=200.0,
    )
    hit_log_odds: float = _field(
        2.0, description="Log-odds added to a cell holding a hit", expected="> 0", gt=0.0
    )
    free_log_odds: float = _field(
        -0.5, description="Log-odds added to cells a beam traverses", expected="<= 0", le=0.0
    )


class SoundSensorConfig(_Model):
    """Binaural microphones: time-difference-of-arrival wedges on the planes."""

    enabled: bool = _field(True, description="Use the binaural microphone pair")
    frame_length_s: float = _field(
        0.064, description="Length of an analysis frame", unit="s", expected="in (0, 1]", gt=0.0, le=1.0
    )
    min_frequency_hz: float = _field(
        200.0, description="Lowest frequency used for localisation", unit="Hz", expected=">= 0", ge=0.0
    )
    max_frequency_hz: float = _field(
        4000.0, description="Highest frequency used for localisation", unit="Hz", expected="> min_frequency_hz",
        gt=0.0,
    )
    speed_of_sound_m_s: float = _field(
        343.0, description="Speed of sound", unit="m/s", expected="in [300, 400]", ge=300.0, le=400.0
    )

    @model_validator(mode="after")
    def _band(self) -> "SoundSensorConfig":
        if self.max_frequency_hz <= self.min_frequency_hz:
            raise ValueError(
                f"max_frequency_hz ({self.max_frequency_hz} Hz) must exceed min_frequency_hz "
                f"({self.min_frequency_hz} Hz)"
            )
        return self


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
    """Bayesian Occupancy Filter: prediction model per plane."""

    time_step_s: float = _field(
        0.1, description="Filter time step", unit="s", expected="in (0, 10]", gt=0.0, le=10.0
    )
    velocities_m_s: list[tuple[float, float]] = _field(
        [(0.0, 0.0), (1.0, 0.0), (-1.0, 0.0), (0.0, 1.0), (0.0, -1.0)],
        description="Velocity hypotheses (vx, vy) of a cell's content",
        unit="m/s",
        expected="at least one pair, each |v| <= 10",
        min_length=1,
    )
    p_keep_velocity: float = _field(
        0.9, description="Probability that a cell's content keeps its velocity over a step",
        expected="in [0, 1]", ge=0.0, le=1.0,
    )
    p_appear: float = _field(
        0.01, description="Probability that an empty cell becomes occupied over a step (births)",
        expected="in [0, 1)", ge=0.0, lt=1.0,
    )
    p_occupied_prior: float = _field(
        0.1, description="Prior occupancy probability of a cell", expected="in (0, 1)", gt=0.0, lt=1.0
    )

    @field_validator("velocities_m_s")
    @classmethod
    def _speeds(cls, v: list[tuple[float, float]]) -> list[tuple[float, float]]:
        for i, (vx, vy) in enumerate(v):
            if (vx * vx + vy * vy) ** 0.5 > 10.0:
                raise item_error(i, f"({vx}, {vy}) m/s is faster than 10 m/s")
        return v


class DetectionModelConfig(_Model):
    """From occupancy to people: thresholds, clustering and tracking gates."""

    occupancy_threshold: float = _field(
        0.6, description="Cells above this posterior occupancy are candidate people",
        expected="in (0, 1)", gt=0.0, lt=1.0,
    )
    person_radius_m: float = _field(
        0.3, description="Radius of a person's footprint", unit="m", expected="in (0, 2]", gt=0.0, le=2.0
    )
    min_planes: int = _field(
        2, description="Planes on which a column must be occupied to count as a person", expected=">= 1", ge=1
    )
    gate_distance_m: float = _field(
        1.0, description="Largest distance between a track and the detection it is associated with",
        unit="m", expected="> 0", gt=0.0,
    )
    max_missed_s: float = _field(
        1.0, description="A track unseen for longer than this is ended", unit="s", expected=">= 0", ge=0.0
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
