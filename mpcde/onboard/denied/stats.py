"""What the denied agent's planner did, counted for metrics.json: :class:`PlanningStats`."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

__all__ = ["PlanningStats"]


@dataclass
class PlanningStats:
    """What the agent's planner did (for metrics)."""

    replans: int = 0
    failures: int = 0
    brakes: int = 0
    swarm_replans: int = 0
    yaw_replans: int = 0
    rest_escapes: int = 0  # stops that ended inside the obstacle band and began an escape (rest_escape.py)
    front_end_failures: dict = field(default_factory=dict)  # refused front-end searches by status ("goal_blocked", "no_path", ...)
    goal_fallbacks: int = 0  # found paths to the window's voxel nearest the goal (clipped goal blocked, no plan or stopping)
    solve_ms: list = field(default_factory=list)
    map_ms: list = field(default_factory=list)

    def metrics(self, components: dict | None = None) -> dict:
        """The counts and median times for metrics.json, with the components' counts ``components`` after the counts."""
        return {
            "replans": self.replans,
            "plan_failures": self.failures,
            "brakes": self.brakes,
            "swarm_replans": self.swarm_replans,
            "yaw_replans": self.yaw_replans,
            "rest_escapes": self.rest_escapes,
            "front_end_failures": dict(sorted(self.front_end_failures.items())),
            "goal_fallbacks": self.goal_fallbacks,
            **(components or {}),
            "replan_ms_median": float(np.median(self.solve_ms)) if self.solve_ms else None,
            "map_ms_median": float(np.median(self.map_ms)) if self.map_ms else None,
        }
