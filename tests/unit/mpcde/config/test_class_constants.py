"""A scenario holds what a researcher brings or sweeps; an algorithm's internal constants are class attributes.

The rule (docs/design.md section 7): a constant no file in data/ sets, no
sweep axis varies and no stack preset sets is a ``typing.ClassVar`` of its
settings class, not a field. The code reads it as before; the reader refuses
it as an unknown key; no range and no ``config.yaml`` holds it.
"""

from __future__ import annotations

import dataclasses
import typing

import pytest

from mpcde.config.io import to_dict
from mpcde.config.scenario import SCENARIO_RANGES, ScenarioConfig, scenario_from_dict
from mpcde.errors import ConfigError

MAX_LEAVES = 200
"""Issue 65's bound on the leaf fields of a scenario (272 when it was filed)."""


def _sections(obj: object, path: str = "") -> list[tuple[str, object]]:
    """(dotted path, instance) of every settings dataclass in the scenario tree, the root included."""
    out = [(path, obj)]
    for f in dataclasses.fields(obj):
        value = getattr(obj, f.name)
        if dataclasses.is_dataclass(value) and not isinstance(value, type):
            out += _sections(value, f"{path}.{f.name}" if path else f.name)
    return out


def _leaves(obj: object, path: str = "") -> list[str]:
    out = []
    for f in dataclasses.fields(obj):
        value, where = getattr(obj, f.name), f"{path}.{f.name}" if path else f.name
        out += _leaves(value, where) if dataclasses.is_dataclass(value) and not isinstance(value, type) else [where]
    return out


def _constants(cls: type) -> list[str]:
    """The lower-case ``ClassVar`` names of ``cls``: settings that are class constants (not ``LINE_SPEED_MPS``-style names)."""
    hints = typing.get_type_hints(cls)
    return sorted(n for n, tp in hints.items() if typing.get_origin(tp) is typing.ClassVar and n.islower())


SECTIONS = _sections(ScenarioConfig())
CONSTANTS = [(f"{path}.{name}", obj, name) for path, obj in SECTIONS if path for name in _constants(type(obj))]


def _mapping(path: str, value: object) -> dict:
    data: dict = {"name": "constants"}
    keys = path.split(".")
    d = data
    for k in keys[:-1]:
        d = d.setdefault(k, {})
    d[keys[-1]] = value
    return data


def test_a_scenario_has_at_most_200_leaf_fields():
    leaves = _leaves(ScenarioConfig())
    assert len(leaves) <= MAX_LEAVES, f"{len(leaves)} leaf fields"
    assert len(CONSTANTS) >= 60  # the pruning's constants are found, so the count above means something


@pytest.mark.parametrize(("path", "obj", "name"), CONSTANTS, ids=[c[0] for c in CONSTANTS])
def test_a_constant_is_read_as_before_and_refused_as_a_scenario_key(path, obj, name):
    value = getattr(obj, name)
    assert value == getattr(type(obj), name)  # the code's cfg.name read is the class's value
    assert name not in {f.name for f in dataclasses.fields(obj)}
    written = to_dict(value) if dataclasses.is_dataclass(value) else value
    with pytest.raises(ConfigError, match="unknown key") as info:
        scenario_from_dict(_mapping(path, written))  # even at its own value
    assert info.value.field == path and "\n" not in str(info.value)


def test_the_resolved_config_file_holds_no_constant():
    written = to_dict(ScenarioConfig())
    for path, _, _ in CONSTANTS:
        node = written
        *head, last = path.split(".")
        for k in head:
            node = node[k]
        assert last not in node, path


def test_every_range_names_a_field_of_its_class():
    stale = [
        f"{cls.__name__}.{name}"
        for cls, table in SCENARIO_RANGES.items()
        for name in table
        if name not in {f.name for f in dataclasses.fields(cls)}
    ]
    assert not stale, f"ranges of names that are not fields (constants have no range): {stale}"
