"""The denied agent's heading: MP-CDE's active yaw planner on its schedule, or heading along travel.

Every ``t_y`` (``YawPlannerConfig.period_s``, 0.1 s) of frame time the agent
hands :class:`ActiveYaw` its map snapshot, its current MINCO trajectory and its
track predictions; the planner (:class:`planners.yaw.YawPlanner`, Alg. 1 lines
1-12) returns a rate-limited yaw sequence that the reference follows until the
next plan, and :meth:`ActiveYaw.update` reports Alg. 1 line 13's replanning
trigger ``S(0) < tau_thr or min_q d_q(0) < C_s`` (d measured with the swarm's
ellipsoid metric E = diag(1, 1, 1/c), as MINCO's clearance is).

The plan starts from the yaw the reference last commanded (not the measured
yaw), so the commanded heading is continuous and never exceeds
``yaw_rate_max``. With ``active`` False the heading follows the direction of
travel, rate-limited (the tracking mode alone: the ablation without active
perception, and the behaviour before the yaw planner existed).

Along travel, two drones converging side by side never enter each other's
85 deg view; ``YawPlannerConfig.tracking_sweep_deg`` swings the tracking-mode
camera about the direction of travel for them. The safety margin (Eq. 1)
ages verified-free space (``YawPlannerConfig.free_max_age_s``, 1 s), for
MP-CDE's Fig. 3 hazard among drones: a drone observing tracked neighbours
would otherwise fly on into space verified free seconds earlier, where a
drone it has not seen now flies.

The three headings compared:
docs/results/history/yaw_planner.md#the-denied-agents-heading-blind-along-travel-active-yaw-forest_swarm-seed-0.
"""

from __future__ import annotations

import time
from collections import Counter
from typing import Sequence

import numpy as np

from perception.types import NeighborPrediction, OccupancySnapshot
from planners.dmpc.collision import ellipsoidal_distance
from planners.minco import MincoTrajectory
from planners.yaw import TrajectoryView, YawPlan, YawPlannerConfig, make_yaw_planner, needs_replan, wrap_angle

__all__ = ["ActiveYaw"]


def trajectory_view(traj: MincoTrajectory | None, hover_world: np.ndarray) -> TrajectoryView:
    """The yaw planner's read-only view of a MINCO trajectory (or of hovering at ``hover_world`` (3,))."""
    if traj is None:
        return TrajectoryView.hover(hover_world)
    return TrajectoryView(
        position_at=lambda t: traj.pos(np.clip(np.asarray(t, float) - traj.t0_s, 0.0, traj.total_duration)),
        velocity_at=lambda t: traj.vel(np.clip(np.asarray(t, float) - traj.t0_s, 0.0, traj.total_duration)),
        end_time_s=traj.t0_s + traj.total_duration,
    )


class ActiveYaw:
    """Heading of one denied drone.

    Args:
        config: the yaw planner's settings.
        active: plan with the active yaw planner (else heading along travel).
        initial_yaw: heading at the start [rad].
        swarm_clearance_m, swarm_z_scale: C_s [m] and c of E for Alg. 1 line 13.
    """

    def __init__(self, config: YawPlannerConfig, active: bool, initial_yaw: float, swarm_clearance_m: float, swarm_z_scale: float) -> None:
        self.config = config
        self.active = active
        self.planner = make_yaw_planner(config) if active else None
        self.plan: YawPlan | None = None
        self.next_plan_s = -np.inf
        self.yaw = float(initial_yaw)
        self.yaw_time_s = 0.0
        self.swarm_clearance_m, self.swarm_z_scale = swarm_clearance_m, swarm_z_scale
        self.modes: Counter = Counter()
        self.plan_ms: list[float] = []
        self._look: tuple[float, float, float] | None = None  # (start [s], start yaw, target yaw [rad]) of look_toward

    def restart(self, yaw: float, time_s: float) -> None:
        """Continue from heading ``yaw`` [rad] at ``time_s`` [s], dropping the yaw plan (a stack hand-over)."""
        self.yaw, self.yaw_time_s = float(yaw), float(time_s)
        self.plan = None
        self.next_plan_s = -np.inf
        self._look = None

    def look_toward(self, time_s: float, target_yaw: float) -> None:
        """From ``time_s`` [s], turn from the commanded yaw to ``target_yaw`` [rad] at the yaw-rate limit and hold it.

        The override of the denied agent's look before moving (``denied.fresh_path_age_s``); it lasts
        until :meth:`restart`, and no yaw plan is made meanwhile (the caller stops calling :meth:`update`).
        """
        self._look = (float(time_s), self._commanded(time_s), float(target_yaw))
        self.plan = None

    def looked_since(self, time_s: float) -> float:
        """How long [s] before ``time_s`` the turn of :meth:`look_toward` reached its target (negative: not yet).

        ``inf`` when no such turn is under way: :meth:`restart` ended it (the denied agent's turn once round, for a
        stop that ended inside the obstacle band, has looked everywhere since).
        """
        if self._look is None:
            return np.inf
        t0, _, err = self._look_turn()
        return time_s - (t0 + abs(err) / self.config.yaw_rate_max_radps)

    def _look_turn(self) -> tuple[float, float, float]:
        """(start [s], start yaw [rad], signed turn to the target [rad], the shorter way) of :meth:`look_toward`."""
        t0, yaw0, target = self._look
        return t0, yaw0, float(wrap_angle(target - yaw0))

    def _looking(self, time_s: float) -> tuple[float, float]:
        """(yaw [rad], yaw rate [rad/s]) of the :meth:`look_toward` turn at ``time_s``."""
        t0, yaw0, err = self._look_turn()
        reach = self.config.yaw_rate_max_radps * max(time_s - t0, 0.0)
        if abs(err) <= reach:
            return yaw0 + err, 0.0
        return yaw0 + np.sign(err) * reach, float(np.sign(err)) * self.config.yaw_rate_max_radps

    def due(self, time_s: float) -> bool:
        """Whether a yaw plan is due at ``time_s`` [s] (every ``period_s``)."""
        return self.active and time_s >= self.next_plan_s - 1e-9

    def update(
        self, time_s: float, snapshot: OccupancySnapshot, traj: MincoTrajectory | None, hover_world: np.ndarray,
        neighbours: Sequence[NeighborPrediction],
    ) -> bool:
        """Plan the yaw at ``time_s`` [s] (call when :meth:`due`); returns Alg. 1 line 13's replanning trigger."""
        t0 = time.perf_counter()
        view = trajectory_view(traj, hover_world)
        yaw_now = self._commanded(time_s)
        self.plan = self.planner.plan(time_s, yaw_now, view, snapshot, neighbours)
        self.plan_ms.append(1e3 * (time.perf_counter() - t0))
        self.modes[self.plan.mode] += 1
        self.next_plan_s = time_s + self.config.period_s
        own = view.positions(np.array([time_s]))[0]
        theta_z = np.sqrt(self.swarm_z_scale)  # ||E^1/2 d|| = ||Theta^-1 d|| with Theta = diag(1, 1, sqrt(c))
        d = [float(ellipsoidal_distance(own - nb.position(time_s), theta_z)) for nb in neighbours]
        return needs_replan(self.plan.safety_margin_s, self.plan.tau_thr_s, min(d, default=np.inf), self.swarm_clearance_m)

    def _commanded(self, time_s: float) -> float:
        """The yaw the reference commands at ``time_s`` under the current plan [rad]."""
        if self._look is not None:
            return float(self._looking(time_s)[0])
        if self.plan is None:
            return self.yaw
        return float(self.plan.yaw_at(time_s)[0])

    def reference(self, time_s: float, vel_world: np.ndarray | None) -> tuple[float, float]:
        """Commanded (yaw [rad], yaw rate [rad/s]) at ``time_s``; ``vel_world`` (3,) is the reference velocity."""
        if self._look is not None:
            yaw, rate = self._looking(time_s)
            self.yaw, self.yaw_time_s = float(yaw), time_s
            return self.yaw, rate
        if self.active:
            if self.plan is None:
                return self.yaw, 0.0
            yaw, rate = self.plan.yaw_at(time_s)
            self.yaw = float(yaw)
            return self.yaw, float(rate)
        dt = max(time_s - self.yaw_time_s, 0.0)
        self.yaw_time_s = time_s
        if vel_world is None or np.hypot(vel_world[0], vel_world[1]) <= 0.2:
            return self.yaw, 0.0
        err = float(wrap_angle(np.arctan2(vel_world[1], vel_world[0]) - self.yaw))
        limit = self.config.yaw_rate_max_radps * dt
        step = float(np.clip(err, -limit, limit))
        self.yaw += step
        return self.yaw, step / dt if dt > 0 else 0.0

    def metrics(self) -> dict:
        """Mode counts and planning time for metrics.json."""
        if not self.active:
            return {}
        total = sum(self.modes.values())
        return {
            "yaw_plans": total,
            "yaw_mode_fraction": {m: self.modes[m] / total for m in ("exploring", "observing", "tracking")} if total else None,
            "yaw_plan_ms_median": float(np.median(self.plan_ms)) if self.plan_ms else None,
        }
