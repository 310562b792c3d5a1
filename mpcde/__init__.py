"""mpcde: quadrotor swarms in simulation when the radio cannot be trusted.

The Python API (``docs/design.md``, "Python API"):

* :func:`mpcde.fly` flies a scenario headless and returns its
  :class:`~mpcde.flight.loop.RunResult` (metrics, state log), optionally
  writing the run folder that ``mpcde fly`` writes;
* :func:`mpcde.load_scenario` reads and checks a scenario file or built-in name;
* :func:`mpcde.all_stacks` lists the onboard stacks (the registry, :mod:`mpcde.stacks`),
  and :func:`mpcde.register_stack` adds one (a :class:`mpcde.Stack`) from a script.

They are imported on first use, so ``import mpcde`` (and reading a scenario)
loads no simulator, detector or planner.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from mpcde.numerics import apply as _apply_numerics

_apply_numerics()  # before numpy, OpenBLAS, torch or numba load here or in a child (mpcde/numerics.py)

from sim.kernel_cache import use_versioned_cache  # noqa: E402

use_versioned_cache()  # before any kernel of this package is compiled (sim/kernel_cache.py)

if TYPE_CHECKING:
    from mpcde.api import fly, load_scenario
    from mpcde.stacks import AgentContext, Stack, Uses, get_stack, register_stack
    from mpcde.stacks import stacks as all_stacks
    from mpcde.config.scenario import ScenarioConfig
    from mpcde.errors import ConfigError
    from mpcde.flight.loop import RunResult

__all__ = [
    "AgentContext", "ConfigError", "RunResult", "ScenarioConfig", "Stack", "Uses", "all_stacks", "fly", "get_stack",
    "load_scenario", "register_stack",
]  # fmt: skip

_WHERE = {
    "fly": "mpcde.api", "load_scenario": "mpcde.api",
    **{name: "mpcde.stacks" for name in ("AgentContext", "Stack", "Uses", "get_stack", "register_stack")},
    "ScenarioConfig": "mpcde.config.scenario", "ConfigError": "mpcde.errors", "RunResult": "mpcde.flight.loop",
}


def __getattr__(name: str) -> Any:
    if name in _WHERE:
        import importlib

        return getattr(importlib.import_module(_WHERE[name]), name)
    if name == "all_stacks":  # mpcde.stacks is the registry's package, so its stacks() is re-exported under this name
        from mpcde.stacks import stacks

        return stacks
    raise AttributeError(f"module 'mpcde' has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted(__all__)
