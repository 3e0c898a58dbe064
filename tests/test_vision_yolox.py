"""The YOLOX person detector (:mod:`planefuse.vision._yolox`): letterbox, grid decoding, NMS and the model checks,
on tiny ONNX models built here whose outputs are known (a wrong stride, grid offset, exponent or letterbox scale
moves a box), and the shared YOLOX-Nano model on real terrace frames against the annotators' boxes."""

from __future__ import annotations

import importlib.util
import math

import cv2
import numpy as np
import pytest

from planefuse.config import config_from_dict
from planefuse.vision import ForegroundParams, YoloxDetector, decode_yolox, letterbox, load_yolox
from planefuse.vision._foreground import BackgroundSubtractor, PersonDetector
from planefuse.vision._yolox import PAD_LEVEL, PersonBoxes, yolox_grid

from conftest import shared_data, shared_model

onnx = pytest.importorskip("onnx", reason="the onnx package (dev extra) builds the test models")
from onnx import TensorProto, helper, numpy_helper  # noqa: E402

#: The engines that can run here (OpenCV always; ONNX Runtime with its package, the dev extra's).
ENGINES = ["opencv"] + (["onnxruntime"] if importlib.util.find_spec("onnxruntime") else [])

#: The test models' canvas [px]: grids 8 x 8, 4 x 4 and 2 x 2, 84 output rows.
SIDE = 64
N_ROWS = 8 * 8 + 4 * 4 + 2 * 2


def constant_model(path, rows: np.ndarray, side: int = SIDE) -> str:
    """An ONNX model with input ``images`` (1, 3, side, side) whose output is ``rows`` (1, A, K) whatever the input
    (``rows + 0 * mean(images)``: the input is used, so every runtime keeps it)."""
    rows = np.asarray(rows, np.float32)[None]
    images = helper.make_tensor_value_info("images", TensorProto.FLOAT, [1, 3, side, side])
    output = helper.make_tensor_value_info("output", TensorProto.FLOAT, list(rows.shape))
    nodes = [
        helper.make_node("ReduceMean", ["images"], ["m"], keepdims=1),  # (1, 1, 1, 1)
        helper.make_node("Reshape", ["m", "shape"], ["m3"]),            # (1, 1, 1)
        helper.make_node("Mul", ["m3", "zero"], ["z"]),
        helper.make_node("Add", ["rows", "z"], ["output"]),
    ]
    inits = [numpy_helper.from_array(rows, "rows"), numpy_helper.from_array(np.zeros(1, np.float32), "zero"),
             numpy_helper.from_array(np.array([1, 1, 1], np.int64), "shape")]
    graph = helper.make_graph(nodes, "yolox_test", [images], [output], inits)
    model = helper.make_model(graph, opset_imports=[helper.make_opsetid("", 13)])
    model.ir_version = 8
    onnx.save(model, str(path))
    return str(path)


def raw_rows(n_classes: int = 1) -> np.ndarray:
    """Rows of a head with nothing found: zero offsets and sizes, objectness 0, class probabilities 0."""
    return np.zeros((N_ROWS, 5 + n_classes), np.float32)


def row_index(stride: int, i: int, j: int, side: int = SIDE) -> int:
    """Output row of cell (column i, row j) of the grid of ``stride``, finest grid first, rows in order."""
    start = 0
    for s in (8, 16, 32):
        if s == stride:
            return start + j * (side // s) + i
        start += (side // s) ** 2
    raise ValueError(stride)


def set_row(rows, stride, i, j, t, obj, cls):
    rows[row_index(stride, i, j)] = [*t, obj, *np.atleast_1d(cls)]


def test_grid_rows_are_the_cells_of_the_three_strides_in_order():
    cell, stride = yolox_grid((96, 64))
    assert len(cell) == 12 * 8 + 6 * 4 + 3 * 2
    assert stride[0] == 8 and stride[96] == 16 and stride[-1] == 32
    assert cell[1].tolist() == [1, 0] and cell[12].tolist() == [0, 1]  # columns first along a row
    assert cell[96 + 6].tolist() == [0, 1]


def test_decoding_one_row_by_hand():
    rows = raw_rows()
    t = (0.5, 0.25, math.log(2.0), math.log(3.0))
    set_row(rows, 16, 2, 1, t, 0.9, 0.8)
    xyxy, score = decode_yolox(rows, (SIDE, SIDE))
    k = row_index(16, 2, 1)
    # centre ((0.5 + 2) 16, (0.25 + 1) 16) = (40, 20), size (2 16, 3 16) = (32, 48)
    np.testing.assert_allclose(xyxy[k], [24.0, -4.0, 56.0, 44.0], rtol=1e-6)
    assert score[k] == pytest.approx(0.72)
    assert np.count_nonzero(score) == 1


def test_letterbox_puts_the_resized_frame_top_left_on_grey():
    rng = np.random.default_rng(0)
    frame = rng.integers(0, 255, (50, 100, 3), dtype=np.uint8)
    blob, r = letterbox(frame, (SIDE, SIDE))
    assert r == pytest.approx(0.64)
    assert blob.shape == (1, 3, SIDE, SIDE) and blob.dtype == np.float32
    expected = cv2.resize(frame, (64, 32), interpolation=cv2.INTER_LINEAR)
    np.testing.assert_array_equal(blob[0, :, :32, :].transpose(1, 2, 0), expected)  # BGR kept, 0-255
    assert (blob[0, :, 32:, :] == PAD_LEVEL).all()


@pytest.mark.parametrize("engine", ENGINES)
def test_detector_maps_a_box_back_to_the_frame_and_clips_it(tmp_path, engine):
    rows = raw_rows()
    set_row(rows, 16, 2, 1, (0.5, 0.25, math.log(2.0), math.log(3.0)), 0.9, 0.8)
    det = YoloxDetector(constant_model(tmp_path / "m.onnx", rows), (SIDE, SIDE), min_score=0.5, engine=engine)
    # a 128 x 96 frame: r = min(64 / 128, 64 / 96) = 0.5, so canvas (24, -4, 56, 44) is frame (48, -8, 112, 88)
    found = det.detect(np.zeros((96, 128, 3), np.uint8))
    np.testing.assert_allclose(found.ltwh_px, [[48.0, 0.0, 64.0, 88.0]], rtol=1e-6)
    np.testing.assert_allclose(found.score, [0.72], rtol=1e-6)


@pytest.mark.parametrize("engine", ENGINES)
def test_non_maximum_suppression_and_the_score_threshold(tmp_path, engine):
    rows = raw_rows()
    set_row(rows, 8, 3, 3, (0.5, 0.5, math.log(3.0), math.log(4.0)), 0.9, 0.9)  # centre (28, 28), 24 x 32
    set_row(rows, 8, 4, 3, (0.0, 0.5, math.log(3.0), math.log(4.0)), 0.8, 0.9)  # centre (32, 28): IoU 0.71
    set_row(rows, 8, 0, 0, (0.5, 0.5, 0.0, 0.0), 0.7, 0.9)                    # far away, 8 x 8
    set_row(rows, 8, 7, 7, (0.5, 0.5, 0.0, 0.0), 0.5, 0.5)                    # score 0.25: below the threshold
    path = constant_model(tmp_path / "m.onnx", rows)
    empty = np.zeros((SIDE, SIDE, 3), np.uint8)
    found = YoloxDetector(path, (SIDE, SIDE), min_score=0.3, nms_iou=0.45, engine=engine).detect(empty)
    np.testing.assert_allclose(found.score, [0.81, 0.63], rtol=1e-6)
    np.testing.assert_allclose(found.ltwh_px[0], [16.0, 12.0, 24.0, 32.0], rtol=1e-6)
    kept_all = YoloxDetector(path, (SIDE, SIDE), min_score=0.3, nms_iou=0.8, engine=engine).detect(empty)
    assert len(kept_all) == 3


@pytest.mark.parametrize("engine", ENGINES)
def test_the_person_class_is_the_one_scored(tmp_path, engine):
    rows = raw_rows(n_classes=3)
    set_row(rows, 32, 1, 1, (0, 0, 0, 0), 0.9, [0.1, 0.9, 0.9])  # a confident box of classes 1 and 2
    found = YoloxDetector(constant_model(tmp_path / "m.onnx", rows), (SIDE, SIDE), min_score=0.2, engine=engine
                          ).detect(np.zeros((SIDE, SIDE, 3), np.uint8))
    assert len(found) == 0


#: Each engine's title in the refusals and its error's gist for a file that is not ONNX.
NOT_ONNX = {"opencv": r"OpenCV's DNN module can run at 416x416 px \(Unsupported format or combination of formats\)",
            "onnxruntime": r"ONNX Runtime can run at 416x416 px \(not a protobuf file\)"}


@pytest.mark.parametrize("engine", ENGINES)
def test_missing_and_non_onnx_files_are_one_line_errors(tmp_path, engine):
    with pytest.raises(ValueError, match=r"nothing\.onnx: person model not found; expected a YOLOX ONNX export"):
        load_yolox(tmp_path / "nothing.onnx", engine=engine)
    text = tmp_path / "weights.onnx"
    text.write_text("not a model\n")
    with pytest.raises(ValueError, match=rf"weights\.onnx: not an ONNX model that {NOT_ONNX[engine]}; expected a YOLOX"
                       ) as err:
        load_yolox(text, engine=engine)
    assert "\n" not in str(err.value)


@pytest.mark.parametrize("engine", ENGINES)
@pytest.mark.parametrize("damage", ["empty", "zeros", "truncated"])
def test_a_damaged_model_file_is_a_one_line_error(tmp_path, engine, damage):
    """An empty file, zeros, a model cut in half: one line naming the file and what was expected, from each engine."""
    good = open(pooled_model(tmp_path / "good.onnx"), "rb").read()
    data = {"empty": b"", "zeros": bytes(1000), "truncated": good[: len(good) // 2]}[damage]
    bad = tmp_path / "bad.onnx"
    bad.write_bytes(data)
    with pytest.raises(ValueError, match=r"bad\.onnx: not an ONNX model that .* can run at 64x64 px \(.+\); expected a "
                                         r"YOLOX ONNX export") as err:
        load_yolox(bad, (SIDE, SIDE), engine=engine)
    assert "\n" not in str(err.value)


@pytest.mark.parametrize("engine", ENGINES)
def test_an_output_that_is_not_yoloxs_layout_is_refused(tmp_path, engine):
    path = constant_model(tmp_path / "m.onnx", raw_rows())
    with pytest.raises(ValueError, match=r"m\.onnx: output shape \(1, 84, 6\) is not YOLOX's raw head layout "
                                         r"\(1, 126, 5 \+ classes\) for a 96x64 px input"):
        load_yolox(path, (96, 64), engine=engine)  # the rows of a 64 x 64 canvas
    with pytest.raises(ValueError, match="not YOLOX's raw head layout"):
        load_yolox(constant_model(tmp_path / "short.onnx", np.zeros((N_ROWS, 5), np.float32)), (SIDE, SIDE),
                   engine=engine)
    decoded = raw_rows()
    decoded[:, 2:4] = 40.0  # pixel sizes: an export with decode_in_inference=True
    with pytest.raises(ValueError, match="decode_in_inference=False"):
        load_yolox(constant_model(tmp_path / "decoded.onnx", decoded), (SIDE, SIDE), engine=engine)


@pytest.mark.parametrize("engine", ENGINES)
def test_a_model_without_the_person_class_is_refused(tmp_path, engine):
    path = constant_model(tmp_path / "m.onnx", raw_rows(n_classes=1))
    with pytest.raises(ValueError, match=r"has 1 classes, so no person class 1"):
        load_yolox(path, (SIDE, SIDE), class_index=1, engine=engine)


@pytest.mark.parametrize("frame, canvas", [((360, 288), (384, 288)), ((1920, 1080), (416, 256)),
                                           ((640, 480), (416, 320)), ((100, 50), (128, 64)), ((416, 416), (416, 416)),
                                           ((10, 2000), (32, 416))])
def test_the_fitted_canvas_keeps_small_frames_and_reduces_large_ones_to_416(frame, canvas):
    from planefuse.vision import fitted_input_size
    assert fitted_input_size(frame) == canvas


def test_the_fitted_canvas_follows_each_frame_size(tmp_path):
    rows = raw_rows()
    set_row(rows, 32, 0, 0, (0.5, 0.5, 0.0, 0.0), 0.9, 0.9)  # centre (16, 16), 32 x 32 on any canvas
    sizes = []
    original = YoloxDetector.__init__

    def spy(self, path, input_wh_px=(416, 416), *a, **kw):
        sizes.append(tuple(input_wh_px))
        original(self, path, input_wh_px, *a, **kw)

    import planefuse.vision._foreground as fgmod
    # a model of fixed 64 x 64 input runs only on 64 x 64 canvases: frames of 64 x 64 and 60 x 40 px (fitted 64 x 64)
    det = PersonDetector(ForegroundParams(person_detector="yolox", person_model=constant_model(tmp_path / "m.onnx", rows)))
    fgmod.YoloxDetector.__init__ = spy
    try:
        a = det.detect(np.zeros((64, 64, 3), np.uint8))
        b = det.detect(np.zeros((40, 60, 3), np.uint8))
        det.detect(np.zeros((40, 60, 3), np.uint8))
    finally:
        fgmod.YoloxDetector.__init__ = original
    assert sizes == [(64, 64)]  # one detector per canvas, built once
    np.testing.assert_allclose(a.ltwh_px, [[0.0, 0.0, 32.0, 32.0]])
    # the 60 x 40 frame fills the 64 x 64 canvas at r = min(64 / 60, 64 / 40): the box is 32 / r frame pixels
    np.testing.assert_allclose(b.ltwh_px, [[0.0, 0.0, 32.0 * 60 / 64, 32.0 * 60 / 64]], rtol=1e-6)


@pytest.mark.parametrize("size", [(0, 64), (64, 50), (64.5, 64), (64,)])
def test_canvas_sizes_must_be_multiples_of_32(size):
    with pytest.raises(ValueError, match="person_input_px"):
        ForegroundParams(person_detector="yolox", person_model="m.onnx", person_input_px=size)


@pytest.mark.parametrize("change, field", [
    (dict(person_detector="yolox"), "person_model"),
    (dict(person_detector="yolox", person_model="m.onnx", person_min_score=1.5), "person_min_score"),
    (dict(person_nms_iou=0.0), "person_nms_iou"),
    (dict(person_outside_weight=1.2), "person_outside_weight"),
    (dict(method="none"), "method"),
])
def test_bad_yolox_settings_are_refused_naming_the_field(change, field):
    with pytest.raises(ValueError, match=field):
        ForegroundParams(**change)


def test_the_default_scores_of_each_detector():
    assert ForegroundParams(person_detector="yolox", person_model="m.onnx").min_person_score == 0.5
    assert ForegroundParams(person_detector="hog").min_person_score == 0.3
    assert ForegroundParams(person_detector="yolox", person_model="m", person_min_score=0.2).min_person_score == 0.2


def test_config_makes_the_model_path_absolute_against_the_file(tmp_path):
    from planefuse.config import load_config
    (tmp_path / "m").mkdir()
    constant_model(tmp_path / "m" / "yolox.onnx", raw_rows())
    cfg = tmp_path / "run.yaml"
    cfg.write_text("recording: rec\nsensors:\n  cameras:\n    person_detector: yolox\n    person_model: m/yolox.onnx\n"
                   "    person_input_px: [64, 64]\n")
    loaded = load_config(cfg)
    assert loaded.sensors.cameras.person_model == str((tmp_path / "m" / "yolox.onnx").resolve())
    fg = loaded.system_params().camera_params.foreground
    assert fg.person_detector == "yolox" and fg.person_model == loaded.sensors.cameras.person_model


@pytest.mark.parametrize("what, message", [("missing", "person model not found"),
                                           ("text", "not an ONNX model that OpenCV's DNN module can run at 416x416 px"),
                                           ("wrong size", "is not YOLOX's raw head layout")])
def test_config_refuses_a_bad_model_before_the_run_naming_field_and_line(tmp_path, what, message):
    """(With person_engine opencv: the other engine's messages are pinned above.)"""
    from planefuse.config import ConfigError, load_config
    if what == "text":
        (tmp_path / "yolox.onnx").write_text("weights\n")
    elif what == "wrong size":
        constant_model(tmp_path / "yolox.onnx", raw_rows())  # the rows of a 64 x 64 canvas, run at 416 x 416
    cfg = tmp_path / "run.yaml"
    cfg.write_text("recording: rec\nsensors:\n  cameras:\n    person_detector: yolox\n    person_model: yolox.onnx\n"
                   "    person_engine: opencv\n")
    with pytest.raises(ConfigError, match=rf"run\.yaml:5: sensors\.cameras\.person_model: .*yolox\.onnx: .*{message}"):
        load_config(cfg)


def pooled_model(path, side: int = SIDE, objectness: float = 0.25) -> str:
    """A model exported, as YOLOX's releases are, with a fixed (1, 3, side, side) input whose graph works at any
    canvas: per stride s, a 1 x 1 convolution (zero weights: every row ``[0, 0, 0, 0, objectness, 1]``) of the
    s x s average of the image, flattened and concatenated finest first, transposed to (1, A, 6)."""
    images = helper.make_tensor_value_info("images", TensorProto.FLOAT, [1, 3, side, side])
    n_rows = sum((side // s) ** 2 for s in (8, 16, 32))
    output = helper.make_tensor_value_info("output", TensorProto.FLOAT, [1, n_rows, 6])
    nodes, grids = [], []
    for s in (8, 16, 32):
        nodes += [helper.make_node("AveragePool", ["images"], [f"p{s}"], kernel_shape=[s, s], strides=[s, s]),
                  helper.make_node("Conv", [f"p{s}", "w", "b"], [f"c{s}"]),
                  helper.make_node("Reshape", [f"c{s}", "flat"], [f"f{s}"])]  # (1, 6, cells)
        grids.append(f"f{s}")
    nodes += [helper.make_node("Concat", grids, ["cat"], axis=2),
              helper.make_node("Transpose", ["cat"], ["output"], perm=[0, 2, 1])]
    inits = [numpy_helper.from_array(np.zeros((6, 3, 1, 1), np.float32), "w"),
             numpy_helper.from_array(np.array([0, 0, 0, 0, objectness, 1], np.float32), "b"),
             numpy_helper.from_array(np.array([1, 6, -1], np.int64), "flat")]
    model = helper.make_model(helper.make_graph(nodes, "yolox_static", [images], [output], inits),
                              opset_imports=[helper.make_opsetid("", 13)])
    model.ir_version = 8
    onnx.save(model, str(path))
    return str(path)


@pytest.mark.parametrize("engine", ENGINES)
def test_an_export_with_a_fixed_input_runs_at_another_canvas(tmp_path, engine):
    """YOLOX's releases fix the input at 416 x 416; the fitted canvas differs. OpenCV reshapes the network, ONNX
    Runtime gets the input's height and width made symbolic: both give the rows of the canvas they run."""
    path = pooled_model(tmp_path / "m.onnx")
    net, info = load_yolox(path, (96, 64), engine=engine)
    assert info.engine == engine and info.input_wh_px == (96, 64)
    out = net.forward(letterbox(np.zeros((64, 96, 3), np.uint8), (96, 64))[0])
    assert out.shape == (1, 12 * 8 + 6 * 4 + 3 * 2, 6)
    np.testing.assert_allclose(out[0], np.tile([0, 0, 0, 0, 0.25, 1], (126, 1)), atol=1e-6)
    assert onnx.load(path).graph.input[0].type.tensor_type.shape.dim[3].dim_value == SIDE  # the file is untouched
    if engine == "onnxruntime":  # the bytes given to ONNX Runtime: a symbolic input, or the file's own at its size
        from planefuse.vision._yolox import _free_input_size
        data = open(path, "rb").read()
        assert _free_input_size(data, (SIDE, SIDE)) is data
        relaxed = onnx.load_from_string(_free_input_size(data, (96, 64)))
        assert [d.dim_param for d in relaxed.graph.input[0].type.tensor_type.shape.dim[2:]] == ["height_px", "width_px"]
        assert relaxed.graph.node == onnx.load(path).graph.node  # the nodes pass through


def test_auto_is_onnxruntime_where_installed_else_opencv(monkeypatch):
    from planefuse.vision import resolve_engine
    import planefuse.vision._yolox as yolox

    present = {"onnxruntime": True}
    monkeypatch.setattr(yolox.importlib.util, "find_spec", lambda m: object() if present.get(m, True) else None)
    assert resolve_engine("auto") == "onnxruntime" and resolve_engine("opencv") == "opencv"
    present["onnxruntime"] = False
    assert resolve_engine("auto") == "opencv"
    with pytest.raises(ValueError, match=r"^person engine 'onnxruntime' needs the onnxruntime package: "
                                         r"pip install 'planefuse\[onnxruntime\]' \(or person_engine: opencv\)$"):
        resolve_engine("onnxruntime")
    with pytest.raises(ValueError, match="person engine must be one of auto, opencv, onnxruntime, got 'tensorrt'"):
        resolve_engine("tensorrt")
    with pytest.raises(ValueError, match="person_engine"):
        ForegroundParams(person_detector="yolox", person_model="m.onnx", person_engine="tensorrt")


def test_config_refuses_onnxruntime_where_it_is_not_installed_at_its_field(tmp_path, monkeypatch):
    from planefuse.config import ConfigError, load_config
    import planefuse.vision._yolox as yolox

    real = yolox.importlib.util.find_spec
    monkeypatch.setattr(yolox.importlib.util, "find_spec", lambda m, *a: None if m == "onnxruntime" else real(m, *a))
    constant_model(tmp_path / "yolox.onnx", raw_rows())
    cfg = tmp_path / "run.yaml"
    cfg.write_text("recording: rec\nsensors:\n  cameras:\n    person_detector: yolox\n    person_model: yolox.onnx\n"
                   "    person_engine: onnxruntime\n    person_input_px: [64, 64]\n")
    with pytest.raises(ConfigError, match=r"run\.yaml:6: sensors\.cameras\.person_engine: person engine 'onnxruntime' "
                                          r"needs the onnxruntime package: pip install 'planefuse\[onnxruntime\]'"):
        load_config(cfg)
    cfg.write_text(cfg.read_text().replace("onnxruntime\n", "auto\n"))
    assert load_config(cfg).sensors.cameras.person_engine == "auto"  # auto falls back to OpenCV


def _one_box_model(tmp_path) -> str:
    rows = raw_rows()
    # centre (28, 28), 16 x 32 canvas px; frames of 64 x 64 px are not resized
    set_row(rows, 8, 3, 3, (0.5, 0.5, math.log(2.0), math.log(4.0)), 1.0, 1.0)
    return constant_model(tmp_path / "m.onnx", rows)


@pytest.mark.parametrize("quantised", [False, True])
def test_boxes_raise_the_likelihood_and_scale_foreground_outside_them(tmp_path, quantised):
    model = _one_box_model(tmp_path)
    common = dict(close_px=0, floor=0.0, ceiling=1.0, method="mean")
    plain = BackgroundSubtractor(SIDE, SIDE, ForegroundParams(**common))
    with_boxes = BackgroundSubtractor(SIDE, SIDE, ForegroundParams(
        **common, person_detector="yolox", person_model=model, person_input_px=(SIDE, SIDE), person_likelihood=0.8,
        person_outside_weight=0.5))
    rng = np.random.default_rng(1)
    bg = rng.uniform(60, 200, (SIDE, SIDE, 3))
    for _ in range(5):
        frame = np.clip(bg + rng.normal(0, 1, bg.shape), 0, 255).astype(np.uint8)
        plain.apply(frame, quantised=quantised), with_boxes.apply(frame, quantised=quantised)
    frame = frame.copy()
    frame[40:60, 40:60] = 255  # a bright patch outside the box: foreground for the subtractor
    a, b = plain.apply(frame, quantised=quantised), with_boxes.apply(frame, quantised=quantised)
    box = np.zeros((SIDE, SIDE), bool)
    box[12:44, 20:36] = True  # x 20-36, y 12-44
    top = 255 if quantised else 1.0
    level = 204 if quantised else np.float32(0.8)
    assert (a[40:60, 40:60][~box[40:60, 40:60]] == top).all()
    assert np.array_equal(b[box], np.maximum(a[box], level))
    outside = ~box
    expected = np.round(0.5 * a[outside].astype(np.float32)) if quantised else 0.5 * a[outside]
    np.testing.assert_allclose(b[outside], expected)
    np.testing.assert_array_equal(with_boxes._people.last_boxes.ltwh_px, [[20.0, 12.0, 16.0, 32.0]])


def test_the_detector_alone_is_its_boxes_on_the_floor(tmp_path):
    sub = BackgroundSubtractor(SIDE, SIDE, ForegroundParams(
        method="none", close_px=0, floor=0.05, person_detector="yolox", person_model=_one_box_model(tmp_path),
        person_input_px=(SIDE, SIDE), person_likelihood=0.9))
    like = sub.apply(np.random.default_rng(2).integers(0, 255, (SIDE, SIDE, 3), dtype=np.uint8))
    box = np.zeros((SIDE, SIDE), bool)
    box[12:44, 20:36] = True
    assert (like[box] == np.float32(0.9)).all() and (like[~box] == np.float32(0.05)).all()


def test_config_builds_the_detector_front_end(tmp_path):
    cfg = config_from_dict({"recording": ".", "sensors": {"cameras": {
        "person_detector": "yolox", "person_model": "x.onnx", "person_input_px": [384, 288],
        "person_min_score": 0.4, "person_nms_iou": 0.5, "person_outside_weight": 0.3, "foreground_method": "none"}}})
    fg = cfg.system_params().camera_params.foreground
    assert (fg.person_detector, fg.person_input_px, fg.person_min_score, fg.person_nms_iou, fg.person_outside_weight,
            fg.method) == ("yolox", (384, 288), 0.4, 0.5, 0.3, "none")


# --- the shared YOLOX-Nano model on real frames ---

@pytest.mark.realdata
def test_yolox_nano_finds_the_annotated_people_of_real_terrace_frames():
    """Terrace c1, frames 0-1499 every 100th (tuning frames), the library's defaults (the canvas fitted to the
    360 x 288 frames: 384 x 288; score 0.5): the detector's boxes against the annotators' visible boxes at IoU 0.5."""
    model = shared_model("yolox_nano") / "yolox_nano.onnx"
    video, pom = shared_data("epfl_video"), shared_data("epfl_pom") / "EPFL-Terrace"
    from planefuse.calib import load_epfl_boxes
    gt = load_epfl_boxes(pom / "terrace1-c1" / "gt" / "gt.txt")
    det = PersonDetector(ForegroundParams(person_detector="yolox", person_model=str(model)))
    assert load_yolox(model)[1].sha256 == "695e750a5d5754bb5a8d5325643b59282191a7e7a564e435a415fd3c578eab14"
    cap = cv2.VideoCapture(str(video / "terrace1-c1.mp4"))
    tp = n_gt = n_det = 0
    for f in range(0, 1500, 100):
        cap.set(cv2.CAP_PROP_POS_FRAMES, f)
        ok, frame = cap.read()
        assert ok
        found = det.detect(frame)
        assert isinstance(found, PersonBoxes) and (found.score >= 0.5).all()
        assert (np.diff(found.score) <= 0).all()
        g = gt.box_xyxy_px[(gt.frame == f) & ~gt.lost]
        xyxy = np.c_[found.ltwh_px[:, :2], found.ltwh_px[:, :2] + found.ltwh_px[:, 2:]]
        n_gt, n_det = n_gt + len(g), n_det + len(xyxy)
        for b in g:
            lt, rb = np.maximum(xyxy[:, :2], b[:2]), np.minimum(xyxy[:, 2:], b[2:])
            inter = np.prod(np.clip(rb - lt, 0, None), axis=1)
            union = np.prod(xyxy[:, 2:] - xyxy[:, :2], axis=1) + np.prod(b[2:] - b[:2]) - inter
            tp += bool(len(xyxy)) and (inter / union).max() >= 0.5
    assert n_gt >= 30
    assert tp / n_gt >= 0.7, (tp, n_gt)
    assert tp / max(n_det, 1) >= 0.8, (tp, n_det)


@pytest.mark.realdata
@pytest.mark.skipif(len(ENGINES) < 2, reason="onnxruntime (the dev extra) is not installed")
def test_both_engines_find_the_same_boxes_on_real_terrace_frames():
    """YOLOX-Nano at the fitted 384 x 288 canvas, run by OpenCV and by ONNX Runtime (its fixed 416 x 416 input made
    symbolic), on terrace frames 0-1499 every 150th of both cameras: the same boxes, to float rounding."""
    model = shared_model("yolox_nano") / "yolox_nano.onnx"
    video = shared_data("epfl_video")
    dets = {e: YoloxDetector(model, (384, 288), min_score=0.5, engine=e) for e in ENGINES}
    n_boxes = 0
    for cam in ("c0", "c1"):
        cap = cv2.VideoCapture(str(video / f"terrace1-{cam}.mp4"))
        for f in range(0, 1500, 150):
            cap.set(cv2.CAP_PROP_POS_FRAMES, f)
            ok, frame = cap.read()
            assert ok
            a, b = (dets[e].detect(frame) for e in ENGINES)
            assert len(a) == len(b), (cam, f)
            np.testing.assert_allclose(a.ltwh_px, b.ltwh_px, atol=0.01)  # [px]
            np.testing.assert_allclose(a.score, b.score, atol=1e-4)
            n_boxes += len(a)
    assert n_boxes >= 40
