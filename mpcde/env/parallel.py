"""The swarm as a PettingZoo ``ParallelEnv``: every drone flown by a learner.

    from mpcde.env import SwarmParallelEnv

    env = SwarmParallelEnv("forest_swarm", cameras=False)
    obs, infos = env.reset(seed=0)
    while env.agents:
        actions = {a: env.action_space(a).sample() for a in env.agents}
        obs, rewards, terminated, truncated, infos = env.step(actions)
    env.close()

Agents ``drone_0 .. drone_{N-1}``. The world is ``mpcde fly``'s
(:class:`mpcde.flight.session.FlightSession`): PyBullet physics at 240 Hz,
the SE(3) controller, the cameras and render pool, the detector, the radio,
the scenario's faults and the metrics. Observations:
:mod:`mpcde.env.observations`; actions: :mod:`mpcde.env.actions`; rewards:
:mod:`mpcde.env.rewards`. A drone terminates at a collision, its motors'
failure or its arrival (options), and hovers where it is from then on; every
live drone is truncated when the scenario ends (``duration_s``, or 1 s after
everyone arrived with ``run.stop_when_arrived``). ``infos[agent]`` holds the
step's collision events involving the drone, whether it arrived, the run's
fault counters and whether its action was clipped.

Seeding: ``reset(seed=s)`` flies the scenario with ``seed: s`` (obstacles,
noise, radio, faults), so the same seed and actions give the same episode;
``reset()`` without a seed takes the scenario's own seed first and then
seeds drawn from the last given one.
"""

from __future__ import annotations

import functools
from pathlib import Path
from typing import Any, Callable

import numpy as np
from gymnasium import spaces
from pettingzoo import ParallelEnv

from mpcde.config.scenario import ScenarioConfig
from mpcde.env.core import EnvCore, load_env_scenario, options_from
from mpcde.env.options import EnvOptions
from mpcde.env.rewards import StepOutcome

__all__ = ["SwarmParallelEnv"]


class SwarmParallelEnv(ParallelEnv):
    """A scenario's swarm, every drone a learner (PettingZoo Parallel API).

    Args:
        scenario: a built-in name (``"forest_swarm"``), a YAML path or a
            :class:`ScenarioConfig`; the scenario's bad fields raise
            :class:`mpcde.errors.ConfigError` here, before any world is built.
        options: :class:`mpcde.env.options.EnvOptions` or a dict of its fields.
        duration_s: replaces the scenario's time limit [s].
        render_mode: ``"rgb_array"`` or None.
        reward: replaces the default reward (:mod:`mpcde.env.rewards`).
        **overrides: EnvOptions fields (``cameras=False``, ``action="reference"``, ...).
    """

    metadata = {"name": "mpcde_swarm_v0", "render_modes": ["rgb_array"], "is_parallelizable": True}

    def __init__(
        self, scenario: str | Path | ScenarioConfig = "forest_swarm", options: EnvOptions | dict | None = None,
        duration_s: float | None = None, render_mode: str | None = None,
        reward: Callable[[StepOutcome], dict[str, float]] | None = None, **overrides: Any,
    ) -> None:  # fmt: skip
        from mpcde.errors import ConfigError

        if render_mode not in (None, "rgb_array"):
            raise ConfigError("render_mode", render_mode, "rgb_array or None")
        opts = options_from(options, **overrides)
        cfg = load_env_scenario(scenario, duration_s=duration_s)
        self.core = EnvCore(cfg, opts, None, reward)
        self.render_mode = render_mode
        self.possible_agents = list(self.core.names)
        self.agents: list[str] = []
        self._obs_space = self.core.observations.space
        self._act_spaces = {a: spaces.Box(self.core.low, self.core.high, dtype=np.float64) for a in self.possible_agents}
        self._obs_spaces = {a: self._obs_space for a in self.possible_agents}

    @functools.lru_cache(maxsize=None)
    def observation_space(self, agent: str) -> spaces.Space:
        """The observation space of ``agent`` (the same object every call)."""
        return self._obs_spaces[agent]

    @functools.lru_cache(maxsize=None)
    def action_space(self, agent: str) -> spaces.Space:
        """The action space of ``agent`` (the same object every call)."""
        return self._act_spaces[agent]

    def reset(self, seed: int | None = None, options: dict | None = None) -> tuple[dict, dict]:
        """Start an episode (``seed``: the scenario seed); the first observations and empty infos."""
        obs = self.core.start(self.core.episode_seed(seed))
        self.agents = list(self.core.live)
        return obs, {a: {} for a in self.agents}

    def step(self, actions: dict[str, Any]) -> tuple[dict, dict, dict, dict, dict]:
        """One control step: (observations, rewards, terminations, truncations, infos) of the agents that acted."""
        out = self.core.step(actions)
        self.agents = list(self.core.live)
        return out

    def render(self) -> np.ndarray | None:
        """The run video's frame now: top view beside the drones' newest camera images (``rgb_array``)."""
        return self.core.render() if self.render_mode == "rgb_array" else None

    def flight_result(self):
        """End the episode and return its :class:`mpcde.flight.loop.RunResult`: the metrics ``mpcde fly`` writes."""
        self.agents = []
        return self.core.result()

    def close(self) -> None:
        """Free PyBullet and the render pool."""
        self.core.close()
