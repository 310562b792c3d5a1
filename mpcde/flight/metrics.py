"""Run metrics from ground truth (DESIGN.md section 4, mpcde: metrics).

Accumulated every physics tick from :class:`sim.ground_truth.TrueState`:

* collisions: drone-drone events (a pair's centre distance falls below
  2 r_robot; counted once per entry) plus drone-obstacle events (a drone
  starts touching an obstacle or the ground, from PyBullet's contacts);
  ``collision_events`` lists each one in order (time [s], kind ``"drone"``
  with the pair and its centre distance [m] at entry, or ``"obstacle"`` with
  the drone), so a run's collisions can be found in its log and video;
* minimum inter-drone centre distance and minimum obstacle clearance (exact
  distance from the drone centre to the nearest obstacle surface, minus r_robot);
* arrival: the first time each drone is within the goal tolerance;
  success = all arrived before the time limit and no collision;
  mission_time_s = the time the last drone arrived (null if not all did);
* path length, mean speed and mean acceleration magnitude (averaged over
  drones, from the true state);
* real-time factor = simulated time / wall time of the loop.

:func:`formation_metrics` adds the formation error chi(k) of a flight that
keeps the goals' formation (DMPC with ``formation_from_goals``, ADMM), from
the state log.
"""

from __future__ import annotations

from typing import Any, Sequence

import numpy as np

from planners.dmpc.formation_graph import FormationGraph, complete_edges, formation_error
from sim.ground_truth import TrueState
from sim.obstacles import ObstacleField
from sim.types import ObstacleSpec

__all__ = ["MetricsAccumulator", "formation_metrics", "pose_error_m"]


def formation_metrics(pos_world: np.ndarray, goals_world: np.ndarray) -> dict[str, float | None]:
    """Formation error of a flight that keeps the formation its goals form (true positions).

    chi(k) = sqrt( (1/E) sum_{i<j} ||(p_i(k) - p_j(k)) - (g_i - g_j)||^2 ) [m] over every pair of drones
    (:func:`planners.dmpc.formation_graph.formation_error` on the complete graph of the goals), so the
    same for every planner and coupling graph; 0 for the goals' shape anywhere, translated.

    Args:
        pos_world: (T, N, 3) true positions of the state log [m].
        goals_world: (N, 3) goals [m].

    Returns:
        ``formation_error_final_m`` (the last sample), ``formation_error_mean_m`` and
        ``formation_error_max_m`` (over the log); None without samples or with one drone.
    """
    goals = np.asarray(goals_world, float)
    pos = np.asarray(pos_world, float)
    keys = ("formation_error_final_m", "formation_error_mean_m", "formation_error_max_m")
    if goals.shape[0] < 2 or pos.ndim != 3 or pos.shape[0] == 0:
        return dict.fromkeys(keys)
    chi = formation_error(pos, FormationGraph(goals - goals.mean(axis=0), complete_edges(goals.shape[0])))
    return dict(zip(keys, (float(chi[-1]), float(chi.mean()), float(chi.max()))))


class MetricsAccumulator:
    """Collects metrics tick by tick; :meth:`update`, then :meth:`result`."""

    def __init__(
        self, goals_world: np.ndarray, obstacles: Sequence[ObstacleSpec], robot_radius_m: float, goal_tolerance_m: float
    ) -> None:
        self.goals = np.asarray(goals_world, float)
        n = self.goals.shape[0]
        self.obstacles = tuple(obstacles)
        self.field = ObstacleField(self.obstacles)
        self.r = robot_radius_m
        self.tol = goal_tolerance_m
        self.min_pair = np.inf
        self.min_obstacle = np.inf
        self._pairs = np.triu_indices(n, 1)  # the drone pairs i < j, in the order collision events list them
        self.in_collision = np.zeros(len(self._pairs[0]), bool)
        self.in_contact = np.zeros(n, bool)
        self.drone_drone_collisions = 0
        self.drone_obstacle_collisions = 0
        self.events: list[dict[str, Any]] = []
        self.arrival_time = np.full(n, np.nan)
        self.path_length = np.zeros(n)
        self.prev_pos: np.ndarray | None = None
        self.prev_vel: np.ndarray | None = None
        self.speed_sum = np.zeros(n)
        self.acc_sum = np.zeros(n)
        self.ticks = 0
        self.time_s = 0.0
        self.min_pair_series: list[tuple[float, float]] = []

    def update(self, s: TrueState, dt_s: float) -> None:
        """Account for one tick of duration ``dt_s`` [s] ending in state ``s``.

        Called at every physics tick, so written for small N: row norms as
        sqrt(einsum) and the pair test on the upper triangle only (cheaper than
        ``np.linalg.norm`` and full matrices).
        """
        n = s.pos_world.shape[0]
        pos, vel = s.pos_world, s.vel_world
        self.time_s = s.time_s
        if n > 1:
            iu, ju = self._pairs
            diff = pos[iu] - pos[ju]
            d = np.sqrt(np.einsum("ij,ij->i", diff, diff))  # (P,) pair distances, i < j
            m = float(d.min())
            self.min_pair = min(self.min_pair, m)
            close = d < 2 * self.r
            entered = np.flatnonzero(close & ~self.in_collision)
            self.drone_drone_collisions += int(entered.size)
            for k in entered:
                self.events.append(
                    {"time_s": float(s.time_s), "kind": "drone", "drones": [int(iu[k]), int(ju[k])], "distance_m": float(d[k])}
                )
            self.in_collision = close
            self.min_pair_series.append((s.time_s, m))
        if self.obstacles:
            clearance = self.field.distance(pos) - self.r
            self.min_obstacle = min(self.min_obstacle, float(clearance.min()))
        new_contact = s.obstacle_contact & ~self.in_contact
        if new_contact.any():
            self.drone_obstacle_collisions += int(new_contact.sum())
            for i in np.flatnonzero(new_contact):
                self.events.append({"time_s": float(s.time_s), "kind": "obstacle", "drones": [int(i)]})
        self.in_contact = s.obstacle_contact.copy()
        to_goal = pos - self.goals
        arrived = (np.einsum("ij,ij->i", to_goal, to_goal) <= self.tol * self.tol) & np.isnan(self.arrival_time)
        if arrived.any():
            self.arrival_time[arrived] = s.time_s
        if self.prev_pos is not None:
            dp, dv = pos - self.prev_pos, vel - self.prev_vel
            self.path_length += np.sqrt(np.einsum("ij,ij->i", dp, dp))
            self.acc_sum += np.sqrt(np.einsum("ij,ij->i", dv, dv)) / dt_s
        self.speed_sum += np.sqrt(np.einsum("ij,ij->i", vel, vel))
        self.prev_pos, self.prev_vel = pos.copy(), vel.copy()
        self.ticks += 1

    @property
    def all_arrived(self) -> bool:
        """Whether every drone has reached its goal at some point."""
        return not np.any(np.isnan(self.arrival_time))

    def result(self, wall_time_s: float, failed: np.ndarray, extra: dict[str, Any] | None = None) -> dict[str, Any]:
        """The metrics dictionary written to ``metrics.json``."""
        collisions = self.drone_drone_collisions + self.drone_obstacle_collisions
        arrived = self.all_arrived
        ticks = max(self.ticks, 1)

        def finite(x: float) -> float | None:
            return float(x) if np.isfinite(x) else None

        out = {
            "success": bool(arrived and collisions == 0),
            "collisions": int(collisions),
            "drone_drone_collisions": int(self.drone_drone_collisions),
            "drone_obstacle_collisions": int(self.drone_obstacle_collisions),
            "collision_events": list(self.events),
            "min_inter_drone_distance_m": finite(self.min_pair),
            "min_obstacle_distance_m": finite(self.min_obstacle),
            "mission_time_s": float(np.max(self.arrival_time)) if arrived else None,
            "arrived": int(np.sum(~np.isnan(self.arrival_time))),
            "n_drones": int(self.goals.shape[0]),
            "failed_drones": [int(i) for i in np.flatnonzero(failed)],
            "path_length_m": float(self.path_length.mean()),
            "mean_speed_mps": float((self.speed_sum / ticks).mean()),
            "mean_accel_mps2": float((self.acc_sum / max(ticks - 1, 1)).mean()),
            "sim_time_s": float(self.time_s),
            "wall_time_s": float(wall_time_s),
            "real_time_factor": float(self.time_s / wall_time_s) if wall_time_s > 0 else None,
        }
        out.update(extra or {})
        return out


def pose_error_m(arrays: dict[str, np.ndarray]) -> dict[str, float | None]:
    """The drones' pose-estimate position error over the logged flight [m]: mean, max, and mean at the end (drift)."""
    est, true = arrays.get("est_pos_world"), arrays.get("pos_world")
    if est is None or true is None or est.ndim != 3 or not est.size:
        return {"pose_error_mean_m": None, "pose_error_max_m": None, "pose_error_final_m": None}
    err = np.linalg.norm(est - true, axis=-1)  # (T, N)
    return {"pose_error_mean_m": float(err.mean()), "pose_error_max_m": float(err.max()), "pose_error_final_m": float(err[-1].mean())}
