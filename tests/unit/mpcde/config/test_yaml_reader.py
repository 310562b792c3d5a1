"""The strict YAML reader: YAML 1.2 core scalars, and one named refusal for every YAML 1.1 surprise and structural abuse."""

from __future__ import annotations

import math
import os

import pytest

from mpcde.config.yaml_reader import MAX_ALIASES, MAX_BYTES, MAX_DEPTH, parse_yaml, read_yaml
from mpcde.errors import ConfigError


def test_plain_scalars_resolve_as_the_yaml_1_2_core_schema():
    doc = parse_yaml("a: [1, -2, +3, 2.5, 1e3, .5, 1., 0x1f, 0o17, .inf, -.inf, true, False, ~, null, '017', text]")
    a = doc["a"]
    assert a[:9] == [1, -2, 3, 2.5, 1000.0, 0.5, 1.0, 31, 15]
    assert a[9] == math.inf and a[10] == -math.inf
    assert a[11:] == [True, False, None, None, "017", "text"]
    assert math.isnan(parse_yaml("x: .nan")["x"])
    assert parse_yaml("") is None and parse_yaml("# a comment only\n") is None


@pytest.mark.parametrize(
    "text, field, words",
    [
        ("seed: 017", "seed", "octal"),
        ("world:\n  obstacles:\n    - {kind: tree, height_m: 017}", "world.obstacles[0].height_m", "octal"),
        ("duration_s: 1:30", "duration_s", "base-60"),
        ("name: 2020-13-45", "name", "date"),
        ("name: 2020-01-02 10:00:00", "name", "date"),
        ("run:\n  cameras: yes", "run.cameras", "true/false"),
        ("run:\n  cameras: off", "run.cameras", "true/false"),
        ("seed: 1_000", "seed", "number"),
        ("seed: 0b101", "seed", "number"),
        ("seed: " + "9" * 30, "seed", "digits"),
        ("seed: !!int 1.5", "seed", "tags"),
        ("run: !!map {cameras: true}", "run", "tags"),
        ("run: {cameras: !!bool maybe}", "run.cameras", "tags"),
        ("name: a\nname: b", "name", "duplicate"),
        ("world:\n  box_fraction: 0.1\n  box_fraction: 0.2", "world.box_fraction", "duplicate"),
        ("1: x", "1", "string"),
        ("world:\n  true: 1", "world.true", "string"),
        ("world:\n  ? [1, 2]\n  : 3", "world", "string"),
        ("name: a\n---\nname: b", "scenario", "one YAML document"),
        ("name: [unclosed", "scenario", "not valid YAML at line"),
    ],
)
def test_each_surprise_is_refused_in_one_line_naming_the_field(text, field, words):
    with pytest.raises(ConfigError) as e:
        parse_yaml(text)
    msg = str(e.value)
    assert e.value.field == field and words in msg and "\n" not in msg, msg


def test_nesting_deeper_than_the_limit_is_refused_without_recursion():
    with pytest.raises(ConfigError, match=f"at most {MAX_DEPTH} levels"):
        parse_yaml("a: " + "[" * 100_000 + "]" * 100_000)  # a recursive reader would hit Python's recursion limit
    assert parse_yaml("a: " + "[" * (MAX_DEPTH - 1) + "]" * (MAX_DEPTH - 1)) is not None


def test_alias_bombs_are_refused_before_they_expand():
    lines = ["a0: &a0 [x, x, x, x, x, x, x, x, x]"]
    for i in range(1, 9):  # 9^9 values once expanded
        lines.append(f"a{i}: &a{i} [" + ", ".join([f"*a{i - 1}"] * 9) + "]")
    with pytest.raises(ConfigError, match="values in one file"):
        parse_yaml("\n".join(lines))
    many = "a: &a 1\nb: [" + ", ".join(["*a"] * (MAX_ALIASES + 1)) + "]"
    with pytest.raises(ConfigError, match="aliases"):
        parse_yaml(many)
    assert parse_yaml("a: &a {x: 1}\nb: *a") == {"a": {"x": 1}, "b": {"x": 1}}  # a few aliases are fine


def test_files_that_are_not_small_utf8_regular_files_are_refused(tmp_path):
    big = tmp_path / "big.yaml"
    big.write_text("name: " + "x" * (MAX_BYTES + 10))
    latin = tmp_path / "latin.yaml"
    latin.write_bytes("name: caf\xe9\n".encode("latin-1"))
    fifo = tmp_path / "fifo.yaml"
    os.mkfifo(fifo)  # opening it for reading would block: it must never be opened
    cases = {big: "larger than", latin: "not UTF-8 text (byte 0xe9 at offset 9)", fifo: "not a regular file", tmp_path: "not a regular file"}
    for path, words in cases.items():
        with pytest.raises(ConfigError, match="^scenario=") as e:
            read_yaml(path)
        assert words in str(e.value), str(e.value)
    with pytest.raises(ConfigError, match="not a regular file"):
        read_yaml("/dev/zero")


def test_control_characters_in_keys_and_values_are_escaped_in_the_message():
    with pytest.raises(ConfigError) as e:
        parse_yaml('world:\n  "bad\\nkey\\e[31m": 1\n  "bad\\nkey\\e[31m": 2')
    msg = str(e.value)
    assert msg.isprintable() and "\\n" in msg and "\\x1b" in msg, msg
