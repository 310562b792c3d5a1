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

Yaw (MP-CDE Sec. IV-A, :mod:`mpcde.onboard.heading`): every t_y = 0.1 s of frame
time the active yaw planner (:mod:`planners.yaw`, Alg. 1) chooses exploring,
observing or tracking from the safety margin S(0) and the tracks, and the
reference follows its rate-limited yaw sequence; its line 13 (S(0) < tau_thr or
a neighbour within C_s now) is replanning trigger (e). With ``active_yaw:
false`` the heading follows the direction of travel (the ablation).
"""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from mpcde.config.denied import DeniedAgentConfig
from mpcde.config.level_rules import flight_level_m
from mpcde.config.perception import PerceptionConfig
from mpcde.onboard.base import AgentCounters, OnboardAgent
from mpcde.onboard.budget import ComputeBudget
from mpcde.onboard.flight_levels import FlightLevels
from mpcde.onboard.fresh_path import FreshPathWatch, Look
from mpcde.onboard.heading import ActiveYaw
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

__all__ = ["DeniedAgent", "DeniedAgentConfig", "PlanningStats"]


@dataclass
class PlanningStats:
    """What the agent's planner did (for metrics)."""

    replans: int = 0
    failures: int = 0
    brakes: int = 0
    swarm_replans: int = 0
    yaw_replans: int = 0
    rest_escapes: int = 0  # stops that ended inside the obstacle band and began an escape (_escape_floor)
    front_end_failures: dict = field(default_factory=dict)  # refused front-end searches by status ("goal_blocked", "no_path", ...)
    goal_fallbacks: int = 0  # found paths to the window's voxel nearest the goal (clipped goal blocked, no plan or stopping)
    solve_ms: list = field(default_factory=list)
    map_ms: list = field(default_factory=list)


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
        swarm_neighbours: how many other drones were launched with this one (the mission's roster, as the
            goal is the mission's; not their state): the yaw planner's ``roster_aware`` reads it.
        neighbour_source: where planning reads the neighbours from, ``source(t, count) -> predictions``
            (``count``: a planning use the source may tally); None: this drone's tracks. The composite
            stacks give theirs: ``auto`` its radio memory fused with the tracks, ``minco_comm`` the radio's plans.
    """

    def __init__(
        self, drone_id: int, goal_world: np.ndarray, config: DeniedAgentConfig, perception_config: PerceptionConfig | None = None,
        perception: NeighbourPerception | None = None,
        budget: ComputeBudget | None = None,
        swarm_neighbours: int = 0,
        neighbour_source: Callable[[float, bool], list[NeighborPrediction]] | None = None,
    ) -> None:
        self.drone_id = drone_id
        self.swarm_neighbours = swarm_neighbours
        self.budget = budget if budget is not None else ComputeBudget()
        self.goal_world = np.asarray(goal_world, float)
        self.config = config
        self.counters = AgentCounters()
        self.stats = PlanningStats()
        self.map = OccupancyMap(config.map, on_esdf=lambda seconds: self.budget.add("esdf", seconds))
        self.maps_frames = True
        self._scan: tuple[float, float, float] | None = None  # (start [s], start yaw [rad], end [s]) of the look-around turn
        self._escaping = False  # leaving the obstacle band of a halting hand-over (_escape_floor)
        self._escape_floor_m: float | None = None
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
            v_max_mps=c.v_max_mps, a_max_mps2=c.a_max_mps2, obstacle_clearance_m=c.clearance_m,
            swarm_clearance_m=c.swarm_clearance_m, swarm_z_scale=c.swarm_z_scale,
        )
        # detector_request: what the loop's batched detector reads (None: no detections)
        self.perception, self.detector_request = onboard_perception(c.perceive_neighbours, perception_config, perception)
        self.search = PathSearchConfig()
        self.levels: FlightLevels | None = None  # config.flight_level_spacing_m: this drone's level, fixed by its first estimate
        self.neighbour_source = neighbour_source
        # look before moving (denied.fresh_path_age_s): the corridor check's state, every t_y
        self.fresh_path = FreshPathWatch(c, c.yaw.period_s, 2.0 * c.map.voxel_m)

    # inputs ---------------------------------------------------------------
    def on_pose_estimate(self, estimate: PoseEstimate) -> None:
        """Own pose estimate; the first one fixes the hover point and heading."""
        self.latest_estimate = estimate
        if self.hover_world is None:
            self.hover_world = estimate.pos_world.copy()
            band = self.config.altitude_band_m
            if np.isfinite(band):  # the layer between the start and goal altitudes, widened by the band
                lo = min(float(self.hover_world[2]), float(self.goal_world[2])) - band
                hi = max(float(self.hover_world[2]), float(self.goal_world[2])) + band
                self._hold_layer(lo, hi)
            spacing = self.config.flight_level_spacing_m
            if np.isfinite(spacing):
                centre = 0.5 * (float(self.hover_world[2]) + float(self.goal_world[2]))
                level = flight_level_m(centre, self.drone_id, self.swarm_neighbours + 1, spacing)
                self.levels = FlightLevels(self.goal_world, level, spacing, self.config.flight_level_release_m)
            yaw = float(yaw_from_rotation(rotation_from_quat_xyzw(estimate.quat_xyzw)))
            c = self.config
            self.heading = ActiveYaw(
                self.yaw_config, c.active_yaw, yaw, c.swarm_clearance_m, c.swarm_z_scale, self.swarm_neighbours
            )
            if c.look_around:  # one revolution from the first estimate on (config.look_around)
                self._schedule_turn(float(estimate.time_s), yaw)

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
        if t < self.config.start_delay_s or self.latest_estimate is None or self._scanning(t) or self._escape_from_rest(t):
            return
        released = glancing = False
        if self.fresh_path.looking:  # the camera turning to a stale point (a hold stops for it, a glance flies on)
            if self._end_look(t):
                released = self.fresh_path.stops
            elif self.fresh_path.stops:
                return  # stopping: no yaw plan, no replan
            else:
                glancing = True
        neighbours = self.neighbours(t)
        yaw_trigger = False
        if not glancing and self.heading.due(t):  # Alg. 1 lines 1-12 every t_y; line 13's trigger is (e)
            with self.budget.measure("yaw"):
                yaw_trigger = self.heading.update(t, self.map.snapshot(), self.trajectory, self.hover_world, neighbours)
        if not released and self._fresh_path_due(t) and self._look_before_moving(t, glancing):
            return
        # the per-frame check reads the newest ESDF and the voxels occupied since (no transform)
        unsafe = False
        if self.trajectory is not None:  # the escape floor is read (and first fixed) only for a plan in hand
            floor = self._escape_floor(self.map.clearance, self.state_at(t)[0]) if self._escaping else None
            unsafe = not self._safe(self.trajectory, self.map.clearance, t, floor)
        conflict = self.trajectory is not None and self._swarm_conflict(self.trajectory, neighbours, t)
        due = t - self.last_plan_time_s >= self.config.replan_period_s or self._climbed(t)
        if self.trajectory is None or unsafe or conflict or yaw_trigger or due or released:
            replanned = self._replan(self.map.snapshot(), neighbours, t)
            self.stats.swarm_replans += int(replanned and conflict)
            self.stats.yaw_replans += int(replanned and yaw_trigger)
            if not replanned and unsafe:
                self._brake(t)

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
        self._scan, self._escaping = None, False
        if self.heading is not None:
            self.heading.restart(yaw, time_s)
        if not look_around:
            return None
        stop = self.trajectory
        return self._begin_turn(stop.t0_s + stop.total_duration, stop.pos(np.array([stop.total_duration]))[0], yaw)

    def look_around_at(self, time_s: float, pos_world: np.ndarray, yaw: float) -> tuple[float, float]:
        """Hover at ``pos_world`` (3,) [m] from ``time_s`` [s] on, turn the camera once round from ``yaw`` [rad] at
        the yaw-rate limit, then plan (the ``auto`` agent's halting hand-over, ``auto.handover: halt``).

        Until ``time_s`` this stack neither plans nor flies: the caller flies the drone to ``pos_world`` and
        brings it to rest there (its last broadcast DMPC plan, to that plan's halt). Returns the turn's start and
        end [s].
        """
        self.trajectory, self.braking = None, False
        return self._begin_turn(time_s, pos_world, yaw)

    def _begin_turn(self, time_s: float, pos_world: np.ndarray, yaw: float) -> tuple[float, float]:
        """Schedule the turn from ``time_s`` [s] at ``pos_world`` (3,) [m] from ``yaw`` [rad], with the escape from
        the obstacle band (:meth:`_escape_floor`) after it; returns the turn's start and end [s]."""
        self.hover_world = np.asarray(pos_world, float).copy()
        self._escaping, self._escape_floor_m = True, None
        self.last_plan_time_s = -np.inf
        return self._schedule_turn(time_s, yaw)

    def _schedule_turn(self, time_s: float, yaw: float) -> tuple[float, float]:
        """One revolution at the yaw-rate limit from ``time_s`` [s] and ``yaw`` [rad] (``_scan``); returns its start
        and end [s]."""
        t0 = float(time_s)
        self._scan = (t0, float(yaw), t0 + 2.0 * np.pi / self.config.yaw_rate_max_radps)
        return t0, self._scan[2]

    def _scanning(self, t: float) -> bool:
        """Whether a look-around turn (config.look_around, :meth:`look_around_at`) is due or on at ``t`` [s], so
        that nothing is planned; when it ends, the trajectory is dropped (the drone hovers where the turn was) and
        the heading continues from where the turn left it."""
        if self._scan is None:
            return False
        t0, yaw0, t_end = self._scan
        if t < t_end - 1e-9:
            return True
        self._scan = None
        self.trajectory, self.braking = None, False
        self.heading.restart(yaw0 + 2.0 * np.pi, t)
        return False

    def _turning(self, t: float) -> bool:
        """Whether the look-around turn itself is on at ``t`` [s] (started, not ended; see :meth:`_scanning`)."""
        return self._scanning(t) and t >= self._scan[0] - 1e-9

    # planning ---------------------------------------------------------------
    def state_at(self, t: float) -> np.ndarray:
        """(3, 3) position, velocity, acceleration of the current reference at ``t``."""
        if self.trajectory is None:
            return np.stack([self.hover_world, np.zeros(3), np.zeros(3)])
        return self.trajectory.pos_vel_acc(t - self.trajectory.t0_s)

    @property
    def band_m(self) -> float:
        """The obstacle band [m]: the clearance from the map's obstacles every plan keeps (0.75 clearance_m), which
        :meth:`_safe` checks and the escapes (:meth:`_escape_floor`, :meth:`_resting_in_band`) start inside."""
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
        docs/results/radio_outage.md); one handed over there has :meth:`_escape_floor`.
        """
        tau = np.linspace(max(t - traj.t0_s, 0.0), traj.total_duration, 40)
        d = distance(traj.pos(tau))
        return bool(np.min(d) >= (self.band_m if floor_m is None else floor_m))

    def _escape_floor(self, distance: Callable[[np.ndarray], np.ndarray], pos_world: np.ndarray) -> float | None:
        """The obstacle clearance [m] :meth:`_safe` asks of a plan from ``pos_world`` (3,) [m] while the drone
        leaves the band it was handed over in or came to rest in (:meth:`_resting_in_band`); None
        (0.75 clearance_m) otherwise.

        A halting hand-over (:meth:`look_around_at`) leaves the drone where the DMPC plan halted, which may be
        inside the denied stack's band (DMPC keeps its own, smaller obstacle margin), and no plan from there
        keeps 0.75 clearance_m. Until the reference first leaves the band, a plan may come no closer than the
        hover point's clearance (taken at the first plan from it), to the ESDF's resolution (half a voxel). A
        drone that entered the band in flight gets no such rule (tried and dropped for all plans:
        docs/results/radio_outage.md).
        """
        if not self._escaping:
            return None
        d = float(distance(np.asarray(pos_world, float)[None])[0])
        if d >= self.band_m:
            self._escaping = False
            return None
        if self._escape_floor_m is None:  # fixed at the first plan from the hover point: no ratchet inwards
            self._escape_floor_m = d - 0.5 * self.config.map.voxel_m
        return self._escape_floor_m

    def _escape_from_rest(self, t: float) -> bool:
        """At the first frame ``t`` [s] at rest inside the obstacle band (:meth:`_resting_in_band`): turn the camera
        once round where the drone rests, then plan out of the band no closer than it rests (:meth:`_escape_floor`);
        the halting hand-over's sequence (:meth:`look_around_at`), so that the neighbours about it are tracks before
        it moves. Returns whether the turn began."""
        if not self._resting_in_band(t):
            return False
        self.stats.rest_escapes += 1
        self._begin_turn(t, self.state_at(t)[0], self.heading.yaw)
        return True

    def _resting_in_band(self, t: float) -> bool:
        """Whether a stop (:meth:`_brake`) has ended by ``t`` [s] with the drone inside the obstacle band
        (0.75 clearance_m on the map's newest clearance) and no escape under way.

        From there every plan starts inside the band, so :meth:`_safe` refuses them all and the drone would hover
        until the map changed (radio_outage seed 19, denied: 667 refused replans, docs/results/radio_outage.md).
        Only a drone at rest qualifies: the same rule for plans begun inside the band in flight was tried and
        dropped (radio_outage.md, "Tried and dropped").
        """
        stop = self.trajectory
        if not self.braking or self._escaping or stop is None or t < stop.t0_s + stop.total_duration - 1e-9:
            return False
        rest = stop.pos(np.array([stop.total_duration]))
        return bool(self.map.clearance(rest)[0] < self.band_m)

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
        if not self._safe(result.trajectory, esdf, t, self._escape_floor(esdf, start[0])):
            self.stats.failures += 1
            return False
        self.trajectory = result.trajectory
        self.braking = False
        self.last_plan_time_s = t
        self.stats.replans += 1
        return True

    def _level_goal(self, pos_world: np.ndarray) -> np.ndarray:
        """The goal this replan from ``pos_world`` (3,) [m] flies to: the goal, or with flight levels
        (:meth:`mpcde.onboard.flight_levels.FlightLevels.goal_and_layer`) the goal of the sequence's step, whose
        layer is then held (``_hold_layer``: the optimiser's altitude penalty and the front end's search)."""
        if self.levels is None:
            return self.goal_world
        goal, (lo, hi) = self.levels.goal_and_layer(pos_world)
        self._hold_layer(lo, hi)
        return goal

    def _hold_layer(self, lo: float, hi: float) -> None:
        """Hold the optimiser's samples (altitude penalty) and the front end's search in altitudes [lo, hi] [m]."""
        self.optimizer = dataclasses.replace(self.optimizer, altitude_band_m=(lo, hi))
        pad = self.config.map.voxel_m  # the search's voxels: the start's own voxel stays in the layer
        self.search = dataclasses.replace(self.search, min_altitude_m=max(0.0, lo - pad), max_altitude_m=hi + pad)

    def _climbed(self, t: float) -> bool:
        """Whether the plan in hand has just brought the drone to its flight level (replan at once for the goal)."""
        if self.levels is None or self.levels.reached or self.trajectory is None:
            return False
        return self.levels.climbed(self.state_at(t)[0])

    def _fresh_path_due(self, t: float) -> bool:
        """Whether the corridor ahead is checked at ``t`` [s] (``denied.fresh_path_age_s`` finite, a plan being flown, every t_y)."""
        return self.fresh_path.enabled and self.trajectory is not None and not self.braking and self.fresh_path.due(t)

    def _look_before_moving(self, t: float, glancing: bool) -> bool:
        """Check the corridor ahead at ``t`` [s] and act on the look it begins; whether a hold (a stop) began."""
        d_stop = float(np.linalg.norm(self.state_at(t)[1])) ** 2 / self.config.a_max_mps2
        look = self.fresh_path.check(self.map.snapshot(), self.trajectory, t, d_stop, glancing, lambda: self._can_stop(t))
        if look is not None:
            self._begin_look(t, look)
        return look is not None and look.stop

    def _can_stop(self, t: float) -> bool:
        """Whether a hold may stop at ``t`` [s]: the straight stopping piece (:meth:`_stopping_piece`, which knows no
        obstacles) keeps out of the obstacle band, or, for a drone already inside it, no closer than it is now."""
        pva = self.state_at(t)
        floor = min(self.band_m, float(self.map.clearance(pva[0][None])[0]) - 0.5 * self.config.map.voxel_m)
        return self._safe(self._stopping_piece(t, pva), self.map.clearance, t, floor)

    def _begin_look(self, t: float, look: Look) -> None:
        """Stop first if the look is a hold, then turn the camera to its point at the rate limit (``ActiveYaw.look_toward``)."""
        if look.stop:
            self._brake(t)
        pos = self.state_at(t)[0]
        self.heading.look_toward(t, float(np.arctan2(look.point_world[1] - pos[1], look.point_world[0] - pos[0])))

    def _end_look(self, t: float) -> bool:
        """Whether the look ends at ``t`` [s]: the commanded yaw has been on the point for two t_y (at most pi / rate + 2 t_y)."""
        if self.heading.looked_since(t) < 2.0 * self.yaw_config.period_s - 1e-9:
            return False
        self.fresh_path.end()
        self.heading.restart(self.heading.reference(t, None)[0], t)
        return True

    def _brake(self, t: float) -> None:
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
        T = max(2.0 * float(np.linalg.norm(v)) / self.config.a_max_mps2, 0.3)
        stop = p + 0.5 * v * T  # a comfortable stopping distance along the current velocity
        return minco_s3(np.stack([p, v, a]), np.stack([stop, np.zeros(3), np.zeros(3)]), np.zeros((0, 3)), np.array([T]), t0_s=t)

    # output -----------------------------------------------------------------
    def reference(self, time_s: float) -> FlatOutputReference:
        """Reference at ``time_s`` [s]: the current MINCO trajectory and the heading of :mod:`mpcde.onboard.heading`."""
        if self.heading is None:  # no pose estimate yet
            return FlatOutputReference.hover(np.zeros(3), 0.0)
        if self._turning(time_s):  # config.look_around or look_around_at: hover, turning at the yaw-rate limit
            t0, yaw0, _ = self._scan
            rate = self.config.yaw_rate_max_radps
            return FlatOutputReference(self.hover_world, np.zeros(3), np.zeros(3), yaw0 + rate * (time_s - t0), rate)
        if self.trajectory is None:
            yaw, yaw_rate = self.heading.reference(time_s, None)
            return FlatOutputReference(self.hover_world, np.zeros(3), np.zeros(3), yaw, yaw_rate)
        p, v, a = self.state_at(time_s)
        yaw, yaw_rate = self.heading.reference(time_s, v)
        return FlatOutputReference(pos_world=p, vel_world=v, acc_world=a, yaw=yaw, yaw_rate=yaw_rate)

    def extra_metrics(self) -> dict:
        """Planner statistics for metrics.json."""
        s = self.stats
        out = {
            "replans": s.replans,
            "plan_failures": s.failures,
            "brakes": s.brakes,
            "swarm_replans": s.swarm_replans,
            "yaw_replans": s.yaw_replans,
            "rest_escapes": s.rest_escapes,
            "front_end_failures": dict(sorted(s.front_end_failures.items())),
            "goal_fallbacks": s.goal_fallbacks,
            **self.fresh_path.metrics(),
            "replan_ms_median": float(np.median(s.solve_ms)) if s.solve_ms else None,
            "map_ms_median": float(np.median(s.map_ms)) if s.map_ms else None,
        }
        if self.heading is not None:
            out.update(self.heading.metrics())
        if self.perception is not None:
            out.update(self.perception.counts.metrics())
        return out
