"""The active yaw planner of MP-CDE (Sec. IV-A, Alg. 1 lines 1-12): :class:`YawPlanner`.

Every t_y (0.1 s) the agent calls :meth:`YawPlanner.plan` with the time, the
current yaw, its current trajectory, its map window and the neighbour
predictions, and gets a :class:`YawPlan` of n + 1 yaws over the next n t_y:

1. A = every prediction handed in; V = those seen within t_hold
   (``time_s - stamp_s <= t_hold_s``; the tracker sets ``stamp_s`` to the
   last camera update).
2. S(0) and tau_s of Eq. 1 (:func:`planners.yaw.safety.safety_margin`).
3. Regime with hysteresis (:func:`planners.yaw.safety.safe_regime`): the
   planner holds whether it is in the exploring/observing regime; it enters
   it at S(0) > tau_thr + 0.1 s and leaves it at S(0) < tau_thr.
4. In that regime: *observing* when A is non-empty and |V| = |A| (every
   neighbour recently seen): steer to the weighted mean bearing (Eq. 6);
   otherwise *exploring* (A empty, or some neighbour not recently seen):
   Dijkstra on the yaw lattice with E (Eq. 3) and V (Eq. 4) for the
   neighbours in A minus V (Alg. 1 line 8; :func:`planners.yaw.explore.explore_yaws`).
5. Otherwise *tracking*: yaw along the direction of travel, swinging about
   it by ``tracking_sweep_deg`` (the tracking swing, not in the paper; 0
   flies the paper's tracking mode).

The paper's ablations (Table III) switch modes off: ``exploring_mode: false``
flies heading-along-travel where exploring would run; ``tracking_mode:
false`` never takes the safety turn of step 5. The paper's comparison, Zhou
et al.'s perception-aware yaw, is its own class
(:class:`planners.yaw.zhou.ZhouYawPlanner`); :func:`make_yaw_planner` picks
the one ``method`` names.

Every mode's output starts at the current yaw, is unwrapped and changes by
at most yaw_rate_max t_y per step. The planner also remembers the sectors of
the yaws it was called with during the last ``window_s`` (the coverage
window W of Eq. 3; see :mod:`planners.yaw.coverage`), in every mode, so the
window is complete when exploring starts.
"""

from __future__ import annotations

import math
from collections import deque
from typing import Sequence

import numpy as np

from perception.types import NeighborPrediction, OccupancySnapshot
from planners.yaw.config import YawPlannerConfig
from planners.yaw.coverage import FanGeometry, cast_fans, past_coverage, visible_cells_xy
from planners.yaw.explore import explore_yaws
from planners.yaw.lattice import LatticePath
from planners.yaw.safety import safe_regime, safety_margin
from planners.yaw.steering import observe_targets, rate_limited, sweep_offsets, track_targets
from planners.yaw.types import SafetyMargin, TrajectoryView, YawPlan

__all__ = ["YawPlanner", "make_yaw_planner", "neighbour_summary", "plan_layers"]


def make_yaw_planner(config: YawPlannerConfig | None = None) -> YawPlanner:
    """The planner ``config.method`` names: MP-CDE's (``"mpcde"``) or Zhou et al.'s (``"zhou"``)."""
    config = config if config is not None else YawPlannerConfig()
    if config.method == "zhou":
        from planners.yaw.zhou import ZhouYawPlanner

        return ZhouYawPlanner(config)
    return YawPlanner(config)


def plan_layers(
    cfg: YawPlannerConfig, time_s: float, yaw: float, trajectory: TrajectoryView, snapshot: OccupancySnapshot
) -> tuple[np.ndarray, np.ndarray, SafetyMargin]:
    """What every yaw planner's plan starts from: the layer times (n + 1,) [s], the trajectory's positions there
    (n + 1, 3) [m] and Eq. 1's safety margin now (Alg. 1 reads S(0)); ValueError on a non-finite time or yaw."""
    if not (math.isfinite(time_s) and math.isfinite(yaw)):
        raise ValueError(f"time_s={time_s!r}, yaw={yaw!r}: allowed finite numbers")
    times = time_s + np.arange(cfg.n_steps + 1) * cfg.period_s
    return times, trajectory.positions(times), safety_margin(snapshot, trajectory, time_s, cfg, profile=False)


def neighbour_summary(time_s: float, own_world: np.ndarray, predictions: Sequence[NeighborPrediction]) -> float:
    """Distance [m] from ``own_world`` (3,) to the nearest predicted neighbour at ``time_s`` (inf without any)."""
    if not predictions:
        return math.inf
    now = np.stack([q.position(time_s) for q in predictions])
    return float(np.min(np.linalg.norm(now - own_world, axis=1)))


class YawPlanner:
    """MP-CDE's active yaw planner for one drone (stateful: regime and coverage window).

    Args:
        config: settings; defaults from MP-CDE Table I.
    """

    def __init__(self, config: YawPlannerConfig | None = None) -> None:
        self.config = config if config is not None else YawPlannerConfig()
        self._fan = FanGeometry.from_config(self.config)
        self._in_safe_regime = False
        self._window: deque[tuple[float, np.ndarray]] = deque()
        self.last_path: LatticePath | None = None
        """The lattice path of the last exploring plan (for inspection), else None."""

    @property
    def in_safe_regime(self) -> bool:
        """Whether the last plan was in the exploring/observing regime (the hysteresis state)."""
        return self._in_safe_regime

    def reset(self) -> None:
        """Forget the regime (back to tracking) and the coverage window."""
        self._in_safe_regime = False
        self._window.clear()
        self.last_path = None

    def plan(
        self,
        time_s: float,
        yaw: float,
        trajectory: TrajectoryView,
        snapshot: OccupancySnapshot,
        predictions: Sequence[NeighborPrediction] = (),
    ) -> YawPlan:
        """Plan the yaw over the next n t_y (MP-CDE Alg. 1 lines 1-12).

        Args:
            time_s: now, absolute [s].
            yaw: current yaw [rad] (any branch; the output continues it).
            trajectory: the drone's current trajectory; its position at
                ``time_s`` is taken as the drone's position.
            snapshot: the drone's map window.
            predictions: the neighbours, the set A of Alg. 1 (all predictions
                handed in; the caller drops pruned tracks).
        """
        cfg = self.config
        times, positions, safety = plan_layers(cfg, time_s, yaw, trajectory, snapshot)
        s0 = safety.margin_now_s
        self._in_safe_regime = safe_regime(self._in_safe_regime, s0, cfg.tau_thr_s, cfg.hysteresis_s)
        active = list(predictions)
        recent = [q for q in active if time_s - q.stamp_s <= cfg.t_hold_s]
        self._remember_sector(time_s, yaw, positions[0], snapshot)
        self.last_path = None
        safe = self._in_safe_regime or not cfg.tracking_mode  # without tracking mode, never the safety turn
        all_seen = bool(active) and len(recent) == len(active)  # |V| = |A|: every neighbour recently seen
        if not safe or not (cfg.exploring_mode or all_seen):
            mode = "tracking"  # unsafe; or, without exploring mode, where exploring would run: heading along travel
            travel = track_targets(trajectory.velocities(times[1:]), cfg.still_speed_mps, yaw)
            swing = sweep_offsets(times[1:], math.radians(cfg.tracking_sweep_deg), cfg.tracking_sweep_period_s)
            yaws = rate_limited(yaw, travel + swing, cfg.max_step_rad)
        elif all_seen:
            mode = "observing"
            yaws = rate_limited(yaw, observe_targets(positions[1:], times[1:], recent, cfg.distance_eps_m, yaw), cfg.max_step_rad)
        else:
            mode = "exploring"
            unseen = [q for q in active if time_s - q.stamp_s > cfg.t_hold_s]  # A \ V, Alg. 1 line 8
            covered = past_coverage(snapshot, np.concatenate([pts for _, pts in self._window]))
            yaws, self.last_path = explore_yaws(cfg, self._fan, yaw, times, positions, snapshot, covered, unseen, cfg.alpha, cfg.beta)
        return YawPlan(
            mode=mode,
            times_s=times,
            yaws=yaws,
            safety_margin_s=s0,
            safe_time_s=safety.safe_time_s,
            tau_thr_s=cfg.tau_thr_s,
            min_neighbour_distance_m=neighbour_summary(time_s, positions[0], active),
            n_recent=len(recent),
            n_active=len(active),
        )

    def _remember_sector(self, time_s: float, yaw: float, pos_world: np.ndarray, snapshot: OccupancySnapshot) -> None:
        """Add the current yaw's visible sector to the coverage window W and drop entries older than window_s.

        An entry at the same time (a repeated call) or later (time went back) is replaced.
        """
        w = self.config.window_s
        self._window = deque(entry for entry in self._window if 0.0 < time_s - entry[0] <= w)
        fan = self._fan
        cast = cast_fans(snapshot, pos_world, fan.azimuths(yaw)[: fan.n_sector], fan.ranges_m)
        self._window.append((time_s, visible_cells_xy(snapshot, cast)))
