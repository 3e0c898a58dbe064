"""Binaural sound: simulation, cochlear filterbank, binaural cues, Bayesian azimuth, plane registration."""

from ._head import (
    HEAD_RADIUS_M,
    SPEED_OF_SOUND_M_S,
    MeasuredHrirs,
    SphericalHead,
    directions_from_azimuth_elevation,
    lateral_from_azimuth,
)
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
    "HEAD_RADIUS_M",
    "SPEED_OF_SOUND_M_S",
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
