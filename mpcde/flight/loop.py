"""A flight from a scenario to its result: prepare (check and resolve), fly to the end, the log and the result types.

The loop itself, tick by tick, is :class:`mpcde.flight.session.FlightSession`
(DESIGN.md section 3); :func:`run_scenario` builds the scenario's agents and
steps a session to its end. The session owns ground truth; agents get only
frames, their own estimate and their inbox.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from mpcde.config.layout import build_layout, check_layout, resolve_obstacles
from mpcde.config.resolve import resolve
from mpcde.config.scenario import ScenarioConfig
from mpcde.flight.session import FlightSession, FrameSink
from mpcde.onboard.budget import ComputeBudget
from mpcde.onboard.factory import make_agent
from sim.types import ObstacleSpec

__all__ = ["PreparedRun", "RunLog", "RunResult", "pose_error_m", "prepare_run", "run_scenario"]


@dataclass
class RunLog:
    """State log at ``run.log_rate_hz``; arrays are stacked at the end.

    Keys of :attr:`arrays` (T samples, N drones): ``time_s`` (T,),
    ``pos_world`` (T, N, 3), ``vel_world`` (T, N, 3), ``yaw`` (T, N),
    ``est_pos_world`` (T, N, 3), ``ref_pos_world`` (T, N, 3), ``failed`` (T, N).
    """

    rows: dict[str, list] = field(default_factory=lambda: {k: [] for k in ("time_s", "pos_world", "vel_world", "yaw", "est_pos_world", "ref_pos_world", "failed")})

    def append(self, **values: Any) -> None:
        """Add one sample (keyword per key)."""
        for k, v in values.items():
            self.rows[k].append(np.asarray(v))

    @property
    def arrays(self) -> dict[str, np.ndarray]:
        """The log as stacked arrays."""
        return {k: np.stack(v) if v else np.zeros((0,)) for k, v in self.rows.items()}


@dataclass
class RunResult:
    """What a run produced (before it is written to disk)."""

    config: ScenarioConfig
    obstacles: tuple[ObstacleSpec, ...]
    starts: np.ndarray
    goals: np.ndarray
    metrics: dict[str, Any]
    log: RunLog


@dataclass(frozen=True)
class PreparedRun:
    """A validated scenario with its resolved layout and obstacles."""

    config: ScenarioConfig
    starts: np.ndarray
    goals: np.ndarray
    obstacles: tuple[ObstacleSpec, ...]


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


def pose_error_m(arrays: dict[str, np.ndarray]) -> dict[str, float | None]:
    """The drones' pose-estimate position error over the logged flight [m]: mean, max, and mean at the end (drift)."""
    est, true = arrays.get("est_pos_world"), arrays.get("pos_world")
    if est is None or true is None or est.ndim != 3 or not est.size:
        return {"pose_error_mean_m": None, "pose_error_max_m": None, "pose_error_final_m": None}
    err = np.linalg.norm(est - true, axis=-1)  # (T, N)
    return {"pose_error_mean_m": float(err.mean()), "pose_error_max_m": float(err.max()), "pose_error_final_m": float(err[-1].mean())}
