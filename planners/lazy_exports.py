"""Package names imported on first use (PEP 562), so that importing a package stays cheap.

:mod:`planners.dmpc`, :mod:`planners.dmpc.mlr` and :mod:`planners.yaw` re-export
their modules' public names this way: reading a planner's settings does not load
its solver. Use in a package's ``__init__.py``::

    _WHERE = {"Name": "package.module", ...}
    __all__ = sorted(_WHERE)
    __getattr__, __dir__ = lazy_exports(__name__, _WHERE)
"""

from __future__ import annotations

import importlib
from collections.abc import Callable
from typing import Any

__all__ = ["lazy_exports"]


def lazy_exports(package: str, where: dict[str, str]) -> tuple[Callable[[str], Any], Callable[[], list[str]]]:
    """The module ``__getattr__`` and ``__dir__`` of ``package``: name -> ``where[name]``'s attribute, imported on first use.

    Any other name raises AttributeError ``"module '<package>' has no attribute '<name>'"``.
    """

    def __getattr__(name: str) -> Any:
        if name in where:
            return getattr(importlib.import_module(where[name]), name)
        raise AttributeError(f"module {package!r} has no attribute {name!r}")

    def __dir__() -> list[str]:
        return sorted(where)

    return __getattr__, __dir__
