"""The one registry of onboard stacks: what each is called, what it reads, how it is built and checked.

A stack is one :class:`Stack` entry. Everything that needs to know about
stacks asks here, never compares a name: config loading (the ``planner.kind``
choice, the stack's settings section, its load-time rules and the fields the
scenario's speed derives), the agent factory (:func:`mpcde.stacks.build.make_agent`),
the flight session (formation metrics), ``mpcde fly --mode``, ``compare``,
sweeps and reports, and the environments' :class:`mpcde.env.StackPolicy`.

The built-in stacks are in :mod:`mpcde.stacks.builtin`. A third-party stack
registers in one of two ways, with no change to this package:

* an installed package declares an entry point in the group ``mpcde.stacks``
  whose object is a :class:`Stack` (or a callable returning one)::

      [project.entry-points."mpcde.stacks"]
      orca = "mpcde_orca:STACK"

* a script or notebook calls :func:`register_stack` before it flies (in the
  processes that fly: a sweep's ``--jobs`` workers import entry points, not a
  script's registrations; docs/stacks.md).

Entry points are read once, at the first question asked of the registry.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from importlib import metadata
from typing import TYPE_CHECKING, Any, Callable, Literal

from mpcde.errors import ConfigError

if TYPE_CHECKING:
    import numpy as np

    from mpcde.config.scenario import ScenarioConfig

__all__ = [
    "ENTRY_POINT_GROUP", "AgentContext", "Derivation", "Stack", "Uses", "get_stack", "register_stack", "stack_for_kind",
    "stack_of", "stacks",
]  # fmt: skip

ENTRY_POINT_GROUP = "mpcde.stacks"
"""The entry-point group through which installed packages add stacks."""

CameraUse = Literal["required", "optional", "none"]


@dataclass(frozen=True)
class Uses:
    """What a stack's agents read besides their own pose estimate.

    Attributes:
        cameras: ``"required"``: the stack sees only through its camera (a
            scenario with ``run.cameras: false`` is refused); ``"optional"``:
            it uses frames where there are some (DMPC scores its tracks);
            ``"none"``: frames are counted, not used.
        radio: its agents read their radio inbox.
        known_obstacles: its agents are given the static obstacles as a prior
            map (the on-demand DMPC paper's assumption); the others map with
            their cameras, and their factory gets none.
        joint: its drones compute together (MLR-DMPC's compute units, ADMM's
            sub-rounds), so it cannot fly a subset of the drones (an
            environment's non-learners).
    """

    cameras: CameraUse = "none"
    radio: bool = False
    known_obstacles: bool = False
    joint: bool = False

    def __post_init__(self) -> None:
        if self.cameras not in ("required", "optional", "none"):
            raise ValueError(f"Uses.cameras={self.cameras!r}: allowed 'required', 'optional', 'none'")


@dataclass(frozen=True)
class Derivation:
    """A field that load time derives from another (:mod:`mpcde.config.resolve`).

    Attributes:
        target: the dotted field that is set.
        source: what it is derived from, as error messages name it.
        derive: the value, from the scenario.
        applies: whether it applies to this scenario (beyond the stack being chosen).
    """

    target: str
    source: str
    derive: Callable[["ScenarioConfig"], Any]
    applies: Callable[["ScenarioConfig"], bool] = lambda cfg: True


@dataclass(frozen=True)
class AgentContext:
    """Everything a stack's factory may give one drone's agent.

    Attributes:
        config: the resolved scenario (its mission: starts, goals, rates, the
            stack's settings; no other drone's state).
        drone_id: the drone being built.
        goals_world: (N, 3) every drone's goal [m] (the mission; a formation takes its offsets from them).
        obstacles: the static obstacles when the stack's ``uses.known_obstacles``, else empty.
        budget: the run's per-component compute time
            (:class:`mpcde.onboard.budget.ComputeBudget`), for the agent to book its work into.
    """

    config: "ScenarioConfig"
    drone_id: int
    goals_world: "np.ndarray"
    obstacles: tuple = ()
    budget: Any = None

    @property
    def goal_world(self) -> "np.ndarray":
        """(3,) this drone's goal [m]."""
        return self.goals_world[self.drone_id]

    @property
    def settings(self) -> Any:
        """The stack's own settings section of the scenario (None for a stack without one)."""
        return stack_of(self.config).settings(self.config)


@dataclass(frozen=True)
class Stack:
    """One onboard stack.

    Attributes:
        name: the word that picks it: ``mpcde fly --mode NAME``, ``compare --modes``, an env policy.
        factory: ``factory(context) -> OnboardAgent`` (:class:`mpcde.onboard.base.OnboardAgent`)
            for one drone, from an :class:`AgentContext`.
        summary: one line for ``--help`` and docs.
        kind: its ``planner.kind`` in a scenario file; default: ``name``.
        uses: what its agents read (:class:`Uses`).
        section: the scenario section holding its settings (a top-level key
            of the file); None: it has none. A built-in section
            (``denied``, ``dmpc``, ...) is a :class:`ScenarioConfig` field;
            a third-party stack's is read into ``config_type``.
        config_type: a third-party section's frozen dataclass (fields with
            defaults, units in the docstring, checks in ``__post_init__``
            raising :class:`mpcde.ConfigError`); read by the scenario reader
            with the same one-line errors. None for built-in sections.
        ranges: the physical range of its section's numbers,
            ``{dataclass: {field: mpcde.config.bounds.Bound}}``.
        check: ``check(config, starts_world, goals_world)``: its load-time
            rules across sections, raising ConfigError; None: none.
        speed_fields: the dotted fields that ``planner.cruise_speed_mps``
            sets when given (its speed limits); empty with ``cruise_speed``.
        cruise_speed: whether it flies ``planner.cruise_speed_mps`` at all
            (False: a scenario setting one is refused).
        derived: further fields it derives at load time (:class:`Derivation`).
        preset: {dotted field: value}: what this stack flies where the scenario does not set the field
            (:func:`mpcde.config.resolve.resolve` applies it before the derivations), so that one
            agent can be offered under a second name with other defaults: ``mpcde_paper`` is the
            ``denied`` agent with MP-CDE as published; a field the file sets wins.
        flies_formation: whether, for a scenario, it keeps the goals'
            formation (the metrics then report the formation error chi).
    """

    name: str
    factory: Callable[[AgentContext], Any]
    summary: str = ""
    kind: str = ""
    uses: Uses = field(default_factory=Uses)
    section: str | None = None
    config_type: type | None = None
    ranges: dict = field(default_factory=dict)
    check: Callable[["ScenarioConfig", "np.ndarray", "np.ndarray"], None] | None = None
    speed_fields: tuple[str, ...] = ()
    cruise_speed: bool = True
    derived: tuple[Derivation, ...] = ()
    preset: dict = field(default_factory=dict)
    flies_formation: Callable[["ScenarioConfig"], bool] = lambda cfg: False

    def __post_init__(self) -> None:
        if not self.kind:
            object.__setattr__(self, "kind", self.name)
        for word in (self.name, self.kind):
            if not (isinstance(word, str) and word.replace("_", "").isalnum() and word[0].isalpha() and len(word) <= 40):
                raise ValueError(f"Stack name/kind {word!r}: a letter, then letters, digits or '_' (at most 40)")
        if not callable(self.factory):
            raise ValueError(f"Stack {self.name!r}: factory must be callable")

    def settings(self, cfg: "ScenarioConfig") -> Any:
        """This stack's section of scenario ``cfg`` (None without one)."""
        if self.section is None:
            return None
        if self.config_type is None:
            return getattr(cfg, self.section)
        return cfg.plugins.get(self.section, self.config_type())


_BY_NAME: dict[str, Stack] = {}
_BY_KIND: dict[str, Stack] = {}
_LOADED = False


def register_stack(stack: Stack, replace: bool = False) -> Stack:
    """Add ``stack`` to the registry (``replace``: over an entry of the same name); returns it.

    Raises:
        ValueError: its name or kind is taken (by another stack, or as a
            built-in scenario section) and ``replace`` is False.
    """
    _load()
    return _add(stack, replace)


def _add(stack: Stack, replace: bool) -> Stack:
    if not isinstance(stack, Stack):
        raise ValueError(f"register_stack: a mpcde.stacks.Stack, not {type(stack).__name__}")
    old = _BY_NAME.get(stack.name)
    clash = _BY_KIND.get(stack.kind)
    if not replace and (old is not None or (clash is not None and clash.name != stack.name)):
        raise ValueError(f"stack {stack.name!r} (planner.kind {stack.kind!r}) is already registered")
    if stack.config_type is not None and stack.section is not None:
        from mpcde.config.scenario import ScenarioConfig

        taken = set(ScenarioConfig.__dataclass_fields__) | {s.section for s in _BY_NAME.values() if s.name != stack.name}
        if stack.section in taken:
            raise ValueError(f"stack {stack.name!r}: section {stack.section!r} is already a scenario section")
    if old is not None:
        _BY_KIND.pop(old.kind, None)
    _BY_NAME[stack.name] = stack
    _BY_KIND[stack.kind] = stack
    return stack


def _load() -> None:
    """Register the built-in stacks, then every installed ``mpcde.stacks`` entry point (once)."""
    global _LOADED
    if _LOADED:
        return
    _LOADED = True
    from mpcde.stacks.builtin import BUILTIN

    for stack in BUILTIN:
        _add(stack, False)
    for ep in sorted(metadata.entry_points(group=ENTRY_POINT_GROUP), key=lambda e: e.name):
        where = f"entry point {ENTRY_POINT_GROUP}:{ep.name}"
        try:
            obj = ep.load()
            stack = obj() if callable(obj) and not isinstance(obj, Stack) else obj
            _add(stack, False)
        except Exception as e:  # a broken plugin is named, not a traceback from inside the loader
            raise ConfigError(where, ep.value, f"a loadable mpcde.stacks.Stack ({type(e).__name__}: {e})") from None


def stacks() -> tuple[Stack, ...]:
    """Every registered stack, built-ins first, in registration order."""
    _load()
    return tuple(_BY_NAME.values())


def _lookup(table: dict[str, Stack], key: Any, field: str, allowed: str) -> Stack:
    _load()
    stack = table.get(key) if isinstance(key, str) else None
    if stack is None:
        raise ConfigError(field, key, allowed.format(", ".join(table), ", ".join(repr(k) for k in table)))
    return stack


def get_stack(name: str, field: str = "mode") -> Stack:
    """The stack called ``name`` (the ``--mode`` word); ConfigError naming ``field`` if there is none."""
    return _lookup(_BY_NAME, name, field, "one of {0}")


def stack_for_kind(kind: str, field: str = "planner.kind") -> Stack:
    """The stack whose ``planner.kind`` is ``kind``; ConfigError naming ``field`` if there is none."""
    return _lookup(_BY_KIND, kind, field, "allowed: {1}")


def stack_of(cfg: "ScenarioConfig") -> Stack:
    """The stack scenario ``cfg`` flies: its ``planner.kind``, or where that is null the headline stack its options
    allow (:data:`mpcde.stacks.builtin.DEFAULT_KIND`, ``auto``; with ``run.cameras`` false
    :data:`~mpcde.stacks.builtin.DEFAULT_KIND_WITHOUT_CAMERAS`, ``dmpc``)."""
    kind = cfg.planner.kind
    if kind is None:
        from mpcde.stacks.builtin import DEFAULT_KIND, DEFAULT_KIND_WITHOUT_CAMERAS

        kind = DEFAULT_KIND if cfg.run.cameras else DEFAULT_KIND_WITHOUT_CAMERAS
    return stack_for_kind(kind)
