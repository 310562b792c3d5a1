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
   neighbour recently seen; with ``roster_aware``, also every neighbour of the
   roster tracked, not in the paper): steer to the weighted mean bearing (Eq. 6;
   with ``observing_sweep``, swinging about it as step 5 does; not in the paper);
   otherwise *exploring* (A empty, or some neighbour not recently seen):
   Dijkstra on the yaw lattice with E (Eq. 3) and V (Eq. 4) for the
   neighbours in A minus V (Alg. 1 line 8).
5. Otherwise *tracking*: yaw along the direction of travel (swinging about it by
   ``tracking_sweep_deg`` when that is set, on the clock or towards the side
   seen longest ago, ``tracking_sweep_pattern``; not in the paper).

The paper's ablations (Table III) switch modes off: ``exploring_mode: false``
flies heading-along-travel where exploring would run; ``tracking_mode:
false`` never takes the safety turn of step 5. ``method: zhou`` is the
paper's comparison, Zhou et al.'s perception-aware yaw (see
:class:`planners.yaw.config.YawPlannerConfig`): the lattice with the unknown
area in view as its only reward, in every situation. ``method: spin`` (not in
the paper) turns the camera counter-clockwise at the yaw-rate limit in every
situation, one revolution every 2 pi / yaw_rate_max (3.1 s by default).

Every mode's output starts at the current yaw, is unwrapped and changes by
at most yaw_rate_max t_y per step. The planner also remembers the sectors of
the yaws it was called with during the last ``window_s`` (the coverage
window W of Eq. 3; see :mod:`planners.yaw.coverage`), in every mode, so the
window is complete when exploring starts; only under ``method: mpcde``, the
one method whose exploring reads it (Zhou's reward has no window, the spin
never explores).
"""

from __future__ import annotations

import math
from collections import deque
from typing import Sequence

import numpy as np

from perception.types import NeighborPrediction, OccupancySnapshot
from planners.yaw.config import YawPlannerConfig
from planners.yaw.coverage import FanGeometry, cast_fans, edge_gains, past_coverage, ray_gains, visible_cells_xy
from planners.yaw.lattice import LatticePath, edge_costs, shortest_path
from planners.yaw.safety import safe_regime, safety_margin
from planners.yaw.steering import observe_targets, rate_limited, sweep_offsets, track_targets
from planners.yaw.types import TrajectoryView, YawPlan
from planners.yaw.visibility import visibility_rewards, wrap_angle

__all__ = ["YawPlanner"]


class YawPlanner:
    """MP-CDE's active yaw planner for one drone (stateful: regime and coverage window).

    Args:
        config: settings; defaults from MP-CDE Table I.
        swarm_neighbours: how many other drones were launched with this one (the mission's roster, not
            their state; 0 for a lone drone); read only with ``config.roster_aware``.
    """

    def __init__(self, config: YawPlannerConfig | None = None, swarm_neighbours: int = 0) -> None:
        if isinstance(swarm_neighbours, bool) or not isinstance(swarm_neighbours, int) or swarm_neighbours < 0:
            raise ValueError(f"swarm_neighbours={swarm_neighbours!r}: allowed an integer >= 0")
        self.config = config if config is not None else YawPlannerConfig()
        self.swarm_neighbours = swarm_neighbours
        self._fan = FanGeometry.from_config(self.config)
        self._in_safe_regime = False
        self._window: deque[tuple[float, np.ndarray]] = deque()
        self._yaws: deque[tuple[float, float]] = deque()  # (time [s], yaw [rad]) of the last window_s's calls ("stalest")
        self._sweep_plan: tuple[np.ndarray, np.ndarray] | None = None  # the "stalest" swing's last layers and ends
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
        self._yaws.clear()
        self._sweep_plan = None
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
        if not (math.isfinite(time_s) and math.isfinite(yaw)):
            raise ValueError(f"time_s={time_s!r}, yaw={yaw!r}: allowed finite numbers")
        cfg = self.config
        n = cfg.n_steps
        times = time_s + np.arange(n + 1) * cfg.period_s
        positions = trajectory.positions(times)  # (n + 1, 3)
        safety = safety_margin(snapshot, trajectory, time_s, cfg, profile=False)  # S(0) is all Alg. 1 reads
        s0 = safety.margin_now_s
        self._in_safe_regime = safe_regime(self._in_safe_regime, s0, cfg.tau_thr_s, cfg.hysteresis_s)
        active = list(predictions)
        recent = [q for q in active if time_s - q.stamp_s <= cfg.t_hold_s]
        if cfg.method == "mpcde":  # the window is read only by MP-CDE's exploring (Eq. 3)
            self._remember_sector(time_s, yaw, positions[0], snapshot)
        if cfg.tracking_sweep_pattern == "stalest":  # the yaws it reads when a tracking spell starts
            self._yaws = deque(entry for entry in self._yaws if 0.0 < time_s - entry[0] <= cfg.window_s)
            self._yaws.append((time_s, yaw))
        self.last_path = None
        safe = self._in_safe_regime or not cfg.tracking_mode  # without tracking mode, never the safety turn
        # |V| = |A|: every neighbour recently seen; with roster_aware, A also holds the roster's untracked neighbours
        all_seen = bool(active) and len(recent) == len(active) and not (cfg.roster_aware and len(active) < self.swarm_neighbours)
        if cfg.method == "spin":  # every direction in view once per revolution, whatever the map or the tracks say
            mode = "spinning"
            yaws = yaw + cfg.yaw_rate_max_radps * (times - time_s)
        elif cfg.method == "zhou":  # Zhou et al.'s yaw: the most unknown space in view along the trajectory, always
            mode = "exploring"
            yaws = self._explore(yaw, times, positions, snapshot, (), zhou=True)
        elif not safe or not (cfg.exploring_mode or all_seen):
            mode = "tracking"  # unsafe; or, without exploring mode, where exploring would run: heading along travel
            travel = track_targets(trajectory.velocities(times[1:]), cfg.still_speed_mps, yaw)
            if cfg.tracking_sweep_pattern == "stalest" and cfg.tracking_sweep_deg > 0.0:
                yaws = self._stalest_sweep(time_s, yaw, times, travel)
            else:
                yaws = rate_limited(yaw, travel + self._swing(times[1:]), cfg.max_step_rad)
        elif all_seen:
            mode = "observing"
            targets = observe_targets(positions[1:], times[1:], recent, cfg.distance_eps_m, yaw)
            if cfg.observing_sweep:  # extension: swing about Eq. 6's bearing, as the tracking mode does about travel
                targets = targets + self._swing(times[1:])
            yaws = rate_limited(yaw, targets, cfg.max_step_rad)
        else:
            mode = "exploring"
            unseen = [q for q in active if time_s - q.stamp_s > cfg.t_hold_s]  # A \ V, Alg. 1 line 8
            yaws = self._explore(yaw, times, positions, snapshot, unseen)
        if mode != "tracking":
            self._sweep_plan = None  # the next tracking spell chooses its first side afresh
        if active:
            now = np.stack([q.position(time_s) for q in active])
            d_min = float(np.min(np.linalg.norm(now - positions[0], axis=1)))
        else:
            d_min = math.inf
        return YawPlan(
            mode=mode,
            times_s=times,
            yaws=yaws,
            safety_margin_s=s0,
            safe_time_s=safety.safe_time_s,
            tau_thr_s=cfg.tau_thr_s,
            min_neighbour_distance_m=d_min,
            n_recent=len(recent),
            n_active=len(active),
        )

    def _swing(self, times_s: np.ndarray) -> np.ndarray:
        """The camera swing's yaw offsets (n,) [rad] at ``times_s`` (n,): ``tracking_sweep_deg`` every ``tracking_sweep_period_s``."""
        cfg = self.config
        return sweep_offsets(times_s, math.radians(cfg.tracking_sweep_deg), cfg.tracking_sweep_period_s)

    def _stalest_sweep(self, time_s: float, yaw: float, times: np.ndarray, travel: np.ndarray) -> np.ndarray:
        """Tracking-mode yaws (n + 1,) [rad] of the ``"stalest"`` swing at layer ``times`` (n + 1,) [s] about the
        travel headings ``travel`` (n,) of layers 1 .. n.

        Full-rate turns between travel - A and travel + A (A = ``tracking_sweep_deg``), reversing where an
        end is reached. The end being turned to carries over from the last plan at ``time_s`` (its layers
        record which end each step turned to). A new tracking spell first turns to the end whose direction
        was last inside the horizontal field of view longest ago (never: oldest; a tie goes left).
        """
        cfg = self.config
        amp, step, half = math.radians(cfg.tracking_sweep_deg), cfg.max_step_rad, 0.5 * cfg.fov_h_rad
        if self._sweep_plan is None:
            seen = {}
            for s in (1, -1):
                end = float(travel[0]) + s * amp
                seen[s] = max((t for t, y in self._yaws if abs(float(wrap_angle(y - end))) <= half), default=-math.inf)
            side = 1 if seen[1] <= seen[-1] else -1
        else:
            last_times, last_sides = self._sweep_plan
            side = int(last_sides[max(int(np.searchsorted(last_times, time_s + 1e-9, side="right")) - 1, 0)])
        sides = np.empty(len(travel) + 1, int)  # sides[i]: the end the step from layer i turns to
        out = np.empty(len(travel) + 1)
        out[0] = yaw
        for i, heading in enumerate(travel):
            sides[i] = side
            err = float(wrap_angle(heading + side * amp - out[i]))
            out[i + 1] = out[i] + min(max(err, -step), step)
            if abs(err) <= step:  # the end is reached within this step: turn back
                side = -side
        sides[-1] = side
        self._sweep_plan = (np.asarray(times, float), sides)
        return out

    def _remember_sector(self, time_s: float, yaw: float, pos_world: np.ndarray, snapshot: OccupancySnapshot) -> None:
        """Add the current yaw's visible sector to the coverage window W and drop entries older than window_s.

        An entry at the same time (a repeated call) or later (time went back) is replaced.
        """
        w = self.config.window_s
        self._window = deque(entry for entry in self._window if 0.0 < time_s - entry[0] <= w)
        fan = self._fan
        cast = cast_fans(snapshot, pos_world, fan.azimuths(yaw)[: fan.n_sector], fan.ranges_m)
        self._window.append((time_s, visible_cells_xy(snapshot, cast)))

    def _explore(
        self,
        yaw: float,
        times: np.ndarray,
        positions: np.ndarray,
        snapshot: OccupancySnapshot,
        unseen: Sequence[NeighborPrediction],
        zhou: bool = False,
    ) -> np.ndarray:
        """Exploring mode: the maximum-reward yaw sequence (n + 1,) on the lattice (Eq. 3-5).

        ``zhou``: Zhou et al.'s reward instead: the unknown area in view only (no coverage window, no V).
        """
        cfg, fan = self.config, self._fan
        m, q = cfg.n_candidates, cfg.max_hop
        if zhou:
            nx, ny, _ = snapshot.shape
            covered = np.zeros((nx + 2) * (ny + 2), dtype=bool)
        else:
            covered = past_coverage(snapshot, np.concatenate([pts for _, pts in self._window]))
        cast = cast_fans(snapshot, positions[1:], fan.azimuths(yaw), fan.ranges_m)
        gains, e_max = edge_gains(ray_gains(cast, covered, fan.areas_m2), fan, m, q)
        e = gains / e_max  # Eq. 3, normalised to [0, 1]
        candidate_yaws = yaw + np.arange(m) * cfg.candidate_spacing_rad
        v = visibility_rewards(positions[1:], times[1:], candidate_yaws, unseen, cfg)  # Eq. 4, in [0, 1]
        alpha, beta = (1.0, 0.0) if zhou else (cfg.alpha, cfg.beta)
        path = shortest_path(edge_costs(e, v, alpha, beta, cfg.turn_penalty))  # Eq. 5
        self.last_path = path
        return yaw + cfg.candidate_spacing_rad * np.concatenate([[0.0], np.cumsum(path.hops)])
