"""Builds each drone's onboard agent for the scenario's planner kind.

The one place that maps ``planner.kind`` to an agent class; every agent
implements :class:`mpcde.onboard.base.OnboardAgent`.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from mpcde.config.auto import FusionConfig
from mpcde.config.dmpc import DmpcAgentConfig
from mpcde.config.perception import PerceptionConfig
from mpcde.config.scenario import ScenarioConfig
from mpcde.onboard.admm import AdmmAgent
from mpcde.onboard.auto import AutoAgent
from mpcde.onboard.base import OnboardAgent
from mpcde.onboard.budget import ComputeBudget
from mpcde.onboard.denied import DeniedAgent
from mpcde.onboard.dmpc import DmpcAgent
from mpcde.onboard.minco_comm import MincoCommAgent
from mpcde.onboard.mlr import MlrAgent
from mpcde.onboard.perception import NeighbourPerception
from mpcde.onboard.placeholder import Agent
from sim.types import ObstacleSpec

__all__ = ["make_agent"]


def make_agent(
    cfg: ScenarioConfig, drone_id: int, goals_world: np.ndarray, obstacles: tuple[ObstacleSpec, ...],
    budget: ComputeBudget | None = None,
) -> OnboardAgent:
    """The onboard agent of drone ``drone_id``.

    Args:
        goals_world: (N, 3) every drone's goal [m] (the mission; a DMPC or
            ADMM formation takes its offsets from them).
        obstacles: the static obstacles, given only to the DMPC agent as its
            prior map (the on-demand DMPC paper assumes known obstacles); the
            other stacks map with their cameras.
        budget: the run's per-component compute time (the perceiving and DMPC agents book into it).
    """
    goal_world = np.asarray(goals_world[drone_id], float)
    kind = cfg.planner.kind
    if kind == "min_jerk_line":
        return Agent(drone_id, np.asarray(goal_world, float), cfg.planner.line_speed_mps, cfg.planner.start_delay_s)
    if kind == "mlr":  # MLR-DMPC does not perceive: no detector, no tracks
        mlr = cfg.mlr.planner_config(len(goals_world), cfg.world.arena_size_m)
        return MlrAgent(drone_id, goals_world, mlr, cfg.planner.start_delay_s, cfg.mlr.ignore_message_loss)
    if kind == "admm":  # the ADMM formation DMPC does not perceive either; the goals are its formation
        p = cfg.planner
        return AdmmAgent(drone_id, goals_world, cfg.admm, cfg.world.arena_size_m, p.start_delay_s, p.line_speed_mps)
    # cfg is resolved (prepare_run): the back-projection's pose noise and the yaw planner's limits are derived
    perception = cfg.perception
    roster = len(goals_world) - 1  # the other drones launched with this one (the yaw planner's roster_aware)
    if kind == "mpcde":
        return DeniedAgent(drone_id, goal_world, cfg.denied, perception, budget=budget, swarm_neighbours=roster)
    if kind == "dmpc":
        return _dmpc_agent(cfg, drone_id, goals_world, obstacles, perception, cfg.dmpc, budget=budget)
    if kind == "minco_comm":  # the denied stack's planner and map, neighbours from the radio
        return MincoCommAgent(drone_id, goal_world, cfg.denied, budget=budget)
    if kind == "auto":
        denied = DeniedAgent(drone_id, goal_world, cfg.denied, perception, budget=budget, swarm_neighbours=roster)
        # one perception for both halves; denied.perceive_neighbours: false turns it off for both
        dmpc = replace(cfg.dmpc, perceive_neighbours=denied.perception is not None)
        comm = _dmpc_agent(cfg, drone_id, goals_world, obstacles, perception, dmpc, denied.perception, cfg.auto.fusion, budget)
        return AutoAgent(cfg.auto, comm, denied)
    raise AssertionError(f"planner.kind={kind!r} has no agent")  # unreachable: PlannerConfig validates kind


def _dmpc_agent(
    cfg: ScenarioConfig, drone_id: int, goals_world: np.ndarray, obstacles: tuple[ObstacleSpec, ...],
    perception_config: PerceptionConfig, dmpc: DmpcAgentConfig, perception: NeighbourPerception | None = None,
    fusion: FusionConfig | None = None, budget: ComputeBudget | None = None,
) -> DmpcAgent:
    """The DMPC agent of ``drone_id`` (formation offsets from the goals when configured)."""
    goals = np.asarray(goals_world, float)
    offsets = None
    if dmpc.formation_from_goals:
        offsets = {j: goals[j] - goals[drone_id] for j in range(len(goals)) if j != drone_id}
    return DmpcAgent(
        drone_id, goals[drone_id], dmpc, cfg.planner.start_delay_s, offsets, obstacles, cfg.physics.quadrotor.robot_radius_m,
        perception_config, perception, fusion, budget,
    )  # fmt: skip
