"""Static obstacles: cylinder "trees" and boxes, a seeded generator and exact distances.

Obstacles stand on the ground (z = 0). A tree is a vertical cylinder; a box is
yawed about z. Density is counted in obstacles per 100 m^2 of arena.
"""

from __future__ import annotations

from typing import Sequence

import numpy as np

from sim.types import ObstacleSpec

__all__ = ["ObstacleField", "ObstacleSpec", "distance_to_obstacles", "generate_obstacles"]


TREE_COLOURS = ((0.45, 0.32, 0.2), (0.35, 0.25, 0.15), (0.3, 0.45, 0.25), (0.5, 0.42, 0.3))
BOX_COLOURS = ((0.6, 0.6, 0.62), (0.55, 0.45, 0.4), (0.4, 0.45, 0.55), (0.7, 0.65, 0.5))


def generate_obstacles(
    rng: np.random.Generator,
    arena_size_m: tuple[float, float],
    density_per_100m2: float,
    keep_clear_xy: np.ndarray,
    clear_radius_m: float,
    box_fraction: float = 0.25,
    tree_radius_m: tuple[float, float] = (0.15, 0.3),
    tree_height_m: tuple[float, float] = (3.0, 5.0),
    box_half_size_m: tuple[float, float] = (0.25, 0.6),
    box_height_m: tuple[float, float] = (1.0, 3.0),
    min_gap_m: float = 0.8,
) -> list[ObstacleSpec]:
    """Place obstacles uniformly in the arena by rejection sampling.

    Args:
        rng: seeded generator.
        arena_size_m: (x, y) extent [m], centred on the origin.
        density_per_100m2: obstacles per 100 m^2.
        keep_clear_xy: (k, 2) points (starts, goals) no obstacle may come within
            ``clear_radius_m`` of (footprint to point).
        clear_radius_m: radius of the clear zones [m].
        box_fraction: share of boxes among obstacles.
        min_gap_m: free gap between two obstacles' footprints [m] so that a
            drone can pass between any two.

    Returns:
        The obstacles; fewer than asked only if the arena is too full (the
        rejection sampler gives up after 200 tries per obstacle).
    """
    ax, ay = arena_size_m
    n = int(round(density_per_100m2 * ax * ay / 100.0))
    keep = np.asarray(keep_clear_xy, float).reshape(-1, 2)
    placed: list[ObstacleSpec] = []
    for _ in range(n):
        for _try in range(200):
            xy = rng.uniform([-ax / 2, -ay / 2], [ax / 2, ay / 2])
            if rng.uniform() < box_fraction:
                c = BOX_COLOURS[rng.integers(len(BOX_COLOURS))]
                ob = ObstacleSpec(
                    kind="box",
                    center_xy=(float(xy[0]), float(xy[1])),
                    height_m=float(rng.uniform(*box_height_m)),
                    half_extents_xy=tuple(float(h) for h in rng.uniform(*box_half_size_m, size=2)),
                    yaw=float(rng.uniform(-np.pi, np.pi)),
                    rgba=(*c, 1.0),
                )
            else:
                c = TREE_COLOURS[rng.integers(len(TREE_COLOURS))]
                ob = ObstacleSpec(
                    kind="tree",
                    center_xy=(float(xy[0]), float(xy[1])),
                    height_m=float(rng.uniform(*tree_height_m)),
                    radius_m=float(rng.uniform(*tree_radius_m)),
                    rgba=(*c, 1.0),
                )
            r = ob.footprint_radius_m
            if keep.size and np.min(np.linalg.norm(keep - xy, axis=1)) < clear_radius_m + r:
                continue
            if any(np.hypot(*(np.subtract(o.center_xy, xy))) < o.footprint_radius_m + r + min_gap_m for o in placed):
                continue
            placed.append(ob)
            break
    return placed


class ObstacleField:
    """Exact distances to a fixed set of obstacles, with their geometry cached as arrays."""

    def __init__(self, obstacles: Sequence[ObstacleSpec]) -> None:
        trees = [o for o in obstacles if o.kind == "tree"]
        boxes = [o for o in obstacles if o.kind == "box"]
        self.tree_c = np.array([o.center_xy for o in trees]).reshape(-1, 2)
        self.tree_r = np.array([o.radius_m for o in trees])
        self.tree_h = np.array([o.height_m for o in trees])
        self.box_c = np.array([o.center_xy for o in boxes]).reshape(-1, 2)
        self.box_he = np.array([o.half_extents_xy for o in boxes]).reshape(-1, 2)
        self.box_h = np.array([o.height_m for o in boxes])
        self.box_cos = np.cos(np.array([o.yaw for o in boxes], float))
        self.box_sin = np.sin(np.array([o.yaw for o in boxes], float))
        self.tree_c, self.box_c, self.box_he = (np.ascontiguousarray(a, float) for a in (self.tree_c, self.box_c, self.box_he))
        self.tree_r, self.tree_h, self.box_h = (np.asarray(a, float) for a in (self.tree_r, self.tree_h, self.box_h))

    def distance(self, points_world: np.ndarray) -> np.ndarray:
        """Distance [m] from (n, 3) points to the nearest surface, (n,); see :func:`distance_to_obstacles`.

        Compiled (:func:`sim.obstacle_distance_kernel.obstacle_distances`, imported on first use so that
        reading a scenario loads no numba); :meth:`distance_numpy` is the same in numpy.
        """
        from sim.obstacle_distance_kernel import obstacle_distances

        pts = np.ascontiguousarray(np.atleast_2d(np.asarray(points_world, float)))
        return obstacle_distances(pts, self.tree_c, self.tree_r, self.tree_h, self.box_c, self.box_he, self.box_h, self.box_cos, self.box_sin)

    def distance_numpy(self, points_world: np.ndarray) -> np.ndarray:
        """:meth:`distance` in numpy (the tests' oracle)."""
        pts = np.atleast_2d(np.asarray(points_world, float))
        best = np.full(pts.shape[0], np.inf)
        z = pts[:, 2:3]
        if self.tree_r.size:
            radial = np.linalg.norm(pts[:, None, :2] - self.tree_c[None], axis=-1) - self.tree_r  # (n, T)
            dz = np.maximum(z - self.tree_h, 0.0) + np.maximum(-z, 0.0)
            d = np.where((radial < 0) & (dz == 0), radial, np.hypot(np.maximum(radial, 0.0), dz))
            best = np.minimum(best, d.min(axis=1))
        if self.box_h.size:
            dx = pts[:, None, 0] - self.box_c[None, :, 0]
            dy = pts[:, None, 1] - self.box_c[None, :, 1]
            qx = np.abs(self.box_cos * dx + self.box_sin * dy) - self.box_he[:, 0]  # box-local |x| - half extent, (n, B)
            qy = np.abs(-self.box_sin * dx + self.box_cos * dy) - self.box_he[:, 1]
            outside_xy = np.hypot(np.maximum(qx, 0.0), np.maximum(qy, 0.0))
            inside = (qx < 0) & (qy < 0)
            dz = np.maximum(z - self.box_h, 0.0) + np.maximum(-z, 0.0)
            d = np.where(inside & (dz == 0), np.maximum(qx, qy), np.hypot(outside_xy, dz))
            best = np.minimum(best, d.min(axis=1))
        return best


def distance_to_obstacles(points_world: np.ndarray, obstacles: Sequence[ObstacleSpec]) -> np.ndarray:
    """Exact Euclidean distance [m] from points to the nearest obstacle surface.

    Vectorised over points and obstacles. For repeated queries against the
    same obstacles build an :class:`ObstacleField` once.

    Args:
        points_world: (n, 3) points [m].
        obstacles: the obstacles.

    Returns:
        (n,) distances [m]; negative inside an obstacle (depth of penetration
        in the horizontal plane); ``inf`` when there are no obstacles.
    """
    return ObstacleField(obstacles).distance_numpy(points_world)  # a one-off (layout checks): numpy, no compiled import
