"""The kinematic limits a planner keeps: :class:`KinematicLimits`, one dataclass for every stack.

Every planner of the package bounds the reference it flies by a speed, an
acceleration and (where its model has a jerk) a jerk limit: MP-CDE's MINCO
penalties (Eq. 15: ``||v||^2 <= v_max^2``, ``||a||^2 <= a_max^2``), the
on-demand DMPC's and MLR-DMPC's per-axis boxes (Luis et al. Eq. 9;
DMPC-Swarm Eq. 13c-13d) and the formation DMPC's (Stomberg et al. Eq. 19).
They are one dataclass so that a scenario spells them the same way in every
section (``denied.limits``, ``dmpc.qp.limits``, ``mlr.limits``,
``admm.limits``), with one set of checks and units. Whether a planner bounds
the norm or each axis is the planner's: its config's docstring says which.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from sim.checks import ConfigError, require_positive

__all__ = ["KinematicLimits", "require_finite_jerk", "require_infinite_jerk"]


@dataclass(frozen=True)
class KinematicLimits:
    """Speed, acceleration and jerk limits of a planned reference.

    Attributes:
        v_max_mps: speed limit [m/s] (the papers' v_max).
        a_max_mps2: acceleration limit [m/s^2] (a_max).
        j_max_mps3: jerk limit [m/s^3] (j_max); inf where the planner's
            model has no jerk to bound (MINCO's penalties, a double
            integrator's piecewise-constant acceleration input), and a
            section whose planner cannot bound it refuses a finite value.
    """

    v_max_mps: float = 1.0
    a_max_mps2: float = 3.0
    j_max_mps3: float = math.inf

    def __post_init__(self) -> None:
        require_positive("v_max_mps", self.v_max_mps, "m/s")
        require_positive("a_max_mps2", self.a_max_mps2, "m/s^2")
        require_positive("j_max_mps3", self.j_max_mps3, "m/s^3", inf_means="no jerk limit")


def require_infinite_jerk(limits: KinematicLimits, why: str) -> None:
    """Refuse a finite ``limits.j_max_mps3`` for a planner that cannot bound the jerk; ``why`` says why not."""
    if limits.j_max_mps3 != math.inf:
        raise ConfigError("limits.j_max_mps3", limits.j_max_mps3, f".inf: {why}")


def require_finite_jerk(limits: KinematicLimits, why: str) -> None:
    """Refuse an infinite ``limits.j_max_mps3`` for a planner whose input is the jerk; ``why`` says why it must bound it."""
    if limits.j_max_mps3 == math.inf:
        raise ConfigError("limits.j_max_mps3", limits.j_max_mps3, f"a finite number > 0 [m/s^3]: {why}")
