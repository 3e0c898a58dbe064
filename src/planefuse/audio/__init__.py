"""Binaural sound: simulation, cochlear filterbank, binaural cues, Bayesian azimuth, plane registration."""

from ._bayes import (
    BinauralSensorModel,
    Localization,
    calibrate_sensor_model,
    default_sensor_model,
    localize,
)
from ._binaural import BinauralCues, binaural_cues, clipped_samples
from ._cochlea import GammatoneFilterbank, check_binaural_signal, erb_space_hz
from ._head import (
    HEAD_RADIUS_M,
    HRIR_INTERPOLATIONS,
    SPEED_OF_SOUND_M_S,
    HrirWarning,
    MeasuredHrirs,
    SphericalHead,
    directions_from_azimuth_elevation,
    lateral_from_azimuth,
)
from ._register import evidence_from_saliency, lateral_angle_of_cells
from ._signals import read_audio, speech_like_signal
from ._simulate import (
    BinauralRecording,
    ShoeBoxRoom,
    SoundSource,
    T_world_head_from_position_yaw,
    binaural_room_impulse_response,
    simulate_binaural,
)

__all__ = [
    "BinauralSensorModel",
    "Localization",
    "calibrate_sensor_model",
    "default_sensor_model",
    "localize",
    "BinauralCues",
    "binaural_cues",
    "clipped_samples",
    "GammatoneFilterbank",
    "check_binaural_signal",
    "erb_space_hz",
    "evidence_from_saliency",
    "lateral_angle_of_cells",
    "HEAD_RADIUS_M",
    "SPEED_OF_SOUND_M_S",
    "HRIR_INTERPOLATIONS",
    "HrirWarning",
    "MeasuredHrirs",
    "SphericalHead",
    "directions_from_azimuth_elevation",
    "lateral_from_azimuth",
    "read_audio",
    "speech_like_signal",
    "BinauralRecording",
    "ShoeBoxRoom",
    "SoundSource",
    "T_world_head_from_position_yaw",
    "binaural_room_impulse_response",
    "simulate_binaural",
]
