"""A flight from a scenario to its result: prepare (check and resolve), fly to the end, the log and the result types.

The loop itself, tick by tick, is :class:`mpcde.flight.session.FlightSession`;
the run's data types are in :mod:`mpcde.flight.run_types` (re-exported here)
(DESIGN.md section 3); :func:`run_scenario` builds the scenario's agents and
steps a session to its end. The session owns ground truth; agents get only
frames, their own estimate and their inbox.
"""

from __future__ import annotations

from mpcde.config.layout import build_layout, check_layout, resolve_obstacles
from mpcde.config.resolve import resolve
from mpcde.config.scenario import ScenarioConfig
from mpcde.flight.metrics import pose_error_m
from mpcde.flight.run_types import PreparedRun, RunLog, RunResult
from mpcde.flight.session import FlightSession, FrameSink
from mpcde.onboard.budget import ComputeBudget
from mpcde.onboard.factory import make_agent

__all__ = ["PreparedRun", "RunLog", "RunResult", "pose_error_m", "prepare_run", "run_scenario"]


def prepare_run(cfg: ScenarioConfig) -> PreparedRun:
    """Derive the settings that follow from others, resolve layout and obstacles and check them.

    Raises ConfigError, writes nothing. ``PreparedRun.config`` is the resolved
    scenario (:func:`mpcde.config.resolve.resolve`), the one the run folder's
    ``config.yaml`` holds.
    """
    cfg = resolve(cfg)
    starts, goals = build_layout(cfg.drones)
    obstacles = resolve_obstacles(cfg, starts, goals)
    check_layout(cfg, starts, goals, obstacles)
    return PreparedRun(cfg, starts, goals, obstacles)


def run_scenario(prepared: PreparedRun, frame_sink: FrameSink | None = None, progress: bool = False) -> RunResult:
    """Fly a prepared scenario to its end: a :class:`mpcde.flight.session.FlightSession` of the scenario's agents, stepped until done.

    Args:
        prepared: from :func:`prepare_run`.
        frame_sink: called at every camera delivery with (time, truth, latest
            frame per drone); the video writer is one.
        progress: show a progress bar over simulated time.
    """
    cfg = prepared.config
    budget = ComputeBudget()
    agents = [make_agent(cfg, i, prepared.goals, prepared.obstacles, budget) for i in range(prepared.starts.shape[0])]
    session = FlightSession(prepared, agents, budget, frame_sink=frame_sink, progress=progress)
    try:
        while not session.done:
            session.step()
        return session.result()
    finally:
        session.close()
