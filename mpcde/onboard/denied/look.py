"""Look before moving, a component of the denied agent: never move into free space the camera has not seen lately.

A drone with one 85 deg camera cannot watch every neighbour; what it can do is
never move into space it has not looked at lately. This module finds, along
the drone's own trajectory, the first point of a horizontal corridor whose
voxel the map holds *free* but last touched by a camera ray more than
``max_age_s`` before the map's newest frame (the snapshot's ``seen_s``): space
where a neighbour that the drone is not tracking may have arrived since. The
denied agent (``denied.fresh_path_age_s``) stops short of such a point and
turns its camera to it before it flies on. Not in MP-CDE.

Geometry. The trajectory is sampled every ``sample_s`` from now; a sample's
arc length is the horizontal distance flown from the first sample. The
corridor is each sample with arc length in ``[near_m, far_m]`` and the two
points ``half_width_m`` either side of it, perpendicular to the horizontal
direction of the path there. ``near_m`` leaves out the space the drone is
already in (the camera ignores depth nearer than the map's ``min_range_m``, so
that space is never seen again once the drone is on it); ``far_m`` is how far
ahead the corridor must be fresh. Unknown and occupied voxels are not stale:
unknown space is the planner's business as before (MP-CDE's Eq. 1 ends the
safe segment there), and trunks do not move; only free space ages, because
only the drones move (the same reason as ``YawPlannerConfig.free_max_age_s``).

Why it exists: it removes the drone-drone contacts that the camera cannot
see coming, a follower closing on a neighbour ahead of it or beside its path
while its camera looks elsewhere (observing, exploring, or the tracking
mode's swing): docs/results/safety.md#look-before-moving.

The rule's state lives in :class:`FreshPathWatch` (when the corridor is
checked next, the look under way, the rest after a point the camera could not
refresh, the counts for metrics.json); :class:`LookBeforeMoving` is the
component the agent composes, with two verbs: :meth:`LookBeforeMoving.gate`
(what the look under way allows this frame) and :meth:`LookBeforeMoving.look_ahead`
(check the corridor and act on the look it begins: a stop, the heading's turn
to the point).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from mpcde.config.denied import DeniedAgentConfig
from perception.types import OccupancySnapshot
from planners.minco import MincoTrajectory

if TYPE_CHECKING:
    from mpcde.onboard.denied.agent import DeniedAgent

__all__ = ["FreshPathWatch", "Gate", "Look", "LookBeforeMoving", "first_stale_point"]


def first_stale_point(
    snapshot: OccupancySnapshot, trajectory: MincoTrajectory, time_s: float, *, max_age_s: float, half_width_m: float,
    near_m: float, far_m: float, sample_s: float = 0.05, horizon_s: float = 6.0,
) -> np.ndarray | None:
    """The first stale corridor point (3,) [m] along ``trajectory`` from ``time_s`` [s], or None (module docstring).

    Args:
        snapshot: the drone's map window (needs ``seen_s``; None there: nothing is stale).
        trajectory: the drone's current trajectory (held at its end after it).
        time_s: now, absolute [s].
        max_age_s: free space last seen longer ago than this before ``snapshot.time_s`` is stale [s].
        half_width_m: half width of the corridor [m].
        near_m, far_m: the corridor spans arc lengths ``[near_m, far_m]`` [m] of the path ahead.
        sample_s: spacing of the trajectory samples [s].
        horizon_s: the path is sampled over ``[time_s, time_s + horizon_s]`` at most [s].

    Points are taken in path order, and at each sample the centre before the
    two sides; the first stale one is returned.
    """
    if snapshot.seen_s is None or not math.isfinite(max_age_s):
        return None
    taus = np.arange(0.0, horizon_s + 1e-9, sample_s)
    local = np.clip(time_s + taus - trajectory.t0_s, 0.0, trajectory.total_duration)
    p = trajectory.pos(local)
    step = np.hypot(*np.diff(p[:, :2], axis=0).T)
    arc = np.concatenate([[0.0], np.cumsum(step)])
    keep = (arc >= near_m) & (arc <= far_m)
    if not np.any(keep):
        return None
    # the path's horizontal direction at each sample (the step that arrives there; the first step for sample 0)
    d = np.diff(p[:, :2], axis=0)
    d = np.concatenate([d[:1], d])
    norm = np.hypot(d[:, 0], d[:, 1])
    keep &= norm > 1e-9  # the held end of the path adds no direction and no new space
    if not np.any(keep):
        return None
    centre = p[keep]
    u = d[keep] / norm[keep, None]
    n = np.stack([-u[:, 1], u[:, 0], np.zeros(len(u))], axis=1)  # left of travel
    points = np.stack([centre, centre + half_width_m * n, centre - half_width_m * n], axis=1).reshape(-1, 3)
    free = snapshot.state_at(points) == OccupancySnapshot.FREE
    if not np.any(free):
        return None
    idx = snapshot.world_to_index(points[free])
    aged = snapshot.seen_s[idx[:, 0], idx[:, 1], idx[:, 2]] < snapshot.time_s - max_age_s
    if not np.any(aged):
        return None
    return points[free][int(np.argmax(aged))].copy()


@dataclass(frozen=True)
class Look:
    """A look the watch began: turn the camera to ``point_world`` (3,) [m]; ``stop``: brake first (a hold), else fly on (a glance)."""

    point_world: np.ndarray
    stop: bool


class FreshPathWatch:
    """The look-before-moving rule's state for one drone (``denied.fresh_path_*``; module docstring).

    Every ``period_s`` (t_y) while a plan is flown, :meth:`check` looks along the
    corridor ahead: a stale point (older than ``fresh_path_age_s``) within the
    stopping distance plus ``fresh_path_distance_m`` begins a hold; else, unless
    a glance is under way, a point older than ``fresh_path_glance_age_s`` within
    the stopping distance plus ``fresh_path_glance_distance_m`` begins a glance.
    A point found again within ``same_point_m`` of the last look's point at the
    next check was not refreshed by that look (it lies in a trunk's shadow): the
    check then rests for ``fresh_path_rest_s`` instead of looking again, so the
    drone is never held for good. A hold whose stop the caller finds unsafe
    (``can_stop`` false: the agent's straight stopping piece would cut into the
    obstacle band) is begun as a glance instead: the drone flies on along its
    obstacle-checked plan while the camera turns to the point (``unsafe_stops``
    counts them).

    Args:
        config: the scenario's ``denied:`` settings (the ``fresh_path_*`` fields).
        period_s: how often the corridor is checked [s] (the yaw period t_y).
        same_point_m: how near a point must be to the last look's to count as the same [m] (two voxels).
    """

    def __init__(self, config: DeniedAgentConfig, period_s: float, same_point_m: float):
        self.config = config
        self.period_s = float(period_s)
        self.same_point_m = float(same_point_m)
        self.since_s: float | None = None  # when the look under way began (None: none)
        self.stops = False  # whether that look is a hold (a stop) or a glance
        self.holds = 0  # stops to look at a stale point of the corridor ahead
        self.glances = 0  # turns of the camera to an ageing point while flying on
        self.unrefreshed = 0  # points still stale after a look at them (the check then rested)
        self.unsafe_stops = 0  # holds begun as glances because their stop was unsafe
        self._next_s = -np.inf  # the corridor is checked every period_s from here
        self._rest_until_s = -np.inf  # after a look that did not refresh its point, the check rests until here
        self._last: np.ndarray | None = None  # the point the last look was at, until a check finds none

    @property
    def enabled(self) -> bool:
        """Whether the rule is on (``fresh_path_age_s`` finite)."""
        return math.isfinite(self.config.fresh_path_age_s)

    @property
    def looking(self) -> bool:
        """Whether a look (hold or glance) is under way."""
        return self.since_s is not None

    def due(self, time_s: float) -> bool:
        """Whether the corridor is checked at ``time_s`` [s] (every ``period_s``, not while resting); books the next check."""
        if time_s < self._next_s - 1e-9 or time_s < self._rest_until_s:
            return False
        self._next_s = time_s + self.period_s
        return True

    def check(
        self, snapshot: OccupancySnapshot, trajectory: MincoTrajectory, time_s: float, stopping_m: float, glancing: bool,
        can_stop: Callable[[], bool] | None = None,
    ) -> Look | None:
        """The look that the corridor ahead begins at ``time_s`` [s], or None (class docstring).

        ``stopping_m``: the drone's stopping distance v^2 / a_max [m]; ``glancing``: a glance is under way
        (only a hold may begin); ``can_stop``: asked only when a hold would begin, whether the drone may stop
        (None: always).
        """
        c = self.config
        kw = dict(half_width_m=c.fresh_path_half_width_m, near_m=c.fresh_path_near_m)
        stale = first_stale_point(snapshot, trajectory, time_s, max_age_s=c.fresh_path_age_s, far_m=stopping_m + c.fresh_path_distance_m, **kw)
        if stale is not None:
            return self.begin(time_s, stale, stop=True, can_stop=can_stop)
        if glancing or not math.isfinite(c.fresh_path_glance_age_s):
            return None
        ageing = first_stale_point(
            snapshot, trajectory, time_s, max_age_s=c.fresh_path_glance_age_s, far_m=stopping_m + c.fresh_path_glance_distance_m, **kw
        )
        if ageing is None:
            self._last = None
            return None
        return self.begin(time_s, ageing, stop=False)

    def begin(
        self, time_s: float, point_world: np.ndarray, stop: bool, can_stop: Callable[[], bool] | None = None
    ) -> Look | None:
        """Begin a look at ``point_world`` (3,) [m] at ``time_s`` [s], or rest the check if it is the last look's point.

        A hold (``stop``) that ``can_stop`` refuses is begun as a glance.
        """
        point = np.asarray(point_world, float).copy()
        last, self._last = self._last, point
        if last is not None and np.linalg.norm(last - point) <= self.same_point_m:
            self.unrefreshed += 1
            self._rest_until_s = time_s + self.config.fresh_path_rest_s
            self._last = None
            return None
        if stop and can_stop is not None and not can_stop():
            stop = False
            self.unsafe_stops += 1
        self.since_s, self.stops = time_s, stop
        if stop:
            self.holds += 1
        else:
            self.glances += 1
        return Look(point, stop)

    def end(self) -> None:
        """The look under way is over."""
        self.since_s = None

    def metrics(self) -> dict:
        """The counts for metrics.json (empty when the rule is off)."""
        if not self.enabled:
            return {}
        return {
            "fresh_path_holds": self.holds, "fresh_path_glances": self.glances, "fresh_path_unrefreshed": self.unrefreshed,
            "fresh_path_unsafe_stops": self.unsafe_stops,
        }  # fmt: skip


@dataclass(frozen=True)
class Gate:
    """What the look under way allows at a frame: ``hold`` (stopped to look: no yaw plan, no replan), ``released``
    (a hold just ended: replan now), ``glancing`` (the camera turns to a point while the drone flies on: no yaw plan)."""

    hold: bool = False
    released: bool = False
    glancing: bool = False


class LookBeforeMoving:
    """Look before moving for one denied agent: the :class:`FreshPathWatch` and what the agent does with its looks.

    Args:
        config: the scenario's ``denied:`` settings.
        period_s: t_y, how often the corridor is checked [s].
        voxel_m: the map's voxel edge [m]; a point within two of the last look's is the same point.
    """

    def __init__(self, config: DeniedAgentConfig, period_s: float, voxel_m: float) -> None:
        self.watch = FreshPathWatch(config, period_s, 2.0 * voxel_m)
        self.period_s = float(period_s)

    @property
    def enabled(self) -> bool:
        """Whether the rule is on (``fresh_path_age_s`` finite)."""
        return self.watch.enabled

    def gate(self, agent: DeniedAgent, t: float) -> Gate:
        """End the look under way at ``t`` [s] once the commanded yaw has been on its point for two t_y
        (at most pi / rate + 2 t_y), and say what it allows this frame."""
        watch = self.watch
        if not watch.looking:
            return Gate()
        if agent.heading.looked_since(t) >= 2.0 * self.period_s - 1e-9:
            watch.end()
            agent.heading.restart(agent.heading.reference(t, None)[0], t)
            return Gate(released=watch.stops)
        return Gate(hold=True) if watch.stops else Gate(glancing=True)

    def look_ahead(self, agent: DeniedAgent, t: float, glancing: bool) -> bool:
        """Check the corridor ahead at ``t`` [s] (every t_y while a plan is flown) and begin the look it finds: a hold
        brakes first, then the heading turns to the point at the rate limit. Whether a hold began."""
        if not (self.enabled and agent.trajectory is not None and not agent.braking and self.watch.due(t)):
            return False
        d_stop = float(np.linalg.norm(agent.state_at(t)[1])) ** 2 / agent.config.limits.a_max_mps2
        look = self.watch.check(agent.map.snapshot(), agent.trajectory, t, d_stop, glancing, lambda: agent.can_stop(t))
        if look is None:
            return False
        if look.stop:
            agent.brake(t)
        pos = agent.state_at(t)[0]
        agent.heading.look_toward(t, float(np.arctan2(look.point_world[1] - pos[1], look.point_world[0] - pos[0])))
        return look.stop

    def metrics(self) -> dict:
        """The watch's counts for metrics.json (empty when the rule is off)."""
        return self.watch.metrics()
