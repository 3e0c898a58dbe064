"""POM configuration files (planefuse.occupancy read_pom / write_pom / run_pom, CLI ``planefuse pom``): bad files
named by file and line, round trips, POM's output format; on POM's own test data, side by side with POM built
from ../shared/reference/pom in a temporary folder (skipped where it cannot be built)."""

from __future__ import annotations

import dataclasses
import importlib.util
import sys
from pathlib import Path

import cv2
import numpy as np
import pytest
from typer.testing import CliRunner

from planefuse.cli import app
from planefuse.occupancy import (
    GenerativeParams,
    MeanFieldSolver,
    Silhouettes,
    read_pom,
    read_pom_masks,
    run_pom,
    write_pom,
    write_pom_result,
)

BENCH = Path(__file__).resolve().parents[1] / "benchmarks"

GOOD = """# two cameras, three locations
ROOM 40 30 2 3
RECTANGLE 0 0 2 3 10 25
RECTANGLE 0 1 notvisible
RECTANGLE 0 2 20 3 30 25
RECTANGLE 1 0 5 0 15 20
RECTANGLE 1 1 25 5 35 29
INPUT_VIEW_FORMAT masks/f%f-c%c.png
RESULT_FORMAT out/proba-f%f.dat
PRIOR 0.05
PROBA_IGNORED 0.99
PROCESS 7 2
"""


def _write(tmp_path: Path, text: str, name: str = "cfg.pom") -> Path:
    p = tmp_path / name
    p.write_text(text)
    return p


def _masks(tmp_path: Path, cfg, frames, people=(0,)):
    (tmp_path / "masks").mkdir(exist_ok=True)
    for f in frames:
        for c, (h, w) in enumerate(cfg.silhouettes.image_sizes):
            img = np.zeros((h, w), np.uint8)
            for k in people:
                x0, y0, x1, y1 = cfg.silhouettes.boxes_px[c, k]
                if x0 >= 0:
                    img[y0:y1 + 1, x0:x1 + 1] = 255
            cv2.imwrite(str(tmp_path / "masks" / f"f{f}-c{c}.png"), img)


def test_read_good_file(tmp_path):
    cfg = read_pom(_write(tmp_path, GOOD))
    assert cfg.silhouettes.boxes_px.shape == (2, 3, 4)
    assert cfg.silhouettes.boxes_px[0, 1].tolist() == [-1, -1, -1, -1]
    assert cfg.silhouettes.boxes_px[1, 2].tolist() == [-1, -1, -1, -1]   # absent = not visible
    assert cfg.params.prior == 0.05 and cfg.params.ignored_below == pytest.approx(0.01)
    assert cfg.frames == [7, 8]


@pytest.mark.parametrize("bad_line, match", [
    ("FOO 1 2", r"cfg\.pom:3: unknown keyword 'FOO'"),
    ("RECTANGLE 0 0 2 3 40 25", r"cfg\.pom:3: rectangle 2 3 40 25 of camera 0 is empty or outside its 40x30 image"),
    ("RECTANGLE 0 0 -1 3 10 25", r"cfg\.pom:3: rectangle .* outside"),
    ("RECTANGLE 0 0 10 3 2 25", r"cfg\.pom:3: rectangle .* empty"),
    ("RECTANGLE 0 5 2 3 10 25", r"cfg\.pom:3: location 5 outside ROOM's 3 locations"),
    ("RECTANGLE 4 0 2 3 10 25", r"cfg\.pom:3: camera 4 is not defined"),
    ("RECTANGLE 0 0 2 3 10", r"cfg\.pom:3: RECTANGLE takes"),
    ("PRIOR 1.5", r"cfg\.pom:3: PRIOR out of range"),
    ("PRIOR abc", r"cfg\.pom:3: PRIOR takes a number"),
    ("PROCESS 1 -2", r"cfg\.pom:3: PROCESS needs a number of frames >= 0"),
])
def test_bad_lines_named_by_file_and_line(tmp_path, bad_line, match):
    lines = GOOD.splitlines()
    lines.insert(2, bad_line)
    with pytest.raises(ValueError, match=match):
        read_pom(_write(tmp_path, "\n".join(lines)))


def test_missing_room_and_missing_mask(tmp_path):
    with pytest.raises(ValueError, match=r"cfg\.pom: no ROOM line"):
        read_pom(_write(tmp_path, "PRIOR 0.1\n"))
    cfg = read_pom(_write(tmp_path, GOOD))
    _masks(tmp_path, cfg, [7])
    (tmp_path / "masks" / "f7-c1.png").unlink()
    with pytest.raises(ValueError, match=r"cfg\.pom:8: INPUT_VIEW_FORMAT: mask of camera 1, frame 7 not found"):
        read_pom_masks(cfg, 7)
    cv2.imwrite(str(tmp_path / "masks" / "f7-c1.png"), np.zeros((10, 10), np.uint8))
    with pytest.raises(ValueError, match=r"cfg\.pom:8: .*f7-c1\.png is 10x10, camera 1 is 40x30"):
        read_pom_masks(cfg, 7)


def test_proba_ignored_keeps_locations_at_the_prior(tmp_path):
    """Regression: PROBA_IGNORED 0.99 became ignored_below 0.010000000000000009 (1 - 0.99 in binary), which left
    every location still at PRIOR 0.01 out of the first synthetic image; POM keeps them (its first iterate)."""
    text = GOOD.replace("PRIOR 0.05", "PRIOR 0.01")
    cfg = read_pom(_write(tmp_path, text))
    assert cfg.params.ignored_below == 0.01
    _masks(tmp_path, cfg, [7], people=(0,))
    masks = read_pom_masks(cfg, 7)
    one = dataclasses.replace(cfg.params, max_iterations=1, tolerance=0.0)
    first = MeanFieldSolver(cfg.silhouettes, one).solve(masks).marginals
    none_left_out = MeanFieldSolver(cfg.silhouettes, dataclasses.replace(one, ignored_below=0.0)).solve(masks)
    assert np.array_equal(first, none_left_out.marginals)
    write_pom(tmp_path / "back.pom", cfg.silhouettes, cfg.params)
    assert "PROBA_IGNORED 0.99\n" in (tmp_path / "back.pom").read_text()


def test_write_read_round_trip(tmp_path, rng):
    x0 = rng.integers(0, 50, (3, 20))
    y0 = rng.integers(0, 40, (3, 20))
    boxes = np.stack([x0, y0, x0 + rng.integers(0, 20, (3, 20)), y0 + rng.integers(0, 30, (3, 20))], -1)
    boxes[1, 3] = -1
    sil = Silhouettes(boxes.astype(np.int32), ((72, 80), (90, 100), (72, 80)))
    params = GenerativeParams(prior=0.003, sigma=0.02, max_iterations=50, ignored_below=0.01)
    p = tmp_path / "out.pom"
    write_pom(p, sil, params, input_view_format="m/%c-%f.png", process=(3, 4), camera_ids=[0, 5, 2], comment="x\ny")
    cfg = read_pom(p)
    assert (cfg.silhouettes.boxes_px == sil.boxes_px).all()
    assert cfg.silhouettes.image_sizes == sil.image_sizes and cfg.camera_ids == (0, 5, 2)
    assert (cfg.params.prior, cfg.params.sigma, cfg.params.max_iterations) == (0.003, 0.02, 50)
    assert cfg.params.ignored_below == pytest.approx(0.01) and cfg.frames == [3, 4, 5, 6]


def test_write_pom_numpy_scalar_parameters_are_plain_numbers(tmp_path):
    """Regression: a numpy scalar PRIOR / SIGMA was written as its repr ("np.float64(0.3)"), which POM cannot read."""
    sil = Silhouettes(np.array([[[0, 0, 9, 9]]], np.int32), ((10, 10),))
    p = tmp_path / "np.pom"
    write_pom(p, sil, GenerativeParams(prior=np.float64(0.3), sigma=np.float32(0.5), ignored_below=np.float64(0.25)))
    text = p.read_text()
    assert "PRIOR 0.3\n" in text and "SIGMA_IMAGE_DENSITY 0.5\n" in text and "PROBA_IGNORED 0.75\n" in text
    assert read_pom(p).params.prior == 0.3


def test_run_writes_pom_result_files(tmp_path):
    cfg = read_pom(_write(tmp_path, GOOD))
    _masks(tmp_path, cfg, [7, 8], people=(0,))
    results = dict(run_pom(cfg))
    assert sorted(results) == [7, 8]
    for f in (7, 8):
        lines = (tmp_path / "out" / f"proba-f{f}.dat").read_text().splitlines()
        assert [ln.split()[0] for ln in lines] == ["0", "1", "2"]
        q = np.array([float(ln.split()[1]) for ln in lines])
        assert q[0] > 0.95 and q[2] < 0.05
        assert np.allclose(q, results[f].marginals, rtol=1e-5, atol=1e-6)


def test_cli_pom_runs_and_names_bad_files(tmp_path):
    cfg = read_pom(_write(tmp_path, GOOD))
    _masks(tmp_path, cfg, [7, 8], people=(2,))
    r = CliRunner().invoke(app, ["pom", str(tmp_path / "cfg.pom"), "--quiet"])
    assert r.exit_code == 0, r.output
    assert (tmp_path / "out" / "proba-f8.dat").is_file()
    bad = _write(tmp_path, GOOD.replace("PRIOR 0.05", "PRIORS 0.05"), "bad.pom")
    r = CliRunner().invoke(app, ["pom", str(bad)])
    assert r.exit_code == 2 and "bad.pom:10: unknown keyword 'PRIORS'" in " ".join(r.output.split())


def _pom_reference():
    spec = importlib.util.spec_from_file_location("_pom_reference", BENCH / "_pom_reference.py")
    mod = importlib.util.module_from_spec(spec)
    sys.modules.setdefault("_pom_reference", mod)
    spec.loader.exec_module(mod)
    return mod


@pytest.mark.realdata
def test_agrees_with_pom_on_its_test_data_held_out_frames(tmp_path):
    """POM's demo (2 real cameras, 1332 locations): damping was chosen on frames 160-174; on frames 175-189 planefuse
    finds >= 90 % of POM's detections (marginal > 0.5) within one location, and its marginals correlate with POM's."""
    from conftest import shared_data

    data = shared_data("epfl_pom_test")
    ref = _pom_reference()
    try:
        exe = ref.build_pom(tmp_path)
    except RuntimeError as exc:
        pytest.skip(f"POM cannot be built here: {exc}")
    pom_file = ref.demo_pom_file(tmp_path, frames=(175, 15), data=data)
    frames = list(range(175, 190))
    pom, _ = ref.run_pom_program(exe, pom_file, 1332, frames, tmp_path / "out")
    ours = np.array([r.marginals for _, r in run_pom(read_pom(pom_file), frames, write=False)])
    a = ref.agreement(ours, pom, (37, 36))
    assert a["pom_detections"] >= 20
    assert a["found_fraction"] >= 0.9
    assert a["pearson"] >= 0.8


def test_pom_export_from_a_recording_then_run(tmp_path):
    """``planefuse pom-export`` writes a .pom (rectangles from the recording's cameras on the configured grid) and
    binary masks that ``planefuse pom`` (and POM) read back."""
    from planefuse.sim import default_scene_config, simulate

    simulate(default_scene_config(duration_s=0.2, seed=1)).write(tmp_path / "rec", masks=False)
    cfg = tmp_path / "run.yaml"
    cfg.write_text("recording: rec\nplanes:\n  heights_m: [0.1, 1.0, 1.6]\n  cell_size_m: 0.5\n")
    out = tmp_path / "exp" / "sim.pom"
    out.parent.mkdir()
    r = CliRunner().invoke(app, ["pom-export", str(cfg), str(out), "--masks", "--n-frames", "3"])
    assert r.exit_code == 0, r.output
    pom_cfg = read_pom(out)
    assert pom_cfg.silhouettes.n_locations == 20 * 20 and pom_cfg.silhouettes.n_cameras == 4
    assert pom_cfg.frames == [0, 1, 2]
    m = cv2.imread(str(out.parent / "masks" / "f2-c3.png"), cv2.IMREAD_GRAYSCALE)
    assert set(np.unique(m)) <= {0, 255}
    r = CliRunner().invoke(app, ["pom", str(out), "--quiet"])
    assert r.exit_code == 0, r.output
    assert len((out.parent / "proba-f2.dat").read_text().splitlines()) == 400


_RECT_CASES = [
    "RECTANGLE 0 0 1 2 3 4\nRECTANGLE 1 2 notvisible\nRECTANGLE 0 0 notvisible\n",   # later line wins
    "RECTANGLE 0 0 1 2 3 4\nRECTANGLE 0 0 2 2 3 4\n",
    "  RECTANGLE 0 0 1 2 3 4\nRECTANGLE 1 1 1 2 3 4\n",                               # leading blanks
    "RECTANGLE\t0 0 1 2 3 4\n", "RECTANGLE 0 0 +1 2 3 4\n", "RECTANGLE 0 0 3_0 2 35 4\n",
    "RECTANGLE 0 0 -1 -1 -1 -1\n", "RECTANGLE 0 1 notvisible 4\n", "RECTANGLE 2 0 1 2 3 4\n",
    "RECTANGLE 0 3 1 2 3 4\n", "RECTANGLE 0 0 1 2 40 4\n", "RECTANGLE 0 0 4 2 3 4\n", "RECTANGLE 0 0 1 2 3\n",
    "RECTANGLE 0 0 1 2 3 x\n", "RECTANGLE 0 -1 notvisible\n", "RECTANGLE notvisible 0 1\n",
    "RECTANGLE 0 notvisible -1\n", "RECTANGLE RECTANGLE 0 1 2 3 4 5\n", "RECTANGLE 0 0 1 2 3 4 # note\n",
    "FOO 1\nRECTANGLE 0 0 1 2 3\n", "RECTANGLE 0 0 1 2 3\nFOO 1\n", "RECTANGLE 0 0 1 2 3 99999999999999999999\n",
    "RECTANGLE \n",
    "RECTANGLE 0 0 1 2 3 4\r\nRECTANGLE 1 2 notvisible\r\n",                         # Windows line ends
    "RECTANGLE 0 0 1 2 3 4\n\nRECTANGLE 1 2 notvisible\n",                           # a blank line in the run
    "RECTANGLE 0 0 1 2 3 4\nPRIOR 0.2\nRECTANGLE 1 2 notvisible\n",                  # run interrupted
    "RECTANGLE 0 0 1 2 3 4\x0cRECTANGLE 1 2 notvisible\n", "RECTANGLE 0 0 1 2 3 4\n# é\n",
    "RECTANGLE 0 0 -1 -1 -1 -1\nRECTANGLE 0 1 1 notvisible\n", "RECTANGLE 0 2 1 2 3 4",   # no final newline
    "RECTANGLE 0 0 1 2 3 4\nPROCESS 0 2\nFOO\n", "RECTANGLE 0 0 1 2 3 4\n  RECTANGLE 0 1 1 2 3 4\n",
]


@pytest.mark.parametrize("rects", _RECT_CASES)
def test_bulk_read_of_rectangles_equals_line_by_line(tmp_path, rects):
    """``read_pom`` reads the ``RECTANGLE `` lines at once (a strict scanner, vectorised checks) and falls back to the
    line-by-line reading where one would fail: the same boxes, or the same error naming the same line."""
    from planefuse.occupancy._pom import _parse

    path = _write(tmp_path, "ROOM -1 -1 2 3\nCAMERA 0 40 30\nCAMERA 1 40 30\n" + rects)
    out = []
    for read in (read_pom, lambda p: _parse(p, enumerate(p.read_text().splitlines(), start=1), None)):
        try:
            out.append(read(path).silhouettes.boxes_px.tolist())
        except ValueError as e:
            out.append(str(e))
    assert out[0] == out[1]


def test_bulk_read_of_a_large_file_equals_line_by_line(tmp_path, rng):
    """200 x 200 locations in 4 cameras (the benchmark's size), some not visible: the same configuration; a file
    written by ``write_pom`` is read by the bulk path (one run of RECTANGLE lines, each written the plain way)."""
    from planefuse.occupancy._pom import _bulk_rectangles, _parse, _rectangle_run

    C, K = 4, 40000
    x0, y0 = rng.integers(0, 300, (C, K)), rng.integers(0, 200, (C, K))
    boxes = np.stack([x0, y0, x0 + rng.integers(0, 59, (C, K)), y0 + rng.integers(0, 87, (C, K))], -1)
    boxes[rng.random((C, K)) < 0.1] = -1
    sil = Silhouettes(boxes.astype(np.int32), ((288, 360),) * C)
    path = tmp_path / "large.pom"
    write_pom(path, sil, GenerativeParams(prior=2e-4), process=(0, 3))
    a, b = read_pom(path), _parse(path, enumerate(path.read_text().splitlines(), start=1), None)
    assert np.array_equal(a.silhouettes.boxes_px, sil.boxes_px)
    assert np.array_equal(a.silhouettes.boxes_px, b.silhouettes.boxes_px)
    assert (a.params, a.process, a.camera_ids, a.silhouettes.image_sizes) == \
        (b.params, b.process, b.camera_ids, b.silhouettes.image_sizes)
    start, end = _rectangle_run(path.read_text())
    assert _bulk_rectangles(path.read_text()[start:end], C * K) is not None


def test_run_pom_reads_grey_levels_as_read_pom_masks_does(tmp_path, rng):
    """``run_pom`` hands the solver the masks' uint8 grey levels (it scales them by 1 / 255 itself), the public
    ``read_pom_masks`` float images: the same marginals, bit for bit, on grey (not only 0 / 255) masks."""
    cfg = read_pom(_write(tmp_path, GOOD))
    (tmp_path / "masks").mkdir()
    for f in (7, 8):
        for c, (h, w) in enumerate(cfg.silhouettes.image_sizes):
            cv2.imwrite(str(tmp_path / "masks" / f"f{f}-c{c}.png"), rng.integers(0, 256, (h, w), dtype=np.uint8))
    solver = MeanFieldSolver(cfg.silhouettes, cfg.params)
    for f, res in run_pom(cfg, write=False):
        assert np.array_equal(res.marginals, solver.solve(read_pom_masks(cfg, f)).marginals)


def test_result_file_lines_are_printf_g(tmp_path, rng):
    """``proba-f<frame>.dat`` holds ``<location> <probability>`` per line with C's ``%g`` (6 significant digits,
    exponent below 1e-4), as POM writes it; the one-format-for-all-lines writer gives every line that a format
    per line gives, for values across the range (0, tiny, near 1, exactly 1)."""
    q = np.concatenate([[0.0, 1.0, 1e-300, 5e-324, 0.9999995, 1 - 1e-6, 1e-4, 9.99999e-5, 0.5], rng.random(500) ** 9])
    path = tmp_path / "proba-f3.dat"
    write_pom_result(path, q)
    lines = path.read_text().splitlines()
    assert lines == [f"{k} {'%g' % v}" for k, v in enumerate(q)]
    assert lines[:3] == ["0 0", "1 1", "2 1e-300"] and lines[4] == "4 1"
    write_pom_result(path, np.zeros(0))
    assert path.read_text() == ""
