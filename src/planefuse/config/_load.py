"""Load, explain and write the run configuration YAML."""

from __future__ import annotations

import hashlib
import json
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Any, get_origin

import yaml
from pydantic import BaseModel, ValidationError
from pydantic.fields import FieldInfo

from ..io._yaml import YamlFileError, excerpt, read_yaml, shorten
from ._models import _LIBRARY_DEFAULTS, ITEM_MARK, RunConfig, library_fields

__all__ = ["ConfigError", "ConfigIssue", "load_config", "config_from_dict", "example_yaml", "config_hash", "config_yaml"]


@dataclass(frozen=True)
class ConfigIssue:
    """One problem in a configuration file.

    Attributes
    ----------
    field_path : str
        Dotted path with list indices, e.g. ``planes.heights_m[2]``; ``""`` for the whole file.
    message : str
        What is wrong.
    expected : str
        The field's unit and accepted range (empty where the field is unknown).
    line : int or None
        1-based line in the file where the offending value starts, where known.
    """

    field_path: str
    message: str
    expected: str = ""
    line: int | None = None


#: Most characters of one issue's message (a bad value is quoted by an excerpt; this bounds the rest).
MESSAGE_CHARS = 400


class ConfigError(ValueError):
    """A configuration file that cannot be read or does not validate.

    ``str(err)`` lists every issue as ``FILE:LINE: FIELD: message (expected: unit, range)``.
    """

    def __init__(self, file: Path | str, issues: list[ConfigIssue]):
        self.file = Path(file)
        self.issues = list(issues)
        super().__init__(self._format())

    def _format(self) -> str:
        lines = [f"{self.file}: {len(self.issues)} configuration error(s)"]
        for it in self.issues:
            where = f"{self.file}:{it.line}" if it.line else f"{self.file}"
            field = it.field_path or "<file>"
            exp = f" (expected: {it.expected})" if it.expected else ""
            lines.append(f"  {where}: {field}: {shorten(it.message, MESSAGE_CHARS)}{exp}")
        return "\n".join(lines)


def _path_str(loc: tuple) -> str:
    out = ""
    for part in loc:
        out += f"[{part}]" if isinstance(part, int) else (f".{part}" if out else str(part))
    return out


def _field_info(loc: tuple) -> FieldInfo | None:
    """FieldInfo of the deepest named field along ``loc`` (list indices stay on their field)."""
    model: type[BaseModel] | None = RunConfig
    info = None
    for part in loc:
        if isinstance(part, int):
            continue
        if model is None or part not in model.model_fields:
            return info if model is None else None
        info = model.model_fields[part]
        ann = info.annotation
        model = ann if isinstance(ann, type) and issubclass(ann, BaseModel) else None
    return info


def _expected(info: FieldInfo | None) -> str:
    if info is None:
        return ""
    extra = info.json_schema_extra if isinstance(info.json_schema_extra, dict) else {}
    unit, exp = extra.get("unit", ""), extra.get("expected", "")
    ann = info.annotation
    if get_origin(ann) is None and ann is bool:
        exp = exp or "true or false"
    elif isinstance(ann, type) and issubclass(ann, BaseModel):
        exp = exp or f"a mapping with fields {', '.join(ann.model_fields)}"
    return ", ".join(s for s in (f"[{unit}]" if unit else "", str(exp)) if s)


def _line_of(root: yaml.Node | None, loc: tuple) -> int | None:
    """1-based line of the YAML key (or list item) at ``loc``, or of its deepest existing parent."""
    node, line = root, (root.start_mark.line + 1 if root is not None else None)
    for part in loc:
        if isinstance(node, yaml.MappingNode) and isinstance(part, str):
            pair = next(((k, v) for k, v in node.value if getattr(k, "value", None) == part), None)
            if pair is None:
                return line
            node, line = pair[1], pair[0].start_mark.line + 1
        elif isinstance(node, yaml.SequenceNode) and isinstance(part, int) and part < len(node.value):
            node = node.value[part]
            line = node.start_mark.line + 1
        else:
            return line
    return line


def _issues_from_validation(err: ValidationError, root: yaml.Node | None) -> list[ConfigIssue]:
    issues = []
    for e in err.errors():
        loc = tuple(p for p in e["loc"] if not (isinstance(p, str) and re.fullmatch(r"function-\w+\[.*\]", p)))
        msg = e["msg"].removeprefix("Value error, ")
        value = e.get("input")
        m = re.match(re.escape(ITEM_MARK) + r"(\d+): (.*)", msg, flags=re.S)
        if m:
            loc, msg = loc + (int(m.group(1)),), m.group(2)
            value = value[int(m.group(1))] if isinstance(value, list) else value
        if e["type"] == "extra_forbidden":
            msg = "unknown field (misspelt, or not part of this section)"
        elif e["type"] == "missing":
            msg = "required field is missing"
        elif "input" in e and not isinstance(value, dict):
            msg = f"{msg}; got {excerpt(value)}"
        issues.append(ConfigIssue(_path_str(loc), msg, _expected(_field_info(loc)), _line_of(root, loc)))
    return issues


def config_from_dict(data: Any, file: Path | str = "<dict>", root_node: yaml.Node | None = None) -> RunConfig:
    """Validate a parsed configuration mapping; raise :class:`ConfigError` naming ``file`` and fields."""
    if not isinstance(data, dict):
        raise ConfigError(file, [ConfigIssue("", f"the file must hold a YAML mapping, got {type(data).__name__}")])
    try:
        cfg = RunConfig.model_validate(data)
    except ValidationError as err:
        raise ConfigError(file, _issues_from_validation(err, root_node)) from None
    issues = [_library_issue(str(err), root_node) for err in cfg.library_errors()]
    if issues:
        raise ConfigError(file, issues)
    return cfg


def _library_owner(path: str) -> str:
    """``Class.attribute`` of a library attribute path such as ``system.tracking.tracker.gate_m``."""
    head, *parts = path.split(".")
    obj = _LIBRARY_DEFAULTS[head]
    for part in parts[:-1]:
        obj = getattr(obj, part)
    return f"{type(obj).__name__}.{parts[-1]}"


def _library_issue(message: str, root: yaml.Node | None) -> ConfigIssue:
    """A library parameter class's error (``Class.attribute must be ...``) reported at the configuration field
    that sets that attribute, with its line and expected range."""
    owners = {_library_owner(lib): field for field, lib in library_fields()}
    m = re.match(r"(\w+\.\w+)(?::| must)\s*(.*)", message, flags=re.S)
    field = owners.get(m.group(1)) if m else None
    if field is None:
        return ConfigIssue("", message)
    loc = tuple(field.split("."))
    text = m.group(2) if message[len(m.group(1))] == ":" else "must " + m.group(2)
    return ConfigIssue(field, f"{text} ({m.group(1)})", _expected(_field_info(loc)), _line_of(root, loc))


def load_config(path: Path | str, *, resolve_paths: bool = True) -> RunConfig:
    """Read and validate a run configuration YAML file.

    Parameters
    ----------
    path : path-like
        The YAML file.
    resolve_paths : bool
        Make ``recording`` and ``outputs.out_dir`` absolute, relative to the
        file's folder (default).

    Returns
    -------
    RunConfig

    Raises
    ------
    ConfigError
        The file is missing, is not YAML, or does not validate; the message
        names the file, each offending field path (``planes.heights_m[2]``),
        its line and the expected unit and range.
    """
    path = Path(path)
    try:  # safe YAML, UTF-8 or UTF-16/32 with a byte-order mark, no alias bomb, no duplicate key (io._yaml)
        data, root = read_yaml(path)
    except YamlFileError as err:
        raise ConfigError(path, [ConfigIssue("", err.problem, line=err.line)]) from None
    cfg = config_from_dict({} if data is None else data, path, root)
    if not resolve_paths:
        return cfg
    cfg = cfg.resolved(path.resolve().parent)
    model_path = cfg.sensors.sound.model_path
    if cfg.sensors.sound.enabled and model_path is not None:
        loc = ("sensors", "sound", "model_path")
        problem = _sound_model_problem(model_path)
        if problem:
            raise ConfigError(path, [ConfigIssue(".".join(loc), problem, _expected(_field_info(loc)),
                                                 _line_of(root, loc))])
    cameras = cfg.sensors.cameras
    if cameras.enabled and cameras.person_detector == "yolox":
        from ..vision import resolve_engine

        try:  # an engine that is not installed: said at its own field
            resolve_engine(cameras.person_engine)
        except ValueError as err:
            loc = ("sensors", "cameras", "person_engine")
            raise ConfigError(path, [ConfigIssue(".".join(loc), str(err), _expected(_field_info(loc)),
                                                 _line_of(root, loc))]) from None
        loc = ("sensors", "cameras", "person_model")
        problem = _person_model_problem(cameras.person_model, cameras.person_input_px or (416, 416),
                                        cameras.person_engine)
        if problem:
            raise ConfigError(path, [ConfigIssue(".".join(loc), problem, _expected(_field_info(loc)),
                                                 _line_of(root, loc))])
    return cfg


def _person_model_problem(model_path: str, input_px, engine: str = "auto") -> str:
    """Why the YOLOX person model at ``model_path`` cannot be run at ``input_px`` by ``engine`` ("" when it loads and
    its output has YOLOX's layout): the run would otherwise stop at its first frame."""
    from ..vision import load_yolox

    try:
        load_yolox(model_path, tuple(input_px), engine=engine)
    except ValueError as err:
        return str(err)
    return ""


def _sound_model_problem(model_path: Path) -> str:
    """Why the binaural sensor model at ``model_path`` cannot be used ("" when it loads)."""
    if not model_path.is_file():
        return f"no file {model_path}"
    from ..audio import BinauralSensorModel

    try:
        BinauralSensorModel.load(model_path)
    except Exception as err:  # noqa: BLE001 - any failure to load is reported as this field's error
        return f"{model_path} is not a sensor model written by planefuse audio calibrate ({type(err).__name__}: {err})"
    return ""


def config_yaml(cfg: RunConfig) -> str:
    """``cfg`` as YAML, every field written out, ending with a comment holding its :func:`config_hash`."""
    return yaml.safe_dump(cfg.model_dump(mode="json"), sort_keys=False) + f"# config_hash: {config_hash(cfg)}\n"


def config_hash(cfg: RunConfig) -> str:
    """SHA-256 (hex) of everything in ``cfg`` that changes the computed results.

    Presentation-only outputs (``out_dir``, ``figures``, ``animation``, ``animation_max_frames``, ``camera_videos``,
    ``report``, ``rerun``, ``figure_dpi``, ``mcap``, ``ros2_bag``) are left out, so changing them does
    not invalidate a run's finished chunks.
    """
    data = cfg.model_dump(mode="json")
    data["outputs"] = {k: data["outputs"][k] for k in ("zarr", "chunk_steps")}
    return hashlib.sha256(json.dumps(data, sort_keys=True).encode()).hexdigest()


# -- the commented example -----------------------------------------------------------------------------------------
def _comment(info: FieldInfo) -> str:
    exp = _expected(info)
    return f"# {info.description}" + (f" -- {exp}" if exp else "")


def _scalar(value: Any) -> str:
    if isinstance(value, Path):
        value = str(value)
    if isinstance(value, tuple):
        value = list(value)
    if isinstance(value, list):
        value = [list(v) if isinstance(v, tuple) else v for v in value]
    return yaml.safe_dump(value, default_flow_style=True, width=10_000).strip().removesuffix("...").strip()


def _note_lines(note: str, pad: str, width: int = 116) -> list[str]:
    """``note`` as comment lines of at most ``width`` characters, indented by ``pad``."""
    import textwrap

    return [pad + "#   " + line for line in textwrap.wrap(note, max(width - len(pad) - 4, 40))]


def _model_lines(model: BaseModel, indent: int, notes: dict[str, str] | None = None, prefix: str = "") -> list[str]:
    pad = "  " * indent
    lines: list[str] = []
    for name, info in type(model).model_fields.items():
        value = getattr(model, name)
        lines.append(pad + _comment(info))
        if notes and f"{prefix}{name}" in notes:
            lines.extend(_note_lines(notes[f"{prefix}{name}"], pad))
        if isinstance(value, BaseModel):
            lines.append(f"{pad}{name}:")
            lines.extend(_model_lines(value, indent + 1, notes, f"{prefix}{name}."))
        else:
            lines.append(f"{pad}{name}: {_scalar(value)}")
    return lines


#: The placeholder recording folder of the example configuration.
EXAMPLE_RECORDING = "recordings/my-scene"


def example_yaml(recording: str = EXAMPLE_RECORDING, config: RunConfig | None = None, *,
                 notes: dict[str, str] | None = None, header: tuple[str, ...] = ()) -> str:
    """A complete, commented example configuration (every field at its default, or at ``config``'s values).

    The comments give each field's meaning, unit and accepted range; the text
    loads back with :func:`load_config` unchanged. ``config`` (e.g. fitted to an existing recording: its planes,
    area and sensors) replaces the defaults; its recording path is replaced by ``recording``. ``notes`` (dotted
    field path -> text, e.g. a profile's measurements) are written as comments under those fields; ``header``
    lines as comments at the top.
    """
    cfg = RunConfig(recording=Path(recording)) if config is None else \
        config.model_copy(update={"recording": Path(recording)})
    head = [
        "# planefuse run configuration.",
        "# Units are in the field names (_m metres, _s seconds, _hz hertz, _m_s metres per second).",
        "# World frame: z up against gravity, the ground plane pi_ref at z = 0, metres.",
        "# Check it with:  planefuse check THIS_FILE.yaml",
        *(f"# {line}" for line in header),
        "",
    ]
    body: list[str] = []
    for name, info in RunConfig.model_fields.items():
        value = getattr(cfg, name)
        body.append(_comment(info))
        if isinstance(value, BaseModel):
            body.append(f"{name}:")
            body.extend(_model_lines(value, 1, notes, f"{name}."))
            body.append("")
        else:
            body.append(f"{name}: {_scalar(value)}")
            body.append("")
    return "\n".join(head + body).rstrip() + "\n"

