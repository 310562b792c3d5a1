"""Builds each drone's onboard agent for the scenario's planner kind.

The one place that maps ``planner.kind`` to an agent class; every agent
implements :class:`mpcde.agent.OnboardAgent`.
"""

from __future__ import annotations

import numpy as np

from mpcde.agent import Agent, OnboardAgent
from mpcde.scenario import ScenarioConfig
from sim.obstacles import ObstacleSpec

__all__ = ["make_agent"]


def make_agent(cfg: ScenarioConfig, drone_id: int, goals_world: np.ndarray, obstacles: tuple[ObstacleSpec, ...]) -> OnboardAgent:
    """The onboard agent of drone ``drone_id``.

    Args:
        goals_world: (N, 3) every drone's goal [m] (the mission; a DMPC
            formation takes its offsets from them).
        obstacles: the static obstacles, given only to the DMPC agent as its
            prior map (the on-demand DMPC paper assumes known obstacles); the
            other stacks map with their cameras.
    """
    goal_world = np.asarray(goals_world[drone_id], float)
    n_drones = len(goals_world)
    kind = cfg.planner.kind
    if kind == "min_jerk_line":
        return Agent(drone_id, np.asarray(goal_world, float), cfg.planner.cruise_speed_mps, cfg.planner.start_delay_s)
    if kind == "mpcde":
        from dataclasses import replace

        from mpcde.agent_denied import DeniedAgent

        # back-projection uncertainty includes the drone's own localisation noise (what its VIO reports)
        pe = cfg.pose_estimate
        bp = replace(cfg.denied.backprojection, pose_pos_std_m=pe.pos_noise_m, pose_yaw_std_rad=pe.yaw_noise_rad)
        fov = (cfg.camera.hfov_deg, cfg.camera.vfov_deg)
        return DeniedAgent(drone_id, goal_world, replace(cfg.denied, backprojection=bp), fov)
    if kind == "dmpc":
        from mpcde.agent_dmpc import DmpcAgent

        goals = np.asarray(goals_world, float)
        offsets = {j: goals[j] - goals[drone_id] for j in range(n_drones) if j != drone_id} if cfg.dmpc.formation_from_goals else None
        return DmpcAgent(drone_id, goal_world, cfg.dmpc, cfg.planner.start_delay_s, offsets, obstacles, cfg.physics.quadrotor.robot_radius_m)
    raise AssertionError(f"planner.kind={kind!r} has no agent")  # unreachable: PlannerConfig validates kind
