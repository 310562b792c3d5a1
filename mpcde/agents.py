"""Builds each drone's onboard agent for the scenario's planner kind.

The one place that maps ``planner.kind`` to an agent class; every agent
implements :class:`mpcde.agent.OnboardAgent`.
"""

from __future__ import annotations

import numpy as np

from mpcde.agent import Agent, OnboardAgent
from mpcde.scenario import ScenarioConfig

__all__ = ["make_agent"]


def make_agent(cfg: ScenarioConfig, drone_id: int, goal_world: np.ndarray, n_drones: int) -> OnboardAgent:
    """The onboard agent of drone ``drone_id`` flying to ``goal_world`` (3,) [m]."""
    kind = cfg.planner.kind
    if kind == "min_jerk_line":
        return Agent(drone_id, np.asarray(goal_world, float), cfg.planner.cruise_speed_mps, cfg.planner.start_delay_s)
    if kind == "mpcde":
        from mpcde.agent_denied import DeniedAgent

        return DeniedAgent(drone_id, goal_world, cfg.denied)
    if kind == "dmpc":
        from mpcde.agent_dmpc import DmpcAgent
        from mpcde.scenario import build_layout, resolve_obstacles

        starts, goals = build_layout(cfg.drones)  # the mission (goals) and the prior map (static obstacles)
        offsets = {j: goals[j] - goals[drone_id] for j in range(n_drones) if j != drone_id} if cfg.dmpc.formation_from_goals else None
        obstacles = resolve_obstacles(cfg, starts, goals)
        return DmpcAgent(drone_id, goal_world, cfg.dmpc, cfg.planner.start_delay_s, offsets, obstacles, cfg.physics.quadrotor.robot_radius_m)
    raise AssertionError(f"planner.kind={kind!r} has no agent")  # unreachable: PlannerConfig validates kind
