"""The ``denied:`` section of a scenario: settings of the MP-CDE (communication-denied) stack."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import ClassVar

from perception.map_config import MapConfig
from planners.limits import KinematicLimits, require_infinite_jerk
from planners.yaw.config import YawPlannerConfig
from sim.checks import require_at_least, require_boolean, require_instance, require_non_negative, require_positive

__all__ = ["DeniedAgentConfig"]


@dataclass(frozen=True)
class DeniedAgentConfig:
    """Settings of the MP-CDE agent.

    Attributes:
        limits: the optimiser's limits on the norms of speed and acceleration
            (:class:`planners.limits.KinematicLimits`; MP-CDE Eq. 15, defaults
            1 m/s and 3 m/s^2); MINCO bounds no jerk, so ``j_max_mps3`` stays inf.
        clearance_m: obstacle clearance of the trajectory on the ESDF [m].
        front_end_clearance_m: clearance required by the front-end search [m].
        replan_period_s: replan at least this often [s] (DESIGN.md: 0.5 s).
        yaw_rate_max_radps: heading rate limit [rad/s] (MP-CDE Table I: 2.0).
        start_delay_s: hover before the first departure [s].
        swarm_clearance_m: C_s [m] kept from tracked neighbours (MP-CDE Table I: 0.7).
        swarm_z_scale: c of the ellipsoidal metric E = diag(1, 1, 1/c) [-] (Eq. 16).
        conflict_horizon_s: look-ahead [s] of replanning trigger (d) along the tracks' predictions.
        perceive_neighbours: run the detector and tracker (False: map only, blind to other drones);
            their settings are the scenario's ``perception:`` section.
        active_yaw: plan the heading with MP-CDE's active yaw planner (False: heading along travel).
        flight_level_spacing_m: s, vertical spacing [m] of the flight levels: drone k of a mission of N
            cruises at z_k = z_c + (k - (N - 1) / 2) s, z_c the mean of its own start and goal altitudes
            (its first pose estimate and its goal), held within s / 8 of it by the altitude penalty of the
            optimiser and the front end's layer. It first climbs (or descends) to its level where it
            is, before it leaves its start, and leaves the level for its goal once within
            ``flight_level_release_m`` of it horizontally, for good. Procedural vertical separation: the
            rule of airspace without surveillance, where traffic that cannot see each other is kept
            apart by assignment rather than by sight. Not in MP-CDE. Why: drones on levels s apart
            cannot touch (contact is 2 robot radii, 0.2 m) while both hold their levels, seen or not,
            so it removes the contacts of neighbours that lost each other from the camera's view
            (docs/results/safety.md#flight-levels). The id and N are the mission's assignment, as the goal is: no
            neighbour's state is read. inf (default): no levels, the paper's free altitude.
        flight_level_release_m: horizontal distance [m] from the goal at which a drone on flight
            levels leaves its level for the goal's altitude.
        fresh_path_age_s: look before moving: free space of the corridor ahead last seen by the camera
            longer than this ago [s] is stale (:mod:`mpcde.onboard.denied.look`). Every t_y the drone checks
            the corridor (half width ``fresh_path_half_width_m``) of its trajectory from
            ``fresh_path_near_m`` to its stopping distance plus ``fresh_path_distance_m`` ahead; at a stale
            point it brakes to a stop, turns the camera to that point at the yaw-rate limit, holds until the
            commanded yaw has been on it for two t_y (frames mapped with the camera there; a hold lasts at
            most pi / yaw_rate_max + 2 t_y), then replans and flies on. A point still stale at the next
            check lies where the camera cannot refresh it (a trunk's shadow): the check then rests for
            ``fresh_path_rest_s``, so the drone is never held for good. A hold whose straight stop would cut
            into the obstacle band is flown as a glance instead (the camera turns, the plan is kept).
            Not in MP-CDE. Why: a drone that only moves into space it looked at within this time sees a
            neighbour in its way unless the neighbour moved there since, so it removes the contacts of
            drones that close outside each other's view (docs/results/safety.md#look-before-moving). inf (this section's
            default, the paper's; the ``denied`` stack's preset sets 1 s, docs/results/denied_default.md#the-decision): off,
            the paper's stack.
        fresh_path_half_width_m: half width [m] of that corridor (a class constant, as the next three and
            ``fresh_path_glance_distance_m``: no scenario or sweep sets them).
        fresh_path_near_m: the corridor starts this far ahead along the path [m] (the space the drone
            is already in is never seen again: the camera's minimum range).
        fresh_path_distance_m: the corridor ends this far beyond the stopping distance v^2 / a_max [m].
        fresh_path_rest_s: how long [s] the check rests after a look that did not refresh its point.
        fresh_path_glance_age_s: the same check's early stage [s]: where no point is stale, the first
            corridor point older than this within the stopping distance plus
            ``fresh_path_glance_distance_m`` turns the camera to it while the drone flies on (the yaw
            plan resumes two t_y after the camera is on it), so that the corridor is refreshed before a
            stop is needed. inf: no glances, holds only.
        fresh_path_glance_distance_m: where the glances' corridor ends beyond the stopping distance [m].
        map: occupancy map settings.
        yaw: active yaw planner settings; its speed limit, yaw-rate limit, t_hold
            and field of view are taken from ``limits.v_max_mps``, ``yaw_rate_max_radps``,
            ``perception.tracker.t_hold_s`` and the scenario's camera, so each is set once.
    """

    limits: KinematicLimits = KinematicLimits(1.0, 3.0)
    clearance_m: float = 0.4
    front_end_clearance_m: float = 0.45
    replan_period_s: float = 0.5
    yaw_rate_max_radps: float = 2.0
    start_delay_s: float = 0.5
    swarm_clearance_m: float = 0.7
    swarm_z_scale: float = 2.0
    conflict_horizon_s: float = 1.2
    perceive_neighbours: bool = True
    active_yaw: bool = True
    flight_level_spacing_m: float = float("inf")
    flight_level_release_m: float = 1.0
    fresh_path_age_s: float = float("inf")
    fresh_path_half_width_m: ClassVar[float] = 0.25
    fresh_path_near_m: ClassVar[float] = 0.3
    fresh_path_distance_m: ClassVar[float] = 1.0
    fresh_path_rest_s: ClassVar[float] = 2.0
    fresh_path_glance_age_s: float = 0.5
    fresh_path_glance_distance_m: ClassVar[float] = 2.0
    map: MapConfig = field(default_factory=MapConfig)
    yaw: YawPlannerConfig = field(default_factory=YawPlannerConfig)

    def __post_init__(self) -> None:
        units = {
            "clearance_m": "m", "front_end_clearance_m": "m",
            "replan_period_s": "s", "yaw_rate_max_radps": "rad/s", "swarm_clearance_m": "m", "conflict_horizon_s": "s",
        }  # fmt: skip
        for name, unit in units.items():
            require_positive(name, getattr(self, name), unit)
        require_non_negative("start_delay_s", self.start_delay_s, "s")
        require_positive("flight_level_spacing_m", self.flight_level_spacing_m, "m", inf_means="no flight levels")
        require_non_negative("flight_level_release_m", self.flight_level_release_m, "m")
        require_positive("fresh_path_age_s", self.fresh_path_age_s, "s", inf_means="no look before moving")
        require_positive("fresh_path_glance_age_s", self.fresh_path_glance_age_s, "s", inf_means="no glances")
        require_at_least("swarm_z_scale", self.swarm_z_scale, 1.0)
        require_boolean("perceive_neighbours", self.perceive_neighbours)
        require_boolean("active_yaw", self.active_yaw)
        require_instance("limits", self.limits, KinematicLimits)
        require_infinite_jerk(self.limits, "MINCO's penalties bound speed and acceleration only (MP-CDE Eq. 15)")
        require_instance("map", self.map, MapConfig)
        require_instance("yaw", self.yaw, YawPlannerConfig)
