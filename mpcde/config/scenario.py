"""Scenario configuration: frozen, validated dataclasses read from YAML.

A scenario file is a mapping whose top-level keys are the fields of
:class:`ScenarioConfig`; every field has a default, a unit and a docstring.
Component settings reuse the components' own config types (camera, radio,
pose estimate, physics) so there is one definition of each field.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, ClassVar, Iterator, Mapping

import numpy as np

from mpcde.config.admm import AdmmAgentConfig
from mpcde.config.auto import AutoAgentConfig
from mpcde.config.bounds import Bound
from mpcde.config.denied import DeniedAgentConfig
from mpcde.config.dmpc import DmpcAgentConfig
from mpcde.config.io import from_dict, load_yaml
from mpcde.config.layout import MAX_DRONES, DronesConfig, ObstacleEntry, WorldConfig, build_layout, resolve_obstacles
from mpcde.config.mlr import MlrAgentConfig
from mpcde.config.perception import PerceptionConfig
from mpcde.config.ranges import RANGES
from mpcde.errors import ConfigError
from mpcde.stacks.builtin import DEFAULT_KIND
from mpcde.stacks.registry import stack_for_kind, stack_of, stacks
from planners.yaw.config import YawPlannerConfig
from sim.camera import CameraConfig
from sim.faults import FaultsConfig
from sim.pose_estimate import PoseEstimateConfig
from sim.radio import RadioConfig
from sim.vehicle.physics_config import PhysicsConfig

__all__ = [
    "SCENARIO_DIR",
    "DronesConfig",
    "ObstacleEntry",
    "PlannerConfig",
    "PluginSections",
    "RunOptions",
    "ScenarioConfig",
    "WorldConfig",
    "build_layout",
    "load_scenario",
    "resolve_obstacles",
    "scenario_from_dict",
]

SCENARIO_DIR = Path(__file__).resolve().parents[2] / "data" / "scenarios"
MAX_NAME_CHARS = 100
"""Longest scenario name [characters]."""


@dataclass(frozen=True)
class PlannerConfig:
    """Onboard planning.

    Attributes:
        kind: the onboard stack, by its ``planner.kind`` (the registry,
            :mod:`mpcde.stacks`; null, the default: the headline stack the
            options allow, ``auto``, or ``dmpc`` with ``run.cameras: false``,
            :func:`mpcde.stacks.registry.stack_of`): ``min_jerk_line``, the placeholder, a blind
            straight minimum-jerk line; ``mpcde``, the communication-denied
            MP-CDE stack, settings in ``denied``; ``dmpc``, DMPC on exchanged
            radio plans, settings in ``dmpc``; ``auto``, DMPC falling back to
            camera tracks and MP-CDE, settings in ``auto``; ``mlr``, MLR-DMPC;
            ``admm``, the ADMM formation DMPC; ``minco_comm``, MP-CDE's
            planner on radio plans; and any registered third-party stack.
        cruise_speed_mps: the swarm's speed [m/s] (MP-CDE's "target velocity"
            regimes, Sec. V-B: 0.5, 1 and 2 m/s), for every stack that flies a
            speed: the peak speed of the placeholder's and ADMM's lines, the
            speed limit of MP-CDE's optimiser (``denied.limits.v_max_mps``, with
            ``mpcde``, ``auto`` and ``minco_comm``) and DMPC's per-axis speed limit
            (``dmpc.qp.limits.v_max_mps``, with ``dmpc`` and ``auto``): each stack's
            ``speed_fields``, derived at load time (:mod:`mpcde.config.resolve`;
            a file that also sets one of those to another value is refused).
            null (the default): each stack's own setting (lines 1 m/s, MP-CDE
            1 m/s, DMPC 2 m/s per axis). A stack without ``cruise_speed``
            (``mlr``) has no single speed and refuses it.
        start_delay_s: hover time before departure [s].
    """

    kind: str | None = None
    cruise_speed_mps: float | None = None
    start_delay_s: float = 0.5

    LINE_SPEED_MPS: ClassVar[float] = 1.0
    """The lines' peak speed [m/s] when ``cruise_speed_mps`` is null."""

    @property
    def line_speed_mps(self) -> float:
        """Peak speed [m/s] of the placeholder's and ADMM's straight lines."""
        return self.LINE_SPEED_MPS if self.cruise_speed_mps is None else float(self.cruise_speed_mps)

    def __post_init__(self) -> None:
        stack = stack_for_kind(self.kind if self.kind is not None else DEFAULT_KIND, "kind")  # null: auto or dmpc, both fly a speed
        if self.cruise_speed_mps is not None and not 0 < self.cruise_speed_mps <= 10:
            raise ConfigError("cruise_speed_mps", self.cruise_speed_mps, "in (0, 10] m/s, or null")
        if self.cruise_speed_mps is not None and not stack.cruise_speed:
            allowed = f"null for planner.kind {self.kind!r} (its speed limits are its section's)"
            raise ConfigError("cruise_speed_mps", self.cruise_speed_mps, allowed)
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


class PluginSections(Mapping):
    """The settings sections of registered third-party stacks: section name -> its frozen dataclass (immutable).

    In a scenario file each is a top-level section named by its stack's
    ``section`` (:class:`mpcde.stacks.Stack`), read into the stack's
    ``config_type`` with the same checks and one-line errors as the built-in
    sections; a section left out is the stack's defaults.
    """

    def __init__(self, sections: Mapping[str, Any] | None = None) -> None:
        self._sections = dict(sorted((sections or {}).items()))

    def __getitem__(self, key: str) -> Any:
        return self._sections[key]

    def __iter__(self) -> Iterator[str]:
        return iter(self._sections)

    def __len__(self) -> int:
        return len(self._sections)

    def __eq__(self, other: object) -> bool:
        return isinstance(other, Mapping) and dict(self) == dict(other)

    def __hash__(self) -> int:
        return hash(tuple(self._sections.items()))

    def __repr__(self) -> str:
        return f"PluginSections({self._sections!r})"


def plugin_section_types() -> dict[str, tuple[type, dict]]:
    """Section name -> (settings dataclass, its ranges) of every registered third-party stack that has one."""
    return {s.section: (s.config_type, s.ranges) for s in stacks() if s.section is not None and s.config_type is not None}


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
            ``radio.rate_hz`` is derived, 2 x the ADMM iterations per step / ``admm.step_s``
            (:mod:`mpcde.config.resolve`, with the other derived fields).
        faults: lost camera frames, detector misses and false boxes, drone
            failures (:mod:`sim.faults`; the radio's and the sensors' own
            faults are in ``radio``, ``camera`` and ``pose_estimate``).
        run: simulation options.
        plugins: the sections of registered third-party stacks
            (:class:`PluginSections`; top-level sections of the file, named by each stack).
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
    faults: FaultsConfig = field(default_factory=FaultsConfig)
    run: RunOptions = field(default_factory=RunOptions)
    plugins: PluginSections = field(default_factory=PluginSections, metadata={"sections": plugin_section_types})

    def __post_init__(self) -> None:
        if not (isinstance(self.name, str) and 1 <= len(self.name) <= MAX_NAME_CHARS and self.name.isprintable()):
            raise ConfigError("name", self.name, f"1 to {MAX_NAME_CHARS} printable characters")
        if not 0 < self.duration_s <= 3600:
            raise ConfigError("duration_s", self.duration_s, "in (0, 3600] s")
        if not 0 <= self.seed < 2**32:
            raise ConfigError("seed", self.seed, "an integer in [0, 2^32)")
        if not isinstance(self.plugins, PluginSections):
            object.__setattr__(self, "plugins", PluginSections(self.plugins))
        stack = stack_of(self)
        if stack.config_type is not None and stack.section not in self.plugins:  # its defaults, written to config.yaml
            object.__setattr__(self, "plugins", PluginSections({**self.plugins, stack.section: stack.config_type()}))
        if stack.uses.cameras == "required" and not self.run.cameras:
            allowed = f"must be true for planner.kind {stack.kind!r}: it sees only through its camera (drop --no-cameras)"
            raise ConfigError("run.cameras", self.run.cameras, allowed)
        if self.run.cameras and (self.camera.width_px % 16 or self.camera.height_px % 16):
            bad = "width_px" if self.camera.width_px % 16 else "height_px"
            allowed = "a multiple of 16 px with run.cameras: true (the detector's stride-16 level)"
            raise ConfigError(f"camera.{bad}", getattr(self.camera, bad), allowed)
        starts, goals = build_layout(self.drones)
        _require_inside_arena(self, starts, goals)
        try:
            self.faults.check_drones(len(starts))
        except ConfigError as e:
            raise e.under("faults") from None
        if stack.check is not None:  # the stack's own load-time rules (mpcde/stacks/builtin.py)
            stack.check(self, starts, goals)


def _require_inside_arena(cfg: ScenarioConfig, starts: np.ndarray, goals: np.ndarray) -> None:
    """ConfigError naming the first start or goal (N, 3) [m] outside the arena or above the altitude limit."""
    hx, hy = (a / 2 for a in cfg.world.arena_size_m)
    for name, pts in (("drones.starts", starts), ("drones.goals", goals)):
        for i, (x, y, z) in enumerate(pts):
            if not (abs(x) <= hx and abs(y) <= hy and 0 <= z <= 20):
                allowed = f"inside the arena, |x| <= {hx:g} m, |y| <= {hy:g} m, 0 <= z <= 20 m"
                raise ConfigError(f"{name}[{i}]", [round(float(v), 3) for v in (x, y, z)], allowed)


SCENARIO_RANGES = {
    **RANGES,
    ScenarioConfig: {"seed": Bound(0, 2**32 - 1), "duration_s": Bound(0.01, 3600, "s")},
    WorldConfig: {
        "arena_size_m": Bound(1, 200, "m"), "obstacle_density_per_100m2": Bound(0, 40, "per 100 m^2"), "box_fraction": Bound(0, 1),
        "clear_radius_m": Bound(0, 10, "m"),
    },
    ObstacleEntry: {
        "center_xy": Bound(-100, 100, "m"), "height_m": Bound(0.1, 100, "m"), "radius_m": Bound(0.01, 20, "m"),
        "half_extents_xy": Bound(0.01, 50, "m"), "yaw": Bound(-7, 7, "rad"),
    },
    DronesConfig: {
        "count": Bound(1, MAX_DRONES), "radius_m": Bound(0.1, 100, "m"), "spacing_m": Bound(0.1, 50, "m"), "altitude_m": Bound(0.3, 20, "m"),
        "starts": Bound(-100, 100, "m"), "goals": Bound(-100, 100, "m"),
    },
    PlannerConfig: {"cruise_speed_mps": Bound(0.01, 10, "m/s"), "start_delay_s": Bound(0, 60, "s")},
    RunOptions: {"render_workers": Bound(-1, 16), "log_rate_hz": Bound(0.1, 240, "Hz"), "goal_tolerance_m": Bound(0.01, 10, "m")},
}
"""The range of every number a scenario may hold (:mod:`mpcde.config.bounds`): the components' plus the scenario's own sections."""


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
        raise ConfigError("scenario", str(p), "an empty file (a scenario is a YAML mapping of fields; see data/scenarios/)")
    if not isinstance(data, dict):
        raise ConfigError("scenario", str(p), "must be a YAML mapping of fields")
    data = {**data, **(overrides or {})}
    if planner_kind is not None:
        planner = data.get("planner")
        planner = planner if isinstance(planner, dict) else ({} if planner is None else planner)
        if isinstance(planner, dict):  # anything else: from_dict names it
            data["planner"] = {**planner, "kind": planner_kind}
    data.setdefault("name", p.stem)
    return scenario_from_dict(data)


def scenario_from_dict(data: dict) -> ScenarioConfig:
    """The checked, resolved scenario of a mapping as a scenario file holds it (what :func:`load_scenario` reads)."""
    _refuse_ignored(data)
    from mpcde.config.resolve import resolve

    return resolve(from_dict(ScenarioConfig, data, ranges=SCENARIO_RANGES), data)


def _is_default(cls: type, key: str, value: object) -> bool:
    default = next(f.default for f in dataclasses.fields(cls) if f.name == key)
    try:
        return bool(value == default or (isinstance(value, list) and tuple(map(tuple, value)) == tuple(map(tuple, default))))
    except TypeError:
        return False


_LAYOUT_FIELDS = {"explicit": {"starts", "goals"}, "antipodal": {"count", "radius_m", "altitude_m"}, "mirror": {"count", "radius_m", "spacing_m", "altitude_m"}}
_OBSTACLE_FIELDS = {"tree": {"radius_m"}, "box": {"half_extents_xy", "yaw"}}


def _refuse_ignored(data: dict) -> None:
    """Refuse a field the file sets that its choice would ignore: a layout's or an obstacle kind's fields set for another.

    ``count`` without ``layout: antipodal`` or ``mirror`` (the default layout is
    explicit), ``starts`` with a generated layout, a tree's ``half_extents_xy``,
    a box's ``radius_m`` or a ``denied.yaw`` setting with ``denied.active_yaw:
    false`` would otherwise be read and silently not used. A
    field at its default is let through: a run folder's ``config.yaml`` holds
    every field, and flying it again must work.
    """
    drones = data.get("drones")
    if isinstance(drones, dict):
        layout = drones.get("layout", "explicit")
        layout = layout if isinstance(layout, str) else None  # any other type: from_dict names it
        used = _LAYOUT_FIELDS.get(layout, set())
        for key in sorted(set().union(*_LAYOUT_FIELDS.values()) - used, key=str):
            if key in drones and layout in _LAYOUT_FIELDS and not _is_default(DronesConfig, key, drones[key]):
                readers = " or ".join(repr(k) for k, v in _LAYOUT_FIELDS.items() if key in v)
                raise ConfigError(f"drones.{key}", drones[key], f"read only with drones.layout {readers} (layout is {layout!r}): set the layout or leave it out")
    denied = data.get("denied")
    yaw = denied.get("yaw") if isinstance(denied, dict) else None
    if isinstance(yaw, dict) and denied.get("active_yaw") is False:
        from mpcde.config.resolve import COMMON  # the yaw fields resolve() sets are written to every run folder

        derived = {d.target.rpartition(".")[2] for d in COMMON if d.target.startswith("denied.yaw.")}
        for key in sorted(set(yaw) - derived, key=str):
            if isinstance(key, str) and key in {f.name for f in dataclasses.fields(YawPlannerConfig)} and not _is_default(YawPlannerConfig, key, yaw[key]):
                raise ConfigError(f"denied.yaw.{key}", yaw[key], "read only with denied.active_yaw: true (it is false): set it true or leave the field out")
    world = data.get("world")
    obstacles = world.get("obstacles") if isinstance(world, dict) else None
    for i, o in enumerate(obstacles if isinstance(obstacles, list) else []):
        kind = o.get("kind", "tree") if isinstance(o, dict) else None
        if not isinstance(kind, str) or kind not in _OBSTACLE_FIELDS:
            continue
        for other, keys in _OBSTACLE_FIELDS.items():
            for key in sorted(keys & set(o) if other != kind else set()):
                if _is_default(ObstacleEntry, key, o[key]):
                    continue
                raise ConfigError(f"world.obstacles[{i}].{key}", o[key], f"read only for kind {other!r} (kind is {kind!r}): set kind: {other} or leave it out")
