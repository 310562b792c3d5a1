"""The ``mlr:`` section of a scenario: settings of the MLR-DMPC stack (DMPC-Swarm)."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Literal, get_args

import numpy as np

from mpcde.errors import ConfigError
from planners.dmpc.mlr.config import MlrConfig
from planners.limits import KinematicLimits, require_finite_jerk
from sim.checks import is_finite_at_least, require_at_least, require_instance, require_non_negative, require_positive

__all__ = ["MlrAgentConfig", "TriggerKind"]


TriggerKind = Literal["rr", "db", "ht"]


_PLANNER = MlrConfig()  # the planner's defaults, which this section mirrors


@dataclass(frozen=True)
class MlrAgentConfig:
    """MLR-DMPC settings of a scenario (the ``mlr:`` mapping of a scenario file).

    N, the number of UAVs, is the scenario's drone count; the other
    :class:`planners.dmpc.mlr.config.MlrConfig` settings (QP weights, OSQP,
    tracker sizes, priority scales) keep their defaults there.

    Attributes:
        num_compute_units: M, CUs hosted by drones 0..M-1 (Sec. 1.1: 1 <= M < N;
            chosen default 2).
        round_s: T, the MLR round [s]; must equal ``1 / radio.rate_hz``
            (Sec. 5.1: 0.2 s).
        trigger: event trigger of Appendix A: ``"rr"`` round-robin, ``"db"``
            distance-based or ``"ht"`` hybrid (default, the paper's best in Fig. 3c).
        horizon_rounds: H, prediction horizon in rounds (a trajectory lasts H T).
        d_hat_min_m: d̂_min, planned minimum ellipsoidal distance between
            reference positions at the check times [m] (Eq. 15; default 0.45 m,
            as in the kinematic swarm: with 1 m/s per axis the margin over the
            2 x 0.1 m collision distance covers the motion between checks and
            the controller's tracking error).
        downwash: c >= 1 of Theta = diag(1, 1, c) (Eq. 2).
        limits: per-axis speed and acceleration (Eq. 13d) and jerk (Eq. 13c)
            limits (:class:`planners.limits.KinematicLimits`).
        altitude_range_m: (lowest, highest) height of the flying box [m].
        arena_margin_m: the box's x and y extent is the arena shrunk by this
            on every side [m].
        ignore_message_loss: fly the Sec. 5.4 baseline (Gräfe et al. 2022:
            CUs assume every trajectory arrived) instead of MLR-DMPC.
    """

    num_compute_units: int = 2
    round_s: float = _PLANNER.round_s
    trigger: TriggerKind = _PLANNER.trigger
    horizon_rounds: int = _PLANNER.horizon_rounds
    d_hat_min_m: float = _PLANNER.d_hat_min_m
    downwash: float = _PLANNER.downwash
    limits: KinematicLimits = _PLANNER.limits
    altitude_range_m: tuple[float, float] = (0.3, 3.0)
    arena_margin_m: float = 0.3
    ignore_message_loss: bool = False

    def __post_init__(self) -> None:
        for name, low in (("num_compute_units", 1), ("horizon_rounds", 2)):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int) or value < low:
                raise ConfigError(name, value, f"an integer >= {low}")
        if self.trigger not in get_args(TriggerKind):  # from_dict checks the Literal; this catches replace()
            raise ConfigError("trigger", self.trigger, f"allowed: {', '.join(repr(a) for a in get_args(TriggerKind))}")
        units = {"round_s": "s", "d_hat_min_m": "m"}
        for name, unit in units.items():
            require_positive(name, getattr(self, name), unit)
        require_at_least("downwash", self.downwash, 1.0)
        require_instance("limits", self.limits, KinematicLimits)
        require_finite_jerk(self.limits, "the jerk is the input (Eq. 13c)")
        require_non_negative("arena_margin_m", self.arena_margin_m, "m")
        lo, hi = self.altitude_range_m
        if not (is_finite_at_least(lo, 0.0) and math.isfinite(hi) and lo < hi):
            allowed = "(lowest, highest) with 0 <= lowest < highest [m]"
            raise ConfigError("altitude_range_m", self.altitude_range_m, allowed)
        if not isinstance(self.ignore_message_loss, bool):
            raise ConfigError("ignore_message_loss", self.ignore_message_loss, "true or false")

    def box_world(self, arena_size_m: tuple[float, float]) -> tuple[np.ndarray, np.ndarray]:
        """(lower (3,), upper (3,)) corners of the flying box [m] in an arena of ``arena_size_m`` (x, y) [m]."""
        half = np.asarray(arena_size_m, float) / 2.0 - self.arena_margin_m
        lo, hi = self.altitude_range_m
        return np.r_[-half, lo], np.r_[half, hi]

    def planner_config(self, n_uavs: int, arena_size_m: tuple[float, float]) -> MlrConfig:
        """The :class:`MlrConfig` for ``n_uavs`` drones in an arena of ``arena_size_m`` [m].

        Raises:
            ConfigError: M >= N, or an arena too small for ``arena_margin_m``.
        """
        if self.num_compute_units >= n_uavs:
            allowed = f"an integer in [1, {n_uavs - 1}]: fewer compute units than drones (N = {n_uavs})"
            raise ConfigError("mlr.num_compute_units", self.num_compute_units, allowed)
        lo, hi = self.box_world(arena_size_m)
        if not np.all(lo < hi):
            raise ConfigError("mlr.arena_margin_m", self.arena_margin_m, f"less than half the arena {arena_size_m} [m]")
        return MlrConfig(
            n_uavs=int(n_uavs), n_cus=self.num_compute_units, round_s=self.round_s, horizon_rounds=self.horizon_rounds,
            d_hat_min_m=self.d_hat_min_m, downwash=self.downwash, limits=self.limits,
            pos_min_world=tuple(float(v) for v in lo), pos_max_world=tuple(float(v) for v in hi),
            trigger=self.trigger,
        )  # fmt: skip
