"""The field checks of the planners' config dataclasses: one line ``"<field>=<value!r>: <allowed>"`` each.

Raised as ValueError (planners/ does not import :mod:`mpcde`; its scenario
loader turns them into its one-line ConfigError with the section prefixed).
The wording matches :func:`mpcde.errors.require_finite_positive`. Booleans
are not numbers here: ``True`` is refused where a number or integer is asked.
Used by the DMPC, ADMM and MLR-DMPC configs; :mod:`planners.yaw.config` keeps its own
twins, whose messages (tested) read ``"...: allowed finite number > 0"``.
"""

from __future__ import annotations

import math
import numbers

import numpy as np

__all__ = [
    "require_at_least", "require_boolean", "require_box", "require_integer_at_least", "require_non_negative",
    "require_positive",
]


def _is_real(value: object) -> bool:
    return isinstance(value, numbers.Real) and not isinstance(value, bool) and math.isfinite(value)


def require_positive(name: str, value: object) -> None:
    """Refuse ``value`` unless it is a finite number > 0 (int, float or numpy scalar)."""
    if not (_is_real(value) and value > 0):
        raise ValueError(f"{name}={value!r}: a finite number > 0")


def require_non_negative(name: str, value: object) -> None:
    """Refuse ``value`` unless it is a finite number >= 0."""
    if not (_is_real(value) and value >= 0):
        raise ValueError(f"{name}={value!r}: a finite number >= 0")


def require_at_least(name: str, value: object, low: float) -> None:
    """Refuse ``value`` unless it is a finite number >= ``low``."""
    if not (_is_real(value) and value >= low):
        raise ValueError(f"{name}={value!r}: a finite number >= {low:g}")


def require_box(lo_name: str, lo: object, hi_name: str, hi: object) -> None:
    """Refuse an axis-aligned box unless both corners are three finite numbers with ``lo < hi`` on every axis."""
    lo_a, hi_a = np.asarray(lo, float), np.asarray(hi, float)
    if lo_a.shape != (3,) or not np.all(np.isfinite(lo_a)):
        raise ValueError(f"{lo_name}={lo!r}: three finite numbers [m]")
    if hi_a.shape != (3,) or not np.all(np.isfinite(hi_a)) or not np.all(lo_a < hi_a):
        raise ValueError(f"{hi_name}={hi!r}: three finite numbers, each > {lo_name}={lo!r}")


def require_integer_at_least(name: str, value: object, low: int) -> None:
    """Refuse ``value`` unless it is an integer (int or numpy integer, not bool) >= ``low``."""
    if isinstance(value, bool) or not isinstance(value, numbers.Integral) or value < low:
        raise ValueError(f"{name}={value!r}: an integer >= {low}")


def require_boolean(name: str, value: object) -> None:
    """Refuse ``value`` unless it is True or False."""
    if not isinstance(value, bool):
        raise ValueError(f"{name}={value!r}: True or False")
