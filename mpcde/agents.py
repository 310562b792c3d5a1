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
    raise AssertionError(f"planner.kind={kind!r} has no agent")  # unreachable: PlannerConfig validates kind
