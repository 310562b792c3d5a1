"""Typed, validated construction of frozen config dataclasses from plain dicts.

The one place where YAML becomes config. Each dataclass field's type is
checked (bool, int, float, str, tuples of numbers, nested dataclasses,
``Literal`` choices); unknown keys are rejected; the dataclass's own
``__post_init__`` checks ranges. Every failure is a :class:`ConfigError` whose
one-line message names the dotted field path, the value and what is allowed.
"""

from __future__ import annotations

import dataclasses
import math
import types
import typing
from pathlib import Path
from typing import Any, get_args, get_origin

import yaml

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


def _convert(value: Any, tp: Any, path: str) -> Any:
    origin = get_origin(tp)
    if origin in _UNIONS:
        for arg in get_args(tp):
            try:
                return _convert(value, arg, path)
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
            return tuple(_convert(v, args[0], f"{path}[{i}]") for i, v in enumerate(value))
        if len(value) != len(args):
            raise ConfigError(path, value, f"must be {_type_name(tp)}")
        return tuple(_convert(v, a, f"{path}[{i}]") for i, (v, a) in enumerate(zip(value, args)))
    if dataclasses.is_dataclass(tp):
        return from_dict(tp, value, path)
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
            if math.isnan(float(value)):
                raise ConfigError(path, value, "must be a number, not NaN")
            return float(value)
        raise ConfigError(path, value, "must be a number")
    if tp is str:
        if isinstance(value, str):
            return value
        raise ConfigError(path, value, "must be a string")
    return value


def from_dict(cls: type, data: Any, path: str = "") -> Any:
    """Build dataclass ``cls`` from mapping ``data``; ``path`` prefixes field names in errors."""
    where = path or cls.__name__
    if data is None:
        data = {}
    if not isinstance(data, dict):
        raise ConfigError(where, data, "must be a mapping of fields")
    hints = typing.get_type_hints(cls)
    fields = {f.name: f for f in dataclasses.fields(cls) if f.init}
    unknown = sorted(set(data) - set(fields))
    if unknown:
        key = unknown[0]
        name = f"{path}.{key}" if path else key
        raise ConfigError(name, data[key], f"unknown key; allowed keys: {', '.join(sorted(fields))}")
    kwargs = {}
    for name, value in data.items():
        full = f"{path}.{name}" if path else name
        kwargs[name] = _convert(value, hints[name], full)
    try:
        return cls(**kwargs)
    except ConfigError as e:  # every settings class checks its fields with sim.checks
        raise e.under(path) from None


def to_dict(obj: Any) -> Any:
    """Plain-data (YAML/JSON-ready) form of a config dataclass tree."""
    if dataclasses.is_dataclass(obj):
        return {f.name: to_dict(getattr(obj, f.name)) for f in dataclasses.fields(obj)}
    if isinstance(obj, (list, tuple)):
        return [to_dict(v) for v in obj]
    if isinstance(obj, float) and math.isinf(obj):
        return "inf" if obj > 0 else "-inf"
    return obj


def load_yaml(path: Path) -> Any:
    """Parse a YAML file; unreadable or malformed files raise :class:`ConfigError`."""
    try:
        text = Path(path).read_text()
    except OSError as e:
        raise ConfigError("scenario", str(path), f"cannot read file ({e.strerror})") from None
    try:
        return yaml.safe_load(text)
    except yaml.YAMLError as e:
        mark = getattr(e, "problem_mark", None)
        where = f" at line {mark.line + 1}" if mark else ""
        raise ConfigError("scenario", str(path), f"not valid YAML{where}") from None
