"""One cell of the evaluation commands' human-readable tables (compare, eval-dmpc, eval-mlr)."""

from __future__ import annotations

import math

__all__ = ["cell"]


def cell(value: float | None, spec: str) -> str:
    """``value`` formatted with ``spec`` (e.g. ``"7.3f"``), or ``-`` right-aligned to the same width when missing.

    Missing: None (a metric that does not apply, e.g. no mission time without arrival) or NaN.
    """
    if value is None or (isinstance(value, float) and math.isnan(value)):
        return format("-", f">{spec.split('.')[0]}")
    return format(value, spec)
