"""Azimuth sweeps: simulate, calibrate, localise, and compare with pyroomacoustics' DOA methods.

Used by the tests (coarse sweeps) and by ``planefuse audio evaluate`` (the table in
docs/results.md). Every method sees the very same two-channel signals, cut into
the same non-overlapping frames (the binaural unit's ``frame_s``), and answers on
the same azimuth grid (the sensor model's, -90..90 deg).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pyroomacoustics as pra

from ._bayes import BinauralSensorModel, calibrate_sensor_model, localize
from ._head import SPEED_OF_SOUND_M_S, MeasuredHrirs, SphericalHead, directions_from_azimuth_elevation
from ._simulate import ShoeBoxRoom, T_world_head_from_position_yaw, simulate_binaural

__all__ = ["SweepScene", "sweep_recordings", "rendered_azimuths_rad", "calibrate_from_simulation", "doa_baselines",
           "evaluate_sweep"]

HeadModel = SphericalHead | MeasuredHrirs


@dataclass(frozen=True)
class SweepScene:
    """Where the sweep happens: room, head pose and source distance.

    Attributes
    ----------
    room : ShoeBoxRoom
        Default 6 x 5 x 3 m, RT60 0.3 s.
    head_position_m : tuple of 3 floats
        Head centre, world frame [m].
    head_yaw_rad : float
        Head yaw [rad].
    distance_m : float
        Source distance from the head centre, at head height [m].
    snr_db : float or None
        Sensor noise.
    """

    room: ShoeBoxRoom = ShoeBoxRoom(dims_m=(6.0, 5.0, 3.0), rt60_s=0.3)
    head_position_m: tuple[float, float, float] = (2.7, 2.75, 1.6)
    head_yaw_rad: float = 0.3
    distance_m: float = 1.5
    snr_db: float | None = 20.0

    @property
    def T_world_head(self) -> np.ndarray:
        return T_world_head_from_position_yaw(self.head_position_m, self.head_yaw_rad)

    def source_position(self, azimuth_rad: float) -> np.ndarray:
        """World position [m] of a source at ``azimuth_rad`` in the head frame, at head height."""
        a = azimuth_rad + self.head_yaw_rad
        return np.asarray(self.head_position_m) + self.distance_m * np.array([np.cos(a), np.sin(a), 0.0])


def sweep_recordings(signal, azimuths_rad, scene: SweepScene, head: HeadModel, fs_hz: float, seed: int = 0):
    """One two-channel recording (n, 2) of ``signal`` per azimuth [rad] of the sweep."""
    return [
        simulate_binaural([(signal, scene.source_position(a), 0.0)], scene.T_world_head, scene.room, head, fs_hz,
                          snr_db=scene.snr_db, seed=seed + i).signal
        for i, a in enumerate(np.asarray(azimuths_rad, dtype=float))
    ]


def rendered_azimuths_rad(head: HeadModel, azimuths_rad) -> np.ndarray:
    """Azimuths [rad] (R,) in [-pi/2, pi/2] that ``head`` really renders for direct sound from ``azimuths_rad``
    (R,) at elevation 0: the lateral angle of :meth:`rendered_directions` (the nearest measured direction of
    a snapping head, the ``bin_deg`` bin of the spherical head, the direction itself when interpolated). Score a
    sweep against these.
    """
    d = directions_from_azimuth_elevation(np.asarray(azimuths_rad, dtype=float).reshape(-1))
    return np.arcsin(np.clip(head.rendered_directions(d)[:, 1], -1.0, 1.0))


def calibrate_from_simulation(head: HeadModel, signal, fs_hz: float, step_deg: float = 5.0,
                              **kwargs) -> BinauralSensorModel:
    """Calibrate ``P(tau | S_theta theta)`` by rendering ``signal`` through ``head`` (anechoic, 30 dB SNR).

    The calibration azimuths run from -90 to 90 deg every ``step_deg``; ``kwargs`` go to
    :func:`calibrate_sensor_model`.
    """
    az = np.deg2rad(np.arange(-90.0, 90.0 + 1e-9, step_deg))
    scene = SweepScene(room=ShoeBoxRoom(dims_m=(4.0, 4.0, 3.0), rt60_s=0.0), head_position_m=(2.0, 2.0, 1.5),
                       head_yaw_rad=0.0, distance_m=1.5, snr_db=30.0)
    recs = sweep_recordings(signal, az, scene, head, fs_hz, seed=1000)
    return calibrate_sensor_model(recs, az, fs_hz, source=f"{head.name} (simulated, anechoic)", **kwargs)


def _gcc_phat_azimuth(X: np.ndarray, freqs_hz: np.ndarray, grid: np.ndarray, mic_distance_m: float) -> float:
    """Plain GCC-PHAT steered over the azimuth grid: X (2, F, S) STFT of [left, right]."""
    G = np.sum(X[0] * np.conj(X[1]), axis=1)
    G = G / np.maximum(np.abs(G), 1e-20)
    tau = mic_distance_m * np.sin(grid) / SPEED_OF_SOUND_M_S  # left leads for sources on the left
    resp = np.real(np.exp(-2j * np.pi * np.outer(tau, freqs_hz)) @ G)
    return float(grid[np.argmax(resp)])


def doa_baselines(signal, fs_hz: float, azimuth_grid_rad, mic_distance_m: float, frame_len: int,
                  freq_range_hz=(100.0, 4000.0)) -> dict[str, float]:
    """Azimuth [rad] from pyroomacoustics' SRP-PHAT and MUSIC, and a plain GCC-PHAT, on the same frames.

    The two ears are given to pyroomacoustics as free-field microphones at
    ``(0, +-mic_distance_m / 2)`` in the head frame (left first), i.e. the ear
    distance: pyroomacoustics knows nothing of the head between them.
    """
    x = np.asarray(signal, dtype=float)
    grid = np.asarray(azimuth_grid_rad, dtype=float)
    X = pra.transform.stft.analysis(x, frame_len, frame_len).transpose(2, 1, 0)  # (M, F, S)
    L = np.array([[0.0, 0.0], [mic_distance_m / 2, -mic_distance_m / 2]])
    out = {}
    for name in ("SRP", "MUSIC"):
        doa = pra.doa.algorithms[name](L, fs_hz, frame_len, c=SPEED_OF_SOUND_M_S, num_src=1, azimuth=grid)
        doa.locate_sources(X, num_src=1, freq_range=list(freq_range_hz))
        out[f"pyroomacoustics {name}" + ("-PHAT" if name == "SRP" else "")] = float(doa.azimuth_recon[0])
    f = np.fft.rfftfreq(frame_len, 1.0 / fs_hz)
    sel = (f >= freq_range_hz[0]) & (f <= freq_range_hz[1])
    out["GCC-PHAT"] = _gcc_phat_azimuth(X[:, sel], f[sel], grid, mic_distance_m)
    return out


def evaluate_sweep(recordings, azimuths_rad, model: BinauralSensorModel, mic_distance_m: float,
                   baselines: bool = True) -> dict[str, np.ndarray]:
    """Absolute azimuth errors [rad] (R,) per method over a sweep of recordings at known azimuths.

    Azimuths are compared as lateral angles (front and back are one measurement for two ears).
    Returns a dict ``method -> errors``; ``"planefuse Bayes"`` is always present, the
    pyroomacoustics/GCC-PHAT baselines if ``baselines``, each twice: with the ear
    distance ``mic_distance_m`` (2a) and with the Woodworth path ``a (pi/2 + 1)``, the
    spacing whose free-field ITD at 90 deg matches a spherical head's. A recording without evidence
    counts as an error of 90 deg.
    """
    truth = np.arcsin(np.sin(np.asarray(azimuths_rad, dtype=float)))
    errs: dict[str, list[float]] = {"planefuse Bayes": []}
    # the ear distance 2a, and the path around a sphere of radius a to the far ear at 90 deg, a (pi/2 + 1)
    spacings = {"ear distance": mic_distance_m, "Woodworth path": mic_distance_m / 2 * (np.pi / 2 + 1)}
    frame_len = int(round(model.frame_s * model.fs_hz))
    for rec, t in zip(recordings, truth):
        loc = localize(rec, model.fs_hz, model)
        errs["planefuse Bayes"].append(abs(loc.map_azimuth_rad - t) if np.isfinite(loc.map_azimuth_rad) else np.pi / 2)
        if baselines:
            band = (model.filterbank.f_min_hz, model.filterbank.f_max_hz)
            for label, d in spacings.items():
                for k, v in doa_baselines(rec, model.fs_hz, model.azimuth_rad, d, frame_len, band).items():
                    errs.setdefault(f"{k} ({label} {d * 100:.1f} cm)", []).append(abs(np.arcsin(np.sin(v)) - t))
    return {k: np.asarray(v) for k, v in errs.items()}
