"""Settings of the ADMM formation DMPC in a scenario (the ``admm:`` mapping; :class:`AdmmAgentConfig`).

The planner is :mod:`planners.dmpc.admm.formation` (Stomberg et al.,
Algorithm 2) with its :class:`planners.dmpc.admm.config.AdmmFormationConfig`;
this section exposes the settings a scenario may change, adds the coupling
graph, the flying box in the arena and the onboard agent's own settings
(:mod:`mpcde.onboard.admm`). OSQP's settings and Remark 1 (delay compensation,
always on: the loop applies a step's plan from the next step on) keep the
planner's defaults.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal, get_args

import numpy as np

from mpcde.errors import ConfigError
from planners.dmpc.admm.config import AdmmFormationConfig
from planners.dmpc.formation_graph import FormationGraph, complete_edges, ring_edges
from planners.dmpc.start_state import TOLERANCE_M, TOLERANCE_MPS
from planners.limits import KinematicLimits, require_infinite_jerk
from sim.checks import is_finite_at_least, require_instance, require_non_negative, require_positive

__all__ = ["EXCHANGES_PER_ITERATION", "AdmmAgentConfig", "GraphKind"]

EXCHANGES_PER_ITERATION = 2  # Algorithm 2: copies (Step 4), then means (Step 6)

GraphKind = Literal["complete", "ring"]
SolverKind = Literal["admm", "dsqp"]
DistanceRowsKind = Literal["copies", "means"]


_PLANNER = AdmmFormationConfig()  # the planner's defaults, which this section mirrors


@dataclass(frozen=True)
class AdmmAgentConfig:
    """ADMM formation DMPC settings of a scenario (the ``admm:`` mapping of a scenario file).

    The formation is the one the goals form: drone i's desired offset to a
    neighbour j is d_ij = goal_i - goal_j (desired p_i - p_j, the planner's
    sign; ``DmpcConfig.formation_offsets`` use p_j - p_i).

    Attributes:
        horizon_steps: K, prediction steps (our DMPC: 15).
        step_s: h, prediction step and MPC sampling interval [s] (paper Sec. 5.1: 0.2 s).
        l_max: ADMM iterations per MPC step (paper Sec. 5.1: 5), per SQP
            iteration with dSQP. Each takes two radio sub-rounds (copies,
            then means), so the radio runs at 2 x the iterations per step / h
            (default 50 Hz).
        solver: ``"admm"`` (Algorithm 2, no distance constraints) or
            ``"dsqp"`` (Algorithm 3: the minimum-distance constraints of Eq. 8
            between every pair of neighbours, :mod:`planners.dmpc.admm.distance`).
        sqp_iterations: q_max, dSQP's outer iterations per MPC step (Sec. 5.2: 5).
        d_min_m: d of Eq. 8 [m] (Sec. 5.2: 0.4 m), with ``solver: dsqp``.
        downwash: c of the distance's Theta = diag(1, 1, c), with ``solver: dsqp``.
        distance_rows: ``"copies"`` (QP (6c) as published) or ``"means"`` (each
            drone's rows against the neighbour's latest consensus mean; the
            default, chosen on the swap), with ``solver: dsqp``
            (:mod:`planners.dmpc.admm.distance`).
        rho: ADMM penalty rho (paper Sec. 5.1: 1).
        weight_formation: q_f on ||(p_i - p_j) - d_ij||^2 per edge, k < K [1/m^2].
        weight_tracking: q_g on ||p_i - r_i||^2, the drone's own reference, k < K [1/m^2].
        weight_input: r on ||u||^2 [s^4/m^2].
        weight_terminal_formation: q_f at k = K [1/m^2].
        weight_terminal_tracking: q_g at k = K [1/m^2].
        weight_slack: c on the soft-constraint slack squared (paper Remark 2).
        limits: per-axis soft speed and hard acceleration limits
            (:class:`planners.limits.KinematicLimits`; our DMPC: 2 m/s, 4 m/s^2);
            the acceleration is the input, so ``j_max_mps3`` stays inf.
        altitude_range_m: (lowest, highest) height of the soft position box [m]
            (chosen as MLR-DMPC's: 0.3-3 m).
        arena_margin_m: the box's x and y extent is the arena shrunk by this
            on every side [m].
        graph: coupling (= communication, paper Assumption 1) graph over the
            drone ids in the scenario's order: ``"complete"`` (every pair, the
            default: a formation of a few drones is held rigidly) or
            ``"ring"`` (i with i + 1 mod N: list the drones around the
            formation for it to be the polygon's sides).
        warm_start: start each step's ADMM from the previous step's shifted
            zbar and gamma (paper Sec. 5.1); false starts every step cold.
        radio_rate_from_step: with ``planner.kind: admm`` the scenario's
            ``radio.rate_hz`` is set to 2 l_max / h, one radio sub-round per
            exchange (so a file written for DMPC's 5 Hz flies ADMM too);
            false: the file's ``radio.rate_hz`` must already equal it.
        max_start_offset_m: with ``solver: admm`` the planner has no
            collision avoidance: every start must lie within this of its slot
            in the goals' formation moved to the starts' centroid [m] (chosen:
            0.5 m, a few robot radii), else the scenario is refused. Keeping
            the formation then keeps the drones apart. dSQP keeps them apart
            itself, so it flies any start.
        state_tolerance_m: a step starts from the own plan's state when the
            pose estimate is within this of it [m], else from the estimate
            (0 = always the estimate). The DMPC agent's rule and default,
            :mod:`planners.dmpc.start_state`: 0.3 m, above the pose estimate's
            drift (the former 0.1 m lets a drift past it ratchet the drone).
        state_tolerance_mps: the same bound on the velocity [m/s] (0.3).
    """

    horizon_steps: int = _PLANNER.horizon_steps
    step_s: float = _PLANNER.step_s
    l_max: int = _PLANNER.l_max
    solver: SolverKind = "admm"
    sqp_iterations: int = _PLANNER.sqp_iterations
    d_min_m: float = _PLANNER.d_min_m
    downwash: float = _PLANNER.downwash
    distance_rows: DistanceRowsKind = _PLANNER.distance_rows
    rho: float = _PLANNER.rho
    weight_formation: float = _PLANNER.weight_formation
    weight_tracking: float = _PLANNER.weight_tracking
    weight_input: float = _PLANNER.weight_input
    weight_terminal_formation: float = _PLANNER.weight_terminal_formation
    weight_terminal_tracking: float = _PLANNER.weight_terminal_tracking
    weight_slack: float = _PLANNER.weight_slack
    limits: KinematicLimits = _PLANNER.limits
    altitude_range_m: tuple[float, float] = (0.3, 3.0)
    arena_margin_m: float = 0.3
    graph: GraphKind = "complete"
    warm_start: bool = _PLANNER.warm_start
    radio_rate_from_step: bool = True
    max_start_offset_m: float = 0.5
    state_tolerance_m: float = TOLERANCE_M
    state_tolerance_mps: float = TOLERANCE_MPS

    def __post_init__(self) -> None:
        for name, low in (("horizon_steps", 2), ("l_max", 1), ("sqp_iterations", 1)):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int) or value < low:
                raise ConfigError(name, value, f"an integer >= {low}")
        positive = {
            "step_s": "s", "rho": "", "weight_input": "s^4/m^2", "weight_slack": "",
            "max_start_offset_m": "m",
        }  # fmt: skip
        for name, unit in positive.items():
            require_positive(name, getattr(self, name), unit)
        require_instance("limits", self.limits, KinematicLimits)
        require_infinite_jerk(self.limits, "the double integrator's input is the acceleration")
        non_negative = {
            "weight_formation": "1/m^2", "weight_tracking": "1/m^2", "weight_terminal_formation": "1/m^2",
            "weight_terminal_tracking": "1/m^2", "arena_margin_m": "m", "state_tolerance_m": "m",
            "state_tolerance_mps": "m/s",
        }  # fmt: skip
        for name, unit in non_negative.items():
            require_non_negative(name, getattr(self, name), unit)
        lo, hi = self.altitude_range_m
        if not (is_finite_at_least(lo, 0.0) and is_finite_at_least(hi, 0.0) and lo < hi):
            allowed = "(lowest, highest) with 0 <= lowest < highest [m]"
            raise ConfigError("altitude_range_m", self.altitude_range_m, allowed)
        if self.graph not in get_args(GraphKind):  # from_dict checks the Literal; this catches replace()
            raise ConfigError("graph", self.graph, f"allowed: {', '.join(repr(a) for a in get_args(GraphKind))}")
        for name, kind in (("solver", SolverKind), ("distance_rows", DistanceRowsKind)):
            if getattr(self, name) not in get_args(kind):
                raise ConfigError(name, getattr(self, name), f"allowed: {', '.join(repr(a) for a in get_args(kind))}")
        for name in ("warm_start", "radio_rate_from_step"):
            if not isinstance(getattr(self, name), bool):
                raise ConfigError(name, getattr(self, name), "true or false")

    @property
    def iterations_per_step(self) -> int:
        """ADMM iterations of one MPC step: l_max, or q_max l_max with dSQP."""
        return self.l_max * (self.sqp_iterations if self.solver == "dsqp" else 1)

    @property
    def radio_rate_hz(self) -> float:
        """The radio rate the formation DMPC needs [Hz]: 2 exchanges per ADMM iteration, per step h."""
        return EXCHANGES_PER_ITERATION * self.iterations_per_step / self.step_s

    @property
    def sub_round_s(self) -> float:
        """One radio sub-round [s]: h / (2 x iterations per step)."""
        return self.step_s / (EXCHANGES_PER_ITERATION * self.iterations_per_step)

    @property
    def rounds_per_step(self) -> int:
        """Radio sub-rounds per MPC step: 2 x iterations per step."""
        return EXCHANGES_PER_ITERATION * self.iterations_per_step

    def box_world(self, arena_size_m: tuple[float, float]) -> tuple[np.ndarray, np.ndarray]:
        """(lower (3,), upper (3,)) corners of the soft position box [m] in an arena of ``arena_size_m`` (x, y) [m]."""
        half = np.asarray(arena_size_m, float) / 2.0 - self.arena_margin_m
        lo, hi = self.altitude_range_m
        return np.r_[-half, lo], np.r_[half, hi]

    def planner_config(self, arena_size_m: tuple[float, float]) -> AdmmFormationConfig:
        """The planner's :class:`AdmmFormationConfig` in an arena of ``arena_size_m`` [m].

        Raises:
            ConfigError: an arena too small for ``arena_margin_m``.
        """
        lo, hi = self.box_world(arena_size_m)
        if not np.all(lo < hi):
            allowed = f"less than half the arena {arena_size_m} [m]"
            raise ConfigError("admm.arena_margin_m", self.arena_margin_m, allowed)
        return AdmmFormationConfig(
            horizon_steps=self.horizon_steps, step_s=self.step_s, weight_formation=self.weight_formation,
            weight_tracking=self.weight_tracking, weight_input=self.weight_input,
            weight_terminal_formation=self.weight_terminal_formation,
            weight_terminal_tracking=self.weight_terminal_tracking, weight_slack=self.weight_slack,
            pos_min_world=tuple(float(v) for v in lo), pos_max_world=tuple(float(v) for v in hi), limits=self.limits,
            rho=self.rho, l_max=self.l_max, delay_compensation=True, warm_start=self.warm_start, solver=self.solver,
            sqp_iterations=self.sqp_iterations, d_min_m=self.d_min_m, downwash=self.downwash,
            distance_rows=self.distance_rows,
        )  # fmt: skip

    def formation(self, goals_world: np.ndarray) -> FormationGraph:
        """The formation the goals (N, 3) [m] form, over :attr:`graph` (slots relative to the goals' centroid)."""
        goals = np.asarray(goals_world, float).reshape(-1, 3)
        n = goals.shape[0]
        edges = complete_edges(n) if self.graph == "complete" else ring_edges(n)
        return FormationGraph(goals - goals.mean(axis=0), edges)
