"""One cell of the evaluation commands' human-readable tables (compare, eval-dmpc, eval-mlr)."""

from __future__ import annotations

import math
import re

__all__ = ["cell"]

_WIDTH = re.compile(r"(?:.?[<>=^])?[+\- ]?z?#?0?(\d*)")


def cell(value: float | None, spec: str) -> str:
    """``value`` formatted with ``spec`` (e.g. ``"7.3f"``), or ``-`` right-aligned to the same width when missing.

    Missing: None (a metric that does not apply, e.g. no mission time without arrival) or NaN.
    """
    if value is None or (isinstance(value, float) and math.isnan(value)):
        return "-".rjust(_width(spec))
    return format(value, spec)


def _width(spec: str) -> int:
    """The width field of a format ``spec`` (0 if none): ``[[fill]align][sign][z][#][0][width]...``."""
    m = _WIDTH.match(spec)
    return int(m.group(1)) if m and m.group(1) else 0
