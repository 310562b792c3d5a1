"""A flight's data types: the prepared scenario, the state log and the result (before it is written to disk)."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from mpcde.config.scenario import ScenarioConfig
from sim.types import ObstacleSpec

if TYPE_CHECKING:
    from mpcde.flight.observed_area import ObservedRaster

__all__ = ["PreparedRun", "RunLog", "RunResult"]


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
    observed: ObservedRaster | None = None
    """The cells each drone's camera saw (mpcde/flight/observed_area.py); None without cameras."""


@dataclass(frozen=True)
class PreparedRun:
    """A validated scenario with its resolved layout and obstacles."""

    config: ScenarioConfig
    starts: np.ndarray
    goals: np.ndarray
    obstacles: tuple[ObstacleSpec, ...]
