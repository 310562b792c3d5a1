"""The one configuration error and the one set of field checks, for every layer.

Every config dataclass of ``sim/``, ``perception/``, ``planners/`` and
``mpcde/`` checks its fields in ``__post_init__`` with these helpers and
raises :class:`ConfigError`, whose one-line message is
``<field>=<value!r>: <allowed>``. The scenario loader
(:func:`mpcde.config.io.from_dict`) prefixes the section path, so a user
reads ``denied.yaw.v_max_mps=0: a finite number > 0`` and the command line
exits with status 2. This module is at the bottom layer so that every layer
may import it (docs/design.md section 1). Booleans are never numbers here:
``True`` is refused where a number or an integer is asked.
"""

from __future__ import annotations

import math
import numbers
import reprlib
from typing import Any, Iterable

import numpy as np

__all__ = [
    "ConfigError", "is_finite_at_least", "require_at_least", "require_boolean", "require_box", "require_in", "require_instance", "require_integer_at_least",
    "require_non_negative", "require_one_of", "require_positive",
]


class ConfigError(ValueError):
    """An invalid setting: the field (a dotted path), the value and what is allowed.

    The message is one line: ``<field>=<value!r>: <allowed>``, whatever the
    input: control characters in the field (a key from a file) are escaped as
    ``repr`` escapes them, and the field, the value's repr and the allowed text
    are each cut to :data:`MESSAGE_PART_CHARS` characters (a value's repr is
    built with :mod:`reprlib`'s limits, so a huge value costs no more).
    """

    def __init__(self, field: str, value: Any, allowed: str) -> None:
        self.field = field
        self.value = value
        self.allowed = allowed
        super().__init__(f"{_one_line(str(field))}={_short_repr(value)}: {_one_line(str(allowed))}")

    def under(self, section: str) -> "ConfigError":
        """The same error with its field inside ``section`` (``"denied"`` + ``"yaw.v_max_mps"``)."""
        if not section or self.field == section or self.field.startswith(section + "."):
            return self
        return ConfigError(f"{section}.{self.field}", self.value, self.allowed)


MESSAGE_PART_CHARS = 200
"""Longest field, value or allowed text in a :class:`ConfigError` message [characters]."""

_REPR = reprlib.Repr()
_REPR.maxlevel, _REPR.maxdict, _REPR.maxlist, _REPR.maxtuple, _REPR.maxset = 3, 6, 6, 6, 6
_REPR.maxstring, _REPR.maxother, _REPR.maxlong = 120, 120, 40


def _cut(text: str) -> str:
    return text if len(text) <= MESSAGE_PART_CHARS else text[: MESSAGE_PART_CHARS - 3] + "..."


def _one_line(text: str) -> str:
    """``text`` with control characters escaped (a newline as ``\\n``, ESC as ``\\x1b``), cut to length."""
    if text.isprintable():
        return _cut(text)
    return _cut("".join(c if c.isprintable() else repr(c)[1:-1] for c in text))


def _short_repr(value: Any) -> str:
    try:
        return _one_line(_REPR.repr(value))
    except Exception:  # a repr that fails (an int past Python's digit limit, a broken object)
        return f"<{type(value).__name__}>"


def _is_real(value: object) -> bool:
    return isinstance(value, numbers.Real) and not isinstance(value, bool) and math.isfinite(value)


def is_finite_at_least(value: object, low: float, strict: bool = False) -> bool:
    """Whether ``value`` is a finite number (not bool) >= ``low`` (> ``low`` with ``strict``)."""
    return _is_real(value) and (value > low if strict else value >= low)


def require_positive(name: str, value: object, unit: str = "", inf_means: str = "") -> None:
    """Refuse ``value`` unless it is a finite number > 0; with ``inf_means`` (what inf stands for) inf too."""
    if inf_means and value == math.inf and not isinstance(value, bool):
        return
    if not (_is_real(value) and value > 0):
        what = "a finite number > 0" + (f" [{unit}]" if unit else "") + (f" (or inf: {inf_means})" if inf_means else "")
        raise ConfigError(name, value, what)


def require_non_negative(name: str, value: object, unit: str = "") -> None:
    """Refuse ``value`` unless it is a finite number >= 0."""
    if not (_is_real(value) and value >= 0):
        raise ConfigError(name, value, "a finite number >= 0" + (f" [{unit}]" if unit else ""))


def require_at_least(name: str, value: object, low: float, strict: bool = False, unit: str = "") -> None:
    """Refuse ``value`` unless it is a finite number >= ``low`` (> ``low`` with ``strict``)."""
    if not (_is_real(value) and (value > low if strict else value >= low)):
        raise ConfigError(name, value, f"a finite number {'>' if strict else '>='} {low:g}" + (f" [{unit}]" if unit else ""))


def require_in(name: str, value: object, low: float, high: float, low_open: bool = False, high_open: bool = False, unit: str = "") -> None:
    """Refuse ``value`` unless it is a finite number in the interval from ``low`` to ``high``."""
    ok = _is_real(value) and (value > low if low_open else value >= low) and (value < high if high_open else value <= high)
    if not ok:
        interval = f"{'(' if low_open else '['}{low:g}, {high:g}{')' if high_open else ']'}"
        raise ConfigError(name, value, f"a number in {interval}" + (f" [{unit}]" if unit else ""))


def require_integer_at_least(name: str, value: object, low: int) -> None:
    """Refuse ``value`` unless it is an integer (int or numpy integer, not bool) >= ``low``."""
    if isinstance(value, bool) or not isinstance(value, numbers.Integral) or value < low:
        raise ConfigError(name, value, f"an integer >= {low}")


def require_boolean(name: str, value: object) -> None:
    """Refuse ``value`` unless it is True or False."""
    if not isinstance(value, bool):
        raise ConfigError(name, value, "True or False")


def require_one_of(name: str, value: object, options: Iterable[object]) -> None:
    """Refuse ``value`` unless it is one of ``options``."""
    options = tuple(options)
    if isinstance(value, bool) or value not in options:
        raise ConfigError(name, value, f"one of {', '.join(repr(o) for o in options)}")


def require_box(lo_name: str, lo: object, hi_name: str, hi: object) -> None:
    """Refuse an axis-aligned box unless both corners are three finite numbers with ``lo < hi`` on every axis."""
    try:
        lo_a, hi_a = np.asarray(lo, float), np.asarray(hi, float)
    except (TypeError, ValueError):
        raise ConfigError(lo_name, lo, "three finite numbers [m]") from None
    if lo_a.shape != (3,) or not np.all(np.isfinite(lo_a)):
        raise ConfigError(lo_name, lo, "three finite numbers [m]")
    if hi_a.shape != (3,) or not np.all(np.isfinite(hi_a)) or not np.all(lo_a < hi_a):
        raise ConfigError(hi_name, hi, f"three finite numbers, each > {lo_name}={lo!r}")


def require_instance(name: str, value: object, cls: type) -> None:
    """Refuse ``value`` unless it is a ``cls`` (a nested settings section built by code, not by the loader)."""
    if not isinstance(value, cls):
        raise ConfigError(name, value, f"a {cls.__name__} (a mapping of its fields in a scenario file)")
