"""Look before moving: the first point of the corridor ahead that the camera saw free, but not recently.

A drone with one 85 deg camera cannot watch every neighbour; what it can do is
never move into space it has not looked at lately. This module finds, along
the drone's own trajectory, the first point of a horizontal corridor whose
voxel the map holds *free* but last touched by a camera ray more than
``max_age_s`` before the map's newest frame (the snapshot's ``seen_s``): space
where a neighbour that the drone is not tracking may have arrived since. The
denied agent (``denied.fresh_path_age_s``, :mod:`mpcde.onboard.denied`) stops
short of such a point and turns its camera to it before it flies on.

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

Why it exists: every drone-drone contact left in the forest sweep at 0.5 and
1 m/s is between two drones that did not have each other in view in the 2 s
before contact, usually a follower closing on a neighbour ahead of it or
beside its path while its camera looked elsewhere (observing, exploring, or
the tracking mode's swing): docs/results/safety.md.
"""

from __future__ import annotations

import math

import numpy as np

from perception.types import OccupancySnapshot
from planners.minco import MincoTrajectory

__all__ = ["first_stale_point"]


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
