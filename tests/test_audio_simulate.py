"""Binaural simulation: ear order, Woodworth ITD, reverberation time, SNR, bad inputs."""

from __future__ import annotations

import numpy as np
import pyroomacoustics as pra
import pytest

from conftest import shared_data
from planefuse.audio import (
    MeasuredHrirs,
    ShoeBoxRoom,
    SoundSource,
    SphericalHead,
    T_world_head_from_position_yaw,
    binaural_room_impulse_response,
    simulate_binaural,
    speech_like_signal,
)

FS = 16000.0
HEAD = np.array([3.0, 2.5, 1.6])
YAW = 0.3


def _source_at(azimuth_deg: float, dist_m: float = 1.5) -> np.ndarray:
    a = np.deg2rad(azimuth_deg) + YAW
    return HEAD + dist_m * np.array([np.cos(a), np.sin(a), 0.0])


def _lead_s(x: np.ndarray, max_lag: int = 20, up: int = 16) -> float:
    """Time by which the left ear leads the right one, from scipy's cross-correlation, upsampled."""
    from scipy.signal import correlate, resample

    y = resample(x, up * len(x), axis=0)
    c = correlate(y[:, 1], y[:, 0], mode="full", method="fft")
    mid = len(y) - 1
    lags = np.arange(-max_lag * up, max_lag * up + 1)
    return lags[np.argmax(c[mid + lags])] / (up * FS)


def test_woodworth_itd_textbook_values():
    h = SphericalHead()
    assert h.itd_s(np.pi / 2) == pytest.approx(0.0875 / 343 * (np.pi / 2 + 1))
    assert h.itd_s(0.0) == 0.0
    assert h.itd_s(-0.4) == pytest.approx(-h.itd_s(0.4))


def test_anechoic_brir_is_the_direct_path_through_the_head():
    head = SphericalHead()
    T = T_world_head_from_position_yaw(HEAD, YAW)
    src = _source_at(40.0)
    brir = binaural_room_impulse_response(src, T, ShoeBoxRoom(rt60_s=0.0), head, FS)
    d = np.linalg.norm(src - HEAD)
    expect = head.hrirs_from_lateral([np.deg2rad(40.0)])[0] / (4 * np.pi * d)
    k = int(round(d / 343.0 * FS))
    np.testing.assert_allclose(brir[:, k : k + head.n_taps], expect, atol=1e-3 * np.abs(expect).max())
    assert np.abs(brir[:, :k]).max() < 1e-9


@pytest.mark.parametrize("azimuth_deg", [-60.0, 0.0, 35.0, 90.0])
def test_spherical_head_itd_sign_and_size(azimuth_deg):
    sig = speech_like_signal(0.5, FS, seed=3)
    T = T_world_head_from_position_yaw(HEAD, YAW)
    rec = simulate_binaural([(sig, _source_at(azimuth_deg), 0.0)], T, ShoeBoxRoom(rt60_s=0.0), snr_db=None)
    assert np.rad2deg(rec.azimuth_rad[0]) == pytest.approx(azimuth_deg, abs=1e-9)
    itd = SphericalHead().itd_s(np.deg2rad(azimuth_deg))
    # Woodworth delay plus the shadow filters' low-frequency phase lag on the far ear (Brown-Duda),
    # which lengthens the broadband ITD by up to ~10 %.
    assert abs(_lead_s(rec.signal)) == pytest.approx(abs(itd), rel=0.12, abs=20e-6)
    assert np.sign(_lead_s(rec.signal)) == np.sign(itd)


def test_reverberation_time_matches_request():
    T = T_world_head_from_position_yaw(HEAD, YAW)
    brir = binaural_room_impulse_response(_source_at(20.0), T, ShoeBoxRoom(rt60_s=0.3), SphericalHead(), FS)
    for ear in brir:
        assert pra.experimental.measure_rt60(ear, FS) == pytest.approx(0.3, rel=0.25)


def test_snr_of_added_noise():
    sig = speech_like_signal(0.4, FS, seed=1)
    T = T_world_head_from_position_yaw(HEAD, YAW)
    clean = simulate_binaural([(sig, _source_at(10.0), 0.0)], T, snr_db=None).signal
    noisy = simulate_binaural([(sig, _source_at(10.0), 0.0)], T, snr_db=20.0, seed=5).signal
    snr = 10 * np.log10(np.mean(clean**2) / np.mean((noisy - clean) ** 2))
    assert snr == pytest.approx(20.0, abs=0.2)


def test_two_sources_with_start_times():
    T = T_world_head_from_position_yaw(HEAD, YAW)
    a = SoundSource(speech_like_signal(0.3, FS, seed=1), _source_at(-45.0), 0.0)
    b = SoundSource(speech_like_signal(0.3, FS, seed=2), _source_at(50.0), 0.5)
    rec = simulate_binaural([a, b], T, ShoeBoxRoom(rt60_s=0.0), snr_db=None, duration_s=1.0)
    assert rec.signal.shape == (16000, 2)
    np.testing.assert_allclose(np.rad2deg(rec.azimuth_rad), [-45.0, 50.0], atol=1e-9)
    np.testing.assert_allclose(rec.intervals_s, [[0.0, 0.3], [0.5, 0.8]])
    # first source alone in its interval: left-of-centre source -> the right ear leads
    assert _lead_s(rec.signal[: int(0.3 * FS)]) < -200e-6
    assert _lead_s(rec.signal[int(0.52 * FS) : int(0.8 * FS)]) > 200e-6


@pytest.mark.realdata
def test_measured_hrirs_ear_order_left_leads_and_is_louder():
    sofa = MeasuredHrirs.from_sofa(shared_data("hrtf_sofa") / "MIT_KEMAR_normal_pinna.sofa", FS)
    ku = MeasuredHrirs.from_ku100_npz(shared_data("hrir_ku100_circular") / "ku100_circular.npz", FS)
    sig = speech_like_signal(0.5, FS, seed=4)
    T = T_world_head_from_position_yaw(HEAD, YAW)
    for head in (sofa, ku):
        rec = simulate_binaural([(sig, _source_at(60.0), 0.0)], T, ShoeBoxRoom(rt60_s=0.0), head, snr_db=None)
        assert _lead_s(rec.signal) > 300e-6, head.name
        assert np.mean(rec.signal[:, 0] ** 2) > 1.3 * np.mean(rec.signal[:, 1] ** 2), head.name


def test_bad_inputs():
    T = T_world_head_from_position_yaw(HEAD, YAW)
    sig = np.zeros(100)
    with pytest.raises(ValueError, match="outside the room"):
        simulate_binaural([(sig, [9.0, 1.0, 1.0], 0.0)], T)
    with pytest.raises(ValueError, match="head centre"):
        simulate_binaural([(sig, [1.0, 1.0, 1.0], 0.0)], T_world_head_from_position_yaw([7.0, 1, 1]))
    with pytest.raises(ValueError, match="mono"):
        SoundSource(np.zeros((100, 2)), [1.0, 1.0, 1.0])
    with pytest.raises(ValueError, match="non-finite"):
        SoundSource(np.full(10, np.nan), [1.0, 1.0, 1.0])
    with pytest.raises(ValueError, match="Hz"):
        simulate_binaural([(sig, [1.0, 1.0, 1.0], 0.0)], T, head=SphericalHead(fs_hz=8000.0))
    with pytest.raises(ValueError, match="sources is empty"):
        simulate_binaural([], T)


def test_speech_like_signal_is_seeded_and_has_pauses():
    a = speech_like_signal(2.0, FS, seed=7)
    np.testing.assert_array_equal(a, speech_like_signal(2.0, FS, seed=7))
    assert not np.array_equal(a, speech_like_signal(2.0, FS, seed=8))
    frame_rms = np.sqrt(np.mean(a[: len(a) // 320 * 320].reshape(-1, 320) ** 2, axis=1))
    assert np.mean(frame_rms < 1e-3 * frame_rms.max()) > 0.05  # silent gaps
