"""Measured HRIR sets of any grid density: interpolation between measured directions, snapping, warnings.

Reference: sets "measured" from the analytic spherical head (Woodworth ITD) on sparse grids, so the true HRIR
of every direction in between is known.
"""

from __future__ import annotations

import shutil
import warnings

import h5py
import numpy as np
import pytest
from conftest import shared_data
from scipy.signal import resample_poly

from planefuse.audio import HrirWarning, MeasuredHrirs, SphericalHead, directions_from_azimuth_elevation
from planefuse.audio._evaluate import rendered_azimuths_rad

FS = 16000.0
HEAD = SphericalHead(fs_hz=FS)


def itd_us(h: np.ndarray) -> float:
    """Interaural delay of an HRIR pair (2, N) [us], > 0 when the left ear leads (cross-correlation, 1/16 sample)."""
    left, right = resample_poly(h[0], 16, 1), resample_poly(h[1], 16, 1)
    lag = np.argmax(np.correlate(right, left, "full")) - (len(left) - 1)
    return lag / (16 * FS) * 1e6


def spherical_set(az_deg, el_deg=0.0, **kwargs) -> MeasuredHrirs:
    d = directions_from_azimuth_elevation(np.deg2rad(az_deg), np.deg2rad(el_deg))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", HrirWarning)
        return MeasuredHrirs(d, HEAD.hrirs_from_lateral(np.arcsin(d[:, 1])), FS, name="sparse", **kwargs)


def true_hrirs(d: np.ndarray) -> np.ndarray:
    return HEAD.hrirs_from_lateral(np.arcsin(np.clip(d[:, 1], -1, 1)))


def test_measured_directions_are_reproduced_exactly():
    s = spherical_set(np.arange(-180.0, 180.0, 15.0))
    np.testing.assert_allclose(s.hrirs_at(s.directions_head), s.hrir, atol=1e-12 * np.abs(s.hrir).max())


def test_horizontal_interpolation_moves_the_itd_where_snapping_jumps():
    s = spherical_set(np.arange(-180.0, 180.0, 15.0))
    snap = spherical_set(np.arange(-180.0, 180.0, 15.0), interpolation="nearest")
    az = np.array([7.5, 37.5, 52.0, 67.5, -22.5, -80.0])
    d = directions_from_azimuth_elevation(np.deg2rad(az))
    truth = np.array([itd_us(h) for h in true_hrirs(d)])
    interp = np.array([itd_us(h) for h in s.hrirs_at(d)])
    nearest = np.array([itd_us(h) for h in snap.hrirs_at(d)])
    assert np.abs(interp - truth).max() < 15.0, (interp, truth)  # 1/4 sample at 16 kHz
    assert np.abs(nearest - truth).max() > 50.0  # half a 15 deg step of Woodworth ITD
    assert np.abs(interp - truth).mean() < 0.25 * np.abs(nearest - truth).mean()


def test_barycentric_weights_on_a_3d_grid():
    rng = np.random.default_rng(0)
    n = 240  # Fibonacci sphere: ~13 deg between neighbours
    k = np.arange(n) + 0.5
    el = np.arcsin(1 - 2 * k / n)
    az = np.pi * (1 + 5**0.5) * k
    s = spherical_set(np.rad2deg(az), np.rad2deg(el))
    q = rng.normal(size=(300, 3))
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    idx, w = s._interpolation_weights(q)
    assert np.all(w >= 0) and np.allclose(w.sum(axis=1), 1.0)
    p = np.einsum("kj,kji->ki", w, s.directions_head[idx])  # the point of the crossed facet
    np.testing.assert_allclose(np.cross(p, q), 0.0, atol=1e-9)  # lies on the ray of the query
    assert np.all(np.einsum("ki,ki->k", p, q) > 0)
    err = np.array([itd_us(a) - itd_us(b) for a, b in zip(s.hrirs_at(q[:40]), true_hrirs(q[:40]))])
    assert np.abs(err).max() < 20.0, err


def test_room_rendering_equals_the_sum_of_interpolated_hrirs():
    rng = np.random.default_rng(1)
    s = spherical_set(np.arange(-180.0, 180.0, 20.0))
    d = rng.normal(size=(50, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    delay = rng.integers(5, 400, 50)
    gain = rng.normal(size=50)
    got = s.render_impulses(d, delay, gain)
    H = s.hrirs_at(d)
    ref = np.zeros_like(got)
    for k in range(50):
        ref[:, delay[k] : delay[k] + H.shape[-1]] += gain[k] * H[k]
    # windowed-sinc fractional delays (good below 0.8 x Nyquist); hrirs_at also cuts each shifted response
    # to N taps where the room rendering keeps its tail: 0.4 % apart
    f = np.fft.rfftfreq(2048, 1 / FS) < 0.8 * FS / 2
    E, R = np.fft.rfft(got - ref, 2048)[:, f], np.fft.rfft(ref, 2048)[:, f]
    assert np.sqrt(np.sum(np.abs(E) ** 2) / np.sum(np.abs(R) ** 2)) < 1e-2
    snap = spherical_set(np.arange(-180.0, 180.0, 20.0), interpolation="nearest")
    got = snap.render_impulses(d, delay, gain)
    ref = np.zeros_like(got)
    for k, j in enumerate(snap.direction_bins(d)):
        ref[:, delay[k] : delay[k] + snap.hrir.shape[-1]] += gain[k] * snap.hrir[j]
    np.testing.assert_allclose(got, ref, atol=1e-12)


def test_sparse_grid_warns_and_the_sweep_reports_the_rendered_azimuth():
    az = np.r_[np.arange(0.0, 46.0, 5.0), 55.0, 65.0, 80.0, 100.0, 115.0, 125.0, np.arange(135.0, 226.0, 5.0),
               235.0, 245.0, 260.0, 280.0, 295.0, 305.0, np.arange(315.0, 360.0, 5.0)]  # CIPIC's horizontal grid
    d = directions_from_azimuth_elevation(np.deg2rad(az))
    h = HEAD.hrirs_from_lateral(np.arcsin(d[:, 1]))
    with pytest.warns(HrirWarning, match=r"up to 20 deg apart \(none between \+80 and \+100 deg azimuth\); HRIRs "
                                         r"in between are interpolated"):
        interp = MeasuredHrirs(d, h, FS, name="cipic-like")
    with pytest.warns(HrirWarning, match="rendered at the nearest measured direction, up to 10 deg away"):
        snap = MeasuredHrirs(d, h, FS, name="cipic-like", interpolation="nearest")
    sweep = np.deg2rad([-90.0, -70.0, 0.0, 52.0, 90.0])
    np.testing.assert_allclose(np.rad2deg(rendered_azimuths_rad(interp, sweep)), [-90, -70, 0, 52, 90], atol=1e-9)
    np.testing.assert_allclose(np.rad2deg(rendered_azimuths_rad(snap, sweep)), [-80, -65, 0, 55, 80], atol=1e-9)
    np.testing.assert_allclose(np.rad2deg(rendered_azimuths_rad(HEAD, sweep)), [-90, -70, 0, 52, 90], atol=0.13)
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # a dense grid is silent
        spherical = MeasuredHrirs(directions_from_azimuth_elevation(np.deg2rad(np.arange(0.0, 360.0, 5.0))),
                                  HEAD.hrirs_from_lateral(np.zeros(72)), FS)
    assert spherical.interpolation == "barycentric"


def test_bad_hrir_arguments():
    d = directions_from_azimuth_elevation(np.deg2rad(np.arange(0.0, 360.0, 5.0)))
    h = HEAD.hrirs_from_lateral(np.arcsin(d[:, 1]))
    with pytest.raises(ValueError, match="interpolation must be one of"):
        MeasuredHrirs(d, h, FS, interpolation="linear")
    with pytest.raises(ValueError, match="grid_deg must be in"):
        MeasuredHrirs(d, h, FS, grid_deg=0.0)
    s = MeasuredHrirs(d, h, FS)
    with pytest.raises(ValueError, match="one row per impulse"):
        s.render_impulses(d[:3], [1, 2], [1.0, 1.0, 1.0])


@pytest.fixture(scope="module")
def kemar():
    return MeasuredHrirs.from_sofa(shared_data("hrtf_sofa") / "MIT_KEMAR_normal_pinna.sofa", FS)


@pytest.mark.realdata
def test_kemar_held_out_directions_are_closer_interpolated_than_snapped(kemar):
    az = np.rad2deg(np.arctan2(kemar.directions_head[:, 1], kemar.directions_head[:, 0])) % 360
    el = np.rad2deg(np.arcsin(kemar.directions_head[:, 2]))
    horizontal = np.abs(el) < 1
    keep = ~horizontal | (np.round(az) % 20 == 0)  # horizontal ring thinned from 5 to 20 deg
    with pytest.warns(HrirWarning, match="up to 20 deg apart"):
        sparse = MeasuredHrirs(kemar.directions_head[keep], kemar.hrir[keep], FS, name="sparse KEMAR")
        snap = MeasuredHrirs(kemar.directions_head[keep], kemar.hrir[keep], FS, name="sparse KEMAR",
                             interpolation="nearest")
    held = np.flatnonzero(horizontal & ~keep & (np.abs(((az + 180) % 360) - 180) <= 90))  # front half
    d, truth = kemar.directions_head[held], kemar.hrir[held]
    rel = lambda h: np.linalg.norm(h - truth, axis=(1, 2)) / np.linalg.norm(truth, axis=(1, 2))  # noqa: E731
    e_interp, e_snap = rel(sparse.hrirs_at(d)), rel(snap.hrirs_at(d))
    assert np.median(e_interp) < 0.75 * np.median(e_snap), (np.median(e_interp), np.median(e_snap))
    itd_err = [abs(itd_us(a) - itd_us(b)) for a, b in zip(sparse.hrirs_at(d), truth)]
    itd_err_snap = [abs(itd_us(a) - itd_us(b)) for a, b in zip(snap.hrirs_at(d), truth)]
    assert np.median(itd_err) < 0.5 * np.median(itd_err_snap), (np.median(itd_err), np.median(itd_err_snap))


@pytest.mark.realdata
def test_old_sofa_version_gives_one_planefuse_warning(tmp_path):
    old = tmp_path / "old_convention.sofa"
    shutil.copy(shared_data("hrtf_sofa") / "MIT_KEMAR_normal_pinna.sofa", old)
    old.chmod(0o644)
    with h5py.File(old, "r+") as f:
        f.attrs["SOFAConventionsVersion"] = "0.4"
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        head = MeasuredHrirs.from_sofa(old, FS, interpolation="nearest")
    assert [w.category for w in caught] == [HrirWarning], [str(w.message) for w in caught]
    msg = str(caught[0].message)
    assert "\n" not in msg and msg.startswith("old_convention.sofa: SOFA conventions version 0.4 (preliminary")
    assert head.hrir.shape[0] == 710
    with pytest.raises(ValueError, match="not a readable SOFA file"):
        (tmp_path / "x.sofa").write_bytes(b"garbage")
        MeasuredHrirs.from_sofa(tmp_path / "x.sofa", FS)
