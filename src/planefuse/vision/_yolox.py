"""A pretrained YOLOX person detector (ONNX, run by ONNX Runtime or OpenCV's DNN module): letterbox, grid
decoding, NMS.

YOLOX (Ge et al. 2021, "YOLOX: Exceeding YOLO Series in 2021", arXiv 2107.08430) is an anchor-free detector:
for an input canvas of ``W x H`` px its head predicts, at every cell of three grids of strides 8, 16 and 32 px
(``(H / s) x (W / s)`` cells each, rows of a grid in order, then the grids from the finest), one vector

    [t_x, t_y, t_w, t_h, objectness, p_1 .. p_C]

where the box centre is ``((t_x + i) s, (t_y + j) s)`` for the cell in column ``i`` and row ``j``, its size
``(exp(t_w) s, exp(t_h) s)`` [canvas px], and objectness and the class probabilities are already squashed to
[0, 1] (the export's "raw" head: ``decode_in_inference=False``). The score of class ``c`` is
``objectness * p_c``. A frame enters the canvas resized by ``r = min(W / w, H / h)`` into the top-left corner,
the rest filled with grey 114, BGR channels, levels 0-255 (no normalisation): YOLOX's own pre-processing.
Boxes that overlap another of higher score by more than an IoU are suppressed (OpenCV's ``NMSBoxes``).

Any ONNX export of that layout loads (YOLOX-Nano, -Tiny, -S, -M ...: same head, more capacity); the checks in
:func:`load_yolox` refuse anything else before a run starts, naming the file and what was expected.

Two engines run the model (:data:`PERSON_ENGINES`): OpenCV's DNN module, always there, and ONNX Runtime (the
optional extra ``planefuse[onnxruntime]``), about twice as fast on one core (docs/benchmarks.md). ``"auto"`` takes
ONNX Runtime where it is installed. YOLOX's releases export a fixed 416 x 416 input; OpenCV reshapes the network
for any canvas, and for ONNX Runtime the export's static height and width are made symbolic before the session is
built (the weights untouched; the graph computes its reshapes from the input), so both run the fitted canvas.
"""

from __future__ import annotations

import hashlib
import importlib.util
import time
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path

import cv2
import numpy as np

__all__ = ["PERSON_ENGINES", "YOLOX_STRIDES", "PersonBoxes", "YoloxDetector", "YoloxModelInfo", "decode_yolox",
           "fitted_input_size", "letterbox", "load_yolox", "model_sha256", "resolve_engine", "yolox_grid"]

#: Strides [px] of YOLOX's three output grids, finest first (the order of the output rows).
YOLOX_STRIDES = (8, 16, 32)
#: Grey level of the letterbox's padding (YOLOX's pre-processing).
PAD_LEVEL = 114.0
#: A raw head's log-size outputs stay well inside this on any image; a decoded export's sizes are pixels.
_MAX_RAW_LOG_SIZE = 12.0
#: What runs the model: ``"auto"`` (ONNX Runtime where installed, else OpenCV), ``"opencv"`` (OpenCV's DNN
#: module), ``"onnxruntime"`` (the ``onnxruntime`` package: ``pip install 'planefuse[onnxruntime]'``).
PERSON_ENGINES = ("auto", "opencv", "onnxruntime")


@dataclass(frozen=True)
class PersonBoxes:
    """One frame's person boxes.

    Attributes
    ----------
    ltwh_px : ndarray, shape (K, 4), float64
        ``left, top, width, height`` [px] in the frame's pixels (u right, v down; MOTChallenge layout), clipped
        to the frame.
    score : ndarray, shape (K,), float64
        Person score in [0, 1] (objectness x person probability), in decreasing order.
    """

    ltwh_px: np.ndarray
    score: np.ndarray

    def __len__(self) -> int:
        return len(self.score)

    @classmethod
    def empty(cls) -> "PersonBoxes":
        return cls(np.zeros((0, 4)), np.zeros(0))


@dataclass(frozen=True)
class YoloxModelInfo:
    """What :func:`load_yolox` found in a model file.

    Attributes
    ----------
    path : str
    input_wh_px : (int, int)
        Canvas width and height [px] the model is run at.
    n_classes : int
        Classes of the head (80 for COCO, where person is class 0).
    engine : str
        What runs it: ``"opencv"`` or ``"onnxruntime"`` (``"auto"`` resolved).
    """

    path: str
    input_wh_px: tuple[int, int]
    n_classes: int
    engine: str = "opencv"

    @property
    def sha256(self) -> str:
        """Hex digest of the file's bytes, read when asked (``planefuse check`` prints it; a run does not need it)."""
        return model_sha256(self.path)


def check_input_size(input_wh_px) -> tuple[int, int]:
    """``(width, height)`` [px] of a YOLOX canvas: positive multiples of the coarsest stride (32)."""
    try:
        w, h = (int(v) for v in input_wh_px)
    except (TypeError, ValueError):
        raise ValueError(f"YOLOX input size must be (width, height) px, got {input_wh_px!r}") from None
    s = YOLOX_STRIDES[-1]
    if w < s or h < s or w % s or h % s or (w, h) != tuple(input_wh_px):
        raise ValueError(f"YOLOX input size (width, height) must be positive multiples of {s} px, got {input_wh_px!r}")
    return w, h


#: The longest canvas side [px] of :func:`fitted_input_size`: YOLOX-Nano's own 416 x 416 input.
FIT_MAX_SIDE_PX = 416


def fitted_input_size(frame_wh_px: tuple[int, int], max_side_px: int = FIT_MAX_SIDE_PX) -> tuple[int, int]:
    """The canvas ``(W, H)`` [px] for frames of ``frame_wh_px``: the frame at its own size, or reduced so that its
    longer side is ``max_side_px`` (never enlarged), each side rounded up to a multiple of 32.

    People keep the scale the model's own square canvas would give a frame larger than it (a 1920 x 1080 frame:
    416 x 256 instead of 416 x 416, the same people in 37 % fewer pixels); a smaller frame is not enlarged. On the
    EPFL terrace (360 x 288 frames, canvas 384 x 288) the system scored as with 416 x 416 on its tuning frames
    (cold starts at 0 and 1000, filtered MODA 0.5 / 1.0 m, MOTA, IDF1: 0.803 / 0.893, 0.788, 0.895 and 0.739 /
    0.897, 0.731, 0.808 against 0.800 / 0.890, 0.788, 0.895 and 0.735 / 0.893, 0.723, 0.811) at 62 % of the cost.
    """
    w, h = (int(v) for v in frame_wh_px)
    if w < 1 or h < 1:
        raise ValueError(f"frame size must be positive (width, height) px, got {frame_wh_px!r}")
    r = min(1.0, max_side_px / max(w, h))
    s = YOLOX_STRIDES[-1]
    return tuple(max(s, -(-int(round(v * r)) // s) * s) for v in (w, h))


@lru_cache(maxsize=8)
def yolox_grid(input_wh_px: tuple[int, int]) -> tuple[np.ndarray, np.ndarray]:
    """Cell indices and strides of YOLOX's output rows for a ``(width, height)`` canvas.

    Returns
    -------
    cell_xy : ndarray, shape (A, 2), float32
        Column ``i`` and row ``j`` of each output row's cell in its grid (read-only).
    stride_px : ndarray, shape (A,), float32
        Its grid's stride [px] (read-only). ``A = sum_s (W / s) (H / s)``.
    """
    w, h = check_input_size(input_wh_px)
    cells, strides = [], []
    for s in YOLOX_STRIDES:
        jj, ii = np.mgrid[0:h // s, 0:w // s]
        cells.append(np.c_[ii.ravel(), jj.ravel()])
        strides.append(np.full(ii.size, s))
    cell_xy, stride_px = np.concatenate(cells).astype(np.float32), np.concatenate(strides).astype(np.float32)
    cell_xy.flags.writeable = stride_px.flags.writeable = False
    return cell_xy, stride_px


def letterbox(frame: np.ndarray, input_wh_px: tuple[int, int]) -> tuple[np.ndarray, float]:
    """YOLOX's input blob of a frame: resized by ``r = min(W / w, H / h)`` into the top-left corner of a grey
    (114) ``W x H`` canvas.

    Parameters
    ----------
    frame : ndarray, shape (h, w, 3) BGR or (h, w) grey, uint8
    input_wh_px : (int, int)
        Canvas ``(W, H)`` [px].

    Returns
    -------
    blob : ndarray, shape (1, 3, H, W), float32
        Channels B, G, R, levels 0-255.
    scale : float
        ``r``: canvas px per frame px (a canvas point ``p`` is the frame's ``p / r``).
    """
    W, H = check_input_size(input_wh_px)
    img = np.asarray(frame)
    if img.dtype != np.uint8 or img.ndim not in (2, 3) or (img.ndim == 3 and img.shape[2] != 3):
        raise ValueError(f"frame must be an (h, w, 3) BGR or (h, w) grey uint8 image, got {img.dtype} {img.shape}")
    if img.ndim == 2:
        img = cv2.cvtColor(img, cv2.COLOR_GRAY2BGR)
    h, w = img.shape[:2]
    r = min(W / w, H / h)
    size = (int(w * r), int(h * r))
    resized = img if size == (w, h) else cv2.resize(img, size, interpolation=cv2.INTER_LINEAR)
    canvas = np.full((H, W, 3), PAD_LEVEL, np.float32)
    canvas[:size[1], :size[0]] = resized
    return np.ascontiguousarray(canvas.transpose(2, 0, 1)[None]), float(r)


def decode_yolox(raw: np.ndarray, input_wh_px: tuple[int, int], class_index: int = 0
                 ) -> tuple[np.ndarray, np.ndarray]:
    """Boxes and one class's scores from YOLOX's raw head output.

    Parameters
    ----------
    raw : ndarray, shape (A, 5 + C) or (1, A, 5 + C)
        ``[t_x, t_y, t_w, t_h, objectness, p_1 .. p_C]`` per output row (module doc).
    input_wh_px : (int, int)
        The canvas ``(W, H)`` [px] the model ran on.
    class_index : int
        The class to score (0 = person in COCO).

    Returns
    -------
    xyxy_px : ndarray, shape (A, 4), float32
        ``x0, y0, x1, y1`` [canvas px]: centre ``(t + cell) * stride``, size ``exp(t_wh) * stride``.
    score : ndarray, shape (A,), float32
        ``objectness * p_class``.
    """
    out = np.asarray(raw, dtype=np.float32)
    if out.ndim == 3 and out.shape[0] == 1:
        out = out[0]
    cell_xy, stride = yolox_grid(tuple(int(v) for v in input_wh_px))
    if out.ndim != 2 or out.shape[0] != len(stride) or out.shape[1] < 6 + class_index:
        raise ValueError(f"YOLOX output must have shape ({len(stride)}, 5 + classes) with class {class_index} for a "
                         f"{input_wh_px[0]}x{input_wh_px[1]} canvas, got {np.shape(raw)}")
    centre = (out[:, :2] + cell_xy) * stride[:, None]
    half = np.exp(np.minimum(out[:, 2:4], _MAX_RAW_LOG_SIZE)) * stride[:, None] / 2
    return np.concatenate([centre - half, centre + half], axis=1), out[:, 4] * out[:, 5 + class_index]


def model_sha256(path) -> str:
    """Hex SHA-256 of a model file's bytes."""
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def resolve_engine(engine: str) -> str:
    """The engine that runs a person model for the setting ``engine`` (:data:`PERSON_ENGINES`): ``"auto"`` is
    ``"onnxruntime"`` where the ``onnxruntime`` package is installed, else ``"opencv"``.

    Raises
    ------
    ValueError
        ``engine`` is not one of :data:`PERSON_ENGINES`, or ``"onnxruntime"`` without its package.
    """
    if engine not in PERSON_ENGINES:
        raise ValueError(f"person engine must be one of {', '.join(PERSON_ENGINES)}, got {engine!r}")
    has_ort = importlib.util.find_spec("onnxruntime") is not None
    if engine == "auto":
        return "onnxruntime" if has_ort else "opencv"
    if engine == "onnxruntime" and not has_ort:
        raise ValueError("person engine 'onnxruntime' needs the onnxruntime package: "
                         "pip install 'planefuse[onnxruntime]' (or person_engine: opencv)")
    return engine


class _OpenCVNet:
    """A model run by OpenCV's DNN module (it reshapes the network to each input)."""

    name = "opencv"

    def __init__(self, path: Path, input_wh_px: tuple[int, int], threads: int) -> None:
        self._net = cv2.dnn.readNetFromONNX(str(path))  # threads: OpenCV's own setting (cv2.setNumThreads)

    def forward(self, blob: np.ndarray) -> np.ndarray:
        self._net.setInput(blob)
        return np.asarray(self._net.forward())


class _OnnxRuntimeNet:
    """A model run by ONNX Runtime on the CPU, its input's static height and width made symbolic where the canvas
    differs from them, on ``threads`` threads that sleep rather than spin between runs."""

    name = "onnxruntime"

    def __init__(self, path: Path, input_wh_px: tuple[int, int], threads: int) -> None:
        import onnxruntime

        options = onnxruntime.SessionOptions()
        options.intra_op_num_threads = max(1, int(threads))
        options.inter_op_num_threads = 1
        options.add_session_config_entry("session.intra_op.allow_spinning", "0")  # idle threads cost no CPU
        options.log_severity_level = 3  # errors only: the checks of load_yolox say what is wrong in one line
        model = _free_input_size(path.read_bytes(), input_wh_px)
        self._session = onnxruntime.InferenceSession(model, options, providers=["CPUExecutionProvider"])
        self._input = self._session.get_inputs()[0].name

    def forward(self, blob: np.ndarray) -> np.ndarray:
        return np.asarray(self._session.run(None, {self._input: blob})[0])


def _free_input_size(model: bytes, input_wh_px: tuple[int, int]) -> bytes:
    """The ONNX model ``model`` (serialised ``ModelProto``) with its first graph input's height and width made
    symbolic where they are fixed to another size than ``input_wh_px`` (YOLOX's releases: 416 x 416), its outputs'
    row counts too, and the stored intermediate shapes that followed from them dropped (the runtime infers them from
    the input); ``model`` itself where nothing needs to change.

    Read through :func:`_onnx_subset`'s few fields of ONNX's schema; the rest of the file (the nodes, the weights)
    passes through as protobuf's unknown fields, byte for byte.
    """
    from google.protobuf.message import DecodeError

    m = _onnx_subset()()
    try:
        m.ParseFromString(model)
    except DecodeError:
        raise ValueError("not a protobuf file") from None
    g = m.graph
    weights = {t.name for t in g.initializer}
    inputs = [i for i in g.input if i.name not in weights]
    dims = inputs[0].type.tensor_type.shape.dim if inputs else []
    w, h = input_wh_px
    if len(dims) != 4 or ([d.dim_value if d.HasField("dim_value") else None for d in dims[2:]] == [h, w]):
        return model  # another layout (load_yolox's checks say so), or already this canvas
    dims[2].dim_param, dims[3].dim_param = "height_px", "width_px"
    for out in g.output:  # (1, A, 5 + C): the rows A follow the canvas
        out_dims = out.type.tensor_type.shape.dim
        if len(out_dims) > 1:
            out_dims[1].dim_param = "rows"
    del g.value_info[:]
    return m.SerializeToString()


@lru_cache(maxsize=1)
def _onnx_subset():
    """The message class of ONNX's ``ModelProto`` reduced to the fields :func:`_free_input_size` reads (the numbers
    and types of onnx.proto: ModelProto.graph 7; GraphProto.initializer 5, input 11, output 12, value_info 13;
    TensorProto.name 8; ValueInfoProto.name 1, type 2; TypeProto.tensor_type 1; TypeProto.Tensor.shape 2;
    TensorShapeProto.dim 1; Dimension.dim_value 1 / dim_param 2, a oneof), built with protobuf (onnxruntime's own
    dependency) rather than the onnx package, whose import costs about 0.7 s of CPU."""
    from google.protobuf import descriptor_pb2, descriptor_pool, message_factory

    F = descriptor_pb2.FieldDescriptorProto
    f = descriptor_pb2.FileDescriptorProto(name="planefuse_onnx_subset.proto", package="planefuse_onnx",
                                           syntax="proto2")

    def message(name, *fields, oneof=None):
        msg = f.message_type.add(name=name)
        if oneof:
            msg.oneof_decl.add(name=oneof)
        for number, fname, ftype, label, type_name in fields:
            field = msg.field.add(name=fname, number=number, type=ftype, label=label)
            if type_name:
                field.type_name = f".planefuse_onnx.{type_name}"
            if oneof:
                field.oneof_index = 0

    opt, rep = F.LABEL_OPTIONAL, F.LABEL_REPEATED
    message("Dimension", (1, "dim_value", F.TYPE_INT64, opt, None), (2, "dim_param", F.TYPE_STRING, opt, None),
            oneof="value")
    message("Shape", (1, "dim", F.TYPE_MESSAGE, rep, "Dimension"))
    message("Tensor", (2, "shape", F.TYPE_MESSAGE, opt, "Shape"))
    message("Type", (1, "tensor_type", F.TYPE_MESSAGE, opt, "Tensor"))
    message("ValueInfo", (1, "name", F.TYPE_STRING, opt, None), (2, "type", F.TYPE_MESSAGE, opt, "Type"))
    message("Weights", (8, "name", F.TYPE_STRING, opt, None))
    message("Graph", (5, "initializer", F.TYPE_MESSAGE, rep, "Weights"),
            (11, "input", F.TYPE_MESSAGE, rep, "ValueInfo"), (12, "output", F.TYPE_MESSAGE, rep, "ValueInfo"),
            (13, "value_info", F.TYPE_MESSAGE, rep, "ValueInfo"))
    message("Model", (7, "graph", F.TYPE_MESSAGE, opt, "Graph"))
    pool = descriptor_pool.DescriptorPool()
    pool.Add(f)
    return message_factory.GetMessageClass(pool.FindMessageTypeByName("planefuse_onnx.Model"))


_ENGINES = {"opencv": _OpenCVNet, "onnxruntime": _OnnxRuntimeNet}


def load_yolox(path, input_wh_px=(416, 416), class_index: int = 0, engine: str = "auto", threads: int = 1):
    """Read a YOLOX ONNX export and check its layout on a grey canvas.

    Parameters
    ----------
    path : str or Path
        The ``.onnx`` file (e.g. ``yolox_nano.onnx`` from the YOLOX project's releases).
    input_wh_px : (int, int)
        Canvas ``(W, H)`` [px] to run at: multiples of 32 (the model's own 416 x 416, or near the frame's size).
    class_index : int
        The person class (0 in COCO).
    engine : str
        What runs it (:data:`PERSON_ENGINES`; :func:`resolve_engine`).
    threads : int
        ONNX Runtime's threads (OpenCV uses its process-wide ``cv2.setNumThreads``).

    Returns
    -------
    net
        The model: ``net.forward(blob (1, 3, H, W) float32) -> (1, A, 5 + C)``, ``net.name`` its engine.
    info : YoloxModelInfo

    Raises
    ------
    ValueError
        One line naming the file: it is missing, not an ONNX model the engine runs at this canvas, its output is
        not YOLOX's raw head for this canvas (shape, or already decoded boxes), or it has no class ``class_index``;
        or the engine is unknown or not installed.
    """
    p = Path(path)
    wh = check_input_size(input_wh_px)
    name = resolve_engine(engine)
    what = "a YOLOX ONNX export (e.g. yolox_nano.onnx from the YOLOX releases)"
    if not p.is_file():
        raise ValueError(f"{p}: person model not found; expected {what}")
    try:
        net = _ENGINES[name](p, wh, threads)
        out = net.forward(np.full((1, 3, wh[1], wh[0]), PAD_LEVEL, np.float32))
    except Exception as exc:  # noqa: BLE001 - each engine's own errors (cv2.error, onnx's DecodeError, ORT's Fail ...)
        raise ValueError(f"{p}: not an ONNX model that {_ENGINE_TITLES[name]} can run at {wh[0]}x{wh[1]} px "
                         f"({_first_line(exc)}); expected {what}") from None
    n_rows = len(yolox_grid(wh)[1])
    if out.ndim != 3 or out.shape[0] != 1 or out.shape[1] != n_rows or out.shape[2] < 6:
        raise ValueError(f"{p}: output shape {out.shape} is not YOLOX's raw head layout (1, {n_rows}, 5 + classes) "
                         f"for a {wh[0]}x{wh[1]} px input (strides {YOLOX_STRIDES})")
    n_classes = out.shape[2] - 5
    if class_index >= n_classes:
        raise ValueError(f"{p}: has {n_classes} classes, so no person class {class_index} (COCO models: 80 classes, "
                         f"person = 0)")
    if np.nanmax(np.abs(out[0, :, 2:4])) > _MAX_RAW_LOG_SIZE or not np.isfinite(out).all() \
            or out[0, :, 4:].min() < 0 or out[0, :, 4:].max() > 1:
        raise ValueError(f"{p}: outputs are not YOLOX's raw head (log sizes and probabilities in [0, 1]); export "
                         "with decode_in_inference=False")
    return net, YoloxModelInfo(str(p), wh, n_classes, name)


_ENGINE_TITLES = {"opencv": "OpenCV's DNN module", "onnxruntime": "ONNX Runtime"}


def _first_line(exc: BaseException) -> str:
    """The gist of an engine's error in one line: OpenCV's "OpenCV(v) file.cpp:line: error: (-code:Kind) what"
    keeps its kind; others their first non-empty line, shortened."""
    text = str(exc)
    if isinstance(exc, cv2.error):
        first = next((ln for ln in text.splitlines() if "error:" in ln), text)
        return first.split("error:", 1)[-1].split(")", 1)[0].split(":", 1)[-1].strip()
    first = next((ln.strip() for ln in text.splitlines() if ln.strip()), type(exc).__name__)
    return first if len(first) <= 160 else first[:157] + "..."


class YoloxDetector:
    """People in frames by a YOLOX ONNX model (module doc).

    Parameters
    ----------
    path : str or Path
        The model file (:func:`load_yolox`).
    input_wh_px : (int, int)
        Canvas ``(W, H)`` [px].
    min_score : float
        Smallest person score kept, in [0, 1].
    nms_iou : float
        Boxes overlapping a better one by more than this IoU are suppressed, in (0, 1].
    class_index : int
        The person class.
    engine : str
        What runs the model (:data:`PERSON_ENGINES`).
    threads : int
        ONNX Runtime's threads (OpenCV's DNN module uses ``cv2.setNumThreads``).
    """

    def __init__(self, path, input_wh_px=(416, 416), min_score: float = 0.3, nms_iou: float = 0.45,
                 class_index: int = 0, engine: str = "auto", threads: int = 1) -> None:
        if not 0.0 <= min_score <= 1.0:
            raise ValueError(f"min_score must lie in [0, 1], got {min_score}")
        if not 0.0 < nms_iou <= 1.0:
            raise ValueError(f"nms_iou must lie in (0, 1], got {nms_iou}")
        self.net, self.info = load_yolox(path, input_wh_px, class_index, engine, threads)
        self.min_score, self.nms_iou, self.class_index = float(min_score), float(nms_iou), int(class_index)

    def detect(self, frame: np.ndarray) -> PersonBoxes:
        """The people in one frame ((h, w, 3) BGR or (h, w) grey uint8): boxes in the frame's pixels."""
        blob, r = letterbox(frame, self.info.input_wh_px)
        xyxy, score = decode_yolox(self.net.forward(blob), self.info.input_wh_px, self.class_index)
        keep = score >= self.min_score
        if not keep.any():
            return PersonBoxes.empty()
        xyxy, score = xyxy[keep] / r, score[keep]
        h, w = np.shape(frame)[:2]
        xyxy[:, 0::2] = np.clip(xyxy[:, 0::2], 0, w)
        xyxy[:, 1::2] = np.clip(xyxy[:, 1::2], 0, h)
        ltwh = np.c_[xyxy[:, :2], xyxy[:, 2:] - xyxy[:, :2]].astype(np.float64)
        idx = np.asarray(cv2.dnn.NMSBoxes(ltwh.tolist(), score.tolist(), self.min_score, self.nms_iou),
                         dtype=int).reshape(-1)
        idx = idx[np.argsort(-score[idx], kind="stable")]
        return PersonBoxes(ltwh[idx], score[idx].astype(np.float64))

    def cost_ms(self, frame_wh_px: tuple[int, int], repeats: int = 5) -> float:
        """Median wall time [ms] of :meth:`detect` on a grey frame of ``(width, height)`` px, in this process
        (OpenCV's current thread count, or ONNX Runtime's ``threads``)."""
        frame = np.full((int(frame_wh_px[1]), int(frame_wh_px[0]), 3), 128, np.uint8)
        self.detect(frame)
        times = []
        for _ in range(repeats):
            t0 = time.perf_counter()
            self.detect(frame)
            times.append(time.perf_counter() - t0)
        return 1000.0 * float(np.median(times))
