"""Hostile YAML (issue 39): alias bombs, duplicate keys, other encodings, deep nesting and huge values are one-line
errors naming the file and the line, found before anything is expanded; no error quotes more than an excerpt."""

from __future__ import annotations

import codecs
import time
import tracemalloc

import pytest
import yaml
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from typer.testing import CliRunner

from planefuse.cli import app
from planefuse.config import ConfigError, example_yaml, load_config
from planefuse.io import load_yaml_model
from planefuse.io._manifest import RecordingManifest
from planefuse.io._yaml import MAX_ALIAS_EXPANSION, YamlFileError, excerpt, read_yaml


def _bomb(levels: int, key: str = "lol") -> str:
    """The "billion laughs" document: ``levels`` anchors, each a list of 10 aliases of the previous one
    (10^levels values once expanded)."""
    lines = [f"{key}0: &a0 [" + ", ".join(['"lol"'] * 10) + "]"]
    lines += [f"{key}{i}: &a{i} [" + ", ".join([f"*a{i - 1}"] * 10) + "]" for i in range(1, levels)]
    return "\n".join(lines) + "\n"


@pytest.mark.parametrize("levels", [6, 9])
def test_a_billion_laughs_configuration_is_refused_before_expanding(tmp_path, levels):
    p = tmp_path / "run.yaml"
    p.write_text(example_yaml() + _bomb(levels))
    tracemalloc.start()
    t0 = time.perf_counter()
    try:
        with pytest.raises(ConfigError, match="aliases expand the document by 1.23e\\+0[69] values") as info:
            load_config(p)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert time.perf_counter() - t0 < 30  # not a speed assertion: 10^9 values would take hours, not a bound
    assert peak < 20e6  # nothing was expanded (10^6 values would be ~50 MB of list references)
    (issue,) = info.value.issues
    assert issue.line == example_yaml().count("\n") + levels - 1  # the anchor repeated most (10 x 10^(levels-1))
    assert len(str(info.value)) < 400


def test_aliases_within_the_bound_are_read_as_plain_yaml(tmp_path):
    p = tmp_path / "a.yaml"
    p.write_text(_bomb(3))  # 10^3 values: a legitimate reuse of anchors
    data, _ = read_yaml(p)
    assert data == yaml.safe_load(_bomb(3)) and len(data["lol2"]) == 10 and data["lol2"][0][0][0] == "lol"
    assert 10**3 < MAX_ALIAS_EXPANSION < 10**5


def test_a_recursive_alias_is_refused(tmp_path):
    p = tmp_path / "a.yaml"
    p.write_text("x: 1\ny: &a [1, *a]\n")
    with pytest.raises(YamlFileError, match=r"a\.yaml:2: an alias refers to the value that holds it"):
        read_yaml(p)


def test_a_duplicate_key_names_the_file_the_key_and_both_lines(tmp_path):
    text = example_yaml()
    line = next(k for k, l in enumerate(text.splitlines()) if l.strip().startswith("cell_size_m:"))
    lines = text.splitlines()
    lines.insert(line + 1, lines[line].replace("0.1", "0.3"))
    p = tmp_path / "run.yaml"
    p.write_text("\n".join(lines) + "\n")
    err = pytest.raises(ConfigError, load_config, p).value
    (issue,) = err.issues
    assert issue.line == line + 2 and f"duplicate key 'cell_size_m' (first at line {line + 1})" in issue.message
    r = CliRunner().invoke(app, ["check", str(p)])
    assert r.exit_code == 2 and "duplicate key 'cell_size_m'" in r.output and "Traceback" not in r.output


def test_a_duplicate_key_in_a_flow_mapping_and_in_a_manifest_is_refused(tmp_path):
    p = tmp_path / "scene.yaml"
    p.write_text("{a: 1, b: 2, a: 3}\n")
    with pytest.raises(ValueError, match=r"scene\.yaml:1: duplicate key 'a' \(first at line 1\)"):
        load_yaml_model(p, RecordingManifest)


def test_a_merge_key_is_not_a_duplicate(tmp_path):
    p = tmp_path / "a.yaml"
    p.write_text("base: &b {x: 1, y: 2}\nc:\n  <<: *b\n  y: 3\n")
    assert read_yaml(p)[0]["c"] == {"x": 1, "y": 3}


@pytest.mark.parametrize("encoding", ["utf-8-sig", "utf-16", "utf-16-be", "utf-32"])
def test_a_configuration_with_a_byte_order_mark_is_read(tmp_path, encoding):
    text = example_yaml()
    raw = text.encode(encoding)
    if encoding == "utf-16-be":
        raw = codecs.BOM_UTF16_BE + raw
    p = tmp_path / "run.yaml"
    p.write_bytes(raw)
    assert load_config(p, resolve_paths=False) == load_config_text(tmp_path, text)


def load_config_text(tmp_path, text):
    q = tmp_path / "plain.yaml"
    q.write_text(text, encoding="utf-8")
    return load_config(q, resolve_paths=False)


@pytest.mark.parametrize("raw, match", [
    ("cell_size_m: 0.1\n".encode("utf-16-le"), "NUL character .*UTF-16 without a byte-order mark"),
    (b"planes:\n  cell_size_m: \xff\xfe\n", r"run\.yaml:2: <file>: not UTF-8 text: invalid byte 0xff"),
    (b"[" * 200_000 + b"]" * 200_000, "nested deeper than 100 levels"),
    (b"planes:\n  cell_size_m: " + b"9" * 5000 + b"\n", "cannot read a value: .*digits"),
])
def test_other_bytes_are_one_line_errors(tmp_path, raw, match):
    p = tmp_path / "run.yaml"
    p.write_bytes(raw)
    with pytest.raises(ConfigError, match=match) as info:
        load_config(p)
    assert len(info.value.issues) == 1 and len(str(info.value)) < 500
    r = CliRunner().invoke(app, ["check", str(p)])
    assert r.exit_code == 2 and r.exception is None or isinstance(r.exception, SystemExit)


def test_an_error_quotes_only_an_excerpt_of_a_huge_value(tmp_path):
    p = tmp_path / "run.yaml"
    text = example_yaml().replace("heights_m: [0.1, 0.5, 1.0, 1.5]", "heights_m: [" + ", ".join(["-1.0"] * 200_000)
                                  + "]")
    p.write_text(text)
    err = pytest.raises(ConfigError, load_config, p).value
    assert len(str(err)) < 1000 and "planes.heights_m" in str(err)
    p.write_text(example_yaml().replace("cell_size_m: 0.1", "cell_size_m: '" + "x" * 1_000_000 + "'"))
    err = pytest.raises(ConfigError, load_config, p).value
    assert len(str(err)) < 1000 and "1000002 characters" in str(err)


def test_excerpt_cuts_and_says_how_long():
    assert excerpt("abc") == "'abc'"
    assert excerpt("x" * 1000).endswith("... (1002 characters)") and len(excerpt("x" * 1000)) < 120
    assert "a list of 1000 items" in excerpt(list(range(1000)))


@given(st.integers(0, 10_000), st.binary(min_size=1, max_size=40))
@settings(max_examples=150, deadline=None, derandomize=True,
          suppress_health_check=[HealthCheck.function_scoped_fixture])
def test_any_bytes_spliced_into_a_configuration_give_a_configuration_or_a_config_error(tmp_path, at, junk):
    """Property: whatever bytes land anywhere in a configuration file, loading it gives a configuration or a
    ``ConfigError`` (one issue line per problem, an excerpt of any value) -- never another exception."""
    raw = example_yaml().encode()
    at = at % len(raw)
    p = tmp_path / "run.yaml"
    p.write_bytes(raw[:at] + junk + raw[at:])
    try:
        load_config(p, resolve_paths=False)
    except ConfigError as err:
        assert all(len(line) < 1200 for line in str(err).splitlines())


@pytest.mark.parametrize("kind", ["fifo", "device", "folder"])
def test_a_configuration_that_is_not_a_regular_file_is_refused_without_reading(tmp_path, kind):
    import os

    if kind == "fifo":
        p = tmp_path / "run.yaml"
        os.mkfifo(p)  # reading it would block forever
    elif kind == "device":
        p = tmp_path / "zero.yaml"
        p.symlink_to("/dev/zero")  # reading it would never end
    else:
        p = tmp_path / "dir.yaml"
        p.mkdir()
    with pytest.raises(ConfigError, match="not a regular file|cannot read the file"):
        load_config(p)
