"""One learner among drones flown by one of the package's stacks, as a Gymnasium env (id ``mpcde/SingleDrone-v0``).

    import gymnasium as gym
    import mpcde.env  # registers the id

    env = gym.make("mpcde/SingleDrone-v0", scenario="forest_swarm", neighbours="denied", cameras=False)
    obs, info = env.reset(seed=0)

The learner flies drone ``learner`` (default 0); the others fly the stack
``neighbours`` names (a registered stack whose drones plan each on their own,
:func:`neighbour_modes`: ``placeholder``, ``denied``, ``comm``, ``auto``,
``minco_comm`` and any such third-party stack), for example a learner among
five MP-CDE drones. By default they fly ``denied`` with cameras and ``comm``
without (``denied`` sees only through its camera). The world, spaces, reward,
termination and truncation are those of :class:`mpcde.env.SwarmParallelEnv`
for one agent (:mod:`mpcde.env.core`).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any, Callable

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from mpcde.config.scenario import ScenarioConfig
from mpcde.env.core import EnvCore, load_env_scenario, options_from
from mpcde.env.options import EnvOptions
from mpcde.env.rewards import StepOutcome

__all__ = ["SingleDroneEnv", "neighbour_modes"]


def neighbour_modes() -> tuple[str, ...]:
    """Stacks that can fly a learner's neighbours (:func:`mpcde.env.policies.solo_modes`)."""
    from mpcde.env.policies import solo_modes

    return solo_modes()


class SingleDroneEnv(gym.Env):
    """One learner-flown drone in a scenario whose other drones fly a stack (Gymnasium API).

    Args:
        scenario: a built-in name, a YAML path or a :class:`ScenarioConfig`.
        neighbours: the stack of the other drones (:func:`neighbour_modes`); None: ``denied`` with cameras,
            ``comm`` without.
        learner: the learner's drone index.
        options: :class:`mpcde.env.options.EnvOptions` or a dict of its fields.
        duration_s: replaces the scenario's time limit [s].
        render_mode: ``"rgb_array"`` or None.
        reward: replaces the default reward (called with the one agent ``drone_<learner>``).
        **overrides: EnvOptions fields.
    """

    metadata = {"render_modes": ["rgb_array"], "render_fps": 25}

    def __init__(
        self, scenario: str | Path | ScenarioConfig = "forest_swarm", neighbours: str | None = None, learner: int = 0,
        options: EnvOptions | dict | None = None, duration_s: float | None = None, render_mode: str | None = None,
        reward: Callable[[StepOutcome], dict[str, float]] | None = None, **overrides: Any,
    ) -> None:  # fmt: skip
        from mpcde.errors import ConfigError

        from mpcde.stacks import get_stack

        if render_mode not in (None, "rgb_array"):
            raise ConfigError("render_mode", render_mode, "rgb_array or None")
        opts = options_from(options, **overrides)
        if neighbours is None:
            neighbours = "denied" if opts.cameras else "comm"
        allowed = neighbour_modes()
        if neighbours not in allowed:
            raise ConfigError("env.neighbours", neighbours, f"one of {', '.join(allowed)}")
        if get_stack(neighbours).uses.cameras == "required" and not opts.cameras:
            raise ConfigError("env.neighbours", neighbours, "a stack that flies without cameras with cameras=False (it sees only through its camera)")
        cfg = load_env_scenario(scenario, mode=neighbours, duration_s=duration_s)
        self.core = EnvCore(cfg, opts, [learner], reward)
        self.agent = self.core.names[0]
        self.observation_space = self.core.observations.space
        self.action_space = spaces.Box(self.core.low, self.core.high, dtype=np.float64)
        self.render_mode = render_mode
        self.metadata = {**self.metadata, "render_fps": opts.control_hz}

    def reset(self, *, seed: int | None = None, options: dict | None = None) -> tuple[dict, dict]:
        """Start an episode (``seed``: the scenario seed); the learner's first observation and an empty info."""
        super().reset(seed=seed)
        obs = self.core.start(self.core.episode_seed(seed))
        return obs[self.agent], {}

    def step(self, action: Any) -> tuple[dict, float, bool, bool, dict]:
        """One control step of the learner (its neighbours fly on): (observation, reward, terminated, truncated, info)."""
        if self.agent not in self.core.live:
            raise RuntimeError("step() after the episode ended: call reset()")
        obs, rewards, terminated, truncated, infos = self.core.step({self.agent: action})
        a = self.agent
        return obs[a], rewards[a], terminated[a], truncated[a], infos[a]

    def render(self) -> np.ndarray | None:
        """The run video's frame now (``rgb_array``)."""
        return self.core.render() if self.render_mode == "rgb_array" else None

    def flight_result(self):
        """End the episode and return its :class:`mpcde.flight.loop.RunResult` (the metrics ``mpcde fly`` writes)."""
        return self.core.result()

    def close(self) -> None:
        """Free PyBullet and the render pool."""
        self.core.close()
