"""Front-end path search on a drone's occupancy window: 26-connected A* and shortcutting.

MP-CDE Sec. IV-C (after GCOPTER) initialises the MINCO trajectory from a
front-end path on the occupancy grid; this module produces it. The search runs
on an :class:`perception.types.OccupancySnapshot` (the compiled A* is
:mod:`planners.voxel_astar`):

* a voxel is *traversable* when it is not occupied and its ESDF value is at
  least the clearance: ``state != 1 and d(x) >= clearance_m``;
* a step of length ``l`` (``voxel_m`` times 1, sqrt 2 or sqrt 3) costs ``l``
  into a known free voxel and ``(1 + unknown_penalty) l`` into an unknown one,
  so the path prefers space the camera has verified but may cross unknown
  space (the ESDF counts unknown as free, see ``OccupancySnapshot``);
* heuristic: the exact 26-connected distance on an empty grid
  ``h = voxel_m (d1 + (sqrt 2 - 1) d2 + (sqrt 3 - sqrt 2) d3)`` with
  ``d1 >= d2 >= d3`` the sorted absolute index differences, admissible for
  ``heuristic_weight = 1``; it is scaled by ``1 + 1e-3`` to break ties
  towards the goal (at most 0.1 % above the optimal cost);
* escape rule: when the drone starts inside the clearance band (pose noise, a
  neighbour that just became an obstacle) the search may enter a
  non-traversable voxel only from a non-traversable voxel and only if its
  distance is strictly larger, so it can climb out of the band but never
  crawl along it through a gap narrower than the clearance; the altitude band
  and a ban on unknown space hold even then.

Goals outside the window are replaced by the point where the straight segment
start -> goal leaves the window; a goal voxel that is not traversable is
replaced by the nearest traversable voxel within ``goal_search_radius_m``.
When the goal was clipped and that fails too (an obstacle straddles the
window's edge where the segment leaves it: the search ball is cut in half by
the edge and a trunk fills the rest), the goal becomes the traversable voxel of
the whole window nearest the *true* goal, the best progress the window allows
(``goal_fallback`` in the result). Likewise when the clipped goal is traversable
but cut off: it lies in a pocket the start cannot reach inside the window (the
unseen shadow behind a trunk at the window's edge, fenced by the trunk and its
clearance band; in a thin altitude layer nothing leads round it). A* then
exhausts the start's component, and the goal becomes the reachable voxel
nearest the true goal, if it is at least a voxel nearer than the start.
Without it a drone that has no plan to fly hovers for good: the window moves
with the drone, the drone does not move, and the same clipped goal is refused
at every frame (``docs/results/safety.md#the-long-2-ms-flight-a-goal-cut-off-in-a-thin-layer``,
``docs/results/history/mp-cde.md#the-front-ends-fallback-goal``).
The caller decides when to allow it (``goal_fallback=False`` refuses as before): the denied agent allows it only
while it has no plan, is stopping or has come to rest at its plan's end, because a drone still flying a plan moves
its window and the clipped goal moves off the obstacle within a few frames,
while the fallback's point may lie well to the side of the course, where a
neighbour may fly abreast. A goal inside the window that is blocked stays ``"goal_blocked"``:
the mission's goal itself is unreachable and no other point stands for it.

The path is then shortcut greedily (from each kept point, the farthest later
path point reachable by a straight segment that stays traversable and costs no
more, with the unknown penalty, than the A* path between them) and long
segments are split, giving a few waypoints suitable as MINCO inner points.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numba import njit

from perception.types import OccupancySnapshot
from planners.voxel_astar import astar
from sim.checks import ConfigError

__all__ = ["PathSearchConfig", "PathSearchResult", "search_path"]


@dataclass(frozen=True)
class PathSearchConfig:
    """Settings of the front-end search.

    Attributes:
        unknown_penalty: extra relative cost [-] of a step into an unknown voxel
            (cost ``(1 + unknown_penalty) * length``); 0 treats unknown as free.
            Default 1.0: a detour through seen free space up to twice as long
            is preferred to crossing unknown space.
        allow_unknown: if False, unknown voxels are not traversable at all.
        heuristic_weight: weight [-] on the heuristic (1 = optimal A*, > 1 =
            weighted A*, faster and at most that factor longer).
        max_expansions: node expansions [-] after which the search gives up.
        goal_search_radius_m: radius [m] around a blocked goal in which the
            nearest traversable voxel replaces it.
        max_segment_m: longest segment [m] between consecutive output
            waypoints; longer shortcut segments are split evenly.
        min_altitude_m: voxels whose centre lies below this world z [m] are
            not traversable (default 0: the ground plane, DESIGN.md section 2;
            keeps paths from diving through unseen ground).
        max_altitude_m: voxels whose centre lies above this world z [m] are
            not traversable (default: no ceiling).
    """

    unknown_penalty: float = 1.0
    allow_unknown: bool = True
    heuristic_weight: float = 1.0
    max_expansions: int = 500_000
    goal_search_radius_m: float = 1.0
    max_segment_m: float = 2.0
    min_altitude_m: float = 0.0
    max_altitude_m: float = float("inf")

    def __post_init__(self) -> None:
        if not self.unknown_penalty >= 0.0:
            raise ConfigError("unknown_penalty", self.unknown_penalty, "allowed >= 0")
        if not self.heuristic_weight >= 1.0:
            raise ConfigError("heuristic_weight", self.heuristic_weight, "allowed >= 1")
        if not self.max_expansions >= 1:
            raise ConfigError("max_expansions", self.max_expansions, "allowed >= 1")
        if not self.goal_search_radius_m >= 0.0:
            raise ConfigError("goal_search_radius_m", self.goal_search_radius_m, "allowed >= 0")
        if not self.max_segment_m > 0.0:
            raise ConfigError("max_segment_m", self.max_segment_m, "allowed > 0")
        if not self.min_altitude_m < self.max_altitude_m:
            raise ConfigError("max_altitude_m", self.max_altitude_m, "allowed > min_altitude_m")


@dataclass(frozen=True)
class PathSearchResult:
    """Outcome of :func:`search_path`.

    Attributes:
        status: ``"found"``, ``"no_path"`` (goal unreachable, e.g. enclosed),
            ``"goal_blocked"`` (no traversable voxel near the goal),
            ``"expansion_limit"``.
        waypoints_world: (m, 3) shortcut waypoints [m], start and goal
            included; ``None`` unless found.
        path_world: (n, 3) the raw A* path [m] (start, voxel centres, goal);
            ``None`` unless found.
        expanded_nodes: voxels expanded by A*.
        cost_m: path cost [m] including unknown penalties (``inf`` unless found).
        goal_used_world: (3,) goal [m] actually searched for (clipped to the
            window and/or moved off an obstacle).
        goal_clipped: True when the goal lay outside the window.
        goal_fallback: True when the clipped goal was blocked within
            ``goal_search_radius_m``, or cut off from the start, and the
            window's traversable (then: reachable) voxel nearest the true goal
            was searched for instead (module docstring).
    """

    status: str
    waypoints_world: np.ndarray | None
    path_world: np.ndarray | None
    expanded_nodes: int
    cost_m: float
    goal_used_world: np.ndarray
    goal_clipped: bool
    goal_fallback: bool = False

    @property
    def found(self) -> bool:
        """True when a path was found."""
        return self.status == "found"


def search_path(
    snapshot: OccupancySnapshot,
    start_world: np.ndarray,
    goal_world: np.ndarray,
    clearance_m: float,
    config: PathSearchConfig = PathSearchConfig(),
    goal_fallback: bool = True,
) -> PathSearchResult:
    """A* from ``start_world`` (3,) to ``goal_world`` (3,) [m] keeping ``clearance_m`` [m] from obstacles.

    ``start_world`` must lie inside the window (raises ValueError otherwise). ``goal_fallback``: a clipped goal
    blocked within ``goal_search_radius_m`` is replaced by the window's traversable voxel nearest the true goal,
    and one cut off from the start by the reachable voxel nearest it (module docstring); False: refused as
    ``"goal_blocked"`` and ``"no_path"``.
    """
    start = np.asarray(start_world, float).reshape(3)
    goal = np.asarray(goal_world, float).reshape(3)
    if not clearance_m >= 0.0:
        raise ValueError(f"clearance_m={clearance_m!r}: allowed >= 0")
    if not snapshot.contains(start[None])[0]:
        raise ValueError(f"start_world={start.tolist()!r}: allowed inside the map window")
    shape = np.asarray(snapshot.shape, np.int64)
    v = snapshot.voxel_m
    # fresh writable arrays, so the compiled search has one signature whether or not the snapshot is read-only
    state = np.asarray(snapshot.state).ravel()
    unknown = state == OccupancySnapshot.UNKNOWN
    dist = np.array(snapshot.distance_m, dtype=np.float32).ravel()
    # hard limits hold even while escaping the clearance band: altitude band, unknown if forbidden
    z_world = snapshot.origin_world[2] + v * (np.arange(snapshot.shape[2]) + 0.5)
    in_band = (z_world >= config.min_altitude_m) & (z_world <= config.max_altitude_m)
    hard_ok = np.broadcast_to(in_band, snapshot.shape).ravel()
    if not config.allow_unknown:
        hard_ok = hard_ok & ~unknown
    ok = hard_ok & (state != OccupancySnapshot.OCCUPIED) & (dist >= clearance_m)

    goal_clipped = not bool(snapshot.contains(goal[None])[0])
    goal_used = _clip_to_window(snapshot, start, goal) if goal_clipped else goal
    start_idx = snapshot.world_to_index(start[None])[0]
    goal_idx = snapshot.world_to_index(goal_used[None])[0]
    fell_back = False
    if not ok[_lin(goal_idx, shape)]:
        goal_idx = _nearest_traversable(ok.reshape(snapshot.shape), snapshot, goal_used, config.goal_search_radius_m)
        if goal_idx is None and goal_clipped and goal_fallback:
            goal_idx = _nearest_traversable(ok.reshape(snapshot.shape), snapshot, goal, np.inf)
            fell_back = goal_idx is not None
        if goal_idx is None:
            return PathSearchResult("goal_blocked", None, None, 0, np.inf, goal_used, goal_clipped)
        goal_used = snapshot.index_to_world(goal_idx[None])[0]

    hard_ok = np.ascontiguousarray(hard_ok)
    args = (unknown, dist, ok, hard_ok, shape, start_idx.astype(np.int64))
    weights = (v, config.unknown_penalty, config.heuristic_weight, config.max_expansions)
    cells, costs, n_expanded, code, closed = astar(*args, goal_idx.astype(np.int64), *weights)
    if code == 1 and goal_clipped and goal_fallback:
        # A* exhausted the start's component, so ``closed`` is everything reachable: the clipped goal lies in a
        # pocket cut off inside the window (module docstring); search for the reachable voxel nearest the true goal
        reachable = closed.reshape(snapshot.shape).astype(bool) & ok.reshape(snapshot.shape)
        best = _nearest_traversable(reachable, snapshot, goal, np.inf)
        # only progress counts: a voxel no nearer the true goal than the start by a voxel leaves it "no_path"
        start_d = float(np.linalg.norm(start - goal)) - v
        if best is not None and float(np.linalg.norm(snapshot.index_to_world(best[None])[0] - goal)) <= start_d:
            goal_idx, goal_used, fell_back = best, snapshot.index_to_world(best[None])[0], True
            cells, costs, more, code, _ = astar(*args, goal_idx.astype(np.int64), *weights)
            n_expanded += more
    if code != 0:
        status = "no_path" if code == 1 else "expansion_limit"
        return PathSearchResult(status, None, None, int(n_expanded), np.inf, goal_used, goal_clipped, fell_back)

    path_world = snapshot.index_to_world(cells)
    path_world[0] = start
    path_world[-1] = goal_used
    if len(path_world) == 1:  # start and goal in the same voxel
        path_world = np.vstack([start, goal_used])
        cells = np.vstack([cells, cells])
        costs = np.array([0.0, float(np.linalg.norm(goal_used - start))])
    keep = _shortcut(cells, costs, ok.reshape(snapshot.shape), unknown.reshape(snapshot.shape), v, config.unknown_penalty)
    waypoints = _split_long(path_world[keep], config.max_segment_m)
    return PathSearchResult("found", waypoints, path_world, int(n_expanded), float(costs[-1]), goal_used, goal_clipped, fell_back)


def _lin(idx: np.ndarray, shape: np.ndarray) -> int:
    """Row-major linear index of a voxel index (3,)."""
    return int((idx[0] * shape[1] + idx[1]) * shape[2] + idx[2])


def _clip_to_window(snapshot: OccupancySnapshot, start: np.ndarray, goal: np.ndarray) -> np.ndarray:
    """Point (3,) where the segment start -> goal leaves the window shrunk by half a voxel."""
    lo = snapshot.origin_world + 0.5 * snapshot.voxel_m
    hi = snapshot.upper_world - 0.5 * snapshot.voxel_m
    d = goal - start
    t_exit = 1.0
    for a in range(3):  # slab method: largest t in [0, 1] with start + t d inside [lo, hi]
        if d[a] > 0:
            t_exit = min(t_exit, (hi[a] - start[a]) / d[a])
        elif d[a] < 0:
            t_exit = min(t_exit, (lo[a] - start[a]) / d[a])
    return start + max(t_exit, 0.0) * d


def _nearest_traversable(
    ok: np.ndarray, snapshot: OccupancySnapshot, point: np.ndarray, radius_m: float
) -> np.ndarray | None:
    """Index (3,) of the traversable voxel nearest ``point`` (3,) within ``radius_m``, or None.

    ``point`` may lie outside the window when ``radius_m`` is infinite (the whole window is searched).
    """
    if np.isinf(radius_m):
        lo, hi = np.zeros(3, np.int64), np.asarray(ok.shape)
    else:
        r = int(np.ceil(radius_m / snapshot.voxel_m))
        c = snapshot.world_to_index(point[None])[0]
        lo = np.maximum(c - r, 0)
        hi = np.minimum(c + r + 1, np.asarray(ok.shape))
    if np.any(hi <= lo):
        return None
    sub = np.argwhere(ok[lo[0] : hi[0], lo[1] : hi[1], lo[2] : hi[2]]) + lo
    if sub.size == 0:
        return None
    d2 = np.sum((snapshot.index_to_world(sub) - point) ** 2, axis=1)
    best = int(np.argmin(d2))
    return sub[best] if d2[best] <= radius_m**2 + 1e-12 else None


def _split_long(points: np.ndarray, max_segment_m: float) -> np.ndarray:
    """Insert evenly spaced points so no segment of ``points`` (m, 3) exceeds ``max_segment_m``."""
    out = [points[0]]
    for a, b in zip(points[:-1], points[1:]):
        n = max(1, int(np.ceil(np.linalg.norm(b - a) / max_segment_m - 1e-9)))
        for k in range(1, n + 1):
            out.append(a + (b - a) * (k / n))
    return np.asarray(out)


@njit(cache=True)
def _segment_cost(a, b, ok, unknown, unknown_penalty):
    """Penalised cost [voxels] of the straight segment a -> b (voxel-index coordinates), inf if it leaves ``ok``."""
    length = np.sqrt(np.sum((b - a) ** 2))
    n = max(1, int(np.ceil(length * 4.0)))  # samples every quarter voxel
    step = length / n
    cost = 0.0
    for k in range(1, n + 1):
        p = a + (b - a) * (k / n)
        i = int(np.floor(p[0] + 0.5))
        j = int(np.floor(p[1] + 0.5))
        m = int(np.floor(p[2] + 0.5))
        if not ok[i, j, m]:
            return np.inf
        cost += step * (1.0 + unknown_penalty) if unknown[i, j, m] else step
    return cost


@njit(cache=True)
def _shortcut_numba(cells_f, costs_vox, ok, unknown, unknown_penalty):
    """Indices of the path points kept by greedy forward shortcutting."""
    n = cells_f.shape[0]
    keep = np.empty(n, np.int64)
    keep[0] = 0
    count = 1
    i = 0
    while i < n - 1:
        j = i + 1
        while j + 1 < n:
            c = _segment_cost(cells_f[i], cells_f[j + 1], ok, unknown, unknown_penalty)
            if c > costs_vox[j + 1] - costs_vox[i] + 1e-6:
                break
            j += 1
        keep[count] = j
        count += 1
        i = j
    return keep[:count]


def _shortcut(
    cells: np.ndarray, costs_m: np.ndarray, ok: np.ndarray, unknown: np.ndarray, voxel_m: float, unknown_penalty: float
) -> np.ndarray:
    """Indices into the path of the points kept after shortcutting (first and last always kept)."""
    return _shortcut_numba(
        cells.astype(np.float64), costs_m / voxel_m, ok, unknown, float(unknown_penalty)
    )
