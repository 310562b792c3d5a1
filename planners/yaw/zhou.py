"""Zhou et al.'s perception-aware yaw planning, MP-CDE's comparison [26] in Table III: :class:`ZhouYawPlanner`.

RAPTOR (T-RO 2021) and FUEL (RA-L 2021) plan the yaw after the position
trajectory: a graph search over candidate yaws at its waypoints for the most
unknown space in view, under the yaw-rate limit. Here that is MP-CDE's lattice
(n, m, rate limit, turn penalty) whose edge reward is only the unknown area in
view, Eq. 3 without the coverage window W, in every situation: no safety
regime chooses a mode and no neighbour visibility term enters. S(0) of Eq. 1
is still computed, with ``free_distance``'s reading, for the replanning
trigger of Alg. 1 line 13, which the agent applies to every method (so Zhou's
replans as often as MP-CDE's would at the same S(0)).
"""

from __future__ import annotations

from typing import Sequence

import numpy as np

from perception.types import NeighborPrediction, OccupancySnapshot
from planners.yaw.config import YawPlannerConfig
from planners.yaw.coverage import FanGeometry
from planners.yaw.explore import explore_yaws
from planners.yaw.lattice import LatticePath
from planners.yaw.planner import neighbour_summary, plan_layers
from planners.yaw.types import TrajectoryView, YawPlan

__all__ = ["ZhouYawPlanner"]


class ZhouYawPlanner:
    """Zhou et al.'s yaw planner for one drone: the most unknown space in view along the trajectory, always.

    The same interface as :class:`planners.yaw.planner.YawPlanner`; it holds no state between calls
    (``in_safe_regime`` is always False).
    """

    def __init__(self, config: YawPlannerConfig | None = None) -> None:
        self.config = config if config is not None else YawPlannerConfig(method="zhou")
        self._fan = FanGeometry.from_config(self.config)
        self.last_path: LatticePath | None = None

    @property
    def in_safe_regime(self) -> bool:
        """Always False: no regime is kept."""
        return False

    def reset(self) -> None:
        """Forget the last path (nothing else is kept)."""
        self.last_path = None

    def plan(
        self,
        time_s: float,
        yaw: float,
        trajectory: TrajectoryView,
        snapshot: OccupancySnapshot,
        predictions: Sequence[NeighborPrediction] = (),
    ) -> YawPlan:
        """The exploring lattice's yaws over the next n t_y with Zhou's reward (arguments as :meth:`YawPlanner.plan`)."""
        cfg = self.config
        times, positions, safety = plan_layers(cfg, time_s, yaw, trajectory, snapshot)
        active = list(predictions)
        recent = [q for q in active if time_s - q.stamp_s <= cfg.t_hold_s]
        nx, ny, _ = snapshot.shape
        nothing_covered = np.zeros((nx + 2) * (ny + 2), dtype=bool)  # no coverage window W
        yaws, self.last_path = explore_yaws(cfg, self._fan, yaw, times, positions, snapshot, nothing_covered, (), 1.0, 0.0)
        return YawPlan(
            mode="exploring",
            times_s=times,
            yaws=yaws,
            safety_margin_s=safety.margin_now_s,
            safe_time_s=safety.safe_time_s,
            tau_thr_s=cfg.tau_thr_s,
            min_neighbour_distance_m=neighbour_summary(time_s, positions[0], active),
            n_recent=len(recent),
            n_active=len(active),
        )
