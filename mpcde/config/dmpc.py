"""The ``dmpc:`` section of a scenario: settings of the communicating (DMPC) stack.

The stack flies one of two explicit schemes, and no setting replaces another:

* committing (the default, DMPC-Swarm's promise under message loss):
  ``commit_when_unheard: true`` with ``qp.collision_mode: bvc`` and
  ``qp.terminal_halt: true`` (the defaults of :class:`CommQpConfig`);
* replanning: ``commit_when_unheard: false`` with any QP. The plain DMPC of the
  on-demand paper is ``commit_when_unheard: false``,
  ``qp.collision_mode: on_demand``, ``qp.terminal_halt: false``
  (:meth:`DmpcAgentConfig.replanning`).

``commit_when_unheard: true`` with on-demand rows, without the halt or with
on-demand obstacle rows is refused at load time, one line naming both fields.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

from mpcde.errors import ConfigError
from planners.dmpc.config import DmpcConfig
from planners.dmpc.start_state import TOLERANCE_M, TOLERANCE_MPS

__all__ = ["CommQpConfig", "DmpcAgentConfig"]


@dataclass(frozen=True)
class CommQpConfig(DmpcConfig):
    """The ``dmpc.qp`` section: :class:`planners.dmpc.DmpcConfig` with the defaults the comm stack flies.

    The planner's own defaults are the on-demand DMPC paper's; the stack's
    default scheme commits when unheard (:class:`DmpcAgentConfig`), which needs
    buffered Voronoi planes and halting plans, so this section's defaults say
    so, for a file that sets only some of its fields as for one that sets none.
    Every other field and its meaning is :class:`~planners.dmpc.DmpcConfig`'s.

    Attributes:
        collision_mode: ``"bvc"`` (DMPC-Swarm Eq. 14-15; see
            :class:`~planners.dmpc.DmpcConfig`), what ``commit_when_unheard``
            needs.
        terminal_halt: True: v[K] = 0 (DMPC-Swarm Eq. 13e), what
            ``commit_when_unheard`` needs.
        max_obstacle_planes: 4 obstacle-plane slots (allocated only when the
            scenario has obstacles).
    """

    collision_mode: str = "bvc"
    terminal_halt: bool = True
    max_obstacle_planes: int = 4


@dataclass(frozen=True)
class DmpcAgentConfig:
    """DMPC settings of a scenario (the ``dmpc:`` mapping of a scenario file).

    Attributes:
        qp: the per-drone QP (:class:`CommQpConfig`, a
            :class:`planners.dmpc.DmpcConfig`); ``qp.step_s`` must equal
            ``1 / radio.rate_hz`` (one round per step). Default: buffered
            Voronoi planes, halting plans, 4 obstacle-plane slots.
        formation_from_goals: keep the formation the goals form: the desired
            offset to neighbour j is d_ij = goal_j - goal_i (on-demand DMPC
            design goal 2), weighted by ``qp.weight_formation``.
        plan_timeout_s: a neighbour's plan older than this [s] is dropped
            (chosen: 3.0 s, the QP horizon K h; beyond it the plan says nothing).
        obstacle_margin_m: clearance [m] kept from an obstacle surface on top
            of the robot radius (chosen: 0.25 m, a few times the controller's
            tracking error at 2 m/s).
        obstacle_range_m: obstacles whose footprint comes closer than this [m]
            to the previous plan get a plane (chosen: 3.0 m). With
            ``commit_when_unheard`` it is derived at load time
            (:mod:`mpcde.config.resolve`): max(3.0, sqrt(2) v_max_mps K h + the
            inflation), every obstacle a plan flown to its halt unrevised can
            reach; a file that sets another value is refused.
        goal_lookahead_m: the QP's goal is the point this far [m] along the
            line to the real goal when the goal is farther (a carrot; 0 =
            always the real goal, the paper's form). Chosen: 4.0 m, two
            thirds of what v_max_mps = 2 m/s covers in the 3 s horizon. With a
            far goal the terminal cost pins the plan to the speed limit at
            every step and OSQP needs many more iterations
            (docs/results/dmpc_agent.md#the-carrot-goal-dmpcgoal_lookahead_m).
        state_tolerance_m: x0 is the own plan's state when the estimated
            position is within this of it [m], else the estimate (0 = always
            the estimate). Chosen: 0.3 m, above the pose estimate's drift; the
            rule, shared with ADMM, and the drift argument:
            :mod:`planners.dmpc.start_state`.
        state_tolerance_mps: the same bound on the velocity [m/s] (chosen: 0.3).
        commit_when_unheard: keep DMPC-Swarm's promise under message loss. A
            neighbour's last plan is kept as broadcast, halt included, however
            old (``plan_timeout_s`` then drops only plans that do not halt), and
            in a round where a neighbour near the own plan sent nothing new (so
            it may not have heard this drone either) the drone does not replan:
            it flies its last broadcast plan, which that neighbour planned
            against, toward its halt. The promise rests on three QP settings,
            required (not replaced) while this is true, each refused otherwise
            with one line naming both fields: ``qp.collision_mode: bvc`` (buffered
            Voronoi planes between the previous plans, Eq. 14-15, which both
            drones of a pair compute alike, so plans solved in the same round
            stay apart; on-demand rows do not), ``qp.terminal_halt: true``
            (every plan ends in a halt, Eq. 13e) and obstacle rows at every step
            (``qp.obstacle_avoidance`` ``auto`` or ``every_step``: a plan flown to
            its halt unrevised must clear the obstacles over its whole horizon,
            not only at its first predicted conflict). It also plans against
            every obstacle the plan can reach: ``obstacle_range_m`` is derived.
            On by default: it keeps the stack's plans apart under message loss
            (docs/results/comm_safety.md#the-full-outage-sweep-plain-cells-included).
            False: replan every round
            against shifted stale plans, with the QP as ``qp`` says
            (:meth:`replanning` gives the on-demand paper's plain DMPC).
            In ``auto`` a stale plan that a camera track replaces no longer counts
            as unheard.
        commit_range_m: a neighbour is near when its last plan comes within this
            [m] of the own plan at a common time over the horizon (chosen: 12 m =
            2 v_max_mps K h at the defaults: two drones replanning unheard can each
            move v_max_mps K h from where the other expects them).
        deadlock_turn_deg: with ``qp.collision_mode: bvc``, a drone whose solved plan has
            stalled short of its goal (it ends within 0.1 m of the start, the goal
            is farther than 0.5 m) turns its carrot this far [deg] to the right:
            the right-hand rule that breaks the symmetric deadlocks of buffered
            Voronoi planes (chosen: 60; 0 = off).
        perceive_neighbours: run the drone's detector and tracker on its frames
            (DESIGN.md: perception runs in every mode, so the tracks are warm
            when an outage starts; settings in the scenario's ``perception:``).
            In ``comm`` mode the tracks are scored (``tracking_*`` metrics) and
            not planned against; the ``auto`` mode plans against them when a
            neighbour's plan is stale (:mod:`mpcde.onboard.fusion`).
    """

    qp: CommQpConfig = field(default_factory=CommQpConfig)
    formation_from_goals: bool = False
    plan_timeout_s: float = 3.0
    obstacle_margin_m: float = 0.25
    obstacle_range_m: float = 3.0
    goal_lookahead_m: float = 4.0
    state_tolerance_m: float = TOLERANCE_M
    state_tolerance_mps: float = TOLERANCE_MPS
    perceive_neighbours: bool = True
    commit_when_unheard: bool = True
    commit_range_m: float = 12.0
    deadlock_turn_deg: float = 60.0

    def __post_init__(self) -> None:
        if not (math.isfinite(self.plan_timeout_s) and self.plan_timeout_s > 0):
            raise ConfigError("plan_timeout_s", self.plan_timeout_s, "a number > 0 [s]")
        if not (math.isfinite(self.obstacle_margin_m) and self.obstacle_margin_m >= 0):
            raise ConfigError("obstacle_margin_m", self.obstacle_margin_m, "a number >= 0 [m]")
        if not (math.isfinite(self.obstacle_range_m) and self.obstacle_range_m > 0):
            raise ConfigError("obstacle_range_m", self.obstacle_range_m, "a number > 0 [m]")
        if not isinstance(self.commit_when_unheard, bool):
            raise ConfigError("commit_when_unheard", self.commit_when_unheard, "true or false")
        if self.commit_when_unheard:
            self._check_committing_qp()
        if not (isinstance(self.deadlock_turn_deg, (int, float)) and 0 <= self.deadlock_turn_deg <= 90):
            raise ConfigError("deadlock_turn_deg", self.deadlock_turn_deg, "a number in [0, 90] [deg]")
        if not (isinstance(self.commit_range_m, (int, float)) and math.isfinite(self.commit_range_m) and self.commit_range_m >= 0):
            raise ConfigError("commit_range_m", self.commit_range_m, "a number >= 0 [m]")
        for name in ("goal_lookahead_m", "state_tolerance_m", "state_tolerance_mps"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value >= 0):
                raise ConfigError(name, value, "a number >= 0")

    def _check_committing_qp(self) -> None:
        """ConfigError naming the QP field and ``dmpc.commit_when_unheard`` when the QP breaks the committing scheme."""
        qp, why = self.qp, "while dmpc.commit_when_unheard is true"
        other = "or set dmpc.commit_when_unheard: false"
        if qp.collision_mode != "bvc":
            raise ConfigError(
                "qp.collision_mode", qp.collision_mode,
                f"'bvc' {why} (its plans stay apart only under buffered Voronoi planes, which both drones of a pair compute alike); {other}",
            )  # fmt: skip
        if qp.terminal_halt is not True:
            raise ConfigError("qp.terminal_halt", qp.terminal_halt, f"true {why} (a committed plan is flown to its halt); {other}")
        if qp.max_obstacle_planes and qp.obstacle_mode != "every_step":
            raise ConfigError(
                "qp.obstacle_avoidance", qp.obstacle_avoidance,
                f"'auto' or 'every_step' {why} (a plan flown to its halt unrevised must clear obstacles at every step); {other}",
            )  # fmt: skip

    def replanning(self, collision_mode: str = "on_demand") -> DmpcAgentConfig:
        """These settings as the replanning scheme: every round replanned against shifted stale plans, no halt.

        With the default ``collision_mode`` this is the plain DMPC of the
        on-demand paper (on-demand collision rows, Sec. 3.4); with ``"bvc"``
        the buffered-Voronoi-cell baseline under the same DMPC. The obstacle
        rows follow ``qp.obstacle_avoidance`` (``auto`` pairs them with the
        collision mode).
        """
        qp = replace(self.qp, collision_mode=collision_mode, terminal_halt=False)
        return replace(self, commit_when_unheard=False, qp=qp)
