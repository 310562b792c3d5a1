"""A strict YAML reader for scenario files: one document of plain data, read as YAML 1.2's core schema.

PyYAML's ``safe_load`` reads YAML 1.1, where ``017`` is 15, ``1:30`` is 90,
``no`` is false and ``2020-01-02`` a date, silently takes the last of two equal
keys, honours explicit tags (``!!int 1.5`` raises inside PyYAML), expands
alias bombs, recurses without limit and reads any file it is given (a FIFO or
``/dev/zero`` blocks it). A scenario file is small hand-written data, so this
reader refuses, each with one line naming the field (:class:`ConfigError`):

* a path that is not a regular file, a file over :data:`MAX_BYTES`, bytes that
  are not UTF-8;
* more than one document, an explicit tag, more than :data:`MAX_ALIASES`
  aliases or :data:`MAX_NODES` values once aliases are expanded, nesting
  deeper than :data:`MAX_DEPTH`;
* a key that is not a string, a duplicate key;
* a plain scalar that YAML 1.1 and 1.2 read differently: a leading-zero
  integer (1.1: octal), base-60 numbers (``1:30``), ``yes``/``no``/``on``/``off``,
  a date or time, digits with underscores or a ``0b`` prefix; and integers of
  more than :data:`MAX_DIGITS` digits.

Plain scalars resolve as in YAML 1.2's core schema: ``null``/``~``/empty,
``true``/``false``, decimal, ``0o`` and ``0x`` integers, floats (``1e3`` too),
``.inf`` and ``.nan``; everything else, and every quoted scalar, is a string.
The document is read from PyYAML's event stream, which is iterative, so no
input can exhaust Python's recursion limit.
"""

from __future__ import annotations

import os
import re
import stat
from pathlib import Path
from typing import Any

import yaml
from yaml import events as ev

from sim.checks import ConfigError

__all__ = ["MAX_ALIASES", "MAX_BYTES", "MAX_DEPTH", "MAX_DIGITS", "MAX_NODES", "read_yaml", "parse_yaml"]

MAX_BYTES = 1 << 20
"""Largest scenario file read [bytes]."""
MAX_DEPTH = 32
"""Deepest nesting of mappings and sequences."""
MAX_ALIASES = 64
"""Most aliases (``*name``) in a document."""
MAX_NODES = 200_000
"""Most values in a document once aliases are expanded."""
MAX_DIGITS = 24
"""Longest integer read [digits]."""

_NULL = re.compile(r"^(?:~|null|Null|NULL|)$")
_BOOL = {"true": True, "True": True, "TRUE": True, "false": False, "False": False, "FALSE": False}
_BOOL_11 = re.compile(r"^(?:yes|Yes|YES|no|No|NO|on|On|ON|off|Off|OFF|y|Y|n|N)$")
_INT = re.compile(r"^[-+]?[0-9]+$")
_INT_OCT = re.compile(r"^0o[0-7]+$")
_INT_HEX = re.compile(r"^0x[0-9a-fA-F]+$")
_FLOAT = re.compile(r"^[-+]?(?:\.[0-9]+|[0-9]+(?:\.[0-9]*)?)(?:[eE][-+]?[0-9]+)?$")
_INF = re.compile(r"^[-+]?\.(?:inf|Inf|INF)$")
_NAN = re.compile(r"^\.(?:nan|NaN|NAN)$")
_SEXAGESIMAL = re.compile(r"^[-+]?[0-9][0-9_]*(?::[0-5]?[0-9])+(?:\.[0-9_]*)?$")
_DATE = re.compile(r"^[0-9]{4}-[0-9]{1,2}-[0-9]{1,2}(?:[Tt ]|$)")
_UNDERSCORE_OR_BINARY = re.compile(r"^[-+]?(?:0b[01_]+|[0-9][0-9_]*_[0-9_]*(?:\.[0-9_]*)?)$")


def read_yaml(path: str | Path, field: str = "scenario") -> Any:
    """Read and parse the YAML file ``path``; every refusal is a :class:`ConfigError` naming ``field`` or a field inside."""
    p = Path(path)
    try:
        st = os.stat(p)
    except OSError as e:
        raise ConfigError(field, str(p), f"cannot read file ({e.strerror})") from None
    if not stat.S_ISREG(st.st_mode):
        raise ConfigError(field, str(p), "not a regular file (a folder, FIFO or device cannot be a scenario)")
    if st.st_size > MAX_BYTES:
        raise ConfigError(field, str(p), f"larger than {MAX_BYTES // 1024} KiB ({st.st_size} bytes)")
    try:
        with open(p, "rb") as f:
            data = f.read(MAX_BYTES + 1)
    except OSError as e:
        raise ConfigError(field, str(p), f"cannot read file ({e.strerror})") from None
    if len(data) > MAX_BYTES:
        raise ConfigError(field, str(p), f"larger than {MAX_BYTES // 1024} KiB")
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError as e:
        raise ConfigError(field, str(p), f"not UTF-8 text (byte 0x{data[e.start]:02x} at offset {e.start})") from None
    return parse_yaml(text, str(p), field)


def parse_yaml(text: str, source: str = "<string>", field: str = "scenario") -> Any:
    """Parse one YAML document ``text`` (from ``source``) into dicts, lists and scalars; None for an empty document."""
    reader = _Reader(source, field)
    try:
        for event in yaml.parse(text, Loader=yaml.SafeLoader):
            reader.feed(event)
    except yaml.YAMLError as e:
        mark = getattr(e, "problem_mark", None)
        where = f" at line {mark.line + 1}, column {mark.column + 1}" if mark else ""
        problem = getattr(e, "problem", None) or type(e).__name__
        raise ConfigError(field, source, f"not valid YAML{where}: {problem}") from None
    return reader.result


class _Reader:
    """Builds the document from parser events with a stack of open containers, checking every rule on the way."""

    def __init__(self, source: str, field: str) -> None:
        self.source, self.field = source, field
        self.stack: list[list[Any]] = []  # [container, path, pending key (mappings)]
        self.anchors: dict[str, tuple[Any, int]] = {}
        self.open_anchors: list[str | None] = []
        self.documents = 0
        self.aliases = 0
        self.nodes = 0
        self.result: Any = None

    def _path(self) -> str:
        if not self.stack:
            return self.field
        container, path, key = self.stack[-1]
        if isinstance(container, dict):
            if key is None:
                return path or self.field
            return f"{path}.{key}" if path else str(key)
        return f"{path}[{len(container)}]"

    def _refuse(self, value: Any, allowed: str, path: str | None = None) -> None:
        raise ConfigError(path or self._path(), value, allowed)

    def _count(self, n: int) -> None:
        self.nodes += n
        if self.nodes > MAX_NODES:
            self._refuse("...", f"more than {MAX_NODES} values in one file (alias expansion?)", self.field)

    def feed(self, event: ev.Event) -> None:
        if isinstance(event, ev.DocumentStartEvent):
            self.documents += 1
            if self.documents > 1:
                self._refuse(self.source, "one YAML document (found a second '---')", self.field)
            return
        if isinstance(event, (ev.StreamStartEvent, ev.StreamEndEvent, ev.DocumentEndEvent)):
            return
        if isinstance(event, ev.AliasEvent):
            self.aliases += 1
            if self.aliases > MAX_ALIASES:
                self._refuse(f"*{event.anchor}", f"at most {MAX_ALIASES} aliases in one file")
            if event.anchor not in self.anchors:
                self._refuse(f"*{event.anchor}", "an alias of an anchor defined before it")
            value, size = self.anchors[event.anchor]
            self._count(size)
            self._add(_copy(value))
            return
        if isinstance(event, (ev.ScalarEvent, ev.MappingStartEvent, ev.SequenceStartEvent)):
            if event.tag is not None and event.tag != "!":
                self._refuse(event.tag, "no explicit YAML tags (write the plain value)")
        if isinstance(event, ev.ScalarEvent):
            self._count(1)
            at_key = bool(self.stack) and isinstance(self.stack[-1][0], dict) and self.stack[-1][2] is None
            value = self._key(event) if at_key else self._scalar(event)
            if event.anchor:
                self.anchors[event.anchor] = (value, 1)
            self._add(value)
            return
        if isinstance(event, (ev.MappingStartEvent, ev.SequenceStartEvent)):
            if len(self.stack) >= MAX_DEPTH:
                self._refuse("...", f"nesting at most {MAX_DEPTH} levels deep")
            if self.stack and isinstance(self.stack[-1][0], dict) and self.stack[-1][2] is None:
                self._refuse("{...}" if isinstance(event, ev.MappingStartEvent) else "[...]", "a key must be a plain string")
            self._count(1)
            path = self._path() if self.stack else ""
            container: Any = {} if isinstance(event, ev.MappingStartEvent) else []
            self.stack.append([container, path, None])
            self.open_anchors.append(event.anchor)
            return
        if isinstance(event, (ev.MappingEndEvent, ev.SequenceEndEvent)):
            container, _, _ = self.stack.pop()
            anchor = self.open_anchors.pop()
            if anchor:
                self.anchors[anchor] = (container, _size(container))
            self._add(container)

    def _add(self, value: Any) -> None:
        if not self.stack:
            self.result = value
            return
        top = self.stack[-1]
        container, path, key = top
        if isinstance(container, list):
            container.append(value)
        elif key is None:  # a key
            if not isinstance(value, str):
                self._refuse(value, "a key must be a string (quote it)", f"{path}.{value!r}" if path else repr(value))
            if value in container:
                self._refuse(value, "a duplicate key (each field once)", f"{path}.{value}" if path else value)
            top[2] = value
        else:
            container[key] = value
            top[2] = None

    def _key(self, event: ev.ScalarEvent) -> str:
        """A mapping key: its text; a plain key that reads as null, true/false or a number is refused."""
        text = event.value
        if event.style is None and event.implicit[0]:
            if _NULL.match(text) or text in _BOOL or _INT.match(text) or _FLOAT.match(text) or _INF.match(text) or _NAN.match(text):
                path = self.stack[-1][1]
                self._refuse(text, "a key must be a string (quote it)", f"{path}.{text}" if path else text)
        return text

    def _scalar(self, event: ev.ScalarEvent) -> Any:
        text = event.value
        if event.style is not None or not event.implicit[0]:
            return text  # quoted (or block) scalar: a string
        if _NULL.match(text):
            return None
        if text in _BOOL:
            return _BOOL[text]
        if _BOOL_11.match(text):
            self._refuse(text, "YAML 1.1 reads this word as true/false: write true or false, or quote it for text")
        if _INT.match(text):
            digits = text.lstrip("+-")
            if len(digits) > 1 and digits[0] == "0":
                self._refuse(text, "a leading 0 (YAML 1.1 reads it as octal): write the number without it, 0o.. for octal")
            if len(digits) > MAX_DIGITS:
                self._refuse(text[:12] + "...", f"an integer of at most {MAX_DIGITS} digits")
            return int(text)
        if _INT_OCT.match(text) or _INT_HEX.match(text):
            if len(text) > MAX_DIGITS + 2:
                self._refuse(text[:12] + "...", f"an integer of at most {MAX_DIGITS} digits")
            return int(text[2:], 8 if text[1] == "o" else 16)
        if _FLOAT.match(text):
            if len(text) > 64:
                self._refuse(text[:12] + "...", "a number of at most 64 characters")
            return float(text)
        if _INF.match(text):
            return float("-inf") if text.startswith("-") else float("inf")
        if _NAN.match(text):
            return float("nan")
        if _SEXAGESIMAL.match(text):
            self._refuse(text, "YAML 1.1 reads this as a base-60 number: quote it for text")
        if _DATE.match(text):
            self._refuse(text, "YAML 1.1 reads this as a date: quote it for text")
        if _UNDERSCORE_OR_BINARY.match(text):
            self._refuse(text, "YAML 1.1 reads this as a number: write plain digits, or quote it for text")
        return text


def _size(value: Any) -> int:
    if isinstance(value, dict):
        return 1 + sum(_size(v) for v in value.values()) + len(value)
    if isinstance(value, list):
        return 1 + sum(_size(v) for v in value)
    return 1


def _copy(value: Any) -> Any:
    if isinstance(value, dict):
        return {k: _copy(v) for k, v in value.items()}
    if isinstance(value, list):
        return [_copy(v) for v in value]
    return value
