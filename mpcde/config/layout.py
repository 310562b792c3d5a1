"""The ``world:`` and ``drones:`` sections: where the drones start and go, where the obstacles stand, and the
checks that they fit together.

:class:`WorldConfig` (the arena, the random forest, the obstacles placed by hand, :class:`ObstacleEntry`)
and :class:`DronesConfig` (the layout) are the sections; :func:`build_layout` turns ``drones`` into start and goal positions,
:func:`resolve_obstacles` adds the seeded random obstacles to the hand-placed
ones, and :func:`check_layout` refuses starts or goals inside an obstacle,
below the robot radius or closer to each other than the safety distance.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Literal

import numpy as np

from mpcde.errors import ConfigError
from sim.obstacles import distance_to_obstacles, generate_obstacles
from sim.types import ObstacleSpec

if TYPE_CHECKING:
    from mpcde.config.scenario import ScenarioConfig

__all__ = ["MAX_DRONES", "MAX_OBSTACLES", "DronesConfig", "ObstacleEntry", "WorldConfig", "build_layout", "check_layout", "resolve_obstacles"]

MAX_DRONES = 32
"""Most drones in a scenario (every layout)."""
MAX_OBSTACLES = 500
"""Most obstacles in a world, hand-placed plus random (the random placement is quadratic in their number)."""


@dataclass(frozen=True)
class ObstacleEntry:
    """An obstacle placed by hand in the scenario file.

    Attributes:
        kind: ``"tree"`` (vertical cylinder) or ``"box"``.
        center_xy: ground position [m].
        height_m: height [m].
        radius_m: tree radius [m].
        half_extents_xy: box half sizes [m].
        yaw: box heading [rad].
    """

    kind: Literal["tree", "box"] = "tree"
    center_xy: tuple[float, float] = (0.0, 0.0)
    height_m: float = 4.0
    radius_m: float = 0.25
    half_extents_xy: tuple[float, float] = (0.5, 0.5)
    yaw: float = 0.0

    def to_spec(self) -> ObstacleSpec:
        """As the world's obstacle type."""
        return ObstacleSpec(self.kind, self.center_xy, self.height_m, self.radius_m, self.half_extents_xy, self.yaw)


@dataclass(frozen=True)
class WorldConfig:
    """Arena and obstacles.

    Attributes:
        arena_size_m: (x, y) extent of the arena [m], centred on the origin.
        obstacle_density_per_100m2: random obstacles per 100 m^2 of arena.
        box_fraction: share of boxes among random obstacles, in [0, 1].
        clear_radius_m: no random obstacle within this of a start or goal [m].
        obstacles: obstacles placed by hand (in addition to random ones).
    """

    arena_size_m: tuple[float, float] = (20.0, 20.0)
    obstacle_density_per_100m2: float = 0.0
    box_fraction: float = 0.25
    clear_radius_m: float = 1.5
    obstacles: tuple[ObstacleEntry, ...] = ()

    def __post_init__(self) -> None:
        if min(self.arena_size_m) <= 0:
            raise ConfigError("arena_size_m", self.arena_size_m, "two sizes > 0 [m]")
        if not 0 <= self.obstacle_density_per_100m2 <= 40:
            raise ConfigError("obstacle_density_per_100m2", self.obstacle_density_per_100m2, "in [0, 40] per 100 m^2")
        if not 0 <= self.box_fraction <= 1:
            raise ConfigError("box_fraction", self.box_fraction, "in [0, 1]")
        if self.clear_radius_m < 0:
            raise ConfigError("clear_radius_m", self.clear_radius_m, ">= 0 [m]")
        n_random = round(self.obstacle_density_per_100m2 * self.arena_size_m[0] * self.arena_size_m[1] / 100.0)
        if len(self.obstacles) + n_random > MAX_OBSTACLES:
            allowed = f"at most {MAX_OBSTACLES} obstacles in all: {len(self.obstacles)} placed + {n_random} random (density x arena area / 100)"
            raise ConfigError("obstacle_density_per_100m2", self.obstacle_density_per_100m2, allowed)
        half = [a / 2 for a in self.arena_size_m]
        for i, o in enumerate(self.obstacles):
            if abs(o.center_xy[0]) > half[0] or abs(o.center_xy[1]) > half[1]:
                raise ConfigError(f"obstacles[{i}].center_xy", o.center_xy, f"inside the arena, |x| <= {half[0]:g} and |y| <= {half[1]:g} m")


@dataclass(frozen=True)
class DronesConfig:
    """Where the drones start and where they go.

    Attributes:
        layout: ``"explicit"`` (``starts`` and ``goals`` given), ``"antipodal"``
            (``count`` drones evenly on a circle of ``radius_m`` fly to the
            opposite point) or ``"mirror"`` (a column of ``count`` drones at
            x = -radius_m, spaced ``spacing_m`` in y, flies to the
            origin-symmetric points: every path crosses the centre region).
        count: number of drones (antipodal, mirror).
        radius_m: circle radius / half the start-goal distance [m].
        spacing_m: lateral spacing of the mirror layout [m].
        altitude_m: flight altitude of generated layouts [m].
        starts: explicit start positions [m].
        goals: explicit goal positions [m].
    """

    layout: Literal["explicit", "antipodal", "mirror"] = "explicit"
    count: int = 2
    radius_m: float = 4.0
    spacing_m: float = 1.5
    altitude_m: float = 1.5
    starts: tuple[tuple[float, float, float], ...] = ((-4.0, 0.0, 1.5), (0.0, -4.0, 1.5))
    goals: tuple[tuple[float, float, float], ...] = ((4.0, 0.0, 1.5), (0.0, 4.0, 1.5))

    def __post_init__(self) -> None:
        if self.layout == "explicit":
            if not 1 <= len(self.starts) <= MAX_DRONES:
                raise ConfigError("starts", f"{len(self.starts)} starts", f"1 to {MAX_DRONES} start positions")
            if len(self.starts) != len(self.goals):
                raise ConfigError("goals", f"{len(self.goals)} goals", f"one goal per start ({len(self.starts)} starts)")
        elif not 1 <= self.count <= MAX_DRONES:
            raise ConfigError("count", self.count, f"an integer in [1, {MAX_DRONES}]")
        if self.radius_m <= 0 or self.spacing_m <= 0:
            raise ConfigError("radius_m", self.radius_m, "radius_m and spacing_m must be > 0 [m]")
        if not 0.3 <= self.altitude_m <= 20:
            raise ConfigError("altitude_m", self.altitude_m, "in [0.3, 20] m")


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
