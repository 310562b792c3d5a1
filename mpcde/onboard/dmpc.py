"""The communicating onboard agent: DMPC over exchanged plans (``planner.kind: dmpc``).

Every radio round (period ``radio.rate_hz``, which must equal the QP step h;
DESIGN.md section 3) the loop first hands the agent its inbox
(:meth:`DmpcAgent.on_radio`), then asks for its broadcast
(:meth:`DmpcAgent.outgoing`). In ``outgoing(t)`` the agent

1. builds its state x0 at t from its own pose estimate (position extrapolated
   from the estimate's time with the estimated velocity; velocity; for the
   triple integrator the acceleration of its own previous plan at t). When
   the estimate agrees with the own previous plan's state at t within
   ``state_tolerance_m`` and ``state_tolerance_mps`` (the controller is
   tracking the plan), x0 is the plan's state instead: the rule shared with
   the ADMM agent, and why, in :mod:`planners.dmpc.start_state`. Setting both
   tolerances to 0 always replans from the estimate.
2. turns the neighbours' latest received plans into
   :class:`perception.types.NeighborPrediction` (source ``"radio"``, stamped
   with the send time, so ``age_s`` is the plan's age). A neighbour with no new
   plan in this round's inbox is planned against with its last plan, evaluated
   at the current times (i.e. shifted; beyond its horizon it extrapolates at
   constant velocity) and counted *stale*; a plan older than
   ``plan_timeout_s`` is dropped,
3. solves its QP (:class:`planners.dmpc.DmpcProblem`; on-demand DMPC Sec. 3,
   or the BVC baseline, DMPC-Swarm Eq. 14-15) toward its goal, with formation
   offsets when configured and half-spaces of the known static obstacles,
4. broadcasts the new plan as a :class:`sim.types.PlanMessage`.

The QP is flown as ``dmpc.qp`` sets it: the agent replaces neither its
collision mode nor its halt. The scheme is the configuration's explicit choice
(:mod:`mpcde.config.dmpc`): committing when unheard (``commit_when_unheard``,
which the configuration accepts only with buffered Voronoi planes, halting
plans and every-step obstacle rows) or replanning every round.

If OSQP fails (:class:`planners.dmpc.DmpcSolveError`) the agent keeps flying
its previous plan shifted to t (a *fallback*). :meth:`DmpcAgent.reference`
samples the current plan (position, velocity, acceleration feed-forward) for
the SE(3) controller, at a constant heading (the heading of the first pose
estimate, which the world sets toward the goal).

Static obstacles: the agent is given the scenario's obstacle list as a prior
map (the on-demand DMPC paper plans against "known obstacle positions"); it
never sees another drone's state except through the radio. For each step k of
its previous plan the nearest point of each obstacle's footprint gives a
vertical separating plane n_k^T p[k] >= n_k^T c_k + r_robot + margin (the
tangent plane at the nearest point, pushed out by the inflation), for the
``max_obstacle_planes`` nearest obstacles. The inflation is the obstacle
safety radius r_obs of on-demand DMPC design goal 4. How the QP uses the
planes is ``qp.obstacle_avoidance``: a row at every step, or on demand (one
row per obstacle at its first predicted conflict, the paper's mechanism and
the default with ``collision_mode: on_demand``; :mod:`planners.dmpc.obstacle`).
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import Any, Sequence

import numpy as np

from mpcde.config.auto import FusionConfig
from mpcde.config.dmpc import DmpcAgentConfig
from mpcde.config.perception import PerceptionConfig
from mpcde.onboard.base import AgentCounters, SampledPlanAgent
from mpcde.onboard.budget import ComputeBudget
from mpcde.onboard.fusion import fuse_neighbours
from mpcde.onboard.perception import NeighbourPerception, onboard_perception
from perception.types import NeighborPrediction
from planners.dmpc import DmpcPlan, DmpcProblem, DmpcSolveError
from planners.dmpc.half_spaces import obstacle_half_spaces
from planners.dmpc.plan_sampler import PlanSampler
from planners.dmpc.start_state import plan_start_state
from sim.types import ObstacleSpec, PlanMessage, PoseEstimate, RadioMessage, RgbdFrame

__all__ = ["DmpcAgent", "DmpcRoundStats", "plan_prediction"]

HALT_TOLERANCE_MPS = 1e-3
"""A received plan whose last velocity is below this on every axis [m/s] halts (OSQP meets v[K] = 0 to its tolerance)."""


@dataclass
class DmpcRoundStats:
    """What one agent's rounds did (for metrics; :meth:`DmpcAgent.extra_metrics`).

    Attributes:
        qp_solve_s: per solved round, OSQP's wall time [s] (update + solve, :attr:`DmpcResult.solve_time_s`).
        qp_build_s: per solved round, Python time [s] building the round's constraints.
        iterations: per solved round, OSQP iterations.
        collision_rows: per solved round, active collision constraints.
        obstacle_rows: per solved round, obstacle rows in the QP (after culling; on demand: conflicts).
        refactorisations: solved rounds whose constraint or cost matrix changed, so that OSQP
            refactorised (:attr:`planners.dmpc.DmpcResult.refactorised`).
        statuses: count per OSQP status (failures included).
        fallbacks: rounds flown on the previous plan because OSQP failed.
        commits: rounds flown on the previous plan because a near neighbour sent nothing new
            (``commit_when_unheard``).
        deadlock_turns: rounds whose carrot the right-hand rule turned (``deadlock_turn_deg``).
        state_resets: rounds whose x0 came from the estimate (it disagreed with the plan, or no plan yet).
        stale_plans: neighbour plans used that were not renewed this round.
        fresh_plans: neighbour plans used that arrived this round.
        dropped_plans: neighbour plans dropped for age (``plan_timeout_s``).
        neighbour_age_s: per used neighbour plan, its age [s] at the round.
        substituted_plans: stale plans replaced by the matched camera track (fusion only).
        unknown_tracks: tracks no plan explains, planned against as extra neighbours (fusion only).
    """

    qp_solve_s: list[float] = field(default_factory=list)
    qp_build_s: list[float] = field(default_factory=list)
    iterations: list[int] = field(default_factory=list)
    collision_rows: list[int] = field(default_factory=list)
    obstacle_rows: list[int] = field(default_factory=list)
    refactorisations: int = 0
    statuses: dict[str, int] = field(default_factory=dict)
    fallbacks: int = 0
    commits: int = 0
    deadlock_turns: int = 0
    state_resets: int = 0
    stale_plans: int = 0
    fresh_plans: int = 0
    dropped_plans: int = 0
    neighbour_age_s: list[float] = field(default_factory=list)
    substituted_plans: int = 0
    unknown_tracks: int = 0


class DmpcAgent(SampledPlanAgent):
    """One drone's DMPC agent (a :class:`mpcde.onboard.base.SampledPlanAgent`, so an :class:`~mpcde.onboard.base.OnboardAgent`).

    Args:
        drone_id: index of the drone.
        goal_world: (3,) goal [m].
        config: the scenario's :class:`DmpcAgentConfig`.
        start_delay_s: hover (goal = start) until this time [s]; the first
            rounds exchange plans before anyone departs.
        formation_offsets: desired p_j - p_i (3,) [m] by neighbour id, or None.
        obstacles: the known static obstacles (prior map).
        robot_radius_m: the drone's radius [m] (obstacle inflation).
        perception_config: the scenario's ``perception:`` settings (used when
            ``config.perceive_neighbours``).
        perception: a perception to share (the ``auto`` agent's); None: its own.
        fusion: plan against camera tracks where a neighbour's plan is stale
            (:func:`mpcde.onboard.fusion.fuse_neighbours`); None: radio plans only.
        budget: where the compute time of tracking and of the DMPC round is booked (the run's).
    """

    def __init__(
        self,
        drone_id: int,
        goal_world: np.ndarray,
        config: DmpcAgentConfig,
        start_delay_s: float = 0.0,
        formation_offsets: dict[int, np.ndarray] | None = None,
        obstacles: Sequence[ObstacleSpec] = (),
        robot_radius_m: float = 0.1,
        perception_config: PerceptionConfig | None = None,
        perception: NeighbourPerception | None = None,
        fusion: FusionConfig | None = None,
        budget: ComputeBudget | None = None,
    ) -> None:
        self.drone_id = int(drone_id)
        self.budget = budget if budget is not None else ComputeBudget()
        self.perception, self.detector_request = onboard_perception(config.perceive_neighbours, perception_config, perception)
        self.fusion = fusion if self.perception is not None else None
        self.goal_world = np.asarray(goal_world, float).reshape(3)
        self.config = config
        self.obstacles = tuple(obstacles)
        # The QP flies as configured: collision mode, halt and obstacle rows are never replaced here.
        # DmpcAgentConfig refuses commit_when_unheard with a QP that breaks its promise (on-demand rows,
        # no halt, on-demand obstacle rows). Only the obstacle-plane slots follow the scenario: none without
        # obstacles, and vertical planes (obstacle_half_spaces) so that the QP may drop their z columns.
        qp = replace(config.qp, vertical_obstacle_planes=True) if self.obstacles else replace(config.qp, max_obstacle_planes=0)
        self.qp_config = qp
        self.problem = DmpcProblem(qp)
        self.start_delay_s = float(start_delay_s)
        self.formation_offsets = formation_offsets
        self.inflation_m = float(robot_radius_m) + config.obstacle_margin_m
        self.obstacle_range_m = config.obstacle_range_m  # derived at load under commit_when_unheard (mpcde.stacks.builtin)
        self.counters = AgentCounters()
        self.stats = DmpcRoundStats()
        self.plan: DmpcPlan | None = None
        self._sampler: PlanSampler | None = None
        self.latest_estimate: PoseEstimate | None = None
        self.start_world: np.ndarray | None = None
        self.yaw = 0.0
        self.neighbour_plans: dict[int, PlanMessage] = {}
        self._renewed: set[int] = set()
        self._solved_last = False  # whether the current plan came from a solved QP (not a commit or a fallback)

    # ------------------------------------------------------------------ inputs
    def on_frame(self, frame: RgbdFrame, detections: list | None = None) -> None:
        """Take one camera frame: track the neighbours its detector found (when it perceives)."""
        self.counters.frames += 1
        if self.perception is not None and detections is not None:
            with self.budget.measure("track"):
                self.perception.update(frame, detections)

    def on_radio(self, messages: list[RadioMessage]) -> None:
        """Take this round's inbox: keep each neighbour's newest plan."""
        self._renewed = set()
        for m in messages:
            self.counters.messages += 1
            if isinstance(m.payload, PlanMessage) and m.sender_id != self.drone_id:
                old = self.neighbour_plans.get(m.sender_id)
                if old is None or m.payload.time_s > old.time_s:
                    self.neighbour_plans[m.sender_id] = m.payload
                    self._renewed.add(m.sender_id)
                    self.counters.plans += 1

    # ------------------------------------------------------------------ round
    def _state(self, time_s: float) -> np.ndarray:
        """x0 at ``time_s``: (6,) [p, v] or (9,) [p, v, a], from the estimate or the plan (module docstring)."""
        pos, vel = self.latest_estimate.extrapolated(time_s)
        from_plan = False
        if self.plan is not None:
            cfg = self.config
            plan_pos, plan_vel = self.plan.position(time_s), self.plan.velocity(time_s)
            pos, vel, from_plan = plan_start_state(pos, vel, plan_pos, plan_vel, cfg.state_tolerance_m, cfg.state_tolerance_mps)
        if not from_plan:
            self.stats.state_resets += 1
        if self.qp_config.model == "double":
            return np.r_[pos, vel]
        acc = self.plan.acceleration(time_s) if self.plan is not None else np.zeros(3)
        return np.r_[pos, vel, acc]

    def _predictions(self, time_s: float) -> list[NeighborPrediction]:
        """The neighbours' plans as predictions; counts fresh, stale and dropped plans."""
        out = []
        for j in sorted(self.neighbour_plans):
            msg = self.neighbour_plans[j]
            age = time_s - msg.time_s
            halts = self.config.commit_when_unheard and _halts(msg)
            if age > self.config.plan_timeout_s and not halts:  # a halted plan says where the neighbour waits
                self.stats.dropped_plans += 1
                continue
            if j in self._renewed:
                self.stats.fresh_plans += 1
            else:
                self.stats.stale_plans += 1
            self.stats.neighbour_age_s.append(age)
            out.append(plan_prediction(j, msg))
        self._renewed = set()
        if self.fusion is None:
            return out
        f = self.fusion
        fused = fuse_neighbours(out, self.perception.predictions(time_s), time_s, f.stale_after_s, f.gate_m, self.qp_config.limits.v_max_mps)
        self.stats.substituted_plans += fused.substituted
        self.stats.unknown_tracks += fused.unknown_tracks
        return fused.predictions

    def radio_predictions(self, time_s: float, max_age_s: float) -> list[NeighborPrediction]:
        """The neighbours' last plans sent within ``max_age_s`` [s] of ``time_s`` [s], as predictions (no counting).

        The ``auto`` agent's memory of the radio while it flies the denied stack.
        """
        plans = sorted(self.neighbour_plans.items())
        return [plan_prediction(j, msg) for j, msg in plans if time_s - msg.time_s <= max_age_s]

    def take_over(self, plan: DmpcPlan, yaw: float) -> None:
        """Start flying DMPC from another stack's reference (the ``auto`` agent's return to the radio).

        ``plan`` is the reference being left, sampled at this QP's step from
        the hand-over time; it becomes the previous plan (x0 and warm start of
        the next round, :meth:`_state`) and the reference until that round. The
        heading is held at ``yaw`` [rad] from now on.
        """
        self.plan = plan
        self._sampler = PlanSampler(plan)
        self.yaw = float(yaw)

    def _round_message(self, time_s: float) -> PlanMessage | None:
        """Run this round's DMPC solve at ``time_s`` [s] and return the plan to broadcast (booked as ``dmpc_qp``)."""
        if self.latest_estimate is None:
            return None
        with self.budget.measure("dmpc_qp"):
            return self._round(time_s)

    def _round(self, time_s: float) -> PlanMessage:
        """The DMPC round: obstacle half-spaces, the QP (or the fallback plan), the message."""
        cfg = self.qp_config
        x0 = self._state(time_s)
        goal = self.goal_world if time_s >= self.start_delay_s - 1e-9 else self.start_world
        lookahead = self.config.goal_lookahead_m
        to_goal = goal - x0[:3]
        dist = float(np.linalg.norm(to_goal))
        if lookahead > 0 and dist > lookahead:
            goal = x0[:3] + to_goal * (lookahead / dist)  # carrot on the line to the goal
        renewed = set(self._renewed)
        predictions = self._predictions(time_s)
        if self.plan is not None and self.config.commit_when_unheard and self._unheard_near(time_s, predictions, renewed):
            self.stats.commits += 1  # fly the last broadcast plan toward its halt: what the unheard neighbour planned against
            self._solved_last = False
            return self._message(time_s, self.plan.shifted(time_s))
        if self._stuck(x0, dist):  # right-hand rule: turn the carrot to the right, the same way for every drone
            self.stats.deadlock_turns += 1
            a = -np.deg2rad(self.config.deadlock_turn_deg)
            d = goal - x0[:3]
            goal = x0[:3] + np.array([np.cos(a) * d[0] - np.sin(a) * d[1], np.sin(a) * d[0] + np.cos(a) * d[1], d[2]])
        obstacles = None
        if cfg.max_obstacle_planes:
            t_steps = time_s + cfg.step_s * np.arange(1, cfg.horizon_steps + 1)
            if self.plan is not None:
                path = self.plan.position(t_steps)
            else:
                path = x0[:3] + x0[3:6] * (t_steps - time_s)[:, None]
            obstacles = obstacle_half_spaces(
                path, self.obstacles, self.inflation_m, self.obstacle_range_m, cfg.max_obstacle_planes
            )
        try:
            res = self.problem.solve(
                x0, goal, predictions, self.plan, self.formation_offsets, t_now_s=time_s, obstacles=obstacles
            )  # fmt: skip
        except DmpcSolveError as e:
            self.stats.statuses[e.status] = self.stats.statuses.get(e.status, 0) + 1
            self.stats.fallbacks += 1
            self._solved_last = False
            if self.plan is None:
                self.plan = DmpcPlan.hover(time_s, cfg.step_s, cfg.horizon_steps, x0[:3])
            else:
                self.plan = self.plan.shifted(time_s)
        else:
            self.stats.statuses[res.status] = self.stats.statuses.get(res.status, 0) + 1
            self.stats.qp_solve_s.append(res.solve_time_s)
            self.stats.qp_build_s.append(res.update_time_s)
            self.stats.iterations.append(res.iterations)
            self.stats.collision_rows.append(res.n_collision_constraints)
            self.stats.obstacle_rows.append(res.n_obstacle_rows)
            self.stats.refactorisations += int(res.refactorised)
            self._solved_last = True
            self.plan = res.plan
        return self._message(time_s, self.plan)

    def _message(self, time_s: float, plan: DmpcPlan) -> PlanMessage:
        """Fly ``plan`` from now on and return it as this round's broadcast."""
        self.plan = plan
        self._sampler = PlanSampler(plan)
        return PlanMessage(
            sender_id=self.drone_id, time_s=float(time_s), times_s=plan.times_s.copy(),
            pos_world=plan.pos_world.copy(), vel_world=plan.vel_world.copy(),
        )  # fmt: skip

    def _stuck(self, x0: np.ndarray, dist_to_goal: float) -> bool:
        """Whether the own plan has stalled short of the goal: it ends within 0.1 m of x0 while the goal is farther than 0.5 m.

        Buffered Voronoi planes (``qp.collision_mode: bvc``, committing or not) let drones that
        face each other symmetrically stop at their planes for good (the deadlock of BVC;
        DMPC-Swarm resolves it apart); the right-hand rule breaks the symmetry. On-demand rows
        are soft and do not deadlock so, and the rule is off with them.
        """
        if self.qp_config.collision_mode != "bvc" or self.config.deadlock_turn_deg == 0 or self.plan is None:
            return False
        if self.plan.t0_s < self.start_delay_s - 1e-9 or not self._solved_last:  # held the start, or committed / fell back
            return False
        return dist_to_goal > 0.5 and float(np.linalg.norm(self.plan.pos_world[-1] - x0[:3])) < 0.1

    def _unheard_near(self, time_s: float, predictions: list[NeighborPrediction], renewed: set[int]) -> bool:
        """Whether a neighbour whose plan (not a camera track) was not renewed this round comes within ``commit_range_m`` of the own plan."""
        t = self.plan.times_s
        t = t[t >= time_s - 1e-9]
        if t.size == 0:
            return False
        mine = self.plan.position(t)
        for p in predictions:
            if p.source != "radio" or p.neighbor_id in renewed:
                continue
            if float(np.min(np.linalg.norm(p.position(t) - mine, axis=1))) < self.config.commit_range_m:
                return True
        return False

    # ------------------------------------------------------------------ metrics
    def extra_metrics(self) -> dict[str, Any]:
        """This agent's DMPC statistics (the loop adds them to ``metrics.json`` under ``agents``).

        ``qp_solve_ms`` is the list of every solved round's OSQP time [ms]
        (update + solve), so an evaluation can pool rounds across drones.
        ``collision_mode``, ``obstacle_avoidance`` (resolved; None without
        obstacle planes) and ``terminal_halt`` are read from the QP the agent
        built, and ``commit_when_unheard`` from its settings: what it flew.
        """
        s = self.stats
        flown = self.problem.config
        solve_ms = np.asarray(s.qp_solve_s) * 1e3

        def stat(values: np.ndarray, q: float) -> float | None:
            return float(np.percentile(values, q)) if values.size else None

        return {
            "drone_id": self.drone_id,
            "planner": "dmpc",
            "collision_mode": flown.collision_mode,
            "obstacle_avoidance": flown.obstacle_mode if flown.max_obstacle_planes else None,
            "terminal_halt": flown.terminal_halt,
            "commit_when_unheard": self.config.commit_when_unheard,
            "rounds": len(s.qp_solve_s) + s.fallbacks,
            "solves": len(s.qp_solve_s),
            "fallbacks": s.fallbacks,
            "commits": s.commits,
            "deadlock_turns": s.deadlock_turns,
            "state_resets": s.state_resets,
            "statuses": dict(s.statuses),
            "fresh_plans": s.fresh_plans,
            "stale_plans": s.stale_plans,
            "dropped_plans": s.dropped_plans,
            "mean_neighbour_age_s": float(np.mean(s.neighbour_age_s)) if s.neighbour_age_s else None,
            "substituted_plans": s.substituted_plans,
            "unknown_tracks": s.unknown_tracks,
            "qp_ms_median": stat(solve_ms, 50),
            "qp_ms_p95": stat(solve_ms, 95),
            "qp_build_ms_median": stat(np.asarray(s.qp_build_s) * 1e3, 50),
            "mean_iterations": float(np.mean(s.iterations)) if s.iterations else None,
            "mean_collision_rows": float(np.mean(s.collision_rows)) if s.collision_rows else None,
            "mean_obstacle_rows": float(np.mean(s.obstacle_rows)) if s.obstacle_rows else None,
            "obstacle_row_rounds": int(np.count_nonzero(s.obstacle_rows)),
            "refactorisations": s.refactorisations,
            "qp_solve_ms": [round(float(v), 5) for v in solve_ms],
            **(self.perception.counts.metrics() if self.perception is not None else {}),
        }


def _halts(msg: PlanMessage) -> bool:
    """Whether a received plan ends at rest (a halting plan, DMPC-Swarm Eq. 13e)."""
    return bool(np.all(np.abs(np.asarray(msg.vel_world)[-1]) < HALT_TOLERANCE_MPS))


def plan_prediction(neighbor_id: int, msg: PlanMessage) -> NeighborPrediction:
    """A received plan as an exact (zero-covariance) radio prediction."""
    return NeighborPrediction(
        neighbor_id=neighbor_id, source="radio", stamp_s=msg.time_s, times_s=np.asarray(msg.times_s, float),
        pos_world=np.asarray(msg.pos_world, float), vel_world=np.asarray(msg.vel_world, float), cov_world=np.zeros((6, 6)),
    )  # fmt: skip
