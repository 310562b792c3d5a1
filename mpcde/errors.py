"""The package's own exception types."""

from __future__ import annotations

import math
from typing import Any

__all__ = ["ConfigError", "MpcdeError", "require_finite_positive"]


class MpcdeError(Exception):
    """Base class of mpcde's errors that the command line turns into exit status 2."""


class ConfigError(MpcdeError, ValueError):
    """An invalid scenario or option: names the field, the value and what is allowed.

    The message is one line: ``<field>=<value!r>: <allowed>``.
    """

    def __init__(self, field: str, value: Any, allowed: str) -> None:
        self.field = field
        self.value = value
        self.allowed = allowed
        super().__init__(f"{field}={value!r}: {allowed}")


def require_finite_positive(config: object, *names: str) -> None:
    """Raise ConfigError ``<name>=<value>: a finite number > 0`` for the first attribute of ``config`` that is not one."""
    for name in names:
        v = getattr(config, name)
        if isinstance(v, bool) or not (isinstance(v, (int, float)) and math.isfinite(v) and v > 0):
            raise ConfigError(name, v, "a finite number > 0")
