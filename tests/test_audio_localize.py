"""Cochlear unit, binaural cues, Bayesian sensor model, localisation accuracy and plane registration."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.signal import gammatone, lfilter

from conftest import shared_data
from planefuse.audio import (
    HEAD_RADIUS_M,
    BinauralSensorModel,
    GammatoneFilterbank,
    MeasuredHrirs,
    ShoeBoxRoom,
    SphericalHead,
    binaural_cues,
    default_sensor_model,
    erb_space_hz,
    evidence_from_saliency,
    localize,
    read_audio,
    simulate_binaural,
    speech_like_signal,
)
from planefuse.audio._evaluate import SweepScene, calibrate_from_simulation, evaluate_sweep, sweep_recordings
from planefuse.grid import PlaneStack

FS = 16000.0


@pytest.fixture(scope="module")
def model() -> BinauralSensorModel:
    return default_sensor_model(FS)


def _delayed_pair(x: np.ndarray, lead_left_s: float) -> np.ndarray:
    """[left, right] with the right ear delayed by ``lead_left_s`` (exact fractional delay via the FFT)."""
    n = 2 * len(x)
    f = np.fft.rfftfreq(n, 1 / FS)
    right = np.fft.irfft(np.fft.rfft(x, n) * np.exp(-2j * np.pi * f * lead_left_s), n)[: len(x)]
    return np.stack([x, right], axis=1)


# -- monaural cochlear unit -----------------------------------------------------------------------
def test_erb_spacing_is_uniform_on_the_erb_scale():
    f = erb_space_hz(100, 4000, 32)
    erb_number = 21.4 * np.log10(1 + 0.00437 * f)
    np.testing.assert_allclose(np.diff(erb_number), np.diff(erb_number)[0], rtol=1e-9)
    assert f[0] == pytest.approx(100) and f[-1] == pytest.approx(4000)


def test_filterbank_matches_scipy_gammatone_and_has_unit_centre_gain(rng):
    fb = GammatoneFilterbank(FS, n_bands=8, f_min_hz=200, f_max_hz=3000)
    x = rng.standard_normal((4000, 2))
    y = fb.process(x)
    assert y.shape == (8, 2, 4000) and y.dtype == np.float32
    for b, fc in enumerate(fb.center_freqs_hz):
        ref = lfilter(*gammatone(fc, "iir", fs=FS), x[:, 1])
        gain = np.dot(y[b, 1], ref) / np.dot(ref, ref)  # ours is normalised to unit centre gain
        np.testing.assert_allclose(y[b, 1] / gain, ref, atol=1e-3 * np.abs(ref).max())
        t = np.arange(8000) / FS
        tone = np.sin(2 * np.pi * fc * t)
        out = fb.process(np.stack([tone, tone], 1))[:, 0, 4000:]
        assert np.argmax(out.std(axis=1)) == b
        assert out[b].std() * np.sqrt(2) == pytest.approx(1.0, rel=0.02)


def test_hair_cell_is_half_wave_rectified_and_smooth(rng):
    fb = GammatoneFilterbank(FS, n_bands=4, f_min_hz=300, f_max_hz=3000, envelope_cutoff_hz=1000.0)
    y = fb.process(rng.standard_normal((4000, 2)))
    assert y.min() >= 0.0


# -- binaural unit ---------------------------------------------------------------------------------
@pytest.mark.parametrize("front_end", ["time", "fft"])
@pytest.mark.parametrize("lead_s", [0.0, 137e-6, -402.5e-6, 610e-6])
def test_itd_with_sub_sample_precision_and_sign(rng, lead_s, front_end):
    x = _delayed_pair(rng.standard_normal(8000), lead_s)
    cues = binaural_cues(x, FS, onset_db=None, front_end=front_end)
    tau = cues.tau_s[cues.active]
    assert tau.size > 100
    assert np.median(tau) == pytest.approx(lead_s, abs=8e-6)  # an eighth of a sample


def test_ild_of_a_level_difference(rng):
    x = rng.standard_normal((8000, 1)) * np.array([[1.0, 0.5]])
    cues = binaural_cues(x, FS, onset_db=None)
    assert np.nanmedian(cues.ild_db[cues.active]) == pytest.approx(20 * np.log10(2), abs=0.05)


def test_silent_audio_gives_no_evidence(model):
    loc = localize(np.zeros((8000, 2)), FS, model)
    assert loc.n_active_frames == 0 and np.isnan(loc.map_azimuth_rad) and loc.source_azimuths_rad.size == 0
    assert not loc.frame_saliency.any() and not loc.saliency.any()
    stack = PlaneStack.from_extent([0.0, 1.6], (0, 4), (0, 4), 0.1)
    ev = evidence_from_saliency(loc.saliency, loc.azimuth_rad, np.eye(4), stack, 0.0)
    assert not ev.log_odds.any()


def test_clipped_audio_gives_no_evidence_not_a_false_peak(model):
    sig = speech_like_signal(1.0, FS, seed=2)
    scene = SweepScene(room=ShoeBoxRoom(rt60_s=0.0))
    x = sweep_recordings(sig, [np.deg2rad(30.0)], scene, SphericalHead(), FS)[0]
    hard = np.clip(x * 1e3 / np.abs(x).max(), -1, 1)  # saturated nearly everywhere
    loc = localize(hard, FS, model)
    assert loc.cues.n_clipped_frames >= 0.9 * len(loc.time_s)
    assert loc.n_active_frames <= 0.1 * len(loc.time_s)
    # mild clipping: only the clipped frames are dropped, the azimuth survives
    mild = np.clip(x, -0.6 * np.abs(x).max(), 0.6 * np.abs(x).max())
    loc = localize(mild, FS, model)
    assert 0 < loc.cues.n_clipped_frames < len(loc.time_s)
    assert np.rad2deg(loc.map_azimuth_rad) == pytest.approx(30.0, abs=5.0)


def test_bad_inputs(model):
    with pytest.raises(ValueError, match="two-channel.*mono"):
        localize(np.zeros(1000), FS, model)
    with pytest.raises(ValueError, match="two-channel.*mono"):
        localize(np.zeros((1000, 1)), FS, model)
    with pytest.raises(ValueError, match="two-channel"):
        localize(np.zeros((1000, 4)), FS, model)
    x = np.random.default_rng(0).standard_normal((1000, 2))
    x[10, 1] = np.nan
    with pytest.raises(ValueError, match="1 NaN"):
        localize(x, FS, model)
    with pytest.raises(ValueError, match="calibrated at 16000"):
        localize(np.zeros((1000, 2)), 44100.0, model)
    with pytest.raises(ValueError, match="front_end"):
        binaural_cues(np.zeros((1000, 2)), FS, front_end="wavelet")


# -- sensor model ----------------------------------------------------------------------------------
def test_model_round_trip(tmp_path, model):
    p = model.save(tmp_path / "m.npz")
    m2 = BinauralSensorModel.load(p)
    np.testing.assert_array_equal(m2.mu_s, model.mu_s)
    np.testing.assert_array_equal(m2.sigma_s, model.sigma_s)
    np.testing.assert_array_equal(m2.filterbank.center_freqs_hz, model.filterbank.center_freqs_hz)
    (tmp_path / "bad.npz").write_bytes(b"not a model")
    with pytest.raises(ValueError, match="not a planefuse binaural sensor model"):
        BinauralSensorModel.load(tmp_path / "bad.npz")


def test_default_model_follows_the_spherical_head(model):
    """Low bands: calibrated mean ITD at 90 deg between Woodworth and the low-frequency limit 1.5x."""
    i90 = np.argmin(np.abs(model.azimuth_rad - np.pi / 2))
    low = model.filterbank.center_freqs_hz < 500
    wood = SphericalHead().itd_s(np.pi / 2)
    assert np.all(model.mu_s[low, i90] > wood) and np.all(model.mu_s[low, i90] < 1.5 * wood)
    i0 = np.argmin(np.abs(model.azimuth_rad))
    assert np.median(np.abs(model.mu_s[low, i0])) < 25e-6  # a twelfth of the 90-deg ITD


def test_frame_saliency_rows_are_distributions_or_zero(model):
    x = sweep_recordings(speech_like_signal(1.0, FS, seed=4), [0.5], SweepScene(), SphericalHead(), FS)[0]
    loc = localize(x, FS, model)
    sums = loc.frame_saliency.sum(axis=1)
    np.testing.assert_allclose(sums[loc.frame_active], 1.0)
    assert not sums[~loc.frame_active].any()
    assert loc.saliency.sum() == pytest.approx(1.0)


# -- accuracy in a reverberant room (RT60 0.3 s, SNR 20 dB), real speech -----------------------------
SWEEP_DEG = np.array([-80.0, -40.0, 0.0, 40.0, 80.0])


def _cmu(name: str, seconds: float) -> np.ndarray:
    x, _ = read_audio(shared_data("speech_cmu_arctic") / name, FS)
    return x[: int(seconds * FS), 0]


@pytest.mark.realdata
def test_spherical_head_sweep_beats_pyroomacoustics(model):
    speech = _cmu("cmu_arctic_us_aew_a0001.wav", 1.5)
    az = np.deg2rad(SWEEP_DEG)
    errs = evaluate_sweep(sweep_recordings(speech, az, SweepScene(), SphericalHead(), FS), az, model,
                          2 * HEAD_RADIUS_M)
    mae = {k: np.rad2deg(v.mean()) for k, v in errs.items()}
    assert mae["planefuse Bayes"] <= 5.0, mae
    for k, v in mae.items():
        assert mae["planefuse Bayes"] <= v, mae


@pytest.mark.realdata
@pytest.mark.parametrize("which", ["kemar", "ku100"])
def test_measured_hrir_sweep(which):
    if which == "kemar":
        head = MeasuredHrirs.from_sofa(shared_data("hrtf_sofa") / "MIT_KEMAR_normal_pinna.sofa", FS)
    else:
        head = MeasuredHrirs.from_ku100_npz(shared_data("hrir_ku100_circular") / "ku100_circular.npz", FS)
    # calibrate on synthetic speech at 15 deg steps, evaluate on a real utterance at other azimuths
    m = calibrate_from_simulation(head, speech_like_signal(1.0, FS, seed=12345), FS, step_deg=15.0)
    speech = _cmu("cmu_arctic_us_axb_a0004.wav", 1.5)
    az = np.deg2rad(np.array([-70.0, -25.0, 10.0, 55.0]))
    errs = evaluate_sweep(sweep_recordings(speech, az, SweepScene(), head, FS), az, m, 0.0, baselines=False)
    assert np.rad2deg(errs["planefuse Bayes"].mean()) <= 5.0, np.rad2deg(errs["planefuse Bayes"])


def test_two_overlapping_talkers_give_two_peaks(model):
    """Two talkers, 1.2 s each, overlapping for 0.4 s (RT60 0.15 s): the saliency map has a peak at each.

    (At RT60 0.3 s the frame-wise maps of two talkers are too noisy to separate; see docs/audio.md.)
    """
    scene = SweepScene(room=ShoeBoxRoom(dims_m=(6.0, 5.0, 3.0), rt60_s=0.15))
    a, b = np.deg2rad(-50.0), np.deg2rad(35.0)
    srcs = [(speech_like_signal(1.2, FS, seed=21), scene.source_position(a), 0.0),
            (speech_like_signal(1.2, FS, seed=22), scene.source_position(b), 0.8)]
    rec = simulate_binaural(srcs, scene.T_world_head, scene.room, snr_db=20.0)
    loc = localize(rec.signal, FS, model)
    found = np.rad2deg(loc.source_azimuths_rad[:2])
    assert np.sort(found) == pytest.approx([-50.0, 35.0], abs=8.0), found
    # most salient first, each with its own peak's saliency
    assert np.all(np.diff(loc.source_saliency) <= 0), loc.source_saliency
    assert loc.source_saliency[0] == pytest.approx(loc.saliency.max())


def test_log_likelihood_ratio_matches_the_documented_model(rng, model):
    """Per band, written from the module docstring in float64: P(tau | S=1) = eps u + (1 - eps) N(r; 0,
    sigma) / n_images, with r the residual to the nearest image one period 1/f_b apart and n_images =
    max(1, 2 max_itd f_b) the images inside the lag range; P(tau | S=0) = u = 1 / (2 max_itd)."""
    B, A = model.mu_s.shape
    tau = rng.uniform(-model.max_itd_s, model.max_itd_s, (B, B))
    a = rng.integers(0, A, B)
    tau[np.arange(B), np.arange(B)] = model.mu_s[np.arange(B), a] + rng.normal(0, 1, B) * model.sigma_s[
        np.arange(B), a]  # near the mean for azimuth a[b], so the normal term matters
    active = np.eye(B, dtype=bool)  # frame b: band b alone
    ours = model.log_likelihood_ratio(tau, active)
    f = model.filterbank.center_freqs_hz[:, None]
    eps, u = model.outlier_weight, 1.0 / (2 * model.max_itd_s)
    r = np.diag(tau)[:, None] - model.mu_s
    r -= np.round(r * f) / f
    n_images = np.maximum(1.0, 2 * model.max_itd_s * f)
    normal = np.exp(-0.5 * (r / model.sigma_s) ** 2) / (np.sqrt(2 * np.pi) * model.sigma_s)
    ref = np.log(eps * u + (1 - eps) * normal / n_images) - np.log(u)
    np.testing.assert_allclose(ours, ref, rtol=1e-4, atol=1e-4)
    assert np.ptp(ref, axis=1).min() > 1.0  # the test is not flat: azimuths differ


@pytest.mark.parametrize("offset_steps", [-0.5, -0.37, -0.1, 0.0, 0.23, 0.49])
def test_peak_refinement_is_exact_on_a_parabola(offset_steps):
    """Sub-grid peak refinement returns the vertex of a sampled parabola exactly (a sign error biases it
    by up to half a grid step, 0.5 deg on the default 1 deg grid, far below localisation tolerances)."""
    from planefuse.audio._bayes import _refine_peak

    grid = np.deg2rad(np.arange(-90.0, 90.5, 1.0))
    vertex = grid[100] + offset_steps * (grid[1] - grid[0])
    y = 3.0 - 40.0 * (grid - vertex) ** 2
    assert _refine_peak(grid, y, int(np.argmax(y[1:-1])) + 1) == pytest.approx(vertex, abs=1e-12)
    # at the ends of the span, no neighbour on one side: the grid value itself
    assert _refine_peak(grid, -(grid - grid[0]) ** 2, 0) == grid[0]
    assert _refine_peak(grid, -(grid - grid[-1]) ** 2, len(grid) - 1) == grid[-1]


def test_reported_source_azimuth_is_the_vertex_through_its_saliency_peak(rng, model):
    """The public route: the first source azimuth is the parabola through the saliency map's largest sample
    and its two neighbours (fitted here with numpy.polyfit), not the grid sample itself."""
    loc = localize(_delayed_pair(rng.standard_normal(8000), 250e-6), FS, model)
    i = int(np.argmax(loc.saliency))
    assert 0 < i < len(loc.saliency) - 1
    a, b, _ = np.polyfit(loc.azimuth_rad[i - 1:i + 2], loc.saliency[i - 1:i + 2], 2)
    assert a < 0
    assert loc.source_azimuths_rad[0] == pytest.approx(-b / (2 * a), abs=1e-9)
    assert loc.source_azimuths_rad[0] != loc.azimuth_rad[i]


# -- registration on the planes --------------------------------------------------------------------
def test_wedge_passes_through_the_true_source_on_every_plane(model):
    scene = SweepScene()
    az = np.deg2rad(35.0)
    rec = simulate_binaural([(speech_like_signal(1.5, FS, seed=5), scene.source_position(az), 0.0)],
                            scene.T_world_head, scene.room, snr_db=20.0)
    loc = localize(rec.signal, FS, model)
    stack = PlaneStack.from_extent([0.0, 0.9, 1.6], (0, 6), (0, 5), 0.05)
    ev = evidence_from_saliency(loc.saliency, loc.azimuth_rad, rec.T_world_head, stack, 1.0)
    assert ev.log_odds.shape == stack.shape and ev.log_odds.dtype == np.float32
    head = np.asarray(scene.head_position_m)
    src = rec.sources_world_m[0]
    for l in range(stack.n_planes):
        peak = ev.log_odds[l].max()
        assert peak > 0.3
        for r in (0.7, 1.5, 2.2):  # every point of the half-line from the head through the source
            iy, ix = stack.index_from_xy(head[:2] + r * (src[:2] - head[:2]) / np.linalg.norm(src[:2] - head[:2]))
            assert ev.log_odds[l, iy, ix] >= 0.7 * peak
        # the mirrored back half-line (azimuth 180 - 35 deg) carries the same evidence: front/back ambiguity
        back = np.pi - az + scene.head_yaw_rad
        iy, ix = stack.index_from_xy(head[:2] + 1.5 * np.array([np.cos(back), np.sin(back)]))
        assert ev.log_odds[l, iy, ix] >= 0.7 * peak
        # off the wedge: at most weak free-space evidence, never strong
        off = az + np.deg2rad(40.0) + scene.head_yaw_rad
        iy, ix = stack.index_from_xy(head[:2] + 1.5 * np.array([np.cos(off), np.sin(off)]))
        assert -0.2 < ev.log_odds[l, iy, ix] <= 0.0
    assert ev.log_odds.min() >= np.log(0.9) - 1e-6


def test_evidence_rejects_bad_saliency():
    stack = PlaneStack.from_extent([1.0], (0, 2), (0, 2), 0.1)
    grid = np.deg2rad(np.arange(-90.0, 91.0))
    with pytest.raises(ValueError, match="saliency"):
        evidence_from_saliency(np.ones(5), grid, np.eye(4), stack, 0.0)
    with pytest.raises(ValueError, match="lateral"):
        evidence_from_saliency(np.ones(181), np.linspace(0, 4, 181), np.eye(4), stack, 0.0)


# -- command line ----------------------------------------------------------------------------------
def test_cli_calibrate_and_localize(tmp_path):
    import soundfile as sf
    from typer.testing import CliRunner

    from planefuse.cli import app

    runner = CliRunner()
    out = tmp_path / "model.npz"
    r = runner.invoke(app, ["audio", "calibrate", "--out", str(out), "--step-deg", "30", "--bands", "16"])
    assert r.exit_code == 0, r.output
    m = BinauralSensorModel.load(out)
    assert m.filterbank.n_bands == 16 and "spherical head" in m.source
    x = sweep_recordings(speech_like_signal(1.0, FS, seed=8), [np.deg2rad(-30.0)], SweepScene(), SphericalHead(), FS)[0]
    wav = tmp_path / "rec.wav"
    sf.write(wav, x / np.abs(x).max() * 0.5, int(FS), subtype="FLOAT")
    r = runner.invoke(app, ["audio", "localize", str(wav), "--model", str(out)])
    assert r.exit_code == 0, r.output
    az = float(r.output.split("azimuth")[1].split("deg")[0])
    assert az == pytest.approx(-30.0, abs=6.0)
    sf.write(tmp_path / "mono.wav", x[:, 0], int(FS))
    r = runner.invoke(app, ["audio", "localize", str(tmp_path / "mono.wav")])
    assert r.exit_code == 2 and r.output.startswith("error: ") and "mono" in r.output  # one line, no traceback
