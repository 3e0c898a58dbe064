"""Evidence for the recording format: exact round trips and clear errors for broken recordings."""

from __future__ import annotations

import shutil
import warnings

import numpy as np
import pytest
import soundfile as sf
import yaml
from hypothesis import given, settings
from hypothesis import strategies as st

from planefuse.io import (
    AudioStream,
    LaserScans,
    LaserStream,
    image_file_problem,
    read_recording,
)
from planefuse.io._timestamps import TimeChecker, read_csv_chunks, write_csv
from planefuse.sim import SceneConfig, simulate


def _small_config(**kw) -> SceneConfig:
    base = {
        "duration_s": 1.0,
        "n_people": 3,
        "seed": 5,
        "laser": {"resolution_deg": 2.0},
        "head": {"rt60_s": 0.0},
        "cameras": [
            {"name": "a", "position_m": [0.3, 0.3, 3.0], "target_m": [5, 5, 0], "width_px": 160, "height_px": 120},
            {"name": "b", "position_m": [9.7, 9.7, 2.8], "target_m": [5, 5, 0], "width_px": 160, "height_px": 120,
             "rate_hz": 10, "time_offset_s": 0.013},
        ],
    }
    base.update(kw)
    return SceneConfig.model_validate(base)


def _synthetic_laser(rng, n_scans=90, n_beams=181) -> LaserStream:
    times = 0.005 + np.arange(n_scans) / 40.0
    ranges = rng.uniform(0.1, 12.0, (n_scans, n_beams))
    ranges[rng.random(ranges.shape) < 0.05] = np.nan
    scans = LaserScans(times, np.linspace(-np.radians(135), np.radians(135), n_beams), ranges,
                       np.radians(10) * np.sin(2 * np.pi * times / 2.0),
                       {"T_world_scanner": np.tile(np.eye(4), (n_scans, 1, 1))})
    return LaserStream("syn_laser", np.eye(4), 40.0, n_scans, dict(SYN_DEVICE), data=scans)


#: A complete laser device entry (planefuse.io.LaserUnitDevice: every field written out, as read back).
SYN_DEVICE = {"scanner": {"angle_min_rad": -2.356, "angle_increment_rad": 0.0262, "n_beams": 181, "range_min_m": 0.1,
                          "range_max_m": 30.0, "range_noise_sigma_m": 0.01, "name": "syn"},
              "offset_tilt_scanner_m": (0.0, 0.0, 0.05), "tilt_min_rad": -0.17, "tilt_max_rad": 0.17,
              "tilt_period_s": 2.0, "scan_duration_s": None}


def _synthetic_audio(rng, n=16000 + 37) -> AudioStream:
    x = (0.1 * rng.normal(size=(n, 2))).astype(np.float32)
    T = np.eye(4)
    T[:3, 3] = [5.0, 0.3, 1.6]
    return AudioStream("syn_head", T, 16000, 0.0, n, data=x)


@pytest.fixture(scope="module")
def written(tmp_path_factory):
    rng = np.random.default_rng(11)
    rec = simulate(_small_config())
    rec.lasers["syn_laser"] = _synthetic_laser(rng)
    rec.audio["syn_head"] = _synthetic_audio(rng)
    out = tmp_path_factory.mktemp("rec") / "r"
    rec.write(out)
    return rec, out


def test_round_trip_is_identical(written):
    rec, out = written
    back = read_recording(out)
    assert back.duration_s == rec.duration_s and back.room_xy_m == rec.room_xy_m
    assert list(back.camera_streams) == ["a", "b"]
    for name, cs in rec.camera_streams.items():
        cb = back.camera(name)
        np.testing.assert_array_equal(cb.times_s, cs.times_s)
        np.testing.assert_array_equal(cb.camera.K, cs.camera.K)
        np.testing.assert_array_equal(cb.camera.T_world_cam, cs.camera.T_world_cam)
        np.testing.assert_array_equal(cb.camera.intrinsics.dist, cs.camera.intrinsics.dist)
        for fa, fb in zip(cs, cb, strict=True):
            assert fa.time_s == fb.time_s
            np.testing.assert_array_equal(fa.image, fb.image)
            np.testing.assert_array_equal(fa.mask, fb.mask)
    assert back.camera("b").times_s[0] == 0.013 and len(back.camera("b")) == 10
    np.testing.assert_array_equal(back.camera("a").background(), rec.camera("a").background())
    for name, s in rec.imus.items():
        a, b = s.read(), back.imu(name).read()
        for f in ("times_s", "gyro_rad_s", "accel_m_s2"):
            np.testing.assert_array_equal(getattr(a, f), getattr(b, f))
        np.testing.assert_array_equal(back.imu(name).T_cam_imu, s.T_cam_imu)
        assert back.imu(name).attached_to == s.attached_to
    for name in ("laser0", "syn_laser"):
        la, lb = rec.laser(name).read(), back.laser(name).read()
        for f in ("times_s", "angles_rad", "ranges_m", "tilt_rad"):
            np.testing.assert_array_equal(getattr(la, f), getattr(lb, f))
        np.testing.assert_array_equal(back.laser(name).T_world_laser, rec.laser(name).T_world_laser)
        assert back.laser(name).model == rec.laser(name).model
    np.testing.assert_array_equal(rec.laser("syn_laser").read().extra["T_world_scanner"],
                                  back.laser("syn_laser").read().extra["T_world_scanner"])
    assert back.laser("syn_laser").model == SYN_DEVICE
    assert len(back.laser("syn_laser").paths) == 1 and len(back.laser("laser0").paths) == 1
    assert np.isfinite(back.laser("laser0").read().ranges_m).all()  # a closed room: every beam returns
    for name in ("head", "syn_head"):
        np.testing.assert_array_equal(rec.binaural(name).read(), back.binaural(name).read())
        np.testing.assert_array_equal(rec.binaural(name).T_world_head, back.binaural(name).T_world_head)
    blocks = list(back.binaural("syn_head").blocks(5000))
    assert [t for t, _ in blocks] == [0.0, 5000 / 16000, 10000 / 16000, 15000 / 16000]
    ga, gb = rec.groundtruth, back.groundtruth
    for f in ("times_s", "person_ids", "xy_m", "heading_rad", "speed_m_s", "height_m"):
        np.testing.assert_array_equal(getattr(ga.people, f), getattr(gb.people, f))
    np.testing.assert_array_equal(ga.bodies, gb.bodies)
    for f in ("times_s", "person_ids", "speaking", "position_m", "azimuth_rad", "elevation_rad"):
        np.testing.assert_array_equal(getattr(ga.sound, f), getattr(gb.sound, f))
    assert SceneConfig.model_validate(back.provenance) == rec.config  # simulation.yaml reproduces the scene
    det = gb.people.detections_at(0.5)
    assert len(det) == 3 and det.time_s == 0.5
    # Interpolated ground truth agrees with the scene's own state at an off-grid time (linear, 2 cm).
    np.testing.assert_allclose(det.xy_m, rec.scene.people_at([0.5]).xy_m[0], atol=0.02)
    np.testing.assert_array_equal(gb.people.xy_at(gb.people.times_s), gb.people.xy_m)


def test_a_read_recording_writes_an_identical_copy(written, tmp_path):
    back = read_recording(written[1])
    back.write(tmp_path / "copy")
    again = read_recording(tmp_path / "copy")
    for fa, fb in zip(back.camera("b"), again.camera("b"), strict=True):
        np.testing.assert_array_equal(fa.image, fb.image)
        np.testing.assert_array_equal(fa.mask, fb.mask)
    np.testing.assert_array_equal(again.imu("b_imu").read().accel_m_s2, back.imu("b_imu").read().accel_m_s2)
    np.testing.assert_array_equal(again.laser("laser0").read().ranges_m, back.laser("laser0").read().ranges_m)
    np.testing.assert_array_equal(again.binaural("head").read(), back.binaural("head").read())
    np.testing.assert_array_equal(again.groundtruth.people.xy_m, back.groundtruth.people.xy_m)
    assert again.provenance == back.provenance


def test_events_are_time_ordered_and_complete(written):
    _, out = written
    back = read_recording(out)
    evs = list(back.events(audio_block_s=0.1))
    times = [e.time_s for e in evs]
    assert times == sorted(times)
    count = {}
    for e in evs:
        count[(e.kind, e.name)] = count.get((e.kind, e.name), 0) + 1
    assert count[("camera", "a")] == 25 and count[("camera", "b")] == 10
    assert count[("imu", "a_imu")] == 200 and count[("laser", "syn_laser")] == 90
    assert count[("binaural", "syn_head")] == 11  # 16037 samples in blocks of 1600
    frame = next(e for e in evs if e.kind == "camera" and e.name == "b")
    np.testing.assert_array_equal(frame.data.image, back.camera("b").frame(0))
    at0 = [(e.kind, e.name) for e in evs if e.time_s == 0.0]  # ties keep the order of kinds
    assert at0 == [("camera", "a"), ("imu", "a_imu"), ("imu", "b_imu"), ("laser", "laser0"),
                   ("binaural", "head"), ("binaural", "syn_head")]
    with pytest.raises(ValueError, match="kinds must be among"):
        next(back.events(kinds=("radar",)))


def test_streams_are_lazy_and_chunked(written):
    _, out = written
    back = read_recording(out)
    chunks = list(back.imu("a_imu").chunks(max_rows=64))
    assert [len(c) for c in chunks] == [64, 64, 64, 8]
    assert np.all(np.diff(np.concatenate([c.times_s for c in chunks])) > 0)
    # Deleting a frame after opening only fails when that frame is read, naming it.
    shutil.copytree(out, out.parent / "lazy")
    lazy = read_recording(out.parent / "lazy")
    (out.parent / "lazy/cameras/a/frames/000020.bmp").unlink()
    lazy.camera("a").frame(19)
    with pytest.raises(ValueError, match=r"cameras/a/frames/000020\.bmp: file not found"):
        lazy.camera("a").frame(20)



def test_frame_files_are_kept_compactly_and_exactly(written, tmp_path):
    """A stream's frame files are one bytes array (no Path object per frame: memory would grow with the
    recording), read back as the exact paths, non-ASCII names included."""
    from planefuse.io._paths import PathArray

    _, out = written
    cs = read_recording(out).camera("a")
    assert isinstance(cs.frame_files, PathArray) and len(cs.frame_files) == len(cs)
    assert cs.frame_files[20] == (out / "cameras/a/frames/000020.bmp").resolve()
    assert cs.frame_files[-1].is_file() and cs.frame_files[:2] == [cs.frame_files[0], cs.frame_files[1]]
    names = [tmp_path / "caméra" / "000001.png", tmp_path / "b" / "x y.png"]
    assert list(PathArray(names)) == names and len(PathArray([])) == 0

def test_jpeg_frames_are_close_and_masks_exact(tmp_path):
    rec = simulate(_small_config(duration_s=0.2))
    rec.write(tmp_path / "j", image_format="jpg")
    back = read_recording(tmp_path / "j")
    for fa, fb in zip(rec.camera("a"), back.camera("a"), strict=True):
        np.testing.assert_array_equal(fa.mask, fb.mask)
        err = fa.image.astype(float) - fb.image
        assert 10 * np.log10(255**2 / np.mean(err**2)) > 35  # PSNR [dB]
    with pytest.raises(ValueError, match="image_format must be one of"):
        rec.write(tmp_path / "x", image_format="tiff")


def test_bmp_frames_are_exact_and_the_default(tmp_path):
    """The default frame format (uncompressed BMP, the fastest to read) gives back the simulated pixels exactly,
    as stored PNG does, and is what ``planefuse simulate`` writes."""
    from planefuse.cli._simulate import simulate as simulate_command

    rec = simulate(_small_config(duration_s=0.12))
    rec.write(tmp_path / "b")
    rec.write(tmp_path / "p", image_format="png")
    frames = sorted((tmp_path / "b" / "cameras" / "a" / "frames").iterdir())
    assert frames and all(f.suffix == ".bmp" for f in frames)
    for fa, fb, fp in zip(rec.camera("a"), read_recording(tmp_path / "b").camera("a"),
                          read_recording(tmp_path / "p").camera("a"), strict=True):
        np.testing.assert_array_equal(fa.image, fb.image)
        np.testing.assert_array_equal(fb.image, fp.image)
        np.testing.assert_array_equal(fa.mask, fb.mask)
    h, w = rec.camera("a").frame(0).shape[:2]
    assert frames[0].stat().st_size >= h * w * 3
    import inspect

    assert inspect.signature(simulate_command).parameters["image_format"].default.default == "bmp"


def test_png_frames_are_exact_at_every_compression_level(tmp_path):
    rec = simulate(_small_config(duration_s=0.12))
    sizes = {}
    for level in (0, 1, 9):
        rec.write(tmp_path / f"p{level}", image_format="png", png_compression=level)
        back = read_recording(tmp_path / f"p{level}")
        for fa, fb in zip(rec.camera("a"), back.camera("a"), strict=True):
            np.testing.assert_array_equal(fa.image, fb.image)
        sizes[level] = sum(f.stat().st_size for f in (tmp_path / f"p{level}" / "cameras" / "a" / "frames").iterdir())
    h, w = rec.camera("a").frame(0).shape[:2]
    assert sizes[0] >= len(rec.camera("a")) * h * w * 3 > sizes[1] >= sizes[9]  # level 0: stored, not deflated
    for bad in (-1, 10, 1.5):
        with pytest.raises(ValueError, match="png_compression must be an integer in 0..9"):
            rec.write(tmp_path / "bad", image_format="png", png_compression=bad)


def _copy(written, tmp_path, name="broken"):
    dst = tmp_path / name
    shutil.copytree(written[1], dst)
    return dst


def test_output_folder_must_be_empty(written):
    with pytest.raises(ValueError, match="output folder is not empty"):
        written[0].write(written[1])


def test_truncated_imu_csv_names_file_and_line(written, tmp_path):
    d = _copy(written, tmp_path)
    p = d / "imu/a_imu.csv"
    text = p.read_text()
    p.write_text(text[: len(text) - 25])  # cut the last line in the middle
    rec = read_recording(d)
    with pytest.raises(ValueError, match=r"a_imu\.csv:201: truncated line"):
        rec.imu("a_imu").read()
    lines = text.splitlines(keepends=True)
    p.write_text("".join(lines[:-10]))  # whole lines missing
    with pytest.raises(ValueError, match=r"a_imu\.csv: manifest says n_samples = 200, file has 190 rows"):
        read_recording(d).imu("a_imu").read()


@pytest.mark.parametrize("fmt, message", [
    ("png", r"000004\.png: PNG end chunk missing \(truncated file\)"),
    ("bmp", r"000004\.bmp: 300 bytes of the \d+ its header declares \(truncated file\)")])
def test_truncated_frame_names_file(tmp_path, fmt, message):
    d = tmp_path / fmt
    simulate(_small_config(duration_s=0.6)).write(d, image_format=fmt)
    p = d / f"cameras/b/frames/000004.{fmt}"
    p.write_bytes(p.read_bytes()[:300])
    rec = read_recording(d)
    rec.camera("b").frame(3)
    with pytest.raises(ValueError, match=message):
        rec.camera("b").frame(4)
    assert image_file_problem(p).endswith("(truncated file)")  # planefuse check, without decoding
    p.write_bytes(b"GARBAGE" + p.read_bytes())
    with pytest.raises(ValueError, match=f"000004\\.{fmt}: not a {fmt.upper()} file \\(corrupt file\\)"):
        read_recording(d).camera("b").frame(4)


def test_truncated_laser_npz_and_wav_name_file(written, tmp_path):
    d = _copy(written, tmp_path)
    p = d / "laser/syn_laser/scans_000000.npz"
    p.write_bytes(p.read_bytes()[:1000])
    with pytest.raises(ValueError, match=r"scans_000000\.npz: cannot read NPZ"):
        read_recording(d).laser("syn_laser").read()
    w = d / "audio/syn_head.wav"
    w.write_bytes(w.read_bytes()[:20000])
    with pytest.raises(ValueError, match=r"syn_head\.wav: .*(truncated|cannot read)"):
        read_recording(d)


def test_missing_stream_names_file(written, tmp_path):
    d = _copy(written, tmp_path)
    (d / "imu/b_imu.csv").unlink()
    with pytest.raises(ValueError, match=r"imu/b_imu\.csv: file not found \(missing stream of imu 'b_imu'\)"):
        read_recording(d)
    d = _copy(written, tmp_path, "b2")
    shutil.rmtree(d / "cameras/a")
    with pytest.raises(ValueError, match=r"cameras/a/times\.csv: file not found"):
        read_recording(d)
    d = _copy(written, tmp_path, "b3")
    (d / "scene.yaml").unlink()
    with pytest.raises(ValueError, match=r"scene\.yaml: file not found"):
        read_recording(d)


def test_unknown_sensor_in_manifest_names_line_and_field(written, tmp_path):
    d = _copy(written, tmp_path)
    m = yaml.safe_load((d / "scene.yaml").read_text())
    m["sensors"].append({"type": "radar", "name": "r0", "file": "radar.bin"})
    text = yaml.safe_dump(m, sort_keys=False)
    (d / "scene.yaml").write_text(text)
    line = text.splitlines().index("- type: radar") + 1
    with pytest.raises(ValueError, match=rf"scene\.yaml:{line}: field sensors\.{len(m['sensors']) - 1}: .*'radar'"):
        read_recording(d)
    m["sensors"].pop()
    m["sensors"][2]["attached_to"] = "nowhere"
    (d / "scene.yaml").write_text(yaml.safe_dump(m, sort_keys=False))
    with pytest.raises(ValueError, match=r"attached_to 'nowhere', which is not a camera"):
        read_recording(d)
    m["sensors"][2]["attached_to"] = "a"
    m["sensors"][0]["T_world_cam"][0][0] = 3.0
    (d / "scene.yaml").write_text(yaml.safe_dump(m, sort_keys=False))
    with pytest.raises(ValueError, match=r"field sensors\.0\.T_world_cam"):
        read_recording(d)


def test_timestamps_going_backwards_name_file_and_line(written, tmp_path):
    d = _copy(written, tmp_path)
    p = d / "imu/a_imu.csv"
    lines = p.read_text().splitlines(keepends=True)
    lines[50], lines[51] = lines[51], lines[50]  # rows for samples 48 and 49 (file lines 51, 52)
    p.write_text("".join(lines))
    with pytest.raises(ValueError, match=r"a_imu\.csv: line 52: time_s .* goes backwards"):
        read_recording(d).imu("a_imu").read()
    t = d / "cameras/a/times.csv"
    lines = t.read_text().splitlines(keepends=True)
    lines[8] = lines[7]
    t.write_text("".join(lines))
    with pytest.raises(ValueError, match=r"times\.csv: line 9: duplicate time_s"):
        read_recording(d)
    g = d / "groundtruth/people.csv"
    lines = g.read_text().splitlines(keepends=True)
    lines[1], lines[-1] = lines[-1], lines[1]
    g.write_text("".join(lines))
    shutil.copy(written[1] / "cameras/a/times.csv", t)
    with pytest.raises(ValueError, match=r"people\.csv:3: time_s .* goes backwards"):
        read_recording(d)


def test_laser_timestamps_backwards_name_field(tmp_path, rng):
    s = _synthetic_laser(rng)
    s.data.times_s[30] = s.data.times_s[10]
    from planefuse.io import Recording

    Recording(duration_s=3.0, lasers={"syn_laser": s}).write(tmp_path / "l")
    with pytest.raises(ValueError, match=r"scans_000000\.npz: time_s\[30\]: time_s .* goes backwards"):
        read_recording(tmp_path / "l").laser().read()


def test_gaps_are_reported(written, tmp_path):
    d = _copy(written, tmp_path)
    p = d / "imu/a_imu.csv"
    lines = p.read_text().splitlines(keepends=True)
    del lines[101:111]
    p.write_text("".join(lines))
    m = yaml.safe_load((d / "scene.yaml").read_text())
    next(s for s in m["sensors"] if s["name"] == "a_imu")["n_samples"] = 190
    (d / "scene.yaml").write_text(yaml.safe_dump(m, sort_keys=False))
    imu = read_recording(d).imu("a_imu")
    with warnings.catch_warnings(record=True) as w:
        warnings.simplefilter("always")
        data = imu.read()
    assert len(data) == 190 and len(imu.gaps) == 1 and imu.gaps[0].missing == 10
    assert imu.gaps[0].after_s == pytest.approx(99 / 200) and imu.gaps[0].before_s == pytest.approx(110 / 200)
    assert any("gap in timestamps" in str(x.message) for x in w)


def test_wav_with_wrong_channels_is_rejected(written, tmp_path):
    d = _copy(written, tmp_path)
    sf.write(d / "audio/syn_head.wav", np.zeros((16037, 1), np.float32), 16000, subtype="FLOAT")
    with pytest.raises(ValueError, match=r"syn_head\.wav: expected 2 channels at fs_hz = 16000, got 1"):
        read_recording(d)


@settings(max_examples=40, deadline=None)
@given(
    st.lists(st.floats(allow_nan=False, allow_infinity=False, width=64), min_size=0, max_size=60),
    st.integers(1, 17),
)
def test_csv_float64_round_trip_exact(tmp_path_factory, values, chunk):
    path = tmp_path_factory.mktemp("csv") / "t.csv"
    a = np.array(values, dtype=float).reshape(-1, 1)
    rows = np.column_stack([np.arange(len(a), dtype=float), a]) if len(a) else np.zeros((0, 2))
    write_csv(path, ["time_s", "v"], rows)
    parts = list(read_csv_chunks(path, ["time_s", "v"], max_rows=chunk))
    back = np.concatenate([p for p, _ in parts]) if parts else np.zeros((0, 2))
    np.testing.assert_array_equal(back, rows)
    assert [line for _, line in parts] == list(range(2, 2 + len(rows), chunk))


@given(st.lists(st.floats(0, 100, allow_nan=False), min_size=2, max_size=50))
def test_time_checker_accepts_exactly_increasing_sequences(ts):
    t = np.array(ts)
    increasing = bool(np.all(np.diff(t) > 0))
    checker = TimeChecker("x.csv")
    if increasing:
        checker.check(t[: len(t) // 2])
        checker.check(t[len(t) // 2 :])
    else:
        with pytest.raises(ValueError, match=r"x\.csv: time_s\[\d+\]: (duplicate|time_s .* goes backwards)"):
            checker.check(t)


@settings(max_examples=15, deadline=None)
@given(
    n_scans=st.integers(0, 900),
    n_beams=st.integers(1, 40),
    per_beam_tilt=st.booleans(),
    seed=st.integers(0, 2**31),
)
def test_laser_and_audio_round_trip_any_shape(tmp_path_factory, n_scans, n_beams, per_beam_tilt, seed):
    from planefuse.io import Recording

    rng = np.random.default_rng(seed)
    times = np.cumsum(rng.uniform(0.01, 0.03, n_scans))  # no gaps at 40 Hz
    ranges = rng.uniform(0, 30, (n_scans, n_beams))
    ranges[rng.random(ranges.shape) < 0.1] = np.inf
    ranges[rng.random(ranges.shape) < 0.05] = np.nan
    tilt = rng.normal(size=(n_scans, n_beams) if per_beam_tilt else n_scans)
    scans = LaserScans(times, rng.uniform(-3, 3, n_beams), ranges, tilt, {"id": np.arange(n_scans)})
    audio = rng.normal(size=(int(rng.integers(0, 3000)), 2)).astype(np.float32)
    T = np.eye(4)
    rec = Recording(duration_s=float(times[-1]) if n_scans else 0.0,
                    lasers={"l": LaserStream("l", T, 40.0, n_scans, dict(SYN_DEVICE), data=scans)},
                    audio={"h": AudioStream("h", T, 8000, 0.25, len(audio), data=audio)})
    out = tmp_path_factory.mktemp("lr") / "r"
    rec.write(out)
    back = read_recording(out)
    b = back.laser("l")
    parts = list(b.chunks())
    assert [len(p) for p in parts] == [min(400, n_scans - a) for a in range(0, n_scans, 400)]
    if n_scans:
        got = b.read()
        np.testing.assert_array_equal(got.times_s, times)
        np.testing.assert_array_equal(got.ranges_m, ranges)
        np.testing.assert_array_equal(got.tilt_rad, tilt)
        np.testing.assert_array_equal(got.extra["id"], np.arange(n_scans))
    h = back.binaural("h")
    np.testing.assert_array_equal(h.read(), audio)
    assert h.start_time_s == 0.25 and h.fs_hz == 8000


def test_laser_device_schema_has_the_fields_of_the_library_classes():
    """The manifest's laser device entry (io) and the library's scanner and unit (laser) are written twice (io
    must not import laser): they must keep the same fields and defaults."""
    import dataclasses
    import inspect

    from planefuse.io import LaserScannerDevice, LaserUnitDevice
    from planefuse.laser import LaserScannerSpec, TiltingUnit

    spec = {f.name: f.default for f in dataclasses.fields(LaserScannerSpec)}
    schema = {k: (v.default if not v.is_required() else dataclasses.MISSING)
              for k, v in LaserScannerDevice.model_fields.items()}
    assert schema == spec
    unit = {k: p.default for k, p in inspect.signature(TiltingUnit).parameters.items() if k != "scanner"}
    device = {k: v.default for k, v in LaserUnitDevice.model_fields.items() if k not in ("scanner", "scan_duration_s")}
    assert {k: unit[k] for k in device} == device


def test_yaml_models_load_the_same_data_and_name_the_line_of_an_error(written, tmp_path):
    """The manifest is parsed by libyaml where PyYAML has it (the pure-Python parser's data), and a YAML or a
    validation error still names the file and the line."""
    from planefuse.io._manifest import RecordingManifest
    from planefuse.io._yaml import _safe_load, load_yaml_model

    text = (written[1] / "scene.yaml").read_text()
    assert _safe_load(text) == yaml.safe_load(text)
    m = load_yaml_model(written[1] / "scene.yaml", RecordingManifest)
    assert m.duration_s == written[0].duration_s
    bad = tmp_path / "bad.yaml"
    bad.write_text(text.replace("duration_s:", "duration_s: [", 1))
    with pytest.raises(ValueError, match=r"bad\.yaml:\d+: invalid YAML"):
        load_yaml_model(bad, RecordingManifest)
    lines = text.splitlines()
    k = next(i for i, l in enumerate(lines) if l.startswith("duration_s:"))
    lines[k] = "duration_s: soon"
    bad.write_text("\n".join(lines) + "\n")
    with pytest.raises(ValueError, match=rf"bad\.yaml:{k + 1}: field duration_s"):
        load_yaml_model(bad, RecordingManifest)
