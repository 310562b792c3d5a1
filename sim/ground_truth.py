"""Ground truth of the swarm, for metrics and dataset labels only.

Nothing here is ever handed to onboard code (perception/, planners/, the agent).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["TrueState"]


@dataclass(frozen=True)
class TrueState:
    """True state of N drones at one instant.

    Attributes:
        time_s: simulated time [s].
        pos_world: (N, 3) [m].
        vel_world: (N, 3) [m/s].
        quat_xyzw: (N, 4) body -> world.
        rotation_body_to_world: (N, 3, 3).
        ang_vel_body: (N, 3) [rad/s].
        obstacle_contact: (N,) bool, touching an obstacle or the ground this tick.
        failed: (N,) bool, motors off (crashed or failed by a scheduled fault).
    """

    time_s: float
    pos_world: np.ndarray
    vel_world: np.ndarray
    quat_xyzw: np.ndarray
    rotation_body_to_world: np.ndarray
    ang_vel_body: np.ndarray
    obstacle_contact: np.ndarray
    failed: np.ndarray
