"""What ``planefuse check`` needs from a recording: cameras, every stream's time stamps, required streams."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from ..geometry import PinholeCamera
from ._recording import read_recording

__all__ = ["check_inputs", "AUDIO_CHECK_STEP_S"]

#: Binaural streams are summarised by the time of one sample every 10 ms (not every sample).
AUDIO_CHECK_STEP_S = 0.01


def check_inputs(recording_dir: str | Path, cfg: Any) -> tuple[list[PinholeCamera], dict[str, np.ndarray], list[str]]:
    """Open a recording and list what a run configuration needs from it, reading every stream's time stamps.

    Parameters
    ----------
    recording_dir : path
        Folder with ``scene.yaml``.
    cfg : planefuse.config.RunConfig
        Uses ``cfg.sensors.cameras.enabled`` / ``.names``, ``cfg.sensors.laser.enabled`` and
        ``cfg.sensors.sound.enabled``.

    Returns
    -------
    cameras : list of PinholeCamera
        The enabled cameras found in the recording.
    stream_times_s : dict of str -> ndarray (N,)
        Time stamps [s] of every stream in the recording (cameras, IMUs, lasers; binaural heads one
        sample every :data:`AUDIO_CHECK_STEP_S`), checked while read.
    expected_streams : list of str
        Streams the configuration needs: the enabled cameras (all of the recording's when ``names`` is
        null), every laser (``"laser"`` if the recording has none) and binaural head (``"binaural"``).

    Raises
    ------
    ValueError
        Unreadable manifest, calibration or stream (file and line/field named).
    """
    rec = read_recording(recording_dir)
    sensors = cfg.sensors
    times: dict[str, np.ndarray] = {}
    for name, cs in rec.camera_streams.items():
        times[name] = cs.times_s
    for name, s in rec.imus.items():
        times[name] = np.concatenate([c.times_s for c in s.chunks()] or [np.zeros(0)])
    for name, s in rec.lasers.items():
        times[name] = np.concatenate([c.times_s for c in s.chunks()] or [np.zeros(0)])
    for name, s in rec.audio.items():
        step = max(1, int(round(AUDIO_CHECK_STEP_S * s.fs_hz)))
        times[name] = s.start_time_s + np.arange(0, s.n_samples, step) / s.fs_hz
    expected: list[str] = []
    cameras: list[PinholeCamera] = []
    if sensors.cameras.enabled:
        names = sensors.cameras.names if sensors.cameras.names is not None else list(rec.camera_streams)
        expected += list(names)
        cameras = [rec.camera_streams[n].camera for n in names if n in rec.camera_streams]
    if sensors.laser.enabled:
        expected += list(rec.lasers) or ["laser"]
    if sensors.sound.enabled:
        expected += list(rec.audio) or ["binaural"]
    return cameras, times, expected
