"""Load YAML files into pydantic models with errors that name the file, the field and the line."""

from __future__ import annotations

from pathlib import Path
from typing import TypeVar

import yaml
from pydantic import BaseModel, ValidationError

__all__ = ["load_yaml_model", "format_validation_error"]

M = TypeVar("M", bound=BaseModel)
#: libyaml's safe loader where PyYAML was built with it (the same data, about 10x faster than the pure-Python one)
_SAFE_LOADER = getattr(yaml, "CSafeLoader", yaml.SafeLoader)


def _locate(node: yaml.Node | None, loc: tuple) -> tuple[int | None, list[str]]:
    """1-based line of the deepest YAML node along ``loc`` (a pydantic error location) and the field path.

    Pydantic puts the tag of a discriminated union into the location (``sensors.0.camera.K``); a key that
    is the ``type`` of the mapping it indexes is dropped from the path.
    """
    line = None if node is None else node.start_mark.line + 1
    parts: list[str] = []
    for key in loc:
        nxt = None
        if isinstance(node, yaml.MappingNode):
            items = {k.value: v for k, v in node.value if isinstance(k, yaml.ScalarNode)}
            if str(key) in items:
                nxt = items[str(key)]
            elif isinstance(items.get("type"), yaml.ScalarNode) and items["type"].value == str(key):
                continue  # union tag, not a field
        elif isinstance(node, yaml.SequenceNode) and isinstance(key, int) and 0 <= key < len(node.value):
            nxt = node.value[key]
        parts.append(str(key))
        if nxt is not None:
            node = nxt
            line = node.start_mark.line + 1
        else:
            node = None
    return line, parts


def format_validation_error(err: ValidationError, source: str, root: yaml.Node | None = None) -> str:
    """One line per problem: ``source:LINE: field a.b.0.c: message``."""
    lines = []
    for e in err.errors():
        loc = tuple(x for x in e["loc"] if not (isinstance(x, str) and x.startswith("function-")))
        line, parts = _locate(root, loc)
        field = ".".join(parts) or "<root>"
        where = f"{source}:{line}" if line is not None else source
        lines.append(f"{where}: field {field}: {e['msg']}")
    return "\n".join(lines)


def _safe_load(text: str):
    """``yaml.safe_load(text)``, parsed by libyaml where it can be; a document libyaml refuses is parsed again by
    the pure-Python parser, whose error (problem and line) is the one reported."""
    try:
        return yaml.load(text, Loader=_SAFE_LOADER)
    except yaml.YAMLError:
        return yaml.safe_load(text)


def load_yaml_model(path: str | Path, model: type[M]) -> M:
    """Read ``path`` (YAML) and validate it as ``model``.

    Raises
    ------
    ValueError
        If the file is missing, is not valid YAML, or does not validate; the
        message names the file, the line and the offending field.
    """
    path = Path(path)
    if not path.is_file():
        raise ValueError(f"{path}: file not found")
    text = path.read_text()
    try:
        data = _safe_load(text)
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        where = f"{path}:{mark.line + 1}" if mark is not None else str(path)
        raise ValueError(f"{where}: invalid YAML: {getattr(exc, 'problem', exc)}") from None
    if data is None:
        data = {}
    if not isinstance(data, dict):
        raise ValueError(f"{path}: expected a mapping at the top level, got {type(data).__name__}")
    try:
        return model.model_validate(data)
    except ValidationError as exc:
        root = yaml.compose(text)  # the nodes' lines, only to name them in the error
        raise ValueError(format_validation_error(exc, str(path), root)) from None
