"""Observed area S_obs [m^2]: the horizontal area a drone's camera has seen during a flight (MP-CDE Fig. 5, Table III).

A metric, computed from the truth (the true camera poses and the true
obstacle geometry), never onboard. MP-CDE measures active perception by how
much of the environment the camera covered (Sec. V-B 1: "observed area
S_obs"); the paper does not define the computation, so this package does:

* **Footprint of one frame.** The camera's horizontal field of view in the
  horizontal plane through the camera: ``N`` rays from the camera position,
  spanning the optical axis's heading +- ``hfov / 2``, one every
  :data:`RAY_STEP_DEG` (341 rays at 85 deg). Each ray stops at the depth
  range ``camera.depth_max_m`` (10 m) or at the first obstacle it meets
  (tree circles and box rectangles of obstacles taller than the camera),
  whichever is nearer: a camera does not see through trees.
* **Raster.** Every cell of a :data:`CELL_M` (0.1 m) grid over the arena
  (plus :data:`MARGIN_M`) that a ray passes through is marked seen; the ray
  is sampled every half cell. Neighbouring rays are 4.4 cm apart at 10 m,
  under half a cell, so the rays leave no unmarked cell between them.
* **S_obs** of a drone: the marked area of the union of its frames'
  footprints over the flight, at every camera tick while it flies (a failed
  drone stops observing). The swarm's: the area of the union over drones.
  A cell a ray touches counts whole, so the raster adds up to one cell's
  width along the region's perimeter (about 2-3 % of one 85 deg, 10 m fan;
  the same for every stack compared).

The camera's pitch and roll are ignored (the footprint is the level fan at
the camera's height), as is the vertical field of view: the paper's Fig. 5
shades the same kind of top-view region.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Sequence

import numpy as np
from numba import njit

from sim.types import ObstacleSpec

__all__ = ["CELL_M", "MARGIN_M", "RAY_STEP_DEG", "ObservedArea", "ObservedRaster"]

CELL_M = 0.1
"""Raster cell edge [m]."""
RAY_STEP_DEG = 0.25
"""Angle between neighbouring rays of a footprint [deg]."""
MARGIN_M = 2.0
"""Raster margin around the arena [m] (rays that leave the raster stop at its edge)."""


@dataclass(frozen=True)
class ObservedRaster:
    """The seen cells of a flight, for plots.

    Attributes:
        seen: (n_drones, nx, ny) bool; cell (i, j) spans ``origin_xy + CELL_M * [i, i+1) x [j, j+1)``.
        origin_xy: (2,) world position [m] of the raster's minimum corner.
        cell_m: cell edge [m].
    """

    seen: np.ndarray
    origin_xy: np.ndarray
    cell_m: float

    def extent(self) -> tuple[float, float, float, float]:
        """(x0, x1, y0, y1) [m] of the raster, for ``imshow``."""
        nx, ny = self.seen.shape[1:]
        x0, y0 = self.origin_xy
        return (x0, x0 + nx * self.cell_m, y0, y0 + ny * self.cell_m)


class ObservedArea:
    """Accumulates each drone's footprints over a flight (module docstring).

    Args:
        obstacles: the true obstacles.
        arena_size_m: (2,) arena edge lengths [m], centred on the origin.
        n_drones: drones of the flight.
        hfov_deg: the camera's horizontal field of view [deg].
        depth_max_m: the camera's depth range [m].
    """

    def __init__(self, obstacles: Sequence[ObstacleSpec], arena_size_m: Sequence[float], n_drones: int, hfov_deg: float, depth_max_m: float) -> None:
        half = np.asarray(arena_size_m, float)[:2] / 2.0 + MARGIN_M
        self.origin_xy = -half
        shape = tuple(int(math.ceil(2.0 * h / CELL_M)) for h in half)
        self.seen = np.zeros((n_drones, *shape), np.bool_)
        trees = [o for o in obstacles if o.kind == "tree"]
        boxes = [o for o in obstacles if o.kind == "box"]
        self._tree = np.array([[*o.center_xy, o.radius_m, o.height_m] for o in trees], float).reshape(-1, 4)
        self._box = np.array([[*o.center_xy, *o.half_extents_xy, math.cos(o.yaw), math.sin(o.yaw), o.height_m] for o in boxes], float).reshape(-1, 7)
        n_rays = int(round(hfov_deg / RAY_STEP_DEG)) + 1
        self._offsets = np.radians(np.linspace(-hfov_deg / 2.0, hfov_deg / 2.0, n_rays))
        self.depth_max_m = float(depth_max_m)

    def add_frame(self, drone: int, transform_camera_to_world: np.ndarray) -> None:
        """Mark the footprint of one frame of ``drone`` taken at the true camera pose (4, 4)."""
        T = np.asarray(transform_camera_to_world, float)
        axis = T[:3, 2]  # the optical axis in world
        heading = math.atan2(axis[1], axis[0])
        _mark_fan(self.seen[drone], self.origin_xy, CELL_M, T[0, 3], T[1, 3], T[2, 3], heading + self._offsets, self.depth_max_m, self._tree, self._box)

    def areas_m2(self) -> tuple[list[float], float]:
        """S_obs per drone [m^2] and the swarm's (the union's)."""
        cell_area = CELL_M * CELL_M
        per = [float(np.count_nonzero(s)) * cell_area for s in self.seen]
        return per, float(np.count_nonzero(np.any(self.seen, axis=0))) * cell_area

    def raster(self) -> ObservedRaster:
        """The seen cells (a copy), for the top-view plot."""
        return ObservedRaster(self.seen.copy(), self.origin_xy.copy(), CELL_M)


@njit(cache=True)
def _ray_hit(px, py, z, dx, dy, t_max, tree, box):  # pragma: no cover - compiled
    """Distance [m] along the unit direction (dx, dy) from (px, py) to the first obstacle taller than z, or t_max."""
    best = t_max
    for k in range(tree.shape[0]):
        if tree[k, 3] <= z:
            continue
        ox, oy, r = px - tree[k, 0], py - tree[k, 1], tree[k, 2]
        b = ox * dx + oy * dy
        c = ox * ox + oy * oy - r * r
        if c <= 0.0:  # the camera inside a trunk sees nothing
            return 0.0
        disc = b * b - c
        if disc >= 0.0:
            t = -b - math.sqrt(disc)
            if 0.0 <= t < best:
                best = t
    for k in range(box.shape[0]):
        if box[k, 6] <= z:
            continue
        cs, sn = box[k, 4], box[k, 5]
        rx, ry = px - box[k, 0], py - box[k, 1]
        ox, oy = cs * rx + sn * ry, -sn * rx + cs * ry  # into the box's frame
        ux, uy = cs * dx + sn * dy, -sn * dx + cs * dy
        t0, t1 = -np.inf, np.inf
        hit = True
        for o, u, h in ((ox, ux, box[k, 2]), (oy, uy, box[k, 3])):
            if abs(u) < 1e-12:
                if abs(o) > h:
                    hit = False
                continue
            a, b2 = (-h - o) / u, (h - o) / u
            if a > b2:
                a, b2 = b2, a
            t0, t1 = max(t0, a), min(t1, b2)
        if hit and t0 <= t1 and t1 >= 0.0:
            if t0 <= 0.0:
                return 0.0
            if t0 < best:
                best = t0
    return best


@njit(cache=True)
def _mark_fan(seen, origin, cell, px, py, z, angles, t_max, tree, box):  # pragma: no cover - compiled
    """Mark the cells of ``seen`` (nx, ny) that the rays at world headings ``angles`` pass through before stopping."""
    nx, ny = seen.shape
    step = 0.5 * cell
    for a in angles:
        dx, dy = math.cos(a), math.sin(a)
        t_end = _ray_hit(px, py, z, dx, dy, t_max, tree, box)
        n = int(t_end / step) + 1
        for s in range(n + 1):
            t = min(s * step, t_end)
            i = int(math.floor((px + t * dx - origin[0]) / cell))
            j = int(math.floor((py + t * dy - origin[1]) / cell))
            if i < 0 or j < 0 or i >= nx or j >= ny:
                break
            seen[i, j] = True
