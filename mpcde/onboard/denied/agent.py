"""The communication-denied agent (MP-CDE): detector + tracks, own map, front end, MINCO, replanning.

What it uses: its own camera frames with the boxes its own detector found in
them (:mod:`mpcde.onboard.detection`), its own pose estimate, and nothing
else. Each frame (MP-CDE Sec. IV-B, :class:`mpcde.onboard.perception.NeighbourPerception`):
detections are back-projected to world measurements (Eq. 7-8) and tracked by
the adaptive Kalman tracker (Eq. 9-12); the depth frame is mapped
(:class:`perception.occupancy_map.OccupancyMap`) with the detection boxes
masked, so neighbours do not become walls. The tracks' predictions are the
neighbours MINCO keeps the swarm clearance C_s from (Eq. 16). What it never
uses: ground truth, the radio. With ``perceive_neighbours: false`` it runs no
detector and flies blind to other drones (the map-only ablation).

Replanning (MP-CDE Alg. 1 line 13 and DESIGN.md section 3): after a frame is
mapped, replan when (a) no trajectory exists, (b) at least ``replan_period_s``
passed since the last plan, (c) the rest of the current trajectory comes
closer than the clearance to an obstacle on the updated ESDF, or (d) within
the next ``conflict_horizon_s`` it comes closer than C_s (ellipsoidal metric
E = diag(1, 1, 1/c) of Eq. 16) to a tracked neighbour's prediction; (d) holds
Alg. 1's ``min_q d_q(0) < C_s`` at its first instant and looks ahead along the
tracks' constant-velocity predictions (MP-CDE: prediction horizons up to
1.2 s), so that a neighbour on a collision course is answered before it is
within C_s. A replan starts
from the current trajectory's own state (position, velocity, acceleration) at
the frame time, so the reference stays continuous; the front end
(:func:`planners.path_search.search_path`) searches the map window, with each
track's capsule added as an obstacle (:mod:`planners.neighbour_field`: C_s, or
1.2 C_s for a track unseen for longer than t_hold), towards the
goal (clipped to the window when the goal lies outside it) and the MINCO
optimiser (:mod:`planners.trajectory_optimizer`) refines that path on the ESDF.
A plan that fails or leaves obstacle clearance violated is rejected (one that
keeps obstacle clearance but not all of C_s is kept: the optimiser's best
separation beats the old plan's); if the current trajectory is itself unsafe
with respect to obstacles, the agent brakes to a stop along it (a stopping
MINCO piece from its current state). A stop that ends inside the obstacle band
(0.75 clearance_m) would leave the drone there for good, since every plan from
that point starts inside the band; there the drone turns the camera once round,
as after a halting hand-over, and then plans out of the band no closer than it
rests (:meth:`DeniedAgent._escape_from_rest`, :meth:`DeniedAgent._escape_floor`).

Yaw (MP-CDE Sec. IV-A, :mod:`mpcde.onboard.denied.heading`): every t_y = 0.1 s of frame
time the active yaw planner (:mod:`planners.yaw`, Alg. 1) chooses exploring,
observing or tracking from the safety margin S(0) and the tracks, and the
reference follows its rate-limited yaw sequence; its line 13 (S(0) < tau_thr or
a neighbour within C_s now) is replanning trigger (e). With ``active_yaw:
false`` the heading follows the direction of travel (the ablation).

:meth:`DeniedAgent.plan_step` is that algorithm, top to bottom. What the package
adds to the paper is composed around it, each a component with its own module
and its own config field, off where the field says so:

* look before moving (:mod:`mpcde.onboard.denied.look`, ``fresh_path_age_s``):
  :meth:`~mpcde.onboard.denied.look.LookBeforeMoving.gate` and
  :meth:`~mpcde.onboard.denied.look.LookBeforeMoving.look_ahead`;
* flight levels (:mod:`mpcde.onboard.denied.levels`, ``flight_level_spacing_m``):
  :meth:`~mpcde.onboard.denied.levels.FlightLevels.goal_and_layer`;
* the turn once round and the band escape (:mod:`mpcde.onboard.denied.rest_escape`):
  after a halting hand-over or a stop inside the obstacle band;
* in the yaw planner, the tracking swing (``yaw.tracking_sweep_deg``) and the
  ageing of free space (``yaw.free_max_age_s``).
"""

from __future__ import annotations

import time
from collections.abc import Callable

import numpy as np

from mpcde.config.denied import DeniedAgentConfig
from mpcde.config.perception import PerceptionConfig
from mpcde.onboard.base import AgentCounters, OnboardAgent
from mpcde.onboard.budget import ComputeBudget
from mpcde.onboard.denied.heading import ActiveYaw
from mpcde.onboard.denied.levels import FlightLevels, held_in_layer
from mpcde.onboard.denied.look import LookBeforeMoving
from mpcde.onboard.denied.rest_escape import RestEscape
from mpcde.onboard.denied.stats import PlanningStats
from mpcde.onboard.perception import NeighbourPerception, onboard_perception
from perception.occupancy_map import OccupancyMap
from perception.types import Detection, NeighborPrediction
from planners.dmpc.collision import ellipsoidal_distance
from planners.minco import MincoTrajectory, minco_s3
from planners.neighbour_field import with_neighbour_capsules
from planners.path_search import PathSearchConfig, search_path
from planners.trajectory_optimizer import TrajectoryOptimizationError, TrajectoryOptimizerConfig, build_trajectory_problem, solve
from sim.rotations import rotation_from_quat_xyzw, yaw_from_rotation
from sim.types import FlatOutputReference, PoseEstimate, RadioMessage, RgbdFrame

__all__ = ["DeniedAgent", "DeniedAgentConfig", "PlanningStats"]  # the config and the stats for the callers that name them here


class DeniedAgent(OnboardAgent):
    """One drone's MP-CDE stack (implements :class:`mpcde.onboard.base.OnboardAgent`).

    Args:
        drone_id: index of the drone.
        goal_world: (3,) goal [m].
        config: the scenario's ``denied:`` settings.
        perception_config: the scenario's ``perception:`` settings (detector, tracker, back-projection).
        perception: a perception to share (the ``auto`` agent's DMPC half reads the same tracks);
            None: the agent makes its own when ``config.perceive_neighbours``.
        budget: where the compute time of tracking, mapping, ESDF and planning is booked (the run's).
        swarm_size: how many drones the mission launched, this one included (the mission's assignment, as the
            goal is; not their state): flight levels space the swarm by it.
        neighbour_source: where planning reads the neighbours from, ``source(t, count) -> predictions``
            (``count``: a planning use the source may tally); None: this drone's tracks. The composite
            stacks give theirs: ``auto`` its radio memory fused with the tracks, ``minco_comm`` the radio's plans.
    """

    def __init__(
        self, drone_id: int, goal_world: np.ndarray, config: DeniedAgentConfig, perception_config: PerceptionConfig | None = None,
        perception: NeighbourPerception | None = None,
        budget: ComputeBudget | None = None,
        swarm_size: int = 1,
        neighbour_source: Callable[[float, bool], list[NeighborPrediction]] | None = None,
    ) -> None:
        self.drone_id = drone_id
        self.swarm_size = swarm_size
        self.budget = budget if budget is not None else ComputeBudget()
        self.goal_world = np.asarray(goal_world, float)
        self.config = config
        self.counters = AgentCounters()
        self.stats = PlanningStats()
        self.map = OccupancyMap(config.map, on_esdf=lambda seconds: self.budget.add("esdf", seconds))
        self.maps_frames = True
        self.escape = RestEscape(config.yaw_rate_max_radps, 0.5 * config.map.voxel_m)  # the turn once round, the band escape
        self.trajectory: MincoTrajectory | None = None
        self.braking = False  # whether self.trajectory is a stopping piece (committed until a replan succeeds)
        self.last_plan_time_s = -np.inf
        self.latest_estimate: PoseEstimate | None = None
        self.hover_world: np.ndarray | None = None
        self.heading: ActiveYaw | None = None  # made from the first pose estimate (its yaw)
        c = config
        self.t_hold_s = (perception_config or PerceptionConfig()).tracker.t_hold_s
        self.yaw_config = c.yaw  # its speed and rate limits, t_hold and field of view derived at load (mpcde/config/resolve.py)
        self.optimizer = TrajectoryOptimizerConfig(
            limits=c.limits, obstacle_clearance_m=c.clearance_m,
            swarm_clearance_m=c.swarm_clearance_m, swarm_z_scale=c.swarm_z_scale,
        )
        # detector_request: what the loop's batched detector reads (None: no detections)
        self.perception, self.detector_request = onboard_perception(c.perceive_neighbours, perception_config, perception)
        self.search = PathSearchConfig()
        self.levels: FlightLevels | None = None  # config.flight_level_spacing_m: this drone's level, fixed by its first estimate
        self.neighbour_source = neighbour_source
        self.look = LookBeforeMoving(c, c.yaw.period_s, c.map.voxel_m)  # denied.fresh_path_age_s, every t_y

    # inputs ---------------------------------------------------------------
    def on_pose_estimate(self, estimate: PoseEstimate) -> None:
        """Own pose estimate; the first one fixes the hover point and heading."""
        self.latest_estimate = estimate
        if self.hover_world is None:
            self.hover_world = estimate.pos_world.copy()
            c = self.config
            if np.isfinite(c.flight_level_spacing_m):
                self.levels = FlightLevels.for_drone(
                    self.drone_id, self.swarm_size, self.hover_world, self.goal_world, c.flight_level_spacing_m, c.flight_level_release_m
                )
            yaw = float(yaw_from_rotation(rotation_from_quat_xyzw(estimate.quat_xyzw)))
            self.heading = ActiveYaw(self.yaw_config, c.active_yaw, yaw, c.swarm_clearance_m, c.swarm_z_scale)

    def on_radio(self, messages: list[RadioMessage]) -> None:
        """Denied: the radio is not used (messages are counted only)."""
        self.counters.messages += len(messages)

    def on_frame(self, frame: RgbdFrame, detections: list[Detection] | None = None) -> None:
        """Track the detected neighbours, map the frame, then replan if due or if the plan became unsafe.

        Args:
            frame: this drone's frame.
            detections: the boxes this drone's detector found in ``frame`` (None: no detector ran).
        """
        self.observe(frame, detections)
        self.plan_step(frame.time_s)

    def observe(self, frame: RgbdFrame, detections: list[Detection] | None = None) -> None:
        """Track the detected neighbours and map the frame (no planning).

        The ``auto`` agent calls this alone while it flies DMPC, so the map and
        the tracks are warm when it falls back to this stack.
        """
        self.counters.frames += 1
        if self.perception is not None and detections is not None:
            with self.budget.measure("track"):
                self.perception.update(frame, detections)
        t0 = time.perf_counter()
        near = None  # where it believes its neighbours are: their depth hits are not obstacles (when on)
        if self.config.map.neighbour_exclusion_m > 0.0:
            t = np.array([frame.time_s])
            near = np.array([nb.position(t)[0] for nb in self.neighbours(frame.time_s, count=False)]).reshape(-1, 3)
        self.map.update(frame, detections or (), near)
        seconds = time.perf_counter() - t0
        self.budget.add("map_insert", seconds)
        self.stats.map_ms.append(1e3 * seconds)

    def plan_step(self, t: float) -> None:
        """Heading and replanning at frame time ``t`` [s] on the map's newest snapshot (module docstring).

        The snapshot (a copy of the window; its ESDF deferred further) is taken only
        when the yaw planner or a replan reads it, not on every frame.
        """
        if t < self.config.start_delay_s or self.latest_estimate is None or self.escape.holds(self, t):
            return
        gate = self.look.gate(self, t)  # the camera turning to a stale point (a hold stops for it, a glance flies on)
        if gate.hold:
            return  # stopped to look: no yaw plan, no replan
        neighbours = self.neighbours(t)
        yaw_trigger = False
        if not gate.glancing and self.heading.due(t):  # Alg. 1 lines 1-12 every t_y; line 13's trigger is (e)
            with self.budget.measure("yaw"):
                yaw_trigger = self.heading.update(t, self.map.snapshot(), self.trajectory, self.hover_world, neighbours)
        if not gate.released and self.look.look_ahead(self, t, gate.glancing):
            return
        # the per-frame check reads the newest ESDF and the voxels occupied since (no transform)
        unsafe = False
        if self.trajectory is not None:  # the escape floor is read (and first fixed) only for a plan in hand
            floor = self.escape.floor(self.map.clearance, self.state_at(t)[0], self.band_m)
            unsafe = not self._safe(self.trajectory, self.map.clearance, t, floor)
        conflict = self.trajectory is not None and self._swarm_conflict(self.trajectory, neighbours, t)
        due = t - self.last_plan_time_s >= self.config.replan_period_s or self._climbed(t)
        if self.trajectory is None or unsafe or conflict or yaw_trigger or due or gate.released:
            replanned = self._replan(self.map.snapshot(), neighbours, t)
            self.stats.swarm_replans += int(replanned and conflict)
            self.stats.yaw_replans += int(replanned and yaw_trigger)
            if not replanned and unsafe:
                self.brake(t)

    def neighbours(self, t: float, count: bool = True) -> list[NeighborPrediction]:
        """The neighbour predictions planned against at ``t`` [s]: ``neighbour_source``'s, else the tracks.

        ``count`` False: a look that is not a planning use (the map's exclusion), not tallied by the source.
        """
        if self.neighbour_source is not None:
            return self.neighbour_source(t, count)
        return self.perception.predictions(t) if self.perception is not None else []

    def _round_message(self, time_s: float) -> None:
        """Denied: nothing is broadcast."""
        return None

    def take_over(
        self, time_s: float, pos_vel_acc: np.ndarray, yaw: float, look_around: bool = False
    ) -> tuple[float, float] | None:
        """Start flying this stack from another stack's reference (the ``auto`` agent's fallback).

        The current trajectory becomes a stopping piece from ``pos_vel_acc``
        ((3, 3) position, velocity, acceleration [m, m/s, m/s^2] of the
        reference being left at ``time_s``), so the reference is continuous;
        the next frame replans (it is due) from that state. The heading
        continues from ``yaw`` [rad] and the yaw planner plans at the next frame.
        ``look_around``: nothing is planned until the stop is over and the camera
        has turned once round where it ended (:meth:`look_around_at`).

        Returns:
            The turn's start and end [s] (None without ``look_around``).
        """
        self.trajectory = self._stopping_piece(time_s, np.asarray(pos_vel_acc, float))
        self.braking = True
        self.last_plan_time_s = -np.inf
        self.escape.cancel()
        if self.heading is not None:
            self.heading.restart(yaw, time_s)
        if not look_around:
            return None
        stop = self.trajectory
        return self.turn_once_round(stop.t0_s + stop.total_duration, stop.pos(np.array([stop.total_duration]))[0], yaw)

    def look_around_at(self, time_s: float, pos_world: np.ndarray, yaw: float) -> tuple[float, float]:
        """Hover at ``pos_world`` (3,) [m] from ``time_s`` [s] on, turn the camera once round from ``yaw`` [rad] at
        the yaw-rate limit, then plan (the ``auto`` agent's halting hand-over, ``auto.handover: halt``).

        Until ``time_s`` this stack neither plans nor flies: the caller flies the drone to ``pos_world`` and
        brings it to rest there (its last broadcast DMPC plan, to that plan's halt). Returns the turn's start and
        end [s].
        """
        self.trajectory, self.braking = None, False
        return self.turn_once_round(time_s, pos_world, yaw)

    def turn_once_round(self, time_s: float, pos_world: np.ndarray, yaw: float) -> tuple[float, float]:
        """Hover at ``pos_world`` (3,) [m] and turn once round from ``time_s`` [s] and ``yaw`` [rad], with the band
        escape after it (:class:`mpcde.onboard.denied.rest_escape.RestEscape`); returns the turn's start and end [s]."""
        self.hover_world = np.asarray(pos_world, float).copy()
        self.last_plan_time_s = -np.inf
        return self.escape.begin(time_s, yaw)

    # planning ---------------------------------------------------------------
    def state_at(self, t: float) -> np.ndarray:
        """(3, 3) position, velocity, acceleration of the current reference at ``t``."""
        if self.trajectory is None:
            return np.stack([self.hover_world, np.zeros(3), np.zeros(3)])
        return self.trajectory.pos_vel_acc(t - self.trajectory.t0_s)

    @property
    def band_m(self) -> float:
        """The obstacle band [m]: the clearance from the map's obstacles every plan keeps (0.75 clearance_m), which
        :meth:`_safe` checks and the escapes (:class:`mpcde.onboard.denied.rest_escape.RestEscape`) start inside."""
        return 0.75 * self.config.clearance_m

    def _safe(
        self, traj: MincoTrajectory, distance: Callable[[np.ndarray], np.ndarray], t: float, floor_m: float | None = None
    ) -> bool:
        """Whether ``traj`` keeps 0.75 clearance_m (or ``floor_m`` [m] when given) from the map's obstacles from
        ``t`` [s] on.

        ``distance`` maps (n, 3) points [m] to their obstacle distance (n,) [m]:
        :meth:`perception.occupancy_map.OccupancyMap.clearance` on the hot
        path, the fresh snapshot's ESDF for a new plan. No escape rule for a
        plan starting inside the band in flight (tried and dropped:
        docs/results/radio_outage.md#tried-and-dropped); one handed over there has the escape's floor.
        """
        tau = np.linspace(max(t - traj.t0_s, 0.0), traj.total_duration, 40)
        d = distance(traj.pos(tau))
        return bool(np.min(d) >= (self.band_m if floor_m is None else floor_m))

    def _swarm_conflict(self, traj: MincoTrajectory, neighbours: list[NeighborPrediction], t: float) -> bool:
        """Whether ``traj`` comes within C_s (metric E of Eq. 16) of a prediction in the next ``conflict_horizon_s``."""
        if not neighbours:
            return False
        times = t + np.linspace(0.0, self.config.conflict_horizon_s, 13)
        own = traj.pos(np.clip(times - traj.t0_s, 0.0, traj.total_duration))
        theta_z = np.sqrt(self.config.swarm_z_scale)  # ||E^1/2 d|| = ||Theta^-1 d|| with Theta = diag(1, 1, sqrt(c))
        d = [np.min(ellipsoidal_distance(own - nb.position(times), theta_z)) for nb in neighbours]
        return min(d) < self.config.swarm_clearance_m

    def _replan(self, snap, neighbours: list[NeighborPrediction], t: float) -> bool:
        start = self.state_at(t)
        snap.distance_m  # a replan needs this frame's ESDF (booked as "esdf" by the map)
        t0 = time.perf_counter()
        c = self.config
        # the front end sees each track as a capsule (planners.neighbour_field); MINCO sees the predictions
        with self.budget.measure("front_end"):
            front = with_neighbour_capsules(
                snap, neighbours, t, c.conflict_horizon_s, c.swarm_clearance_m, self.t_hold_s, reach_m=c.front_end_clearance_m + 0.3
            )
            try:
                # the window's nearest voxel to the goal stands in for a blocked or cut-off clipped goal only for a
                # drone with no plan to fly, stopping, or at rest at its plan's end (a climb to its flight level):
                # its window no longer moves (planners.path_search, module docstring)
                plan = self.trajectory
                stalled = plan is None or self.braking or t >= plan.t0_s + plan.total_duration
                goal = self._level_goal(start[0])
                path = search_path(front, start[0], goal, c.front_end_clearance_m, self.search, goal_fallback=stalled)
            except ValueError:  # the planned start left the map window (the map moves with the frames it gets)
                self.stats.failures += 1
                return False
        if not path.found:
            self.stats.failures += 1
            self.stats.front_end_failures[path.status] = self.stats.front_end_failures.get(path.status, 0) + 1
            return False
        self.stats.goal_fallbacks += path.goal_fallback
        goal_pva = np.stack([path.goal_used_world, np.zeros(3), np.zeros(3)])
        try:
            with self.budget.measure("optimiser"):
                problem = build_trajectory_problem(start, goal_pva, path.waypoints_world, snap, neighbours, t, self.optimizer)
                result = solve(problem)
        except (TrajectoryOptimizationError, ValueError):
            self.stats.failures += 1
            return False
        self.stats.solve_ms.append(1e3 * (time.perf_counter() - t0))
        esdf = lambda p: snap.distance_and_gradient(p)[0]  # noqa: E731
        if not self._safe(result.trajectory, esdf, t, self.escape.floor(esdf, start[0], self.band_m)):
            self.stats.failures += 1
            return False
        self.trajectory = result.trajectory
        self.braking = False
        self.last_plan_time_s = t
        self.stats.replans += 1
        return True

    def _level_goal(self, pos_world: np.ndarray) -> np.ndarray:
        """The goal this replan from ``pos_world`` (3,) [m] flies to: the goal, or with flight levels
        (:meth:`mpcde.onboard.denied.levels.FlightLevels.goal_and_layer`) the goal of the sequence's step, whose
        layer the optimiser's altitude penalty and the front end's search then hold."""
        if self.levels is None:
            return self.goal_world
        goal, (lo, hi) = self.levels.goal_and_layer(pos_world)
        self.optimizer, self.search = held_in_layer(self.optimizer, self.search, lo, hi, self.config.map.voxel_m)
        return goal

    def _climbed(self, t: float) -> bool:
        """Whether the plan in hand has just brought the drone to its flight level (replan at once for the goal)."""
        if self.levels is None or self.levels.reached or self.trajectory is None:
            return False
        return self.levels.climbed(self.state_at(t)[0])

    def can_stop(self, t: float) -> bool:
        """Whether a hold may stop at ``t`` [s]: the straight stopping piece (:meth:`_stopping_piece`, which knows no
        obstacles) keeps out of the obstacle band, or, for a drone already inside it, no closer than it is now."""
        pva = self.state_at(t)
        floor = min(self.band_m, float(self.map.clearance(pva[0][None])[0]) - 0.5 * self.config.map.voxel_m)
        return self._safe(self._stopping_piece(t, pva), self.map.clearance, t, floor)

    def brake(self, t: float) -> None:
        """Stop from the current state with a single minimum-jerk piece (no obstacle knowledge).

        A stop already under way is kept, not restarted: a minimum-jerk piece
        starts with the current acceleration and zero jerk, so one restarted
        at every frame (every failed replan while the plan is unsafe) never
        builds up its deceleration: from 2 m/s, restarted at 25 Hz, the
        reference is still at 1.62 m/s after 0.5 s against 1.37 m/s for the
        committed piece (whose peak deceleration is 0.75 a_max). ``brakes``
        counts the stops started.
        """
        if self.braking and self.trajectory is not None:
            return
        self.trajectory = self._stopping_piece(t, self.state_at(t))
        self.braking = True
        self.last_plan_time_s = t
        self.stats.brakes += 1

    def _stopping_piece(self, t: float, pva: np.ndarray) -> MincoTrajectory:
        """One minimum-jerk piece from ``pva`` (3, 3) at ``t`` [s] to rest, over 2 |v| / a_max (>= 0.3 s)."""
        p, v, a = pva
        T = max(2.0 * float(np.linalg.norm(v)) / self.config.limits.a_max_mps2, 0.3)
        stop = p + 0.5 * v * T  # a comfortable stopping distance along the current velocity
        return minco_s3(np.stack([p, v, a]), np.stack([stop, np.zeros(3), np.zeros(3)]), np.zeros((0, 3)), np.array([T]), t0_s=t)

    # output -----------------------------------------------------------------
    def reference(self, time_s: float) -> FlatOutputReference:
        """Reference at ``time_s`` [s]: the current MINCO trajectory and the heading of :mod:`mpcde.onboard.denied.heading`."""
        if self.heading is None:  # no pose estimate yet
            return FlatOutputReference.hover(np.zeros(3), 0.0)
        if self.escape.turning(self, time_s):  # the turn once round: hover, turning at the yaw-rate limit
            yaw, rate = self.escape.turn_yaw(time_s)
            return FlatOutputReference(self.hover_world, np.zeros(3), np.zeros(3), yaw, rate)
        if self.trajectory is None:
            yaw, yaw_rate = self.heading.reference(time_s, None)
            return FlatOutputReference(self.hover_world, np.zeros(3), np.zeros(3), yaw, yaw_rate)
        p, v, a = self.state_at(time_s)
        yaw, yaw_rate = self.heading.reference(time_s, v)
        return FlatOutputReference(pos_world=p, vel_world=v, acc_world=a, yaw=yaw, yaw_rate=yaw_rate)

    def extra_metrics(self) -> dict:
        """Planner statistics for metrics.json."""
        out = self.stats.metrics(self.look.metrics())
        if self.heading is not None:
            out.update(self.heading.metrics())
        if self.perception is not None:
            out.update(self.perception.counts.metrics())
        return out
