"""The package's own exception types."""

from __future__ import annotations

from typing import Any

__all__ = ["ConfigError", "MpcdeError"]


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
