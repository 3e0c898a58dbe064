"""Figures, animation, the HTML report (rendered in headless Chromium) and the rerun recording."""

from __future__ import annotations

import json
import re
import shutil
import subprocess

import cv2
import imageio.v3 as iio
import numpy as np
import pytest

from planefuse.geometry import default_camera_ring
from planefuse.grid import GroundDetections, PlaneStack
from planefuse.outputs import OutputSettings, OutputWriter
from planefuse.pipeline import write_presentation
from planefuse.viz import (
    FigureInputs,
    RerunLogger,
    animate_stack,
    grid_lines_world,
    occupancy_mean,
    plane_entity,
    plot_camera_grid,
    plot_metrics,
    plot_saliency,
    rrd_entity_paths,
    run_figures,
    stack_frames,
)


@pytest.fixture(scope="module")
def stack():
    return PlaneStack.from_extent([0.0, 0.8, 1.6], (0, 10), (0, 8), 0.5)


@pytest.fixture(scope="module")
def finished_run(tmp_path_factory, stack):
    """A short fake run finished with every kind of figure; shared by the report tests."""
    rng = np.random.default_rng(0)
    w = _fake_run(tmp_path_factory.mktemp("run"), stack, rng)
    w.finish()
    return write_presentation(w, OutputSettings(figure_dpi=50), _inputs(rng))


def _fake_run(out_dir, stack, rng, n=12, rerun=False) -> OutputWriter:
    w = OutputWriter(out_dir, stack, config_hash="h", chunk_steps=5, config_text="planes:\n  cell_size_m: 0.5\n")
    if rerun:
        w.attach_rerun(RerunLogger(out_dir / "planefuse.rrd", stack))
    for k in range(n):
        occ = rng.random(stack.shape) * 0.3
        occ[:, 6, 4 + k // 3] = 0.95  # a person walking along +x
        w.write_detections(k, GroundDetections(0.1 * k, [[2.25 + 0.5 * (k // 3), 3.25]], [0.9]))
        w.write_tracks(k, 0.1 * k, [1], [[2.25 + 0.5 * (k // 3), 3.25]], [[1.6, 0.0]])
        w.write_occupancy(k, 0.1 * k, occ)
    w.write_metrics({"MOTA": 0.75, "MOTP_m": 0.12, "ospa_m": list(rng.random(n))})
    return w


def _inputs(rng) -> FigureInputs:
    cams = default_camera_ring()[:2]
    return FigureInputs(
        cameras=cams,
        camera_images={cams[0].name: (rng.random((288, 360)) * 255).astype(np.uint8)},
        laser_points_world=rng.random((200, 3)) * [10, 8, 2],
        saliency=rng.random((20, 18)),
        saliency_times_s=np.arange(20) * 0.05,
        saliency_azimuth_rad=np.linspace(-np.pi / 2, np.pi / 2, 18),
    )


def test_camera_figure_draws_the_ignore_regions(stack):
    """A camera's ignore regions (pixels that are not scene evidence) are outlined on its frame, with a legend entry;
    a camera without any has neither."""
    cam = default_camera_ring()[0]
    w, h = cam.intrinsics.width_px, cam.intrinsics.height_px
    mask = np.zeros((h, w), bool)
    mask[230:285, 130:356] = True  # the EPFL terrace's watermark
    ax = plot_camera_grid(cam, stack, ignore_mask=mask).axes[0]
    assert "ignored (no evidence)" in [t.get_text() for t in ax.get_legend().get_texts()]
    outline = np.concatenate([p.vertices for c in ax.collections for p in c.get_paths() if len(p.vertices)])
    assert outline[:, 0].min() == pytest.approx(129.5, abs=0.6) and outline[:, 0].max() == pytest.approx(355.5, abs=0.6)
    assert outline[:, 1].min() == pytest.approx(229.5, abs=0.6) and outline[:, 1].max() == pytest.approx(284.5, abs=0.6)
    bare = plot_camera_grid(cam, stack, ignore_mask=np.zeros((h, w), bool)).axes[0]
    assert not bare.collections
    assert "ignored (no evidence)" not in [t.get_text() for t in bare.get_legend().get_texts()]


def test_grid_lines_project_like_opencv(stack):
    lines = grid_lines_world(stack, 1, spacing_m=2.0, samples=7)
    assert lines.shape == (6 + 5, 7, 3)  # x = 0,2,..,10 and y = 0,2,..,8
    np.testing.assert_allclose(lines[..., 2], 0.8)
    cam = default_camera_ring()[0]
    fig = plot_camera_grid(cam, stack, spacing_m=2.0)
    drawn = np.concatenate([np.c_[l.get_xdata(), l.get_ydata()] for l in fig.axes[0].lines])
    world = np.concatenate([grid_lines_world(stack, l, 2.0).reshape(-1, 3) for l in range(stack.n_planes)])
    T = cam.T_cam_world
    in_front = (world @ T[:3, :3].T + T[:3, 3])[:, 2] > 0
    rvec, _ = cv2.Rodrigues(T[:3, :3])
    ref, _ = cv2.projectPoints(world[in_front], rvec, T[:3, 3], cam.K, cam.intrinsics.dist)
    np.testing.assert_allclose(drawn[in_front], ref.reshape(-1, 2), atol=1e-6)
    assert np.isnan(drawn[~in_front]).all()


def test_stack_frames_put_cells_and_tracks_where_the_world_is(stack):
    L, ny, nx = stack.shape
    occ = np.zeros((2, L, ny, nx), np.float32)
    occ[0, 1, 0, nx - 1] = 1.0  # plane 1, lowest-y / highest-x cell -> bottom right of panel 1
    occ[1, 0, :, :] = np.nan
    frames = stack_frames(stack, occ, cell_px=2, gap_px=4)
    w = nx * 2
    assert frames.shape == (2, ny * 2, 3 * w + 8, 3)
    panel1 = frames[0, :, w + 4: 2 * w + 4]
    bright = np.argwhere(panel1.sum(-1) > 600)
    assert bright[:, 0].min() == ny * 2 - 2 and bright[:, 1].min() == w - 2
    assert (frames[1, :, :w] == 90).all()  # unknown cells are grey
    tracks = {"step": np.array([1.0]), "x_m": np.array([0.25]), "y_m": np.array([7.75])}  # top-left cell
    f = stack_frames(stack, np.zeros((2, L, ny, nx), np.float32), tracks, cell_px=2)
    assert (f[1, 0, 0] == 255).all() and not (f[0, 0, 0] == 255).all()


def test_animation_gif_and_mp4(tmp_path, stack, rng):
    occ = rng.random((9,) + stack.shape).astype(np.float32)
    gif = animate_stack(tmp_path / "a.gif", stack, occ, fps=5, block_steps=4)
    frames = iio.imread(gif, index=None)
    L, ny, nx = stack.shape
    expected = stack_frames(stack, occ, cell_px=max(1, min(8, (1200 - 4 * (L - 1)) // (L * nx))))
    assert np.array_equal(frames[..., :3], expected)  # every frame exact: one global palette, no quantisation
    from PIL import Image
    with Image.open(gif) as im:
        assert im.n_frames == 9 and im.info["duration"] == 200 and im.info["loop"] == 0
    mp4 = animate_stack(tmp_path / "a.mp4", stack, occ)
    cap = cv2.VideoCapture(str(mp4))
    assert int(cap.get(cv2.CAP_PROP_FRAME_COUNT)) == 9
    ok, first = cap.read()  # the colours survive the lossy codec in the right channel order
    rgb = cv2.cvtColor(first, cv2.COLOR_BGR2RGB).astype(float)
    ref = expected[0, : rgb.shape[0], : rgb.shape[1]].astype(float)
    assert ok and np.abs(rgb - ref).mean() < 10 < np.abs(rgb - ref[..., ::-1]).mean()
    with pytest.warns(UserWarning, match="shows 4 of 9"):
        animate_stack(tmp_path / "b.gif", stack, occ, max_frames=4)
    with pytest.raises(ValueError, match=".gif or .mp4"):
        animate_stack(tmp_path / "a.avi", stack, occ)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.gif", "a.mp4", "b.gif"]


class _BlockReads:
    """An occupancy array that refuses to be read more than ``block`` steps at a time (what a long run's
    figures and animation must do with ``occupancy.zarr``), and counts the steps read."""

    def __init__(self, occ, block):
        self.occ, self.block, self.steps_read = occ, block, 0
        self.shape = occ.shape

    def __getitem__(self, key):
        got = np.asarray(self.occ[key])
        n = 1 if isinstance(key, (int, np.integer)) else got.shape[0]
        assert n <= self.block, f"read {n} steps at once"
        self.steps_read += n
        return got


def test_figures_and_animation_read_occupancy_a_block_at_a_time(tmp_path, stack, rng):
    occ = rng.random((150,) + stack.shape).astype(np.float32)
    occ[:40, 0, 2, 3] = np.nan  # a cell unobserved in the first 40 steps
    occ[:, 1, 0, 0] = np.nan  # a cell never observed
    with pytest.warns(RuntimeWarning, match="Mean of empty slice"):
        ref = np.nanmean(occ, axis=0)
    np.testing.assert_allclose(occupancy_mean(_BlockReads(occ, 64)), ref, rtol=1e-6, equal_nan=True)
    lazy = _BlockReads(occ, 64)
    figs = run_figures(stack, lazy, np.arange(150) * 0.1, {"step": np.array([])}, {}, {}, FigureInputs(), dpi=40)
    assert {"occupancy_last", "occupancy_mean"} <= set(figs) and lazy.steps_read == 151
    lazy = _BlockReads(occ, 1)
    with pytest.warns(UserWarning, match="shows 100 of 150"):
        gif = animate_stack(tmp_path / "a.gif", stack, lazy, max_frames=100, block_steps=16)
    assert lazy.steps_read == 100 and iio.imread(gif, index=None).shape[0] == 100
    zarr = pytest.importorskip("zarr")
    z = zarr.create_array(zarr.storage.MemoryStore(), shape=occ.shape, chunks=(10,) + stack.shape, dtype="float32")
    z[:] = occ
    assert np.array_equal(animate_stack(tmp_path / "z.gif", stack, z).read_bytes(),
                          animate_stack(tmp_path / "n.gif", stack, occ).read_bytes())


def test_plot_input_checks():
    with pytest.raises(ValueError, match="saliency must have shape"):
        plot_saliency(np.arange(3), np.arange(4), np.zeros((4, 3)))
    assert plot_metrics({"note": "text only"}) is None


def test_finish_writes_figures_animation_and_self_contained_report(finished_run):
    written = finished_run
    expected = {"occupancy_last", "occupancy_mean", "camera_cam0", "camera_cam1", "saliency", "laser_points",
                "metrics", "animation", "report"}
    assert set(written) == expected
    for name in expected - {"animation", "report"}:
        img = iio.imread(written[name])
        assert img.ndim == 3 and min(img.shape[:2]) > 50 and img.std() > 5, name
    html = written["report"].read_text()
    assert html.count("<img") == 7
    assert not re.search(r"(src|href)=['\"]?(https?:|//)", html), "the report must not load external resources"
    for needle in ("MOTA", "0.75", "ospa_m", "cell_size_m: 0.5", "numpy", "opencv-python-headless", "time steps"):
        assert needle in html


CHECK_SCRIPT = """<img id="control" src="data:image/png;base64,AAAA" style="display:none">
<script>window.addEventListener('load', () => {
  const imgs = [...document.images];
  const out = document.createElement('pre'); out.id = 'imgcheck';
  out.textContent = JSON.stringify(imgs.map(i => ({id: i.id, ok: i.complete, w: i.naturalWidth, h: i.naturalHeight})));
  document.body.appendChild(out);
});</script></body>"""


def test_report_renders_in_headless_chromium(tmp_path, finished_run):
    chromium = shutil.which("chromium") or shutil.which("chromium-browser")
    if chromium is None:
        pytest.skip("Debian's chromium is not installed (.ci/run installs it with apt-get)")
    report = finished_run["report"]
    page = tmp_path / "probe.html"  # the report plus a probe that lists every image's decoded size
    page.write_text(report.read_text().replace("</body>", CHECK_SCRIPT))
    cmd = [chromium, "--headless", "--no-sandbox", "--disable-gpu", "--disable-background-networking",
           "--disable-component-update", "--disable-sync", "--no-first-run", f"--user-data-dir={tmp_path / 'prof'}",
           "--virtual-time-budget=5000", "--dump-dom", page.as_uri()]
    dom = subprocess.run(cmd, capture_output=True, text=True, timeout=120).stdout
    m = re.search(r'<pre id="imgcheck">(.*?)</pre>', dom, flags=re.S)
    assert m, f"the probe did not run; chromium printed: {dom[:300]}"
    imgs = json.loads(m.group(1).replace("&quot;", '"'))
    control = [i for i in imgs if i["id"] == "control"]
    figures = [i for i in imgs if i["id"] != "control"]
    assert control == [{"id": "control", "ok": True, "w": 0, "h": 0}]  # a broken image is detected as such
    assert len(figures) == 7
    assert all(i["ok"] and i["w"] > 100 and i["h"] > 100 for i in figures), figures


def test_rerun_recording_holds_expected_entities(tmp_path, stack, rng):
    w = _fake_run(tmp_path, stack, rng, n=4, rerun=True)
    cams = default_camera_ring()[:2]
    w.rerun.log_cameras(cams)
    w.rerun.set_time(3, 0.3)
    w.rerun.log_camera_image("cam0", np.zeros((288, 360), np.uint8))
    w.rerun.log_laser("lrf0", rng.random((50, 3)))
    w.rerun.log_sound_wedge("binaural", [5.0, 4.0, 1.5], 0.2, 0.6)
    w.finish()
    path = tmp_path / "planefuse.rrd"
    assert path == tmp_path / "planefuse.rrd" and not list(tmp_path.glob(".*pf-tmp*"))
    paths = rrd_entity_paths(path)
    expected = {"/world", "/world/tracks", "/world/detections", "/world/cameras/cam0", "/world/cameras/cam1",
                "/world/cameras/cam0/image", "/world/laser/lrf0", "/world/sound/binaural"}
    for h in stack.heights_m:
        expected |= {f"/planes/{plane_entity(h)}", f"/world/planes/{plane_entity(h)}/outline",
                     f"/world/planes/{plane_entity(h)}/occupied"}
    assert expected <= paths, expected - paths


def test_report_says_when_a_run_has_no_scores():
    """A run without ground truth has its counts and a note that there are no scores; a scored run has no note."""
    from planefuse.report._html import render_report

    counts = render_report({}, {"n_steps": 600, "n_tracks": 146, "missing_camera_frames": {"c0": 0, "c1": 2}}, "")
    assert "No scores: the recording has no people ground truth" in counts
    assert "missing_camera_frames.c1" in counts and "No metrics were computed" not in counts
    scored = render_report({}, {"moda": 0.9, "n_steps": 50}, "")
    assert "No scores" not in scored
    assert "No metrics were computed" in render_report({}, {}, "")
