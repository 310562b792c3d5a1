"""The machinery both environments share: a :class:`mpcde.flight.session.FlightSession` stepped between control steps.

:class:`EnvCore` builds the session of a scenario
(:func:`mpcde.flight.loop.open_session`) with an
:class:`mpcde.env.external.ExternalDrone` for every learner-flown drone and the
scenario's own stack (:func:`mpcde.stacks.build.make_agent`) for the others,
so the world, cameras, detector, radio, faults and metrics are those of
``mpcde fly``: there is no second simulator. A control step holds each
learner's action (:mod:`mpcde.env.actions`) and runs physics ticks until
simulated time reaches the next control tick (k / ``control_hz``, event-driven
like the camera: 9 or 10 ticks of 240 Hz per 25 Hz step).
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path
from typing import Any, Callable, Sequence

import numpy as np

from mpcde.config.scenario import ScenarioConfig
from mpcde.env.actions import action_bounds, check_action
from mpcde.env.external import ExternalDrone
from mpcde.env.observations import ObservationBuilder
from mpcde.env.options import EnvOptions
from mpcde.env.rewards import StepOutcome, default_reward
from mpcde.errors import ConfigError
from mpcde.flight.session import EPS_S
from sim.rendering.pool_keeper import PoolKeeper

__all__ = ["EnvCore", "load_env_scenario"]

CEILING_M = 10.0
"""Lowest top of the reference action's flying box [m] (it is raised to twice the highest start or goal)."""


def load_env_scenario(scenario: str | Path | ScenarioConfig, mode: str | None = None, duration_s: float | None = None) -> ScenarioConfig:
    """A scenario for an environment: a :class:`ScenarioConfig`, a YAML path or a built-in name (``mode`` replaces its stack)."""
    from mpcde.api import load_scenario

    if isinstance(scenario, ScenarioConfig):
        if mode is not None:
            from mpcde.stacks import get_stack

            scenario = replace(scenario, planner=replace(scenario.planner, kind=get_stack(mode).kind))
        return scenario if duration_s is None else replace(scenario, duration_s=duration_s)
    return load_scenario(scenario, mode=mode, duration_s=duration_s)


def options_from(options: EnvOptions | dict | None, **overrides: Any) -> EnvOptions:
    """EnvOptions from an instance, a dict of fields or None (the defaults), then ``overrides``; unknown fields refused."""
    if options is None:
        base: dict = {}
    elif isinstance(options, EnvOptions):
        base = {f: getattr(options, f) for f in EnvOptions.__dataclass_fields__}
    elif isinstance(options, dict):
        unknown = sorted(set(options) - set(EnvOptions.__dataclass_fields__))
        if unknown:
            raise ConfigError(f"env.{unknown[0]}", options[unknown[0]], f"a field of EnvOptions: {', '.join(EnvOptions.__dataclass_fields__)}")
        base = dict(options)
    else:
        raise ConfigError("env", options, "EnvOptions, a dict of its fields or None")
    base.update({k: v for k, v in overrides.items() if v is not None})
    return EnvOptions(**base)


class EnvCore:
    """One environment's world: learners' drones, the others' stacks, the session, rewards and terminations.

    Args:
        cfg: the scenario (its ``planner.kind`` flies the drones that are not learners).
        options: the environment's options.
        learners: the drones a learner flies; None: all.
        reward: replaces :func:`mpcde.env.rewards.default_reward`.
    """

    def __init__(self, cfg: ScenarioConfig, options: EnvOptions, learners: Sequence[int] | None, reward: Callable[[StepOutcome], dict[str, float]] | None = None) -> None:
        from mpcde.flight.loop import prepare_run
        from sim.camera import intrinsics

        self.options = options
        if not options.cameras:
            cfg = replace(cfg, run=replace(cfg.run, cameras=False))
            if learners is None:  # no stack flies; the scenario's may need cameras (mpcde, auto) and would be refused
                from mpcde.stacks import get_stack

                cfg = replace(cfg, planner=replace(cfg.planner, kind=get_stack("placeholder").kind))
        elif not cfg.run.cameras:
            raise ConfigError("env.cameras", True, "the scenario has run.cameras: false; pass cameras=False")
        self.cfg = cfg
        self.prepared = prepare_run(cfg)  # validates the scenario; the layout's size fixes the spaces
        n = self.n = self.prepared.starts.shape[0]
        learners = list(range(n)) if learners is None else list(learners)
        bad = [i for i in learners if not (isinstance(i, (int, np.integer)) and 0 <= i < n)]
        if bad or len(set(learners)) != len(learners) or not learners:
            raise ConfigError("env.learners", list(learners), f"distinct drone indices in [0, {n - 1}]")
        self.learners = [int(i) for i in learners]
        self.names = [f"drone_{i}" for i in self.learners]
        self.index = dict(zip(self.names, self.learners))
        self.reward_fn = reward if reward is not None else default_reward
        half = np.asarray(cfg.world.arena_size_m, float) / 2
        top = max(CEILING_M, 2.0 * float(max(self.prepared.starts[:, 2].max(), self.prepared.goals[:, 2].max())))
        self.low, self.high, self.action_names = action_bounds(
            options.action, options.max_speed_mps, options.max_accel_mps2, options.max_yaw_rate_rps, np.r_[-half, 0.0], np.r_[half, top]
        )
        self.observations = ObservationBuilder(cfg, options, intrinsics(cfg.camera), n)
        self.session = None
        self.pools = PoolKeeper()  # one render pool for all episodes: a reset loads the scene, starts no workers
        self._seeds: np.random.Generator | None = None  # draws the seeds of unseeded resets
        self._composer = None
        self.drones: dict[str, ExternalDrone] = {}

    # episodes -----------------------------------------------------------------
    def episode_seed(self, seed: int | None) -> int:
        """The scenario seed of the next episode: ``seed`` when given (it also seeds the draws of later
        unseeded resets); otherwise the scenario's own seed first, then seeds drawn from the last given one."""
        if seed is not None:
            if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or not 0 <= seed < 2**32:
                raise ConfigError("seed", seed, "an integer in [0, 2^32)")
            self._seeds = np.random.default_rng(int(seed))
            return int(seed)
        if self._seeds is None:
            self._seeds = np.random.default_rng(self.cfg.seed)
            return int(self.cfg.seed)
        return int(self._seeds.integers(0, 2**32))

    def start(self, seed: int) -> dict[str, dict]:
        """Close any running episode and start one with scenario seed ``seed``; the learners' first observations."""
        from mpcde.flight.loop import open_session, prepare_run

        self.end_episode()
        cfg = replace(self.cfg, seed=int(seed))
        prepared = prepare_run(cfg) if cfg.seed != self.prepared.config.seed else self.prepared
        if prepared.starts.shape[0] != self.n:
            raise ConfigError("seed", seed, f"a seed whose layout has {self.n} drones, as the spaces were built for")
        self.prepared = prepared  # its config's seed is the episode's
        o = self.options
        perceive = any(k in o.observe for k in ("tracks", "detections"))
        self.drones = {
            name: ExternalDrone(i, o.action, perceive, prepared.config.perception, o.broadcast, o.plan_samples, o.plan_horizon_s)
            for name, i in self.index.items()
        }  # fmt: skip
        self.session = open_session(prepared, agents={d.drone_id: d for d in self.drones.values()}, pools=self.pools)
        self._composer = None
        t = self.session.time_s
        for d in self.drones.values():
            d.act(t, None)  # hover where it estimates it is until its first action
        self.next_control = 0.0
        self._advance_control_clock(t)
        self.events_seen = 0
        self.live = list(self.names)
        self.clipped = dict.fromkeys(self.names, False)
        return {a: self.observe(a) for a in self.live}

    def _advance_control_clock(self, t: float) -> None:
        while self.next_control <= t + EPS_S:
            self.next_control += 1.0 / self.options.control_hz

    def observe(self, agent: str) -> dict:
        """The observation of ``agent`` now."""
        i = self.index[agent]
        return self.observations.observe(self.drones[agent], self.session.time_s, self.prepared.goals[i])

    def step(self, actions: dict[str, Any]) -> tuple[dict, dict, dict, dict, dict]:
        """Apply the live agents' actions, fly to the next control tick; (obs, rewards, terminated, truncated, infos) of those agents.

        An agent missing from ``actions`` keeps its held action; the actions
        of agents that have terminated or been truncated are ignored (their
        drones hover); a name that is no agent raises ValueError.
        """
        if self.session is None:
            raise RuntimeError("step() before reset()")
        stray = sorted(set(actions) - set(self.names))
        if stray:
            raise ValueError(f"actions[{stray[0]!r}]: not an agent (agents: {', '.join(self.names)})")
        actions = {a: v for a, v in actions.items() if a in self.live}
        s = self.session
        t0 = s.time_s
        clip = self.options.invalid_action == "clip"
        for a, act in actions.items():
            value, changed = check_action(a, act, self.low, self.high, self.action_names, clip)
            self.clipped[a] = changed
            self.drones[a].act(t0, value)
        pos_before = s.truth.pos_world.copy()
        arrived_before = ~np.isnan(s.metrics.arrival_time)
        failed_before = s.truth.failed.copy()
        while not s.done:
            s.step()
            if s.time_s >= self.next_control - EPS_S:
                break
        self._advance_control_clock(s.time_s)
        t1 = s.time_s
        events = tuple(s.metrics.events[self.events_seen :])
        self.events_seen = len(s.metrics.events)
        hit = {int(j) for e in events for j in e["drones"]} | set(np.flatnonzero(s.truth.failed & ~failed_before).tolist())
        newly = ~np.isnan(s.metrics.arrival_time) & ~arrived_before
        agents = tuple(self.live)
        collided = {a: self.index[a] in hit for a in agents}
        arrived = {a: bool(newly[self.index[a]]) for a in agents}
        o = self.options
        outcome = StepOutcome(agents, dict(self.index), t0, t1, pos_before, s.truth.pos_world.copy(), self.prepared.goals, collided, arrived, events, o.progress_weight, o.collision_penalty, o.arrival_bonus)
        rewards = {a: float(r) for a, r in self.reward_fn(outcome).items() if a in agents}
        terminated = {a: bool((o.terminate_on_collision and collided[a]) or (o.terminate_on_arrival and arrived[a]) or s.truth.failed[self.index[a]]) for a in agents}
        truncated = {a: bool(s.done and not terminated[a]) for a in agents}
        faults = s.faults.report()
        infos = {
            a: {
                "time_s": t1,
                "collision_events": [e for e in events if self.index[a] in e["drones"]],
                "arrived": arrived[a],
                "faults": faults,
                "action_clipped": self.clipped[a],
            }
            for a in agents
        }
        obs = {a: self.observe(a) for a in agents}
        for a in agents:
            if terminated[a] or truncated[a]:
                self.drones[a].freeze(t1)
        self.live = [a for a in agents if not (terminated[a] or truncated[a])]
        return obs, rewards, terminated, truncated, infos

    # outputs ------------------------------------------------------------------
    def render(self) -> np.ndarray | None:
        """The run video's frame now: top view beside the drones' newest camera images (None before reset)."""
        s = self.session
        if s is None:
            return None
        if self._composer is None:
            from mpcde.flight.video import FrameComposer

            cfg, p = self.prepared.config, self.prepared
            self._composer = FrameComposer(p.obstacles, p.goals, cfg.world.arena_size_m, (cfg.camera.width_px, cfg.camera.height_px))
        return self._composer.compose(s.time_s, s.truth, s.latest_frames)

    def result(self):
        """End the episode and return its :class:`mpcde.flight.loop.RunResult` (the metrics of ``mpcde fly``)."""
        if self.session is None:
            raise RuntimeError("result() before reset()")
        return self.session.result()

    def end_episode(self) -> None:
        """Free the running episode's PyBullet world (the render pool stays for the next episode)."""
        if self.session is not None:
            self.session.close()

    def close(self) -> None:
        """Free the running episode and the render pool (its worker processes and shared memory)."""
        try:
            self.end_episode()
        finally:
            self.pools.close()
