"""Typed, validated construction of frozen config dataclasses from plain dicts.

The one place where YAML becomes config. The file is read by the strict
reader (:mod:`mpcde.config.yaml_reader`); each dataclass field's type is
checked (bool, int, float, str, tuples of numbers, nested dataclasses,
``Literal`` choices); unknown keys are rejected; with ``ranges`` every number
is checked against its physical range (:mod:`mpcde.config.bounds`) before its
class is built, and the dataclass's own ``__post_init__`` checks consistency.
Every failure is a :class:`ConfigError` whose one-line message names the
dotted field path, the value and what is allowed.
"""

from __future__ import annotations

import dataclasses
import math
import types
import typing
from pathlib import Path
from typing import Any, get_args, get_origin

from mpcde.config.bounds import Ranges, check_value
from mpcde.config.yaml_reader import read_yaml
from mpcde.errors import ConfigError

__all__ = ["from_dict", "load_yaml", "to_dict"]

_UNIONS = (typing.Union, types.UnionType)  # Optional[X] / Union[X, Y] and the PEP 604 spelling X | None


def _type_name(tp: Any) -> str:
    origin = get_origin(tp)
    if origin is typing.Literal:
        return "one of " + ", ".join(repr(a) for a in get_args(tp))
    if origin is tuple:
        args = get_args(tp)
        if len(args) == 2 and args[1] is Ellipsis:
            return f"a list of {_type_name(args[0])}"
        return f"a list of {len(args)} ({', '.join(_type_name(a) for a in args)})"
    if origin in _UNIONS:
        return " or ".join(_type_name(a) for a in get_args(tp))
    if dataclasses.is_dataclass(tp):
        return "a mapping"
    return {bool: "true/false", int: "an integer", float: "a number", str: "a string", type(None): "null"}.get(tp, str(tp))


def _convert(value: Any, tp: Any, path: str, ranges: Ranges | None = None) -> Any:
    origin = get_origin(tp)
    if origin in _UNIONS:
        for arg in get_args(tp):
            try:
                return _convert(value, arg, path, ranges)
            except ConfigError:
                continue
        raise ConfigError(path, value, f"must be {_type_name(tp)}")
    if origin is typing.Literal:
        if value in get_args(tp):
            return value
        raise ConfigError(path, value, f"allowed: {', '.join(repr(a) for a in get_args(tp))}")
    if origin is tuple:
        if not isinstance(value, (list, tuple)):
            raise ConfigError(path, value, f"must be {_type_name(tp)}")
        args = get_args(tp)
        if len(args) == 2 and args[1] is Ellipsis:
            return tuple(_convert(v, args[0], f"{path}[{i}]", ranges) for i, v in enumerate(value))
        if len(value) != len(args):
            raise ConfigError(path, value, f"must be {_type_name(tp)}")
        return tuple(_convert(v, a, f"{path}[{i}]", ranges) for i, (v, a) in enumerate(zip(value, args)))
    if dataclasses.is_dataclass(tp):
        return from_dict(tp, value, path, ranges)
    if tp is type(None):
        if value is None:
            return None
        raise ConfigError(path, value, "must be null")
    if tp is bool:
        if isinstance(value, bool):
            return value
        raise ConfigError(path, value, "must be true or false")
    if tp is int:
        if isinstance(value, int) and not isinstance(value, bool):
            return value
        raise ConfigError(path, value, "must be an integer")
    if tp is float:
        if isinstance(value, str) and value.strip().lower() in ("inf", ".inf", "infinity"):
            return math.inf
        if isinstance(value, (int, float)) and not isinstance(value, bool):
            try:
                number = float(value)
            except OverflowError:  # an integer past the float range
                raise ConfigError(path, value, "must be a number within the float range") from None
            if math.isnan(number):
                raise ConfigError(path, value, "must be a number, not NaN")
            return number
        raise ConfigError(path, value, "must be a number")
    if tp is str:
        if isinstance(value, str):
            return value
        raise ConfigError(path, value, "must be a string")
    return value


def from_dict(cls: type, data: Any, path: str = "", ranges: Ranges | None = None) -> Any:
    """Build dataclass ``cls`` from mapping ``data``; ``path`` prefixes field names in errors.

    With ``ranges`` (:data:`mpcde.config.scenario.SCENARIO_RANGES`), every
    number of every field is checked against its range before ``cls`` is built.
    """
    where = path or cls.__name__
    if data is None:
        data = {}
    if not isinstance(data, dict):
        raise ConfigError(where, data, "must be a mapping of fields")
    hints = typing.get_type_hints(cls)
    fields = {f.name: f for f in dataclasses.fields(cls) if f.init and "sections" not in f.metadata}
    # a field with metadata "sections" (a callable: name -> (dataclass, ranges)) gathers the mapping's extra
    # sections, each read as its dataclass (the scenario's third-party stacks, mpcde.config.scenario.PluginSections)
    gathered = {f.name: f.metadata["sections"]() for f in dataclasses.fields(cls) if f.init and "sections" in f.metadata}
    extra = {key for kinds in gathered.values() for key in kinds}
    unknown = sorted(set(data) - set(fields) - extra, key=str)
    if unknown:
        key = unknown[0]
        name = f"{path}.{key}" if path else key
        raise ConfigError(name, data[key], f"unknown key; allowed keys: {', '.join(sorted(set(fields) | extra))}")
    kwargs = {
        name: _convert(value, hints[name], f"{path}.{name}" if path else name, ranges) for name, value in data.items() if name in fields
    }
    for name, kinds in gathered.items():
        kwargs[name] = {
            key: from_dict(tp, data[key], f"{path}.{key}" if path else key, {**(ranges or {}), **own})
            for key, (tp, own) in kinds.items() if key in data
        }  # fmt: skip
    out_of_range: list[ConfigError] = []
    for name, value in kwargs.items():
        try:
            check_value(name, value, (ranges or {}).get(cls, {}).get(name))
        except ConfigError as e:
            out_of_range.append(e)
    try:
        built = cls(**kwargs)
    except ConfigError as e:  # every settings class checks its fields with sim.checks
        blamed = e.field.split(".")[0].split("[")[0]
        if out_of_range and all(blamed != r.field.split("[")[0] for r in out_of_range):
            raise out_of_range[0].under(path) from None  # the class blamed a sibling of the value out of range
        raise e.under(path) from None
    except (ArithmeticError, ValueError, TypeError, MemoryError) as e:  # an extreme value a check computed with
        if out_of_range:
            raise out_of_range[0].under(path) from None
        raise ConfigError(path or cls.__name__, "...", f"refused by its checks ({type(e).__name__})") from None
    if out_of_range:
        raise out_of_range[0].under(path) from None
    return built


def to_dict(obj: Any) -> Any:
    """Plain-data (YAML/JSON-ready) form of a config dataclass tree."""
    if dataclasses.is_dataclass(obj):
        out = {f.name: to_dict(getattr(obj, f.name)) for f in dataclasses.fields(obj) if "sections" not in f.metadata}
        for f in dataclasses.fields(obj):  # gathered sections (from_dict) are the mapping's own top-level keys again
            if "sections" in f.metadata:
                out.update({key: to_dict(value) for key, value in getattr(obj, f.name).items()})
        return out
    if isinstance(obj, (list, tuple)):
        return [to_dict(v) for v in obj]
    if isinstance(obj, float) and math.isinf(obj):
        return "inf" if obj > 0 else "-inf"
    return obj


def load_yaml(path: Path) -> Any:
    """Parse a YAML file strictly (:func:`mpcde.config.yaml_reader.read_yaml`); refusals raise :class:`ConfigError`."""
    return read_yaml(path)
