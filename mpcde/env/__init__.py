"""The world as learning environments (``pip install -e ".[env]"``: pettingzoo, gymnasium).

* :class:`SwarmParallelEnv` (PettingZoo ``ParallelEnv``): every drone a learner.
* :class:`SingleDroneEnv` (Gymnasium, id ``mpcde/SingleDrone-v0``): one learner
  among drones flown by one of the package's stacks.
* :class:`StackPolicy`: a stack (``denied``, ``comm``, ...) as a policy over
  the observations.
* :class:`EnvOptions`: control rate, action mode, observation entries, slots, bounds, reward weights.

Importing this package registers ``mpcde/SingleDrone-v0`` with Gymnasium.
"""

from __future__ import annotations

try:
    import gymnasium
    import pettingzoo  # noqa: F401
except ModuleNotFoundError as e:  # the core install has no learning libraries
    raise ModuleNotFoundError(f"mpcde.env needs {e.name}: pip install -e '.[env]' (scripts/setup.sh installs it)", name=e.name) from None

from mpcde.env.options import EnvOptions
from mpcde.env.parallel import SwarmParallelEnv
from mpcde.env.policies import StackPolicy
from mpcde.env.single import SingleDroneEnv

__all__ = ["ENV_ID", "EnvOptions", "SingleDroneEnv", "StackPolicy", "SwarmParallelEnv"]

ENV_ID = "mpcde/SingleDrone-v0"
if ENV_ID not in gymnasium.registry:
    gymnasium.register(id=ENV_ID, entry_point="mpcde.env.single:SingleDroneEnv")
