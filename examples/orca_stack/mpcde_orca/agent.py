"""One drone flying ORCA on its own camera tracks (an mpcde onboard agent).

What it sees is what every mpcde agent may see: its own pose estimate, its
own camera frames with its own detector's boxes (tracked by the package's
adaptive Kalman tracker, :class:`mpcde.onboard.perception.NeighbourPerception`)
and its radio inbox, which it ignores: a denied swarm. At every camera frame
it solves ORCA (:mod:`mpcde_orca.orca`) in the horizontal plane against every
tracked neighbour, treating each as an ORCA agent (reciprocity assumed, as
in the paper) whose velocity is the track's, and holds its altitude toward
the goal's. The reference it flies is the flat output at that velocity,
heading along travel so that the camera looks where the drone goes.

ORCA knows nothing of static obstacles here: fly it in open worlds
(``crossing``, ``antipodal``), or add the drone's depth map as obstacle lines.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from mpcde.onboard.base import AgentCounters, OnboardAgent
from mpcde.onboard.perception import onboard_perception
from mpcde_orca.config import OrcaConfig
from mpcde_orca.orca import orca_half_plane, solve_velocity
from sim.rotations import rotation_from_quat_xyzw, yaw_from_rotation
from sim.types import FlatOutputReference

__all__ = ["OrcaAgent"]


def _wrap(angle: float) -> float:
    return float((angle + np.pi) % (2.0 * np.pi) - np.pi)


class OrcaAgent(OnboardAgent):
    """ORCA on camera tracks for drone ``drone_id``.

    Args:
        drone_id: the drone.
        goal_world: (3,) its goal [m].
        config: the ``orca`` section.
        perception_config: the scenario's ``perception`` section (detector, tracker, back-projection).
        robot_radius_m: one drone's radius [m] (the combined radius is twice it plus the margin).
        speed_mps: the horizontal speed limit [m/s].
        start_delay_s: hover this long [s] before moving.
    """

    def __init__(
        self, drone_id: int, goal_world: np.ndarray, config: OrcaConfig, perception_config: Any, robot_radius_m: float,
        speed_mps: float, start_delay_s: float,
    ) -> None:
        self.drone_id = drone_id
        self.goal_world = np.asarray(goal_world, float)
        self.config = config
        self.radius_m = 2.0 * robot_radius_m + config.radius_margin_m
        self.speed_mps = float(speed_mps)
        self.start_delay_s = float(start_delay_s)
        self.counters = AgentCounters()
        self.perception, self.detector_request = onboard_perception(True, perception_config)
        self.estimate = None
        self.start_s: float | None = None
        self.yaw = 0.0
        self.plan_time_s = 0.0
        self.plan_pos = None  # (3,) where the drone was at plan_time_s
        self.velocity = np.zeros(3)  # the commanded velocity [m/s]
        self.accel = np.zeros(3)
        self.solves = 0
        self.infeasible = 0
        self.neighbours_seen = 0

    def on_pose_estimate(self, estimate: Any) -> None:
        """The drone's own estimate (the first fixes the start time and heading)."""
        if self.estimate is None:
            self.start_s = float(estimate.time_s)
            self.yaw = float(yaw_from_rotation(rotation_from_quat_xyzw(estimate.quat_xyzw)))
            self.plan_pos = np.asarray(estimate.pos_world, float).copy()
            self.plan_time_s = float(estimate.time_s)
        self.estimate = estimate

    def on_frame(self, frame: Any, detections: Any = None) -> None:
        """Track the frame's detections, then choose the velocity for the next frame period."""
        self.counters.frames += 1
        if detections is not None:
            self.perception.update(frame, detections)
        if self.estimate is None:
            return
        t = float(frame.time_s)
        if t < self.start_s + self.start_delay_s:
            return
        self._plan(t)

    def on_radio(self, messages: list) -> None:
        """A denied swarm: the inbox is counted, not used."""
        self.counters.messages += len(messages)

    def _round_message(self, time_s: float) -> None:
        return None  # silent

    def _plan(self, t: float) -> None:
        c = self.config
        pos = np.asarray(self.estimate.pos_world, float)
        vel = np.asarray(self.estimate.vel_world, float)
        to_goal = self.goal_world - pos
        dist_xy = float(np.linalg.norm(to_goal[:2]))
        slow = min(1.0, dist_xy / max(self.speed_mps * c.arrive_s, 1e-6))
        v_pref = to_goal[:2] / dist_xy * self.speed_mps * slow if dist_xy > 1e-3 else np.zeros(2)
        lines = []
        for p in self.perception.predictions(t):
            rel_pos = (p.position(t) - pos)[:2]
            cov_xy = p.position_cov(t)[0, :2, :2]  # (2, 2) [m^2]
            sigma = float(np.sqrt(max(np.trace(cov_xy), 0.0) / 2.0))
            rel_vel = vel[:2] - p.vel_world[-1][:2]
            lines.append(orca_half_plane(rel_pos, rel_vel, vel[:2], self.radius_m + c.sigma_scale * sigma, c.horizon_s, 0.04))
        self.neighbours_seen += len(lines)
        v_xy, ok = solve_velocity(lines, v_pref, self.speed_mps)
        self.solves += 1
        self.infeasible += 0 if ok else 1
        v_z = float(np.clip(c.vertical_gain_per_s * to_goal[2], -c.max_climb_mps, c.max_climb_mps))
        target = np.array([v_xy[0], v_xy[1], v_z])
        dt = max(t - self.plan_time_s, 1e-3)
        change = target - self.velocity
        limit = c.max_accel_mps2 * dt
        norm = float(np.linalg.norm(change))
        if norm > limit:
            change *= limit / norm
        self.accel = change / dt
        self.velocity = self.velocity + change
        self.plan_time_s, self.plan_pos = t, pos.copy()
        if float(np.linalg.norm(self.velocity[:2])) > 0.2:  # turn the camera toward travel
            turn = _wrap(float(np.arctan2(self.velocity[1], self.velocity[0])) - self.yaw)
            self.yaw = _wrap(self.yaw + float(np.clip(turn, -c.yaw_rate_max_radps * dt, c.yaw_rate_max_radps * dt)))

    def reference(self, time_s: float) -> FlatOutputReference:
        """The flat output at the chosen velocity from where the drone was when it chose it (a hover before)."""
        if self.plan_pos is None:
            return FlatOutputReference.hover(np.zeros(3))
        pos = self.plan_pos + self.velocity * max(float(time_s) - self.plan_time_s, 0.0)
        return FlatOutputReference(pos_world=pos, vel_world=self.velocity.copy(), acc_world=np.zeros(3), yaw=self.yaw, yaw_rate=0.0)

    def extra_metrics(self) -> dict[str, Any]:
        """ORCA's solves and how often the half-planes left no velocity."""
        return {"drone_id": self.drone_id, "planner": "orca", "orca_solves": self.solves, "orca_infeasible": self.infeasible,
                "neighbour_lines": self.neighbours_seen}  # fmt: skip
