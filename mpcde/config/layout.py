"""Where the drones start and go, where the obstacles stand, and the checks that they fit together.

:func:`build_layout` turns ``drones`` into start and goal positions,
:func:`resolve_obstacles` adds the seeded random obstacles to the hand-placed
ones, and :func:`check_layout` refuses starts or goals inside an obstacle,
below the robot radius or closer to each other than the safety distance.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from mpcde.errors import ConfigError
from sim.obstacles import distance_to_obstacles, generate_obstacles
from sim.types import ObstacleSpec

if TYPE_CHECKING:
    from mpcde.config.scenario import DronesConfig, ScenarioConfig

__all__ = ["build_layout", "check_layout", "resolve_obstacles"]


def build_layout(drones: DronesConfig) -> tuple[np.ndarray, np.ndarray]:
    """Start and goal positions, (N, 3) each [m]."""
    if drones.layout == "explicit":
        return np.asarray(drones.starts, float), np.asarray(drones.goals, float)
    n, r, z = drones.count, drones.radius_m, drones.altitude_m
    if drones.layout == "antipodal":
        a = 2 * np.pi * np.arange(n) / n
        starts = np.stack([r * np.cos(a), r * np.sin(a), np.full(n, z)], axis=1)
        return starts, starts * np.array([-1.0, -1.0, 1.0])
    y = (np.arange(n) - (n - 1) / 2) * drones.spacing_m
    starts = np.stack([np.full(n, -r), y, np.full(n, z)], axis=1)
    return starts, starts * np.array([-1.0, -1.0, 1.0])


def resolve_obstacles(cfg: ScenarioConfig, starts: np.ndarray, goals: np.ndarray) -> tuple[ObstacleSpec, ...]:
    """Hand-placed plus seeded random obstacles, clear of starts and goals."""
    explicit = [o.to_spec() for o in cfg.world.obstacles]
    rng = np.random.default_rng([cfg.seed, 0x0B57])
    keep = np.concatenate([starts[:, :2], goals[:, :2]])
    placed = generate_obstacles(
        rng, cfg.world.arena_size_m, cfg.world.obstacle_density_per_100m2, keep, cfg.world.clear_radius_m, box_fraction=cfg.world.box_fraction
    )
    # drop random obstacles that overlap hand-placed ones
    placed = [p for p in placed if all(np.hypot(*np.subtract(p.center_xy, e.center_xy)) > p.footprint_radius_m + e.footprint_radius_m + 0.5 for e in explicit)]
    return tuple(explicit + placed)


def check_layout(cfg: ScenarioConfig, starts: np.ndarray, goals: np.ndarray, obstacles: tuple[ObstacleSpec, ...]) -> None:
    """Reject starts or goals inside obstacles and goals or starts closer than the safety distance."""
    r = cfg.physics.quadrotor.robot_radius_m
    for name, pts in (("drones.starts", starts), ("drones.goals", goals)):
        if obstacles:
            d = distance_to_obstacles(pts, obstacles)
            bad = np.flatnonzero(d < r)
            if bad.size:
                i = int(bad[0])
                raise ConfigError(f"{name}[{i}]", [round(float(v), 3) for v in pts[i]], f"inside or within {r} m of an obstacle")
        if np.any(pts[:, 2] < r):
            i = int(np.flatnonzero(pts[:, 2] < r)[0])
            raise ConfigError(f"{name}[{i}]", [round(float(v), 3) for v in pts[i]], f"z must be >= robot radius {r} m")
        dist = np.linalg.norm(pts[:, None] - pts[None], axis=-1) + np.eye(len(pts)) * 1e9
        if np.any(dist < 2 * r + 0.1):
            i, j = np.unravel_index(np.argmin(dist), dist.shape)
            raise ConfigError(f"{name}[{j}]", [round(float(v), 3) for v in pts[j]], f"closer than the safety distance {2 * r + 0.1:.2f} m to {name}[{i}]")
