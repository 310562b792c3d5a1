"""ORCA as a third-party mpcde stack: ``pip install examples/orca_stack``, then ``mpcde fly crossing --mode orca``.

:data:`STACK` is the registry entry the ``mpcde.stacks`` entry point names
(pyproject.toml). The contract it meets: mpcde's docs/stacks.md.
"""

from __future__ import annotations

from typing import Any

from mpcde.config.bounds import Bound
from mpcde.stacks import AgentContext, Stack, Uses
from mpcde_orca.config import OrcaConfig

__all__ = ["STACK", "OrcaConfig"]


def make_orca_agent(ctx: AgentContext) -> Any:
    """One drone's ORCA agent (the scenario's ``orca`` section, its cruise speed when it sets one)."""
    from mpcde_orca.agent import OrcaAgent

    cfg, settings = ctx.config, ctx.settings
    speed = cfg.planner.cruise_speed_mps or settings.max_speed_mps
    return OrcaAgent(
        ctx.drone_id, ctx.goal_world, settings, cfg.perception, cfg.physics.quadrotor.robot_radius_m, speed,
        cfg.planner.start_delay_s,
    )  # fmt: skip


STACK = Stack(
    name="orca",
    factory=make_orca_agent,
    summary="ORCA (reciprocal velocity obstacles) on the drone's own camera tracks; no static obstacles",
    uses=Uses(cameras="required"),
    section="orca",
    config_type=OrcaConfig,
    ranges={OrcaConfig: {"horizon_s": Bound(0.1, 20, "s"), "max_speed_mps": Bound(0.05, 10, "m/s")}},
)
