"""Builds each drone's onboard agent from the registry entry of the scenario's stack.

The one place that turns a scenario into agents; every agent implements
:class:`mpcde.onboard.base.OnboardAgent`.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from mpcde.stacks.registry import AgentContext, stack_of

__all__ = ["make_agent"]


def make_agent(cfg: Any, drone_id: int, goals_world: np.ndarray, obstacles: tuple = (), budget: Any = None) -> Any:
    """The onboard agent of drone ``drone_id`` for the stack ``cfg.planner.kind`` names.

    Args:
        cfg: the resolved scenario (:func:`mpcde.flight.loop.prepare_run`).
        goals_world: (N, 3) every drone's goal [m] (the mission; a DMPC or
            ADMM formation takes its offsets from them).
        obstacles: the static obstacles (:class:`sim.types.ObstacleSpec`),
            passed on only to a stack whose ``uses.known_obstacles`` (the
            on-demand DMPC paper's prior map); the others map with their cameras.
        budget: the run's per-component compute time (:class:`mpcde.onboard.budget.ComputeBudget`).
    """
    stack = stack_of(cfg)
    known = tuple(obstacles) if stack.uses.known_obstacles else ()
    ctx = AgentContext(cfg, int(drone_id), np.asarray(goals_world, float), known, budget)
    return stack.factory(ctx)
