"""Ranges for the numbers of a scenario: every number finite and physically sensible, checked with its whole path.

Each settings class keeps the checks that make it consistent (``depth_min_m <
depth_max_m``, ``> 0`` where a zero divides). A range adds what a scenario
must never get past: a finite number (inf only where the field says what it
means) inside an interval that makes physical sense for a small quadrotor
swarm, so that ``camera.rate_hz: 1e300`` or ``dmpc.qp.horizon_steps: 2**64``
is refused at load time in one line instead of hanging or crashing a flight.
A range applies to every number of a tuple field (each coordinate of
``drones.starts``). The table is :data:`mpcde.config.ranges.RANGES` plus the
scenario's own sections (:data:`mpcde.config.scenario.SCENARIO_RANGES`).
:func:`mpcde.config.io.from_dict` checks a field before its class is built
(so no ``__post_init__`` sees a value it could overflow on), and
:func:`check_ranges` walks a config built in code (:func:`mpcde.config.resolve.resolve`).
A test fails on a numeric field of the scenario tree with no range, so a new
field cannot arrive unbounded.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

from sim.checks import ConfigError

__all__ = ["Bound", "Ranges", "check_ranges", "check_value"]


@dataclass(frozen=True)
class Bound:
    """A closed range [low, high] in ``unit``; ``inf`` says what an infinite value means where one is allowed."""

    low: float
    high: float
    unit: str = ""
    inf: str = ""

    def allowed(self, integer: bool) -> str:
        """What the range allows, in words (the end of a :class:`ConfigError` line)."""
        kind = "an integer" if integer else "a finite number"
        text = f"{kind} in [{self.low:g}, {self.high:g}]" + (f" {self.unit}" if self.unit else "")
        return text + (f" (or inf: {self.inf})" if self.inf else "")


Ranges = Mapping[type, Mapping[str, Bound]]
"""Settings class -> field name -> its range."""


def check_value(path: str, value: Any, bound: Bound | None) -> None:
    """Refuse every number in ``value`` (a number or nested tuples/lists of them) outside ``bound``, naming ``path``."""
    if bound is None:
        return
    if isinstance(value, (tuple, list)):
        for i, v in enumerate(value):
            check_value(f"{path}[{i}]", v, bound)
        return
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        return  # not a number: the type check names it
    if bound.inf and value == math.inf:
        return
    if not (math.isfinite(value) and bound.low <= value <= bound.high):
        raise ConfigError(path, value, bound.allowed(isinstance(value, int)))


def check_ranges(obj: Any, ranges: Ranges, path: str = "") -> None:
    """Walk the config tree ``obj`` and refuse the first number outside its range (ConfigError with the whole path)."""
    if isinstance(obj, (tuple, list)):
        for i, v in enumerate(obj):
            check_ranges(v, ranges, f"{path}[{i}]")
        return
    if not dataclasses.is_dataclass(obj) or isinstance(obj, type):
        return
    table = ranges.get(type(obj), {})
    for f in dataclasses.fields(obj):
        value = getattr(obj, f.name)
        where = f"{path}.{f.name}" if path else f.name
        check_value(where, value, table.get(f.name))
        check_ranges(value, ranges, where)
