"""Scenario configuration: frozen, validated dataclasses read from YAML.

A scenario file is a mapping whose top-level keys are the fields of
:class:`ScenarioConfig`; every field has a default, a unit and a docstring.
Component settings reuse the components' own config types (camera, radio,
pose estimate, physics) so there is one definition of each field.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any, Literal, get_args

import numpy as np

from mpcde.config.admm import AdmmAgentConfig
from mpcde.config.auto import AutoAgentConfig
from mpcde.config.denied import DeniedAgentConfig
from mpcde.config.dmpc import DmpcAgentConfig
from mpcde.config.io import from_dict, load_yaml
from mpcde.config.mlr import MlrAgentConfig
from mpcde.config.perception import PerceptionConfig
from mpcde.errors import ConfigError
from sim.camera import CameraConfig
from sim.obstacles import distance_to_obstacles, generate_obstacles
from sim.pose_estimate import PoseEstimateConfig
from sim.radio import RadioConfig
from sim.types import ObstacleSpec
from sim.vehicle.physics_config import PhysicsConfig

__all__ = [
    "SCENARIO_DIR",
    "DronesConfig",
    "ObstacleEntry",
    "PlannerConfig",
    "RunOptions",
    "ScenarioConfig",
    "WorldConfig",
    "build_layout",
    "load_scenario",
    "resolve_obstacles",
]

SCENARIO_DIR = Path(__file__).resolve().parents[2] / "data" / "scenarios"


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
            if not self.starts or len(self.starts) != len(self.goals):
                raise ConfigError("goals", self.goals, f"one goal per start ({len(self.starts)} starts), at least one")
        elif not 1 <= self.count <= 32:
            raise ConfigError("count", self.count, "an integer in [1, 32]")
        if self.radius_m <= 0 or self.spacing_m <= 0:
            raise ConfigError("radius_m", self.radius_m, "radius_m and spacing_m must be > 0 [m]")
        if not 0.3 <= self.altitude_m <= 20:
            raise ConfigError("altitude_m", self.altitude_m, "in [0.3, 20] m")


PlannerKind = Literal["min_jerk_line", "mpcde", "dmpc", "auto", "mlr", "admm"]


@dataclass(frozen=True)
class PlannerConfig:
    """Onboard planning.

    Attributes:
        kind: ``"min_jerk_line"``, the placeholder (a straight minimum-jerk
            line to the goal, blind to obstacles and neighbours), or
            ``"mpcde"``, the communication-denied stack (own map from the
            camera, A* front end, MINCO; settings in ``denied``), or
            ``"dmpc"``, the communicating stack (DMPC on exchanged radio
            plans; settings in ``dmpc``), or ``"auto"``, both: DMPC while
            the radio delivers, falling back neighbour by neighbour to camera
            tracks and, when the radio is out, to the denied stack (settings
            in ``auto``, ``dmpc`` and ``denied``; :mod:`mpcde.onboard.auto`), or
            ``"mlr"``, MLR-DMPC (DMPC-Swarm: compute units hosted by the first
            drones, message-loss recovery; settings in ``mlr``; obstacle-free
            scenarios only; :mod:`mpcde.onboard.mlr`), or ``"admm"``, the
            cooperative formation DMPC solved by ADMM across neighbours
            (Stomberg et al.; the goals are the formation; settings in
            ``admm``; obstacle-free scenarios whose drones start in formation;
            the radio runs at the ADMM exchange rate; :mod:`mpcde.onboard.admm`).
        cruise_speed_mps: peak speed along the line [m/s] (MP-CDE flights: 1 m/s).
        start_delay_s: hover time before departure [s].
    """

    kind: PlannerKind = "min_jerk_line"
    cruise_speed_mps: float = 1.0
    start_delay_s: float = 0.5

    def __post_init__(self) -> None:
        if self.kind not in get_args(PlannerKind):  # from_dict checks the Literal; this catches dataclasses.replace
            raise ConfigError("kind", self.kind, f"allowed: {', '.join(repr(a) for a in get_args(PlannerKind))}")
        if not 0 < self.cruise_speed_mps <= 10:
            raise ConfigError("cruise_speed_mps", self.cruise_speed_mps, "in (0, 10] m/s")
        if self.start_delay_s < 0:
            raise ConfigError("start_delay_s", self.start_delay_s, ">= 0 s")


@dataclass(frozen=True)
class RunOptions:
    """How the simulation runs (not what it simulates).

    Attributes:
        cameras: render every drone's camera at ``camera.rate_hz``.
        render_workers: render processes; -1 uses one per CPU core, 0 renders
            in the main process.
        log_rate_hz: rate of the state log and plots [Hz].
        stop_when_arrived: end the run 1 s after every drone reached its goal.
        goal_tolerance_m: a drone has arrived within this of its goal [m].
    """

    cameras: bool = True
    render_workers: int = -1
    log_rate_hz: float = 20.0
    stop_when_arrived: bool = True
    goal_tolerance_m: float = 0.3

    def __post_init__(self) -> None:
        if self.render_workers < -1 or self.render_workers > 16:
            raise ConfigError("render_workers", self.render_workers, "-1 (one per core), 0 (in-process) or 1-16")
        if not 0 < self.log_rate_hz <= 240:
            raise ConfigError("log_rate_hz", self.log_rate_hz, "in (0, 240] Hz")
        if not self.goal_tolerance_m > 0:
            raise ConfigError("goal_tolerance_m", self.goal_tolerance_m, "> 0 m")


@dataclass(frozen=True)
class ScenarioConfig:
    """A complete scenario.

    Attributes:
        name: scenario name (reports).
        seed: seed of every random choice of the run (obstacles, noise, radio).
        duration_s: time limit of the run [s].
        world: arena and obstacles.
        drones: starts and goals.
        camera: the forward RGB-D camera of every drone.
        radio: the broadcast channel.
        pose_estimate: self-localisation error.
        physics: physics rate, airframe and controller.
        planner: onboard planning.
        perception: every perceiving agent's detector, tracker and back-projection.
        denied: the MP-CDE (communication-denied) agent's settings.
        dmpc: the DMPC (communicating) agent's settings.
        auto: the ``auto`` agent's mode switch and plan/track fusion.
        mlr: the MLR-DMPC agent's settings.
        admm: the ADMM formation DMPC agent's settings. With ``planner.kind:
            admm`` and ``admm.radio_rate_from_step`` (default) the scenario's
            ``radio.rate_hz`` is derived, ``2 admm.l_max / admm.step_s``
            (:mod:`mpcde.config.resolve`, with the other derived fields).
        run: simulation options.
    """

    name: str = "scenario"
    seed: int = 0
    duration_s: float = 30.0
    world: WorldConfig = field(default_factory=WorldConfig)
    drones: DronesConfig = field(default_factory=DronesConfig)
    camera: CameraConfig = field(default_factory=CameraConfig)
    radio: RadioConfig = field(default_factory=RadioConfig)
    pose_estimate: PoseEstimateConfig = field(default_factory=PoseEstimateConfig)
    physics: PhysicsConfig = field(default_factory=PhysicsConfig)
    planner: PlannerConfig = field(default_factory=PlannerConfig)
    perception: PerceptionConfig = field(default_factory=PerceptionConfig)
    denied: DeniedAgentConfig = field(default_factory=DeniedAgentConfig)
    dmpc: DmpcAgentConfig = field(default_factory=DmpcAgentConfig)
    auto: AutoAgentConfig = field(default_factory=AutoAgentConfig)
    mlr: MlrAgentConfig = field(default_factory=MlrAgentConfig)
    admm: AdmmAgentConfig = field(default_factory=AdmmAgentConfig)
    run: RunOptions = field(default_factory=RunOptions)

    def __post_init__(self) -> None:
        if not 0 < self.duration_s <= 3600:
            raise ConfigError("duration_s", self.duration_s, "in (0, 3600] s")
        if not 0 <= self.seed < 2**32:
            raise ConfigError("seed", self.seed, "an integer in [0, 2^32)")
        if self.planner.kind in ("mpcde", "auto") and not self.run.cameras:
            allowed = f"must be true for planner.kind {self.planner.kind!r}: it sees only through its camera (drop --no-cameras)"
            raise ConfigError("run.cameras", self.run.cameras, allowed)
        if self.planner.kind in ("dmpc", "auto") and abs(self.dmpc.qp.step_s * self.radio.rate_hz - 1.0) > 1e-6:
            raise ConfigError("dmpc.qp.step_s", self.dmpc.qp.step_s, f"must equal 1 / radio.rate_hz = {1.0 / self.radio.rate_hz:g} s (one DMPC round per step)")
        if self.planner.kind == "mlr":
            _check_mlr(self)
        if self.planner.kind == "admm":
            _check_admm(self)


def _refuse_obstacles(world: WorldConfig, kind: str, why: str) -> None:
    """ConfigError if the world has static obstacles: planner.kind ``kind`` cannot avoid them (``why``)."""
    why = f"{why}; fly obstacles with planner.kind 'dmpc' (--mode comm)"
    if world.obstacles:
        raise ConfigError("world.obstacles", [o.kind for o in world.obstacles], f"none for planner.kind {kind!r}: {why}")
    if world.obstacle_density_per_100m2 > 0:
        density = world.obstacle_density_per_100m2
        raise ConfigError("world.obstacle_density_per_100m2", density, f"0 for planner.kind {kind!r}: {why}")


def _require_inside_box(starts: np.ndarray, goals: np.ndarray, planner: Any, box_name: str, section: str) -> None:
    """ConfigError naming the first start or goal (n, 3) [m] outside ``planner``'s pos_min_world..pos_max_world."""
    lo, hi = np.asarray(planner.pos_min_world), np.asarray(planner.pos_max_world)
    for name, pts in (("drones.starts", starts), ("drones.goals", goals)):
        outside = np.flatnonzero(np.any((pts < lo) | (pts > hi), axis=1))
        if outside.size:
            i = int(outside[0])
            box = f"[{', '.join(f'{v:g}' for v in lo)}] to [{', '.join(f'{v:g}' for v in hi)}] m"
            allowed = f"inside {box_name} {box} (the arena less {section}.arena_margin_m, {section}.altitude_range_m)"
            raise ConfigError(f"{name}[{i}]", [round(float(v), 3) for v in pts[i]], allowed)


def _check_mlr(cfg: ScenarioConfig) -> None:
    """The cross-field rules of ``planner.kind: mlr`` (:mod:`mpcde.onboard.mlr`); raises ConfigError."""
    mlr, radio, world = cfg.mlr, cfg.radio, cfg.world
    if abs(mlr.round_s * radio.rate_hz - 1.0) > 1e-6:
        allowed = f"must equal 1 / radio.rate_hz = {1.0 / radio.rate_hz:g} s (one MLR round per radio round)"
        raise ConfigError("mlr.round_s", mlr.round_s, allowed)
    if not radio.delay_s < mlr.round_s:
        allowed = f"< mlr.round_s = {mlr.round_s:g} s for planner.kind 'mlr' (messages are read in the next round)"
        raise ConfigError("radio.delay_s", radio.delay_s, allowed)
    _refuse_obstacles(world, "mlr", "MLR-DMPC has no obstacle constraints")
    starts, goals = build_layout(cfg.drones)
    planner = mlr.planner_config(len(starts), world.arena_size_m)  # M < N and the flying box
    _require_inside_box(starts, goals, planner, "MLR-DMPC's flying box", "mlr")


def _check_admm(cfg: ScenarioConfig) -> None:
    """The cross-field rules of ``planner.kind: admm`` (:mod:`mpcde.onboard.admm`); raises ConfigError."""
    admm, radio, world = cfg.admm, cfg.radio, cfg.world
    if admm.radio_rate_from_step:  # the rate resolve() gives the radio (mpcde/config/resolve.py)
        radio = replace(radio, rate_hz=admm.radio_rate_hz)
    elif abs(radio.rate_hz * admm.step_s - admm.rounds_per_step) > 1e-6:
        allowed = (
            f"must equal 2 x admm.l_max / admm.step_s = {admm.radio_rate_hz:g} Hz for planner.kind 'admm' (one "
            "radio sub-round per ADMM exchange), or set admm.radio_rate_from_step: true"
        )
        raise ConfigError("radio.rate_hz", radio.rate_hz, allowed)
    if not radio.delay_s < admm.sub_round_s:
        allowed = f"< one ADMM sub-round admm.step_s / (2 admm.l_max) = {admm.sub_round_s:g} s for planner.kind 'admm'"
        raise ConfigError("radio.delay_s", radio.delay_s, allowed)
    if cfg.physics.physics_hz < radio.rate_hz - 1e-9:
        allowed = f">= the ADMM radio rate {radio.rate_hz:g} Hz for planner.kind 'admm' (a tick per sub-round)"
        raise ConfigError("physics.physics_hz", cfg.physics.physics_hz, allowed)
    _refuse_obstacles(world, "admm", "the ADMM formation OCP has no obstacle constraints")
    if cfg.planner.cruise_speed_mps > admm.v_max:
        allowed = f"<= admm.v_max = {admm.v_max:g} m/s for planner.kind 'admm' (the own reference's speed)"
        raise ConfigError("planner.cruise_speed_mps", cfg.planner.cruise_speed_mps, allowed)
    starts, goals = build_layout(cfg.drones)
    planner = admm.planner_config(cfg.world.arena_size_m)  # the soft position box fits the arena
    _require_inside_box(starts, goals, planner, "the ADMM position box", "admm")
    # no collision avoidance: the drones must start in the goals' formation (moved to the starts' centroid)
    slots = goals - goals.mean(axis=0) + starts.mean(axis=0)
    offset = np.linalg.norm(starts - slots, axis=1)
    if np.any(offset > admm.max_start_offset_m):
        i = int(np.argmax(offset))
        allowed = (
            f"within admm.max_start_offset_m = {admm.max_start_offset_m:g} m of its slot in the goals' formation "
            f"({offset[i]:.2f} m off) for planner.kind 'admm': it has no collision avoidance"
        )
        raise ConfigError(f"drones.starts[{i}]", [round(float(v), 3) for v in starts[i]], allowed)


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


def load_scenario(
    path_or_name: str | Path, overrides: dict | None = None, planner_kind: str | None = None
) -> ScenarioConfig:
    """Read a scenario file (or the name of a built-in one in ``data/scenarios``).

    Args:
        path_or_name: a YAML path, or a built-in name such as ``"crossing"``.
        overrides: top-level fields replacing the file's (e.g. ``{"seed": 3}``).
        planner_kind: replaces the file's ``planner.kind`` before the scenario
            is checked (``--mode``), so that whatever a kind derives (the
            ``admm`` radio rate) starts from the file's own values.
    """
    p = Path(path_or_name)
    if not p.exists() and (SCENARIO_DIR / f"{path_or_name}.yaml").exists():
        p = SCENARIO_DIR / f"{path_or_name}.yaml"
    if not p.exists():
        builtins = ", ".join(sorted(q.stem for q in SCENARIO_DIR.glob("*.yaml")))
        raise ConfigError("scenario", str(path_or_name), f"no such file; built-in scenarios: {builtins}")
    data = load_yaml(p)
    if data is None:
        data = {}
    if not isinstance(data, dict):
        raise ConfigError("scenario", str(p), "must be a YAML mapping of fields")
    data = {**data, **(overrides or {})}
    if planner_kind is not None:
        planner = data.get("planner")
        planner = planner if isinstance(planner, dict) else ({} if planner is None else planner)
        if isinstance(planner, dict):  # anything else: from_dict names it
            data["planner"] = {**planner, "kind": planner_kind}
    data.setdefault("name", p.stem)
    from mpcde.config.resolve import resolve

    return resolve(from_dict(ScenarioConfig, data), data)
