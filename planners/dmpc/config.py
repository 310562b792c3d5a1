"""Configuration of the per-drone DMPC QP (:class:`DmpcConfig`).

Defaults come from the on-demand DMPC paper (``papers/on-demand-dmpc-formation.txt``,
Sec. 4: K = 15, h = 0.2 s, a_max_mps2 = 4 m/s^2, r_min_m = 0.2 m in simulation and
0.4 m in flight), from the reference implementation of on-demand DMPC by Luis,
Vukosavljev and Schoellig (``online_dmpc``: goal weight 100 over the last 3
steps, linear slack penalty 5e4, quadratic 1, conflict margin 0.05 m,
neighbourhood 3 r_min_m, downwash ellipsoid c = 2) and from DMPC-Swarm Eq. 2
(the downwash scaling matrix Theta). Values without a source are marked
"chosen" and say why.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from planners.limits import KinematicLimits
from sim.checks import (
    ConfigError,
    require_at_least,
    require_boolean,
    require_box,
    require_instance,
    require_integer_at_least,
    require_non_negative,
    require_positive,
)

__all__ = ["DmpcConfig"]

_MODELS = ("double", "triple")
_COLLISION_MODES = ("on_demand", "bvc")
_OBSTACLE_MODES = ("auto", "on_demand", "every_step")


@dataclass(frozen=True)
class DmpcConfig:
    """Settings of one drone's DMPC quadratic program.

    Class constants (:data:`typing.ClassVar`, not fields: no scenario, sweep or
    preset sets them, so a scenario file that names one is refused as an
    unknown key; docs/design.md section 7): ``goal_steps``,
    ``weight_slack_quadratic``, ``weight_slack_linear``, ``slack_max_m``, ``neighbourhood_factor``,
    ``conflict_margin_m``, ``on_demand_time``, ``conflict_substeps``,
    ``obstacle_culling`` and the ``osqp_*`` solver settings. A test that needs
    another value overrides one in a subclass.

    Attributes:
        horizon_steps: K, number of prediction steps (on-demand DMPC Sec. 4: 15).
        step_s: h, prediction step and DMPC round period in [s] (Sec. 4: 0.2 s).
        model: ``"double"`` (state [p, v], input acceleration; on-demand DMPC
            Eq. 6) or ``"triple"`` (state [p, v, a], input jerk).
        goal_steps: theta, number of final horizon steps pulled towards the
            goal (on-demand DMPC F_e; online_dmpc ``spd_f = 3``).
        weight_goal: q_k of the goal term in [1/m^2] (online_dmpc ``s_free = 100``).
        weight_formation: q_f of the formation term in [1/m^2] (chosen: 10, a
            tenth of the goal weight so the goal still wins far from it).
        weight_smoothness: q_Theta of the input-difference term, in
            [s^4/m^2] (double) or [s^6/m^2] (triple) (chosen: 1.0; against
            weight_goal = 100 it smooths the inputs without slowing the
            8-drone swap).
        weight_slack_quadratic: zeta, quadratic slack penalty in [1/m^2]
            (chosen: 1e4. online_dmpc uses ``quad_coll_penalty = 1``, but with
            OSQP that leaves the slack's curvature 1e4 times below its linear
            price and ADMM then hits the iteration limit; 1e4 keeps the linear
            (exact-penalty) term and converges;
            docs/results/dmpc_qp.md#behind-dmpcconfigs-defaults).
        weight_slack_linear: xi, linear slack penalty in [1/m]
            (online_dmpc ``lin_coll_penalty = -5e4`` on a non-positive slack).
        slack_max_m: upper bound on one slack (relaxation) in [m]
            (online_dmpc ``relax_lim = 10``).
        pos_min_world: (3,) lower corner of the position box in world [m]
            (chosen: a 40 m x 40 m arena, 0.2 m above the ground).
        pos_max_world: (3,) upper corner of the position box in world [m].
        limits: per-axis limits (:class:`planners.limits.KinematicLimits`):
            speed ``v_max_mps`` [m/s] (chosen: 2.0 m/s; the paper reports mean
            speeds below 1 m/s), acceleration ``a_max_mps2`` [m/s^2] (on-demand
            DMPC Sec. 4: 4) and jerk ``j_max_mps3`` [m/s^3], triple integrator
            only (chosen: 20).
        r_min_m: minimum ellipsoidal inter-drone distance in [m] (on-demand DMPC
            Sec. 5 flight: 0.4 m).
        downwash: c >= 1, vertical stretch of the collision ellipsoid,
            Theta = diag(1, 1, c) (DMPC-Swarm Eq. 2; online_dmpc ``c_a = 2``);
            the distance is ||Theta^-1 (p_i - p_j)||_2.
        collision_mode: ``"on_demand"`` (one soft linearised constraint per
            close neighbour at the first predicted conflict; on-demand DMPC
            Sec. 3.4) or ``"bvc"`` (hard time-varying buffered Voronoi planes at
            every step against every neighbour; DMPC-Swarm Eq. 14-15).
        neighbourhood_factor: on-demand constraints are built only for
            neighbours closer than ``neighbourhood_factor * r_min_m`` at the
            conflict step (on-demand DMPC Sec. 3.4 and online_dmpc: 3).
        conflict_margin_m: a conflict is predicted when the distance is below
            ``r_min_m + conflict_margin_m`` in [m] (online_dmpc ``check_horizon``: 0.05).
        on_demand_time: where each on-demand plane constrains the plan:
            ``"first_conflict"`` (the paper: all at the first conflict k_c) or
            ``"closest_approach"`` (chosen default: at the deepest point of each
            neighbour's conflict starting at k_c; see
            :func:`planners.dmpc.collision.on_demand_constraints` for why).
        conflict_substeps: S, the previous plans are checked for conflicts at S
            times per step and the on-demand plane constrains the position at the
            first conflicting time (exact: within a step the position is affine in
            U too). S = 1 is the paper's sample-only check. Chosen: 4, because two
            drones at v_max_mps = 2 m/s head-on move 0.8 m relative per step of
            0.2 s, more than 2 r_min_m, so a sample-only check lets them pass
            through each other between samples ("tunnelling"; observed in the
            8-drone swap with S = 1).
        max_neighbours: number of neighbour slots in the QP (fixed sparsity);
            more neighbours than this are cut to the nearest ones (chosen: 8).
        max_obstacle_planes: number of static obstacles the QP takes (one
            half-space per obstacle: a slot per horizon step with
            ``every_step``, one slot per obstacle with ``on_demand``; 0
            disables them; chosen: 0).
        obstacle_avoidance: how the obstacle half-spaces enter the QP:
            ``"every_step"`` (one hard row per obstacle and horizon step, the
            conventional form), ``"on_demand"`` (on-demand DMPC Sec. 3.4 applied
            to "known obstacle positions": the own previous plan is checked
            against each obstacle's half-spaces and ONE hard row is added for an
            obstacle only when it predicts a conflict, at the time chosen by
            ``on_demand_time``; :mod:`planners.dmpc.obstacle`) or ``"auto"``
            (default: pairs with ``collision_mode``, on_demand -> on_demand as in
            the paper, bvc -> every_step as the conventional baseline; resolved
            by :attr:`obstacle_mode`, so ``replace(cfg, collision_mode=...)``
            re-pairs it).
        obstacle_culling: leave out an obstacle half-space at a step where
            the QP's own velocity and input limits already imply it (no
            feasible plan can reach the plane then, so the solution is the
            same; see ``DmpcProblem._fill_obstacles``). Chosen: True.
        vertical_obstacle_planes: every obstacle half-space has a horizontal
            normal (vertical planes, as the agent builds around trees and
            boxes); its rows then hold only the x, y input columns, a third
            fewer entries in every KKT refactorisation
            (docs/results/dmpc_qp.md#behind-dmpcconfigs-defaults). A plane with a z component is then
            rejected. Chosen default: False (general planes).
        terminal_halt: if true, v[K] = 0 (and a[K] = 0 for the triple
            integrator), DMPC-Swarm Eq. 13e; makes a shifted plan a feasible
            candidate, i.e. recursive feasibility of the BVC problem.
        osqp_eps_abs: OSQP absolute tolerance (chosen: 1e-4).
        osqp_eps_rel: OSQP relative tolerance (chosen: 1e-4).
        osqp_max_iter: OSQP iteration limit (chosen: 10000, well above what
            the hardest on-demand rounds of the 8-drone swap need;
            docs/results/dmpc_qp.md#behind-dmpcconfigs-defaults).
        osqp_check_termination: OSQP checks its residuals every this many
            iterations (chosen: 5 instead of OSQP's 25: a warm-started round
            converges in a few iterations; docs/results/dmpc_qp.md#behind-dmpcconfigs-defaults).
        osqp_polish: run OSQP's solution polishing (exact active-set solve).
        osqp_scaling: OSQP's Ruiz equilibration iterations (OSQP default 10).
            OSQP re-runs them on every matrix update, so they are part of
            each round's refactorisation cost (see ``DmpcProblem``).
    """

    horizon_steps: int = 15
    step_s: float = 0.2
    model: str = "double"
    goal_steps: ClassVar[int] = 3
    weight_goal: float = 100.0
    weight_formation: float = 10.0
    weight_smoothness: float = 1.0
    weight_slack_quadratic: ClassVar[float] = 1.0e4
    weight_slack_linear: ClassVar[float] = 5.0e4
    slack_max_m: ClassVar[float] = 10.0
    pos_min_world: tuple[float, float, float] = (-20.0, -20.0, 0.2)
    pos_max_world: tuple[float, float, float] = (20.0, 20.0, 10.0)
    limits: KinematicLimits = KinematicLimits(2.0, 4.0, 20.0)
    r_min_m: float = 0.4
    downwash: float = 2.0
    collision_mode: str = "on_demand"
    neighbourhood_factor: ClassVar[float] = 3.0
    conflict_margin_m: ClassVar[float] = 0.05
    on_demand_time: ClassVar[str] = "closest_approach"
    conflict_substeps: ClassVar[int] = 4
    max_neighbours: int = 8
    max_obstacle_planes: int = 0
    obstacle_avoidance: str = "auto"
    obstacle_culling: ClassVar[bool] = True
    vertical_obstacle_planes: bool = False
    terminal_halt: bool = False
    osqp_eps_abs: ClassVar[float] = 1e-4
    osqp_eps_rel: ClassVar[float] = 1e-4
    osqp_max_iter: ClassVar[int] = 10000
    osqp_check_termination: ClassVar[int] = 5
    osqp_polish: ClassVar[bool] = False
    osqp_scaling: ClassVar[int] = 4

    def __post_init__(self) -> None:
        require_integer_at_least("horizon_steps", self.horizon_steps, 2)
        require_positive("step_s", self.step_s)
        if self.model not in _MODELS:
            raise ConfigError("model", self.model, f"one of {', '.join(_MODELS)}")
        if not isinstance(self.goal_steps, (int, np.integer)) or self.goal_steps < 1:
            raise ConfigError("goal_steps", self.goal_steps, "an integer >= 1")
        if self.horizon_steps < self.goal_steps:
            raise ConfigError("horizon_steps", self.horizon_steps, f"an integer >= goal_steps = {self.goal_steps} (the steps pulled to the goal)")
        require_positive("weight_goal", self.weight_goal)
        for name in ("weight_formation", "weight_smoothness", "weight_slack_linear"):
            require_non_negative(name, getattr(self, name))
        require_positive("weight_slack_quadratic", self.weight_slack_quadratic)
        require_positive("slack_max_m", self.slack_max_m)
        require_box("pos_min_world", self.pos_min_world, "pos_max_world", self.pos_max_world)
        require_instance("limits", self.limits, KinematicLimits)
        for name in ("r_min_m", "neighbourhood_factor"):
            require_positive(name, getattr(self, name))
        require_at_least("downwash", self.downwash, 1.0)
        if self.collision_mode not in _COLLISION_MODES:
            raise ConfigError("collision_mode", self.collision_mode, f"one of {', '.join(_COLLISION_MODES)}")
        if self.neighbourhood_factor < 1.0:
            raise ConfigError("neighbourhood_factor", self.neighbourhood_factor, "a number >= 1")
        require_non_negative("conflict_margin_m", self.conflict_margin_m)
        if self.on_demand_time not in ("first_conflict", "closest_approach"):
            raise ConfigError("on_demand_time", self.on_demand_time, "one of first_conflict, closest_approach")
        require_integer_at_least("conflict_substeps", self.conflict_substeps, 1)
        require_integer_at_least("max_neighbours", self.max_neighbours, 1)
        require_integer_at_least("max_obstacle_planes", self.max_obstacle_planes, 0)
        if self.obstacle_avoidance not in _OBSTACLE_MODES:
            raise ConfigError("obstacle_avoidance", self.obstacle_avoidance, f"one of {', '.join(_OBSTACLE_MODES)}")
        for name in ("vertical_obstacle_planes", "obstacle_culling", "terminal_halt"):
            require_boolean(name, getattr(self, name))
        require_positive("osqp_eps_abs", self.osqp_eps_abs)
        require_positive("osqp_eps_rel", self.osqp_eps_rel)
        require_integer_at_least("osqp_max_iter", self.osqp_max_iter, 1)
        require_integer_at_least("osqp_check_termination", self.osqp_check_termination, 1)
        require_integer_at_least("osqp_scaling", self.osqp_scaling, 0)
        require_boolean("osqp_polish", self.osqp_polish)

    @property
    def state_dim(self) -> int:
        """Dimension of the state: 6 (double) or 9 (triple)."""
        return 6 if self.model == "double" else 9

    @property
    def obstacle_mode(self) -> str:
        """``obstacle_avoidance`` resolved: ``"on_demand"`` or ``"every_step"`` ("auto" follows ``collision_mode``)."""
        if self.obstacle_avoidance != "auto":
            return self.obstacle_avoidance
        return "on_demand" if self.collision_mode == "on_demand" else "every_step"

    @property
    def horizon_s(self) -> float:
        """Prediction horizon K h in [s]."""
        return self.horizon_steps * self.step_s

    @property
    def theta_inv_diag(self) -> np.ndarray:
        """(3,) diagonal of Theta^-1 = diag(1, 1, 1/c) (DMPC-Swarm Eq. 2)."""
        return np.array([1.0, 1.0, 1.0 / self.downwash])
