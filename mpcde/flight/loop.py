"""A flight from a scenario to its result: prepare (check and resolve), fly to the end, the log and the result types.

The loop itself, tick by tick, is :class:`mpcde.flight.session.FlightSession`;
the run's data types are in :mod:`mpcde.flight.run_types` (re-exported here)
(DESIGN.md section 3); :func:`run_scenario` builds the scenario's agents and
steps a session to its end. The session owns ground truth; agents get only
frames, their own estimate and their inbox.
"""

from __future__ import annotations

from collections.abc import Mapping

from mpcde.config.layout import build_layout, check_layout, resolve_obstacles
from mpcde.config.resolve import resolve
from mpcde.config.scenario import ScenarioConfig
from mpcde.flight.metrics import pose_error_m
from mpcde.flight.run_types import PreparedRun, RunLog, RunResult
from mpcde.flight.session import FlightSession, FrameSink
from mpcde.onboard.base import OnboardAgent
from mpcde.onboard.budget import ComputeBudget
from mpcde.stacks.build import make_agent
from sim.rendering.pool_keeper import PoolKeeper

__all__ = ["PreparedRun", "RunLog", "RunResult", "open_session", "pose_error_m", "prepare_run", "run_scenario"]


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


def open_session(
    prepared: PreparedRun, *, agents: Mapping[int, OnboardAgent] | None = None,
    frame_sink: FrameSink | None = None, progress: bool = False, pools: PoolKeeper | None = None,
) -> FlightSession:  # fmt: skip
    """A :class:`FlightSession` of ``prepared``'s scenario at time 0, each drone flown by the scenario's agent.

    The one place a flight's agents are built from its resolved config
    (``prepared.config``, so they are the agents ``mpcde fly`` flies), all
    booking into one fresh :class:`ComputeBudget`. The caller steps the
    session and must ``close()`` it (its render pool holds processes and
    shared memory).

    Args:
        prepared: from :func:`prepare_run`.
        agents: drone id -> an agent that flies that drone instead of the
            scenario's own (the PettingZoo environment's externally driven
            drones, a traced agent); every other drone gets ``make_agent``'s.
        frame_sink, progress: as in :func:`run_scenario`.
        pools: where the render pool is taken from, kept across flights (the environments' resets;
            :class:`mpcde.flight.session.FlightSession`); None: the session's own.
    """
    given = dict(agents or {})
    n = prepared.starts.shape[0]
    if any(not 0 <= int(i) < n for i in given):
        raise ValueError(f"agents: drone ids must be in 0..{n - 1}, got {sorted(given)}")
    budget = ComputeBudget()
    cfg = prepared.config
    flown = [given[i] if i in given else make_agent(cfg, i, prepared.goals, prepared.obstacles, budget) for i in range(n)]
    return FlightSession(prepared, flown, budget, frame_sink=frame_sink, progress=progress, pools=pools)


def run_scenario(prepared: PreparedRun, frame_sink: FrameSink | None = None, progress: bool = False, pools: PoolKeeper | None = None) -> RunResult:
    """Fly a prepared scenario to its end: a :class:`mpcde.flight.session.FlightSession` of the scenario's agents, stepped until done.

    Args:
        prepared: from :func:`prepare_run`.
        frame_sink: called at every camera delivery with (time, truth, latest
            frame per drone); the video writer is one.
        progress: show a progress bar over simulated time.
        pools: as in :func:`open_session` (a sweep's worker keeps one across its flights).
    """
    session = open_session(prepared, frame_sink=frame_sink, progress=progress, pools=pools)
    try:
        while not session.done:
            session.step()
        return session.result()
    finally:
        session.close()
