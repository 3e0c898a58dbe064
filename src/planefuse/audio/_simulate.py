"""Binaural acoustic simulation: sources in a reverberant shoe-box room heard by a head.

The room's image sources come from pyroomacoustics' image-source model
(``pra.ShoeBox``, wall absorption and reflection order from ``pra.inverse_sabine``
for the requested RT60). Every image source is then heard *through the head*:
its direction in the head frame selects an HRIR pair of the head model
(:class:`~planefuse.audio.SphericalHead` or :class:`~planefuse.audio.MeasuredHrirs`),
its path length gives the delay and its wall damping / (4 pi r) the gain. Image
sources sharing an HRIR bin are summed into one impulse train, which is then
convolved with that bin's HRIR pair, so the binaural room impulse response
carries the head's ITD and ILD for the direct path *and* every reflection.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import pyroomacoustics as pra
from scipy.signal import fftconvolve

from ..geometry import (
    apply_transform,
    check_points,
    check_transform,
    invert_transform,
    rotation_from_roll_pitch_yaw,
    transform_from_rotation_translation,
)
from ._head import SPEED_OF_SOUND_M_S, MeasuredHrirs, SphericalHead

__all__ = [
    "ShoeBoxRoom",
    "SoundSource",
    "BinauralRecording",
    "simulate_binaural",
    "binaural_room_impulse_response",
    "T_world_head_from_position_yaw",
]

HeadModel = SphericalHead | MeasuredHrirs


def T_world_head_from_position_yaw(position_m, yaw_rad: float = 0.0) -> np.ndarray:
    """``T_world_head`` (4, 4) of an upright head at ``position_m`` (3,) [m] looking along yaw [rad] (0 = world +x)."""
    p = check_points(position_m, 3, "position_m").reshape(3)
    return transform_from_rotation_translation(rotation_from_roll_pitch_yaw(0.0, 0.0, yaw_rad), p)


@dataclass(frozen=True)
class ShoeBoxRoom:
    """A rectangular room ``[min_corner, min_corner + dims]`` in world coordinates.

    Attributes
    ----------
    dims_m : tuple of 3 floats
        Length, width, height [m].
    rt60_s : float
        Reverberation time [s]; 0 gives an anechoic room (direct path only).
    min_corner_m : tuple of 3 floats
        World coordinates of the room's corner with the smallest x, y, z [m].
    max_order : int or None
        Image-source order; None takes it from ``pra.inverse_sabine``.
    """

    dims_m: tuple[float, float, float] = (6.0, 5.0, 3.0)
    rt60_s: float = 0.3
    min_corner_m: tuple[float, float, float] = (0.0, 0.0, 0.0)
    max_order: int | None = None

    def __post_init__(self) -> None:
        d = np.asarray(self.dims_m, dtype=float)
        if d.shape != (3,) or not np.isfinite(d).all() or np.any(d <= 0):
            raise ValueError(f"ShoeBoxRoom.dims_m must be 3 positive lengths [m], got {self.dims_m}")
        c = np.asarray(self.min_corner_m, dtype=float)
        if c.shape != (3,) or not np.isfinite(c).all():
            raise ValueError(f"ShoeBoxRoom.min_corner_m must be 3 finite coordinates [m], got {self.min_corner_m}")
        if not (np.isfinite(self.rt60_s) and self.rt60_s >= 0):
            raise ValueError(f"ShoeBoxRoom.rt60_s must be >= 0 s, got {self.rt60_s}")
        object.__setattr__(self, "dims_m", tuple(float(x) for x in d))
        object.__setattr__(self, "min_corner_m", tuple(float(x) for x in c))

    def contains(self, p_world) -> np.ndarray:
        """Whether world points (..., 3) [m] lie strictly inside the room."""
        p = check_points(p_world, 3, "p_world") - np.asarray(self.min_corner_m)
        return np.all((p > 0) & (p < np.asarray(self.dims_m)), axis=-1)

    def image_sources(self, source_world_m, fs_hz: float) -> tuple[np.ndarray, np.ndarray]:
        """Image sources of a source with pyroomacoustics' image-source model.

        Returns
        -------
        images_world_m : ndarray, shape (K, 3)
            Image-source positions in world coordinates [m] (row 0 = the source itself).
        damping : ndarray, shape (K,)
            Product of the wall reflection amplitudes along each path (1 for the direct path).
        """
        corner = np.asarray(self.min_corner_m)
        src = np.asarray(source_world_m, dtype=float).reshape(3) - corner
        if self.rt60_s == 0:
            absorption, order = 1.0, 0
        else:
            try:
                absorption, order = pra.inverse_sabine(self.rt60_s, list(self.dims_m))
            except ValueError as e:
                raise ValueError(f"room {self.dims_m} m cannot have RT60 = {self.rt60_s} s: {e}") from e
        if self.max_order is not None:
            order = int(self.max_order)
        room = pra.ShoeBox(list(self.dims_m), fs=fs_hz, materials=pra.Material(absorption), max_order=order,
                           air_absorption=False)
        room.add_source(src)
        room.add_microphone(np.asarray(self.dims_m) / 2)  # images do not depend on the receiver in a shoe box
        room.image_source_model()
        s = room.sources[0]
        images = s.images.T + corner
        damping = np.mean(s.damping, axis=0)
        first = int(np.argmin(s.orders))
        perm = np.r_[first, np.delete(np.arange(len(images)), first)]
        return images[perm], damping[perm]


@dataclass(frozen=True)
class SoundSource:
    """A static sound source: a mono signal at a world position, starting at ``start_s``.

    Attributes
    ----------
    signal : ndarray, shape (n,)
        Source signal at the simulation rate (free-field pressure at 1 m, arbitrary units).
    position_world_m : ndarray, shape (3,)
        Position in the world frame [m].
    start_s : float
        Start time of the signal on the recording's clock [s] (>= 0).
    """

    signal: np.ndarray
    position_world_m: np.ndarray
    start_s: float = 0.0

    def __post_init__(self) -> None:
        s = np.asarray(self.signal, dtype=float)
        if s.ndim != 1 or s.size == 0:
            raise ValueError(f"SoundSource.signal must be a non-empty mono signal (n,), got shape {s.shape}")
        if not np.isfinite(s).all():
            raise ValueError("SoundSource.signal has non-finite samples")
        p = check_points(self.position_world_m, 3, "SoundSource.position_world_m").reshape(-1)
        if p.shape != (3,):
            raise ValueError(f"SoundSource.position_world_m must have shape (3,), got {p.shape}")
        if not (np.isfinite(self.start_s) and self.start_s >= 0):
            raise ValueError(f"SoundSource.start_s must be >= 0 s, got {self.start_s}")
        object.__setattr__(self, "signal", s)
        object.__setattr__(self, "position_world_m", p)


@dataclass(frozen=True)
class BinauralRecording:
    """A two-channel recording and the ground truth of its sources.

    Attributes
    ----------
    signal : ndarray, shape (n, 2), float64
        Ear signals, column 0 = left ear, column 1 = right ear.
    fs_hz : float
        Sampling rate [Hz].
    T_world_head : ndarray, shape (4, 4)
        Pose of the head (maps head coordinates into the world).
    sources_head_m : ndarray, shape (S, 3)
        Source positions in the head frame [m].
    sources_world_m : ndarray, shape (S, 3)
        Source positions in the world frame [m].
    intervals_s : ndarray, shape (S, 2)
        Start and end of each source's dry signal on the recording clock [s].
    """

    signal: np.ndarray
    fs_hz: float
    T_world_head: np.ndarray
    sources_head_m: np.ndarray
    sources_world_m: np.ndarray
    intervals_s: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))

    @property
    def azimuth_rad(self) -> np.ndarray:
        """True azimuth (S,) [rad] of each source in the head frame, (-pi, pi], +pi/2 = left."""
        return np.arctan2(self.sources_head_m[:, 1], self.sources_head_m[:, 0])

    @property
    def elevation_rad(self) -> np.ndarray:
        """True elevation (S,) [rad] of each source in the head frame."""
        p = self.sources_head_m
        return np.arctan2(p[:, 2], np.hypot(p[:, 0], p[:, 1]))

    @property
    def duration_s(self) -> float:
        return len(self.signal) / self.fs_hz


def binaural_room_impulse_response(
    source_world_m,
    T_world_head,
    room: ShoeBoxRoom,
    head: HeadModel,
    fs_hz: float,
) -> np.ndarray:
    """Binaural room impulse response (2, n) at ``fs_hz`` from a source to the two ears.

    Parameters
    ----------
    source_world_m : array_like, shape (3,)
        Source position, world frame [m].
    T_world_head : array_like, shape (4, 4)
        Head pose.
    room : ShoeBoxRoom
        The room (must contain the source and the head centre).
    head : SphericalHead or MeasuredHrirs
        Head model, at ``fs_hz``.
    fs_hz : float
        Sampling rate [Hz].

    Returns
    -------
    ndarray, shape (2, n)
        Row 0 left ear, row 1 right ear. Includes the head model's bulk delay.
    """
    if head.fs_hz != fs_hz:
        raise ValueError(f"head model is at {head.fs_hz} Hz but the simulation runs at {fs_hz} Hz")
    images, damping = room.image_sources(source_world_m, fs_hz)
    T_head_world = invert_transform(T_world_head)
    p_head = apply_transform(T_head_world, images)
    dist = np.linalg.norm(p_head, axis=1)
    if dist[0] < 1.5 * 0.0875:
        raise ValueError(f"source is {dist[0]:.3f} m from the head centre: closer than the head allows")
    if room.rt60_s > 0:  # drop images that arrive after the -60 dB time
        keep = dist <= dist[0] + SPEED_OF_SOUND_M_S * room.rt60_s
        p_head, dist, damping = p_head[keep], dist[keep], damping[keep]
    gain = damping / (4 * np.pi * dist)
    delay = np.round(dist / SPEED_OF_SOUND_M_S * fs_hz).astype(np.int64)
    return head.render_impulses(p_head / dist[:, None], delay, gain)


def simulate_binaural(
    sources,
    T_world_head,
    room: ShoeBoxRoom | None = None,
    head: HeadModel | None = None,
    fs_hz: float = 16000.0,
    snr_db: float | None = 20.0,
    seed: int = 0,
    duration_s: float | None = None,
) -> BinauralRecording:
    """Simulate what two ears hear of static sources in a reverberant shoe-box room.

    Parameters
    ----------
    sources : sequence of SoundSource or (signal, position_world_m, start_s) tuples
        Mono source signals at ``fs_hz``, world positions [m], start times [s].
    T_world_head : array_like, shape (4, 4)
        Head pose: maps head coordinates (x forward, y left, z up) into the world.
    room : ShoeBoxRoom, optional
        Default: 6 x 5 x 3 m, RT60 0.3 s, corner at the world origin.
    head : SphericalHead or MeasuredHrirs, optional
        Default: ``SphericalHead(fs_hz=fs_hz)``.
    fs_hz : float
        Sampling rate [Hz] of the sources and of the output.
    snr_db : float or None
        White, independent sensor noise on each ear, ``snr_db`` below the mean
        power of the noiseless ear signals over the whole recording; None = no noise.
    seed : int
        Seed of the noise.
    duration_s : float, optional
        Length of the recording [s]; default: until the last reverberant tail ends.

    Returns
    -------
    BinauralRecording
        ``signal`` (n, 2) [left, right] plus the sources' ground truth.
    """
    room = ShoeBoxRoom() if room is None else room
    head = SphericalHead(fs_hz=fs_hz) if head is None else head
    T = check_transform(T_world_head, "T_world_head")
    items = [s if isinstance(s, SoundSource) else SoundSource(*s) for s in sources]
    if not items:
        raise ValueError("sources is empty: give at least one (signal, position_world_m, start_s)")
    head_pos = T[:3, 3]
    if not room.contains(head_pos):
        raise ValueError(f"head centre {head_pos.tolist()} is outside the room {room}")
    parts = []
    for k, s in enumerate(items):
        if not room.contains(s.position_world_m):
            raise ValueError(f"source {k} at {s.position_world_m.tolist()} is outside the room {room}")
        brir = binaural_room_impulse_response(s.position_world_m, T, room, head, fs_hz)
        start = int(round(s.start_s * fs_hz))
        parts.append((start, fftconvolve(s.signal[None, :], brir, axes=-1)))
    n = max(a + p.shape[1] for a, p in parts) if duration_s is None else int(round(duration_s * fs_hz))
    out = np.zeros((2, n))
    for start, p in parts:
        m = max(0, min(p.shape[1], n - start))
        out[:, start : start + m] += p[:, :m]
    if snr_db is not None:
        power = np.mean(out**2)
        rng = np.random.default_rng(seed)
        out += rng.standard_normal(out.shape) * np.sqrt(power / 10 ** (snr_db / 10))
    pos_world = np.stack([s.position_world_m for s in items])
    intervals = np.array([[s.start_s, s.start_s + len(s.signal) / fs_hz] for s in items])
    return BinauralRecording(
        signal=out.T.copy(),
        fs_hz=float(fs_hz),
        T_world_head=T,
        sources_head_m=apply_transform(invert_transform(T), pos_world),
        sources_world_m=pos_world,
        intervals_s=intervals,
    )
