"""Run configuration: one YAML file validated by pydantic models, and the pre-run checks.

``load_config(path)`` returns a :class:`RunConfig` or raises :class:`ConfigError`
naming the file, each field path and its expected unit and range;
``example_yaml()`` is the commented example written by ``planefuse config init``;
``check_recording(...)`` runs the checks of ``planefuse check`` on loaded sensor data.
"""

from ._check import CheckIssue, CheckReport, check_recording
from ._preflight import check_run_config
from ._load import ConfigError, ConfigIssue, config_from_dict, config_hash, config_yaml, example_yaml, load_config
from ._models import (
    CameraSensorConfig,
    DetectionModelConfig,
    FilterModelConfig,
    LaserSensorConfig,
    ModelsConfig,
    OutputsConfig,
    PlanesConfig,
    SceneConfig,
    RunConfig,
    SensorsConfig,
    SoundSensorConfig,
    library_fields,
)
from ._profiles import (
    PROFILES,
    REAL_VIDEO,
    SIMULATED,
    FittedConfig,
    Profile,
    ProfileSetting,
    config_for_recording,
    profile_for_recording,
)

__all__ = [
    "CameraSensorConfig",
    "CheckIssue",
    "CheckReport",
    "FittedConfig",
    "PROFILES",
    "Profile",
    "ProfileSetting",
    "REAL_VIDEO",
    "SIMULATED",
    "config_for_recording",
    "profile_for_recording",
    "check_run_config",
    "ConfigError",
    "ConfigIssue",
    "DetectionModelConfig",
    "FilterModelConfig",
    "LaserSensorConfig",
    "ModelsConfig",
    "OutputsConfig",
    "PlanesConfig",
    "SceneConfig",
    "RunConfig",
    "SensorsConfig",
    "SoundSensorConfig",
    "check_recording",
    "config_from_dict",
    "config_hash",
    "config_yaml",
    "example_yaml",
    "library_fields",
    "load_config",
]
