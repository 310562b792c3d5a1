"""PLACEHOLDER planner: a minimum-jerk straight line from the start to the goal.

Named for what it is. It knows nothing of obstacles or other drones; it stands
in until the MINCO optimiser (MP-CDE Sec. IV-C) and DMPC are wired into the
agent, so that the world, cameras, radio, metrics and outputs can be exercised
end to end. Collisions it causes are reported honestly by the metrics.

Profile: p(t) = p0 + (g - p0) s(tau), s = 10 tau^3 - 15 tau^4 + 6 tau^5,
tau = (t - t0) / T, which has zero velocity and acceleration at both ends; its
peak speed is 1.875 L / T, so T = 1.875 L / v_cruise. Yaw points along the line.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from sim.types import FlatOutputReference

__all__ = ["MinJerkLine"]


@dataclass(frozen=True)
class MinJerkLine:
    """One straight minimum-jerk segment.

    Attributes:
        start_world: (3,) start position [m].
        goal_world: (3,) goal position [m].
        t0_s: departure time [s].
        duration_s: T [s].
        yaw: heading held along the line [rad].
    """

    start_world: np.ndarray
    goal_world: np.ndarray
    t0_s: float
    duration_s: float
    yaw: float

    @staticmethod
    def plan(start_world: np.ndarray, goal_world: np.ndarray, t0_s: float, cruise_speed_mps: float, yaw: float | None = None) -> "MinJerkLine":
        """Line from ``start_world`` (3,) to ``goal_world`` (3,) with peak speed ``cruise_speed_mps``."""
        if not cruise_speed_mps > 0:
            raise ValueError(f"cruise_speed_mps={cruise_speed_mps!r}: must be > 0")
        start, goal = np.asarray(start_world, float), np.asarray(goal_world, float)
        d = goal - start
        length = float(np.linalg.norm(d))
        if yaw is None:
            yaw = float(np.arctan2(d[1], d[0])) if np.linalg.norm(d[:2]) > 1e-6 else 0.0
        return MinJerkLine(start, goal, float(t0_s), max(1.875 * length / cruise_speed_mps, 1e-3), yaw)

    def sample(self, t_s: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Position, velocity, acceleration (n, 3) at absolute times (n,)."""
        tau = np.clip((np.atleast_1d(np.asarray(t_s, float)) - self.t0_s) / self.duration_s, 0.0, 1.0)
        T = self.duration_s
        s = 10 * tau**3 - 15 * tau**4 + 6 * tau**5
        ds = (30 * tau**2 - 60 * tau**3 + 30 * tau**4) / T
        dds = (60 * tau - 180 * tau**2 + 120 * tau**3) / T**2
        d = self.goal_world - self.start_world
        return self.start_world + s[:, None] * d, ds[:, None] * d, dds[:, None] * d

    def reference(self, t_s: float) -> FlatOutputReference:
        """Controller reference at absolute time ``t_s`` [s] (scalar maths: called at 240 Hz per drone)."""
        tau = min(max((t_s - self.t0_s) / self.duration_s, 0.0), 1.0)
        T = self.duration_s
        s = tau**3 * (10 - 15 * tau + 6 * tau * tau)
        ds = 30 * tau * tau * (1 - tau) ** 2 / T
        dds = 60 * tau * (1 - tau) * (1 - 2 * tau) / (T * T)
        d = self.goal_world - self.start_world
        return FlatOutputReference(pos_world=self.start_world + s * d, vel_world=ds * d, acc_world=dds * d, yaw=self.yaw, yaw_rate=0.0)
