"""DMPC-Swarm's high-level planner against deadlocks: UAVs make room (Appendix, "High-level path planner").

In a dense swap every UAV can end up held by its neighbours' buffered
Voronoi constraints (Eq. 15) with no QP step that improves its cost: the
swarm stands still although no UAV has arrived. Recomputing does not help.
DMPC-Swarm (after Park et al. 2022) lets a planner on the CU replace, while
such a deadlock lasts, the target x_i,target of QP (13) by an intermediate
target:

* **detection** (chosen rule; the paper says "when all velocities fall below
  a threshold"): over the last ``make_room_rounds`` rounds the UAVs farther
  than ``arrived_m`` from their targets came closer to them by less
  than ``make_room_progress_m`` on average (a UAV that moved away counts as
  0), as the CU knows from the UAVs' state messages (the last one received
  per UAV). Why not a speed threshold: docs/results/mlr_dmpc.md;
* **who makes room**: UAV i makes room for UAV j when (a) they are within
  ``make_room_radius_m``, (b) j is not closer to its target than i, and (c) i
  moves towards j or i lies between j and j's target (within
  ``make_room_radius_m`` of the segment);
* **where to**: for the closest such j, the intermediate target is
  p_i + ``make_room_step_m`` (p_i - p_j) / ||p_i - p_j|| plus a random
  horizontal offset of norm ``make_room_noise_m`` (it breaks symmetric
  deadlocks), clipped to the flying space;
* **until**: the detection no longer holds, or the conditions for i no
  longer hold; then the UAV flies to its real target again.

Design choice (the paper: "each CU runs its portion of the high-level planner
for its assigned subset of UAVs ... the intermediate target positions are
communicated in the subsequent communication round"): here every CU runs the
same rule for the UAV it is about to compute, from what it has heard, and the
random offset is drawn from a generator seeded by (round of detection, UAV i, UAV j),
so CUs that heard the same messages choose the same target without another
message field. CUs that heard different messages may choose different
targets; a target only enters the QP's cost (13a), never its constraints, so
Lemmas 1-2 and the collision guarantee (Theorem 3) are untouched either way.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from planners.dmpc.mlr.config import MlrConfig
from planners.dmpc.mlr.types import UavStateMessage

__all__ = ["MakeRoomPlanner"]


class MakeRoomPlanner:
    """The deadlock detector and make-room targets of one CU (module docstring).

    Args:
        config: the shared :class:`MlrConfig` (its ``make_room_*`` fields and ``arrived_m``).
        initial_pos_world: (N, 3) start positions [m] (until state messages arrive).
        initial_targets_world: (N, 3) targets [m].
    """

    def __init__(self, config: MlrConfig, initial_pos_world: np.ndarray, initial_targets_world: np.ndarray) -> None:
        n = config.n_uavs
        self.config = config
        self.pos_world = np.array(initial_pos_world, float).reshape(n, 3)
        self.vel_world = np.zeros((n, 3))
        self.targets_world = np.array(initial_targets_world, float).reshape(n, 3)
        self._history: list[np.ndarray] = []  # distance to target per UAV, the last make_room_rounds + 1 rounds
        self._since: int | None = None  # round in which the current deadlock was detected
        self.detections = 0  # deadlocks detected so far

    @property
    def active(self) -> bool:
        """Whether the swarm is deadlocked, so that the planner replaces targets."""
        return self._since is not None

    def observe(self, k: int, states: Mapping[int, UavStateMessage]) -> None:
        """Round k: the state messages received (lost ones keep the last known state); update the detection."""
        cfg = self.config
        for i, m in states.items():
            if not np.array_equal(m.target_world, self.targets_world[i]):
                self._history.clear()  # a new target: progress restarts
            self.pos_world[i], self.vel_world[i], self.targets_world[i] = m.pos_world, m.vel_world, m.target_world
        dist = np.linalg.norm(self.targets_world - self.pos_world, axis=1)
        self._history.append(dist)
        del self._history[: -(cfg.make_room_rounds + 1)]
        away = dist > cfg.arrived_m
        deadlock = False
        if len(self._history) > cfg.make_room_rounds and away.any():
            progress = np.clip(self._history[0] - dist, 0.0, None)  # UAVs making room do not count against it
            deadlock = float(progress[away].mean()) < cfg.make_room_progress_m
        if deadlock and self._since is None:
            self._since = k
            self.detections += 1
        elif not deadlock:
            self._since = None

    def target(self, uav: int, target_world: np.ndarray) -> np.ndarray:
        """The target to plan ``uav`` to: an intermediate one while it must make room, else ``target_world`` (3,)."""
        j = self.gives_way_to(uav) if self._since is not None else None
        if j is None:
            return target_world
        cfg = self.config
        away = self.pos_world[uav] - self.pos_world[j]
        if np.linalg.norm(away[:2]) > 1e-6:
            away[2] = 0.0
        norm = float(np.linalg.norm(away))
        direction = away / norm if norm > 1e-9 else np.array([1.0, 0.0, 0.0])
        rng = np.random.default_rng([self._since, uav, j, 0x40F])
        angle = rng.uniform(0.0, 2.0 * np.pi)
        noise = cfg.make_room_noise_m * np.array([np.cos(angle), np.sin(angle), 0.0])
        goal = self.pos_world[uav] + cfg.make_room_step_m * direction + noise
        return np.clip(goal, cfg.pos_min_world, cfg.pos_max_world)

    def gives_way_to(self, i: int) -> int | None:
        """The closest UAV j that UAV i must make room for (conditions a-c of the module docstring), or None."""
        cfg = self.config
        p, t, v = self.pos_world, self.targets_world, self.vel_world
        d_target = np.linalg.norm(t - p, axis=1)
        best, best_d = None, np.inf
        for j in range(cfg.n_uavs):
            if j == i:
                continue
            rel = p[j] - p[i]
            dist = float(np.linalg.norm(rel))
            if dist > cfg.make_room_radius_m or d_target[j] < d_target[i]:  # (a), (b)
                continue
            towards = float(v[i] @ rel) > 0.0
            path = t[j] - p[j]
            length = float(np.linalg.norm(path))
            between = False
            if length > 1e-9:
                u = path / length
                s = float((p[i] - p[j]) @ u)
                lateral = float(np.linalg.norm(p[i] - p[j] - s * u))
                between = 0.0 < s < length and lateral < cfg.make_room_radius_m
            if (towards or between) and dist < best_d:  # (c)
                best, best_d = j, dist
        return best
