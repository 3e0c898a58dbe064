"""Read YAML files safely and load them into pydantic models with errors that name the file, the field and the
line.

Every YAML file planefuse reads from a user (run configuration, recording manifest, scene) goes through
:func:`read_yaml`: PyYAML's safe loader (no Python objects), and before anything is built from the document

- its encoding: UTF-8 (with or without a byte-order mark), or UTF-16/UTF-32 with a byte-order mark, as the YAML
  specification allows; any other bytes are a one-line error naming the file and the line;
- its size: at most :data:`MAX_YAML_BYTES`, nested at most :data:`MAX_YAML_DEPTH` levels deep (checked on the
  parser's events, before libyaml's recursive composer could overflow the C stack);
- its aliases: a document whose aliases (``*name``) would add more than :data:`MAX_ALIAS_EXPANSION` values once
  expanded ("billion laughs": 9 levels of 10 aliases are 10^9 values from a few hundred bytes) or refer to
  themselves is refused from the composed node graph, which holds every anchored value once, so the refusal
  costs no more than the file's own size;
- its keys: a key given twice in one mapping is refused (YAML leaves it undefined; PyYAML keeps the last
  silently, e.g. a second ``cell_size_m`` replaced the first without a word).

Error messages quote at most :data:`EXCERPT_CHARS` characters of a value (:func:`excerpt`).
"""

from __future__ import annotations

import codecs
import os
import stat
from pathlib import Path
from typing import Any, TypeVar

import yaml
from pydantic import BaseModel, ValidationError

__all__ = ["load_yaml_model", "format_validation_error", "read_yaml", "parse_yaml", "YamlFileError", "excerpt", "shorten",
           "MAX_YAML_BYTES", "MAX_YAML_DEPTH", "MAX_ALIAS_EXPANSION", "EXCERPT_CHARS"]

M = TypeVar("M", bound=BaseModel)
#: libyaml's safe loader where PyYAML was built with it (the same data, about 10x faster than the pure-Python one)
_SAFE_LOADER = getattr(yaml, "CSafeLoader", yaml.SafeLoader)
#: Largest YAML file read [bytes] (a configuration or manifest is a few kB; a recording's manifest with many
#: sensors some 100 kB).
MAX_YAML_BYTES = 16 * 2**20
#: Most values (scalars, sequences, mappings) that aliases may add to a document once expanded. A configuration
#: that reuses a block with an anchor adds tens; the "billion laughs" document adds 10^9.
MAX_ALIAS_EXPANSION = 10_000
#: Most characters of a value quoted in an error message.
EXCERPT_CHARS = 80

_MERGE_TAG = "tag:yaml.org,2002:merge"


class YamlFileError(ValueError):
    """A YAML file that cannot be read: ``str(err)`` is ``FILE[:LINE]: problem`` (one line).

    Attributes
    ----------
    path : Path
    line : int or None
        1-based line of the problem, where known.
    problem : str
        What is wrong, without the file and line.
    """

    def __init__(self, path: Path | str, problem: str, line: int | None = None):
        self.path, self.problem, self.line = Path(path), problem, line
        super().__init__(f"{path}:{line}: {problem}" if line is not None else f"{path}: {problem}")


def excerpt(value: Any, limit: int = EXCERPT_CHARS) -> str:
    """``repr(value)``, cut to about ``limit`` characters with the total length said (never the whole of a huge
    value in an error message)."""
    if isinstance(value, (list, tuple, dict, set)) and len(value) > limit:
        kind = type(value).__name__
        head = repr(value[:8] if isinstance(value, (list, tuple)) else type(value)(list(value)[:8])
                    if isinstance(value, set) else dict(list(value.items())[:8]))
        return f"{head[:limit]}... (a {kind} of {len(value)} items)"
    return shorten(repr(value), limit)


def shorten(text: str, limit: int = EXCERPT_CHARS) -> str:
    """``text`` cut to ``limit`` characters, with its total length said where it was cut."""
    return text if len(text) <= limit else f"{text[:limit]}... ({len(text)} characters)"


def _decode(raw: bytes, path: Path) -> str:
    """The text of a YAML file: UTF-8 (a byte-order mark is dropped), or UTF-16/32 with a byte-order mark."""
    for bom, encoding in ((codecs.BOM_UTF32_LE, "utf-32"), (codecs.BOM_UTF32_BE, "utf-32"),
                          (codecs.BOM_UTF8, "utf-8-sig"), (codecs.BOM_UTF16_LE, "utf-16"),
                          (codecs.BOM_UTF16_BE, "utf-16")):
        if raw.startswith(bom):
            break
    else:
        encoding = "utf-8"
    try:
        text = raw.decode(encoding)
    except UnicodeDecodeError as err:
        line = raw[:err.start].count(b"\n") + 1 if encoding == "utf-8" else None
        hint = (" (it looks like UTF-16 without a byte-order mark)" if encoding == "utf-8" and b"\x00" in raw[:64]
                else "")
        raise YamlFileError(path, f"not {encoding.upper().removesuffix('-SIG')} text{hint}: invalid byte "
                            f"0x{raw[err.start]:02x} at offset {err.start}; save the file as UTF-8", line) from None
    if "\x00" in text:
        at = text.index("\x00")
        raise YamlFileError(path, f"not text: a NUL character at offset {at} (UTF-16 without a byte-order mark, or a "
                            "binary file?); save the file as UTF-8", text[:at].count("\n") + 1)
    return text


def _children(node: yaml.Node) -> list[yaml.Node]:
    if isinstance(node, yaml.SequenceNode):
        return list(node.value)
    if isinstance(node, yaml.MappingNode):
        return [n for pair in node.value for n in pair]
    return []


def _check_graph(root: yaml.Node, path: Path) -> None:
    """Refuse self-referring aliases, aliases expanding beyond :data:`MAX_ALIAS_EXPANSION` values and duplicate
    keys, walking the composed graph (each anchored node once) without recursion."""
    size: dict[int, int] = {}   # id(node) -> values in its expansion (itself included), once walked
    refs: dict[int, int] = {}   # id(node) -> times the document refers to it (> 1: aliased)
    nodes: dict[int, yaml.Node] = {}
    on_path: set[int] = set()   # the nodes being walked: meeting one again is a cycle
    stack: list[tuple[yaml.Node, bool]] = [(root, False)]
    while stack:
        node, leaving = stack.pop()
        key = id(node)
        if leaving:
            on_path.discard(key)
            size[key] = 1 + sum(size[id(c)] for c in _children(node))
            continue
        if key in size:
            refs[key] += 1
            continue
        if key in on_path:
            raise YamlFileError(path, "an alias refers to the value that holds it (a recursive document)",
                                node.start_mark.line + 1)
        refs[key], nodes[key] = 1, node
        if isinstance(node, yaml.MappingNode):
            _check_duplicate_keys(node, path)
        on_path.add(key)
        stack.append((node, True))
        stack.extend((c, False) for c in reversed(_children(node)))
    added = size[id(root)] - len(nodes)
    if added > MAX_ALIAS_EXPANSION:
        worst = nodes[max(refs, key=lambda k: (refs[k] - 1) * size[k])]
        line = worst.start_mark.line + 1
        raise YamlFileError(path, f"aliases expand the document by {added:.3g} values (at most "
                            f"{MAX_ALIAS_EXPANSION} allowed; the anchor at line {line}, {size[id(worst)]:.3g} "
                            f"values, appears {refs[id(worst)]} times): write the values out instead", line)


def _check_duplicate_keys(node: yaml.MappingNode, path: Path) -> None:
    seen: dict[tuple[str, str], int] = {}
    for k, _ in node.value:
        if not isinstance(k, yaml.ScalarNode) or k.tag == _MERGE_TAG:
            continue
        line = k.start_mark.line + 1
        if (k.tag, k.value) in seen:
            raise YamlFileError(path, f"duplicate key {excerpt(k.value)} (first at line {seen[(k.tag, k.value)]}): "
                                "YAML would keep one of them silently; remove the other", line)
        seen[(k.tag, k.value)] = line


def read_yaml(path: str | Path) -> tuple[Any, yaml.Node | None]:
    """Read a YAML file safely: its data (None for an empty document) and its composed root node (None then).

    Raises
    ------
    YamlFileError
        (a ``ValueError``) The file is missing or unreadable, larger than :data:`MAX_YAML_BYTES`, not UTF-8 (or
        UTF-16/32 with a byte-order mark), not YAML, nested too deeply, holds aliases expanding beyond
        :data:`MAX_ALIAS_EXPANSION` values or referring to themselves, or a duplicate key. One line, naming the
        file and, where known, the line.
    """
    path = Path(path)
    try:
        if not stat.S_ISREG(os.stat(path).st_mode):  # a FIFO would block the read forever, /dev/zero never end
            raise YamlFileError(path, "not a regular file")
        with open(path, "rb") as f:
            raw = f.read(MAX_YAML_BYTES + 1)
    except OSError as err:
        raise YamlFileError(path, f"cannot read the file ({err.strerror or err})") from None
    if len(raw) > MAX_YAML_BYTES:
        raise YamlFileError(path, f"larger than {MAX_YAML_BYTES / 2**20:g} MiB: not a planefuse YAML file")
    return parse_yaml(_decode(raw, path), path)


def parse_yaml(text: str, source: str | Path = "<text>") -> tuple[Any, yaml.Node | None]:
    """:func:`read_yaml` of a text already read (``source`` names it in errors)."""
    try:
        root = _compose(text, source)
        if root is None:
            return None, None
        _check_graph(root, Path(source))
        return _construct(root), root
    except yaml.YAMLError as err:
        mark = getattr(err, "problem_mark", None)
        problem = getattr(err, "problem", None) or str(err).splitlines()[0]
        raise YamlFileError(source, f"invalid YAML: {shorten(str(problem), 200)}",
                            mark.line + 1 if mark is not None else None) from None
    except YamlFileError:
        raise
    except (ValueError, TypeError, OverflowError) as err:  # a value the safe constructor cannot build (an int of
        # more than 4300 digits, a bad timestamp, ...)
        raise YamlFileError(source, f"cannot read a value: {shorten(str(err), 200)}") from None
    except RecursionError:
        raise YamlFileError(source, "nested too deeply to be read (hundreds of levels of lists or mappings)") \
            from None


#: Deepest nesting of lists and mappings read (a configuration nests 4 levels; libyaml's composer recurses in C and
#: overflows the stack at some 10^5 levels).
MAX_YAML_DEPTH = 100


def _check_depth(text: str, source: str | Path) -> None:
    """Refuse a document nested deeper than :data:`MAX_YAML_DEPTH`, from its event stream (the parser is iterative:
    no recursion, whatever the depth)."""
    depth = 0
    for event in yaml.parse(text, Loader=_SAFE_LOADER):
        if isinstance(event, (yaml.SequenceStartEvent, yaml.MappingStartEvent)):
            depth += 1
            if depth > MAX_YAML_DEPTH:
                raise YamlFileError(source, f"nested deeper than {MAX_YAML_DEPTH} levels of lists or mappings: not "
                                    "a planefuse YAML file", event.start_mark.line + 1)
        elif isinstance(event, (yaml.SequenceEndEvent, yaml.MappingEndEvent)):
            depth -= 1


def _compose(text: str, source: str | Path) -> yaml.Node | None:
    """The document's node graph, composed by libyaml where it can be; a document libyaml refuses is composed
    again by the pure-Python parser, whose error (problem and line) is the one reported."""
    if _SAFE_LOADER is not yaml.SafeLoader:
        try:
            _check_depth(text, source)
        except yaml.YAMLError:
            pass  # reported by the pure-Python parser below
        loader = _SAFE_LOADER(text)
        try:
            return loader.get_single_node()
        except yaml.YAMLError:
            pass
        finally:
            loader.dispose()
    else:
        _check_depth(text, source)
    loader = yaml.SafeLoader(text)
    try:
        return loader.get_single_node()
    finally:
        loader.dispose()


def _construct(root: yaml.Node) -> Any:
    """The Python data of a composed (and checked) document, built by the safe constructor (no Python objects)."""
    loader = yaml.SafeLoader("")
    try:
        return loader.construct_document(root)
    finally:
        loader.dispose()


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
    """One line per problem: ``source:LINE: field a.b.0.c: message`` (a value quoted by at most
    :data:`EXCERPT_CHARS` characters)."""
    lines = []
    for e in err.errors():
        loc = tuple(x for x in e["loc"] if not (isinstance(x, str) and x.startswith("function-")))
        line, parts = _locate(root, loc)
        field = ".".join(parts) or "<root>"
        where = f"{source}:{line}" if line is not None else source
        lines.append(f"{where}: field {field}: {shorten(e['msg'], 300)}")
    return "\n".join(lines)


def load_yaml_model(path: str | Path, model: type[M]) -> M:
    """Read ``path`` (YAML, :func:`read_yaml`) and validate it as ``model``.

    Raises
    ------
    ValueError
        If the file is missing, is not valid YAML (or is refused by :func:`read_yaml`), or does not validate; the
        message names the file, the line and the offending field.
    """
    path = Path(path)
    if not path.is_file():
        raise ValueError(f"{path}: file not found")
    data, root = read_yaml(path)
    if data is None:
        data = {}
    if not isinstance(data, dict):
        raise ValueError(f"{path}: expected a mapping at the top level, got {type(data).__name__}")
    try:
        return model.model_validate(data)
    except ValidationError as exc:
        raise ValueError(format_validation_error(exc, str(path), root)) from None


def _safe_load(text: str):
    """The data of a YAML text, checked as :func:`read_yaml` checks a file (libyaml where it can)."""
    return parse_yaml(text)[0]
