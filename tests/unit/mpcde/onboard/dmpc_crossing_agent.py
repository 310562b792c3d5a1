"""A lone DMPC agent of the crossing scenario, for the agent tests that drive its radio rounds by hand."""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from mpcde.config.scenario import load_scenario
from mpcde.onboard.dmpc import DmpcAgent
from mpcde.stacks.build import make_agent


def crossing_dmpc_agent(goals: np.ndarray, **dmpc) -> DmpcAgent:
    """Drone 0 of ``crossing`` as a DMPC agent (no start delay, perception off), ``goals`` (n, 3) [m], ``dmpc`` overrides."""
    cfg = load_scenario("crossing")
    cfg = replace(cfg, planner=replace(cfg.planner, kind="dmpc", start_delay_s=0.0), dmpc=replace(cfg.dmpc, perceive_neighbours=False, **dmpc))
    agent = make_agent(cfg, 0, goals, ())
    assert isinstance(agent, DmpcAgent)
    return agent
