"""Wiring of the laser and binaural streams into the simulation: frames, poses and timing agree with the scene."""

from __future__ import annotations

import numpy as np
import soundfile as sf
from conftest import shared_data
import pytest
from scipy.signal import correlate

from planefuse.laser import points_world_from_scan
from planefuse.sim import SceneConfig, simulate
from planefuse.laser import tilting_unit_from_device


@pytest.fixture(scope="module")
def rec():
    cfg = SceneConfig.model_validate({
        "duration_s": 4.0, "seed": 2, "cameras": [], "imu": None,
        "laser": {"resolution_deg": 0.5},
        "head": {"rt60_s": 0.0},
    })
    return simulate(cfg)


def test_laser_points_lie_on_the_scene(rec):
    scene = rec.scene
    las = rec.laser()
    unit = tilting_unit_from_device(las.model)
    scans = las.read()
    assert scans.ranges_m.shape == (160, 541) and scans.tilt_rad.shape == (160, 541)
    np.testing.assert_array_equal(scans.times_s, np.arange(160) / 40.0)
    # Reading again ray casts again, reproducibly.
    np.testing.assert_array_equal(las.read().ranges_m, scans.ranges_m)
    # The nod follows the unit's triangle wave (each beam at its own instant within the 25 ms scan).
    frac = np.arange(541) / 541 * 0.025
    np.testing.assert_allclose(scans.tilt_rad, unit.tilt_at(scans.times_s[:, None] + frac[None]))
    x0, x1, y0, y1 = scene.room_xy_m
    n_people_hits = 0
    for k in range(0, 160, 8):
        ok = np.isfinite(scans.ranges_m[k])
        p = points_world_from_scan(scans.angles_rad[ok], scans.ranges_m[k, ok], scans.tilt_rad[k, ok],
                                   las.T_world_laser, unit)
        # Every return is on the floor, a wall or a person (range noise 1 cm).
        on_floor = np.abs(p[:, 2]) < 0.05
        on_wall = (np.minimum.reduce([p[:, 0] - x0, x1 - p[:, 0], p[:, 1] - y0, y1 - p[:, 1]]) < 0.05)
        cyl, _, sph, _ = scene.bodies_at(scans.times_s[k] + 0.0125)
        d_cyl = np.hypot(p[:, None, 0] - cyl[None, :, 0], p[:, None, 1] - cyl[None, :, 1]) - cyl[None, :, 2]
        in_z = (p[:, None, 2] > cyl[None, :, 3] - 0.05) & (p[:, None, 2] < cyl[None, :, 4] + 0.05)
        on_person = (np.where(in_z, np.abs(d_cyl), np.inf).min(axis=1) < 0.12) | (
            np.abs(np.linalg.norm(p[:, None] - sph[None, :, :3], axis=2) - sph[None, :, 3]).min(axis=1) < 0.12)
        assert (on_floor | on_wall | on_person).mean() > 0.995
        n_people_hits += int((on_person & ~on_floor & ~on_wall).sum())
    assert n_people_hits > 50


def _itd_s(left: np.ndarray, right: np.ndarray, fs: float) -> float:
    """Broadband ITD (> 0 when the left ear leads), cross-correlation peak with parabolic refinement."""
    c = correlate(right, left, mode="full", method="fft")
    lags = np.arange(-len(left) + 1, len(right))
    keep = np.abs(lags) <= int(1e-3 * fs)
    c, lags = c[keep], lags[keep]
    i = int(np.argmax(c))
    y0, y1, y2 = c[i - 1], c[i], c[i + 1]
    return (lags[i] + 0.5 * (y0 - y2) / (y0 - 2 * y1 + y2)) / fs


def test_binaural_itd_matches_groundtruth_azimuth(rec):
    audio = rec.binaural()
    x = audio.read()
    fs = audio.fs_hz
    assert x.shape == (64000, 2) and x.dtype == np.float32
    gt = rec.groundtruth.sound
    for q, pid in enumerate(gt.person_ids):
        spk = next(s for s in rec.config.speakers if s.person_id == pid)
        a, b = spk.intervals_s[0]
        seg = x[int(a * fs) : int(b * fs)]
        tau = _itd_s(seg[:, 0].astype(float), seg[:, 1].astype(float), fs)
        talking = gt.speaking[:, q]
        az, el = gt.azimuth_rad[talking, q].mean(), gt.elevation_rad[talking, q].mean()
        lateral = np.arcsin(np.cos(el) * np.sin(az))
        woodworth = audio.head_radius_m / 343.0 * (lateral + np.sin(lateral))
        assert np.sign(tau) == np.sign(woodworth)
        assert abs(tau - woodworth) < 80e-6, (pid, tau, woodworth)
    # Silence outside the talking intervals is only sensor noise: much weaker than speech.
    quiet = x[: int(0.15 * fs)]
    loud = x[int(0.3 * fs) : int(1.7 * fs)]
    assert np.sqrt(np.mean(quiet**2)) < 0.3 * np.sqrt(np.mean(loud**2))


def test_speaker_wav_file_is_heard_only_while_talking(tmp_path):
    fs = 16000
    t = np.arange(int(0.3 * fs)) / fs
    sf.write(tmp_path / "voice.wav", (0.5 * np.sin(2 * np.pi * 440 * t)).astype(np.float32), fs)
    cfg = SceneConfig.model_validate({
        "duration_s": 2.0, "n_people": 2, "seed": 1, "cameras": [], "imu": None, "laser": None,
        "head": {"rt60_s": 0.0},
        "speakers": [{"person_id": 1, "intervals_s": [[0.8, 1.4]], "wav_path": str(tmp_path / "voice.wav")}],
    })
    x = simulate(cfg).binaural().read()
    rms = np.sqrt(np.mean(x.reshape(20, -1, 2) ** 2, axis=(1, 2)))  # per 100 ms
    # The tone (looped) during [0.8, 1.4] s; elsewhere sensor noise 20 dB below the mean power of the recording.
    assert rms[9:13].min() > 10 * rms[:7].max()
    spec = np.abs(np.fft.rfft(x[int(0.9 * fs) : int(1.3 * fs), 0]))
    assert abs(np.argmax(spec) * fs / (0.4 * fs) - 440) < 5


@pytest.mark.realdata
def test_sofa_hrtf_head_hears_talkers_on_the_right_side():
    sofa = shared_data("hrtf_sofa") / "MIT_KEMAR_normal_pinna.sofa"
    cfg = SceneConfig.model_validate({
        "duration_s": 4.0, "seed": 2, "cameras": [], "imu": None, "laser": None,
        "head": {"rt60_s": 0.0, "hrtf_sofa": str(sofa)},
    })
    rec = simulate(cfg)
    audio = rec.binaural()
    assert audio.hrtf_sofa == str(sofa)
    x = audio.read().astype(float)
    gt = rec.groundtruth.sound
    for q, pid in enumerate(gt.person_ids):
        a, b = next(s for s in cfg.speakers if s.person_id == pid).intervals_s[0]
        seg = x[int(a * audio.fs_hz) : int(b * audio.fs_hz)]
        tau = _itd_s(seg[:, 0], seg[:, 1], audio.fs_hz)
        az = gt.azimuth_rad[gt.speaking[:, q], q].mean()
        lateral = np.arcsin(np.sin(az))
        # KEMAR's ITD follows Woodworth's spherical head of radius ~8.75 cm within ~0.1 ms.
        assert abs(tau - 0.0875 / 343.0 * (lateral + np.sin(lateral))) < 120e-6, (pid, tau, az)
