"""Every number a scenario holds has a physical range, checked at load time with its whole path."""

from __future__ import annotations

import dataclasses
import math
import typing

import pytest

from mpcde.config.bounds import Bound, check_ranges
from mpcde.config.resolve import resolve
from mpcde.config.scenario import SCENARIO_RANGES, ObstacleEntry, ScenarioConfig, load_scenario
from mpcde.errors import ConfigError


def _numeric_leaves(cls: type, obj: object, path: str = "") -> list[tuple[str, type, str, type]]:
    """(path, owning class, field name, type) of every int/float field, or tuple of them, below ``cls``."""
    out = []
    hints = typing.get_type_hints(cls)
    for f in dataclasses.fields(cls):
        value, tp = getattr(obj, f.name), hints[f.name]
        where = f"{path}.{f.name}" if path else f.name
        if dataclasses.is_dataclass(value) and not isinstance(value, type):
            out += _numeric_leaves(type(value), value, where)
        elif tp in (int, float) or (typing.get_origin(tp) is tuple and {int, float} & set(_flat_args(tp))):
            out.append((where, cls, f.name, tp))
    return out


def _flat_args(tp: object) -> list[object]:
    args = []
    for a in typing.get_args(tp):
        args += _flat_args(a) if typing.get_args(a) else [a]
    return args


LEAVES = _numeric_leaves(ScenarioConfig, ScenarioConfig()) + [
    (f"world.obstacles[0].{n}", ObstacleEntry, n, t) for p, _, n, t in _numeric_leaves(ObstacleEntry, ObstacleEntry())
]


def test_every_number_of_the_scenario_tree_has_a_range():
    missing = [path for path, cls, name, _ in LEAVES if name not in SCENARIO_RANGES.get(cls, {})]
    assert not missing, f"numeric fields with no range in mpcde/config/ranges.py or SCENARIO_RANGES: {missing}"
    assert len(LEAVES) > 150  # the walk reaches the whole tree (its constants are class attributes, not fields)


def test_the_defaults_lie_inside_their_ranges():
    check_ranges(ScenarioConfig(), SCENARIO_RANGES)
    check_ranges(ObstacleEntry(), SCENARIO_RANGES)


def _override(path: str, value: object) -> dict:
    if path.startswith("world.obstacles[0]."):
        return {"world": {"obstacles": [{"kind": "tree", path.rsplit(".", 1)[1]: value}]}}
    keys = path.split(".")
    d: dict = {keys[-1]: value}
    for k in reversed(keys[:-1]):
        d = {k: d}
    return d


def _merge(base: dict, extra: dict) -> dict:
    out = dict(base)
    for k, v in extra.items():
        out[k] = _merge(out[k], v) if isinstance(v, dict) and isinstance(out.get(k), dict) else v
    return out


@pytest.mark.parametrize("path, cls, name, tp", LEAVES, ids=[leaf[0] for leaf in LEAVES])
def test_extreme_values_are_refused_naming_the_whole_path(path, cls, name, tp):
    default = getattr(cls(), name)
    extremes = [1e300, -1e300, math.inf, -math.inf, 2**64] if tp in (int, float) else []
    if isinstance(default, tuple):  # a tuple field: one extreme element
        flat = default[0] if default and isinstance(default[0], tuple) else default
        extremes = [[1e300] * len(flat)] if flat else [[1e300]]
        if default and isinstance(default[0], tuple):
            extremes = [[e] + [list(p) for p in default[1:]] for e in extremes]
    bound = SCENARIO_RANGES[cls][name]
    for value in extremes:
        if bound.inf and value == math.inf:
            continue
        with pytest.raises(ConfigError) as e:
            load_scenario("crossing", _override(path, value))
        msg = str(e.value)
        assert e.value.field.startswith(path) and "\n" not in msg, msg


def test_a_config_built_in_code_meets_the_same_ranges():
    cfg = ScenarioConfig()
    bad = dataclasses.replace(cfg, camera=dataclasses.replace(cfg.camera, rate_hz=1e9))
    with pytest.raises(ConfigError, match=r"^camera\.rate_hz=1000000000\.0: a finite number in \[0\.5, 120\] Hz$"):
        resolve(bad)


def test_a_bound_with_an_infinite_meaning_says_it():
    b = Bound(0, 10, "m", inf="no range limit")
    assert b.allowed(False) == "a finite number in [0, 10] m (or inf: no range limit)"
    assert load_scenario("crossing", {"radio": {"range_m": ".inf"}}).radio.range_m == math.inf
    with pytest.raises(ConfigError, match=r"^radio\.range_m=-inf"):
        load_scenario("crossing", {"radio": {"range_m": -math.inf}})


def test_a_setting_its_choice_would_ignore_is_refused(tmp_path):
    cases = {
        "drones: {count: 6}\n": "drones.count",
        "drones: {layout: mirror, count: 3, starts: [[0.0, 0.0, 1.5]]}\n": "drones.starts",
        "drones: {layout: antipodal}\nworld:\n  obstacles: [{center_xy: [3.0, 3.0], yaw: 0.3}]\n": "world.obstacles[0].yaw",
        "drones: {layout: antipodal}\nworld:\n  obstacles: [{kind: box, center_xy: [3.0, 3.0], radius_m: 0.4}]\n": "world.obstacles[0].radius_m",
        "drones: {layout: antipodal}\ndenied: {active_yaw: false, yaw: {tracking_sweep_deg: 10}}\n": "denied.yaw.tracking_sweep_deg",
    }
    for text, field in cases.items():
        path = tmp_path / "s.yaml"
        path.write_text(text)
        with pytest.raises(ConfigError) as e:
            load_scenario(path)
        assert e.value.field == field, str(e.value)
    path.write_text("drones: {layout: antipodal, count: 3}\ndenied: {active_yaw: false, yaw: {tracking_sweep_deg: 60}}\n")
    assert load_scenario(path).drones.count == 3  # a field at its default is no choice ignored
