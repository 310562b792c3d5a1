"""The ``dmpc:`` section of a scenario: settings of the communicating (DMPC) stack."""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from mpcde.errors import ConfigError
from planners.dmpc.config import DmpcConfig
from planners.dmpc.start_state import TOLERANCE_M, TOLERANCE_MPS

__all__ = ["DmpcAgentConfig"]


@dataclass(frozen=True)
class DmpcAgentConfig:
    """DMPC settings of a scenario (the ``dmpc:`` mapping of a scenario file).

    Attributes:
        qp: the per-drone QP (:class:`planners.dmpc.DmpcConfig`); ``qp.step_s``
            must equal ``1 / radio.rate_hz`` (one round per step). Default: the
            QP's defaults with 4 obstacle-plane slots (allocated only when the
            scenario has obstacles).
        formation_from_goals: keep the formation the goals form: the desired
            offset to neighbour j is d_ij = goal_j - goal_i (on-demand DMPC
            design goal 2), weighted by ``qp.weight_formation``.
        plan_timeout_s: a neighbour's plan older than this [s] is dropped
            (chosen: 3.0 s, the QP horizon K h; beyond it the plan says nothing).
        obstacle_margin_m: clearance [m] kept from an obstacle surface on top
            of the robot radius (chosen: 0.25 m, a few times the controller's
            tracking error at 2 m/s).
        obstacle_range_m: obstacles whose footprint comes closer than this [m]
            to the previous plan get a plane (chosen: 3.0 m).
        goal_lookahead_m: the QP's goal is the point this far [m] along the
            line to the real goal when the goal is farther (a carrot; 0 =
            always the real goal, the paper's form). Chosen: 4.0 m, two
            thirds of what v_max = 2 m/s covers in the 3 s horizon. With a
            far goal the terminal cost pins the plan to the speed limit at
            every step and OSQP needs many more iterations (measured:
            docs/results/dmpc_agent.md).
        state_tolerance_m: x0 is the own plan's state when the estimated
            position is within this of it [m], else the estimate (0 = always
            the estimate). Chosen: 0.3 m, above the pose estimate's drift; the
            rule, shared with ADMM, and the drift argument:
            :mod:`planners.dmpc.start_state`.
        state_tolerance_mps: the same bound on the velocity [m/s] (chosen: 0.3).
        commit_when_unheard: keep DMPC-Swarm's promise under message loss. Every
            plan ends in a halt (the QP's terminal constraint v[K] = 0, Eq. 13e,
            is forced on), the drone-drone constraints are buffered Voronoi
            planes between the previous plans (Eq. 14-15; ``qp.collision_mode``
            is forced to ``bvc``, and the obstacle rows follow it to every step and
            cover every obstacle the plan can reach, ``obstacle_range_m`` raised to
            sqrt(2) v_max K h + the inflation, so that a plan flown to its halt
            clears the obstacles over its whole horizon), so that
            plans solved in the same round stay apart; a neighbour's last plan is kept as broadcast, halt
            included, however old (``plan_timeout_s`` then drops only plans that
            do not halt), and in a round where a neighbour near the own plan sent
            nothing new (so it may not have heard this drone either) the drone
            does not replan: it flies its last broadcast plan, which that
            neighbour planned against, toward its halt. False: the plain DMPC
            of the paper (replan every round against shifted stale plans).
            In ``auto`` a stale plan that a camera track replaces no longer counts
            as unheard.
        commit_range_m: a neighbour is near when its last plan comes within this
            [m] of the own plan at a common time over the horizon (chosen: 12 m =
            2 v_max K h at the defaults: two drones replanning unheard can each
            move v_max K h from where the other expects them).
        deadlock_turn_deg: with ``commit_when_unheard``, a drone whose plan has
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

    qp: DmpcConfig = field(default_factory=lambda: DmpcConfig(max_obstacle_planes=4))
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
        if not (isinstance(self.deadlock_turn_deg, (int, float)) and 0 <= self.deadlock_turn_deg <= 90):
            raise ConfigError("deadlock_turn_deg", self.deadlock_turn_deg, "a number in [0, 90] [deg]")
        if not (isinstance(self.commit_range_m, (int, float)) and math.isfinite(self.commit_range_m) and self.commit_range_m >= 0):
            raise ConfigError("commit_range_m", self.commit_range_m, "a number >= 0 [m]")
        for name in ("goal_lookahead_m", "state_tolerance_m", "state_tolerance_mps"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value >= 0):
                raise ConfigError(name, value, "a number >= 0")
