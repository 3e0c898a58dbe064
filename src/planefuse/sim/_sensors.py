"""The laser and binaural streams of a simulated scene, via :mod:`planefuse.laser` and :mod:`planefuse.audio`."""

from __future__ import annotations

from collections.abc import Iterator

import numpy as np

from ..audio import (
    MeasuredHrirs,
    ShoeBoxRoom,
    SoundSource,
    SphericalHead,
    read_audio,
    simulate_binaural,
    speech_like_signal,
)
from ..io import AudioStream, LaserScans, LaserStream
from ..laser import LaserScannerSpec, TiltingUnit, simulate_nodding_sweep
from ._config import HeadSpec, LaserSpec
from ._scene import Scene

__all__ = ["tilting_unit_from_spec", "laser_stream", "audio_stream", "SCAN_DURATION_S"]

#: Time a scanner takes to sweep its beams (UTM-30LX: 25 ms); each beam gets the tilt of its own instant.
SCAN_DURATION_S = 0.025
#: A new BRIR is computed when a talking person has moved this far [m].
_SOURCE_STEP_M = 0.15
#: Cross-fade between consecutive source segments [s].
_FADE_S = 0.02


def tilting_unit_from_spec(spec: LaserSpec) -> TiltingUnit:
    """The :class:`planefuse.laser.TiltingUnit` a :class:`LaserSpec` describes."""
    inc = np.radians(spec.resolution_deg)
    n = int(round(spec.fov_deg / spec.resolution_deg)) + 1
    scanner = LaserScannerSpec(-np.radians(spec.fov_deg) / 2, float(inc), n, spec.range_min_m, spec.max_range_m,
                               spec.range_noise_m, spec.name)
    return TiltingUnit(scanner, tilt_min_rad=float(np.radians(spec.tilt_min_deg)),
                       tilt_max_rad=float(np.radians(spec.tilt_max_deg)), tilt_period_s=spec.tilt_period_s)


def _model_of(unit: TiltingUnit) -> dict:
    sc = unit.scanner
    return {
        "scanner": {"angle_min_rad": sc.angle_min_rad, "angle_increment_rad": sc.angle_increment_rad,
                    "n_beams": sc.n_beams, "range_min_m": sc.range_min_m, "range_max_m": sc.range_max_m,
                    "range_noise_sigma_m": sc.range_noise_sigma_m, "name": sc.name},
        "offset_tilt_scanner_m": tuple(unit.offset_tilt_scanner_m),
        "tilt_min_rad": unit.tilt_min_rad,
        "tilt_max_rad": unit.tilt_max_rad,
        "tilt_period_s": unit.tilt_period_s,
        "scan_duration_s": SCAN_DURATION_S,
    }


def laser_stream(scene: Scene, spec: LaserSpec, times_s: np.ndarray, seed: int) -> LaserStream:
    """A lazily simulated laser stream: chunks of scans are ray cast when read (reproducibly)."""
    unit = tilting_unit_from_spec(spec)
    T = spec.T_world_laser()
    times_s = np.asarray(times_s, dtype=float)

    def generate(max_scans: int, start: int = 0) -> Iterator[LaserScans]:
        # chunks keep their boundaries (and random streams) whatever ``start``: a resumed run sees the same scans
        for a in range(start - start % max_scans, len(times_s), max_scans):
            t = times_s[a : a + max_scans]
            rng = np.random.default_rng([seed, 6, a])
            scans = simulate_nodding_sweep(unit, T, scene, t, rng, scan_duration_s=SCAN_DURATION_S)
            chunk = LaserScans(t, unit.scanner.angles_rad, np.stack([s.ranges_m for s in scans]),
                               np.stack([s.tilt_rad for s in scans]))
            yield chunk if a >= start else chunk.slice(start - a, len(chunk))

    return LaserStream(spec.name, T, spec.rate_hz, len(times_s), _model_of(unit), generate=generate)


def _head_model(spec: HeadSpec):
    if spec.hrtf_sofa is None:
        return SphericalHead(radius_m=spec.head_radius_m, fs_hz=float(spec.fs_hz))
    return MeasuredHrirs.from_sofa(spec.hrtf_sofa, fs_hz=float(spec.fs_hz))


def audio_stream(scene: Scene, seed: int) -> AudioStream:
    """Simulate the binaural head's ear signals for the scene's speakers (``config.speakers``).

    Each talker is a static source per segment of their talking interval (a new segment whenever they
    have moved more than 15 cm; they stand still while talking, see :class:`Scene`), at the head sphere's
    centre, with 20 ms cross-fades between segments; pyroomacoustics image sources in the walled room
    (floor to wall height), heard through the spherical head or the SOFA HRTF; 20 dB SNR sensor noise.
    """
    cfg = scene.config
    spec = cfg.head
    fs = int(spec.fs_hz)
    x0, x1, y0, y1 = scene.room_xy_m
    room = ShoeBoxRoom(dims_m=(x1 - x0, y1 - y0, scene.wall_height_m), rt60_s=spec.rt60_s, min_corner_m=(x0, y0, 0.0))
    T = spec.T_world_head()
    sources = []
    for i, spk in enumerate(cfg.speakers):
        if spk.wav_path is not None:
            x, _ = read_audio(spk.wav_path, fs)
            dry = np.resize(x.mean(axis=1), int(np.ceil(cfg.duration_s * fs)) + 1)  # loop a short file
        else:
            dry = speech_like_signal(cfg.duration_s, fs, seed=seed * 1000 + 17 * i + spk.person_id)
        for a, b in spk.intervals_s:
            t = np.arange(a, b, 0.02)
            pos = scene.mouth_positions_at(t)[:, spk.person_id]
            starts = [0]
            for k in range(1, len(t)):
                if np.linalg.norm(pos[k, :2] - pos[starts[-1], :2]) > _SOURCE_STEP_M:
                    starts.append(k)
            bounds = [t[k] for k in starts] + [b]
            for j, k in enumerate(starts):
                sa, sb = bounds[j], bounds[j + 1]
                mid = np.argmin(np.abs(t - 0.5 * (sa + sb)))
                # Trapezoid window: ramps of _FADE_S centred on inner boundaries sum to one across segments.
                lo = sa - (_FADE_S / 2 if j > 0 else 0.0)
                hi = sb + (_FADE_S / 2 if j < len(starts) - 1 else 0.0)
                i0, i1 = int(round(lo * fs)), min(int(round(hi * fs)), len(dry))
                tt = np.arange(i0, i1) / fs
                w = np.ones(i1 - i0)
                if j > 0:
                    w *= np.clip((tt - lo) / _FADE_S, 0, 1)
                if j < len(starts) - 1:
                    w *= np.clip((hi - tt) / _FADE_S, 0, 1)
                if i1 > i0:
                    sources.append(SoundSource(dry[i0:i1] * w, pos[mid], start_s=max(lo, 0.0)))
    n = int(round(cfg.duration_s * fs))
    if sources:
        sim = simulate_binaural(sources, T, room, _head_model(spec), float(fs), snr_db=20.0, seed=seed,
                                duration_s=cfg.duration_s)
        signal = sim.signal.astype(np.float32)
    else:
        signal = np.zeros((n, 2), np.float32)
    return AudioStream(spec.name, T, fs, 0.0, len(signal), spec.head_radius_m,
                       None if spec.hrtf_sofa is None else str(spec.hrtf_sofa), data=signal)
