"""The cross-field rules of the denied stack's flight levels (``denied.flight_level_spacing_m``).

Drone k of N cruises at z_k = z_c + (k - (N - 1) / 2) s, z_c the mean of its own start
and goal altitudes (:class:`mpcde.config.denied.DeniedAgentConfig`). Two rules make the
levels what they promise, checked at load time for the stacks that fly them (their
registry entries' ``check``, :mod:`mpcde.stacks.builtin`): every drone's z_c is the same, so that the levels are distinct and s apart;
and the lowest and highest levels lie within the altitudes a layout may use.
:meth:`mpcde.config.scenario.ScenarioConfig.__post_init__` calls :func:`check_flight_levels`.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from mpcde.errors import ConfigError

if TYPE_CHECKING:
    from mpcde.config.scenario import ScenarioConfig

__all__ = ["LEVEL_ALTITUDES_M", "check_flight_levels", "flight_level_m"]

LEVEL_ALTITUDES_M = (0.3, 20.0)
"""(lowest, highest) altitude [m] a flight level may have: those a layout's starts and goals may have."""


def flight_level_m(centre_m: float, drone_id: int, drones: int, spacing_m: float) -> float:
    """z_k = z_c + (k - (N - 1) / 2) s [m]: the level of drone ``drone_id`` of ``drones`` about ``centre_m`` [m]."""
    return centre_m + (drone_id - 0.5 * (drones - 1)) * spacing_m


def check_flight_levels(cfg: ScenarioConfig, starts: np.ndarray, goals: np.ndarray) -> None:
    """ConfigError if the flight levels of the layout's starts and goals (N, 3) [m] are not distinct or leave the altitudes."""
    spacing = cfg.denied.flight_level_spacing_m
    if not np.isfinite(spacing):
        return
    centres = 0.5 * (starts[:, 2] + goals[:, 2])
    odd = np.flatnonzero(np.abs(centres - centres[0]) > 1e-6)
    if odd.size:
        i = int(odd[0])
        allowed = (
            f"inf (no levels) unless every drone's start and goal altitudes share one mean: drone {i}'s is "
            f"{centres[i]:.3g} m, drone 0's {centres[0]:.3g} m (the levels are spaced about it)"
        )
        raise ConfigError("denied.flight_level_spacing_m", spacing, allowed)
    n = len(starts)
    lo, hi = LEVEL_ALTITUDES_M
    lowest, highest = flight_level_m(centres[0], 0, n, spacing), flight_level_m(centres[0], n - 1, n, spacing)
    if n > 1 and not (lowest >= lo - 1e-9 and highest <= hi + 1e-9):  # a level on the floor is allowed: 1.5 - 3 x 0.4 is 0.2999... in floats
        largest = min(centres[0] - lo, hi - centres[0]) / (0.5 * (n - 1))
        allowed = (
            f"<= {largest:.3g} m for {n} drones about {centres[0]:.3g} m (levels from "
            f"{lowest:.3g} to {highest:.3g} m; allowed {lo:g} to {hi:g} m)"
        )
        raise ConfigError("denied.flight_level_spacing_m", spacing, allowed)
