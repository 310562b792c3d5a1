"""One drone's neighbour perception: its detections -> 3-D measurements -> Kalman tracks.

MP-CDE Sec. IV-B wired onboard: each camera frame's detections (the drone's
own detector on the drone's own frame, :class:`mpcde.onboard.detection.BatchedDetector`)
are back-projected with the frame's depth and the drone's *estimated* camera
pose (Eq. 7-8, :func:`perception.backprojection.backproject`) and fed to the
adaptive-covariance multi-target tracker (Eq. 9-12,
:class:`perception.tracker.MultiTargetTracker`). The planners read the
tracks as :class:`perception.types.NeighborPrediction` (confirmed and coasting
tracks; ``stamp_s`` is the time each was last seen).

The back-projection's pose-noise terms are the drone's own localisation
white noise (the uncertainty its VIO reports), as in ``mpcde eval-tracking``'s
pipeline source. Nothing here sees another drone's ground truth.

Every planner stack that perceives (DESIGN.md: "Perception runs in every
mode, so tracks are warm when an outage starts") takes its settings from the
scenario's ``perception:`` section, :class:`PerceptionConfig`.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Sequence

import numpy as np

from mpcde.config.perception import DetectorRequest, PerceptionConfig
from perception.backprojection import BackprojectionConfig, backproject
from perception.tracker import MultiTargetTracker
from perception.tracker_config import TrackerConfig
from perception.types import Detection, NeighborPrediction
from sim.types import RgbdFrame

__all__ = ["NeighbourPerception", "PerceptionConfig", "PerceptionCounts", "onboard_perception"]


@dataclass
class PerceptionCounts:
    """What the perception of one drone has handled (for metrics).

    Attributes:
        detections: detector boxes.
        measurements: boxes back-projected to a 3-D measurement.
        without_depth: boxes dropped for lack of valid depth.
        update_ms: wall time [ms] of each back-projection + tracker update (one per frame).
    """

    detections: int = 0
    measurements: int = 0
    without_depth: int = 0
    update_ms: list = field(default_factory=list)

    def metrics(self) -> dict:
        """The counts for metrics.json (``tracking_ms_median``: median update time [ms], null before a frame)."""
        return {
            "detections": self.detections, "measurements": self.measurements,
            "detections_without_depth": self.without_depth,
            "tracking_ms_median": float(np.median(self.update_ms)) if self.update_ms else None,
        }  # fmt: skip


class NeighbourPerception:
    """Back-projection + tracker of one drone (MP-CDE Sec. IV-B).

    Args:
        tracker: tracker settings (MP-CDE Table I defaults).
        backprojection: depth window and covariance model of Eq. 7-8.
    """

    @classmethod
    def from_config(cls, config: PerceptionConfig) -> "NeighbourPerception":
        """The perception ``config`` describes."""
        return cls(config.tracker, config.backprojection)

    def __init__(self, tracker: TrackerConfig, backprojection: BackprojectionConfig) -> None:
        self.config = tracker
        self.tracker = MultiTargetTracker(tracker)
        self.backprojection = backprojection
        self.counts = PerceptionCounts()

    def update(self, frame: RgbdFrame, detections: Sequence[Detection]) -> None:
        """Back-project ``detections`` of ``frame`` and update the tracks to the frame time."""
        t0 = time.perf_counter()
        result = backproject(frame, detections, self.backprojection)
        self.tracker.update(frame.time_s, result.measurements)
        c = self.counts
        c.detections += len(detections)
        c.measurements += len(result.measurements)
        c.without_depth += int(result.skipped.size)
        c.update_ms.append(1e3 * (time.perf_counter() - t0))

    def predictions(self, time_s: float) -> list[NeighborPrediction]:
        """Confirmed and coasting tracks propagated to ``time_s`` [s] (Eq. 12); empty before the first frame."""
        last = self.tracker.time_s
        if last is None:
            return []
        return self.tracker.predictions(max(float(time_s), last))


def onboard_perception(
    perceive: bool, config: PerceptionConfig | None, shared: NeighbourPerception | None = None
) -> tuple[NeighbourPerception | None, DetectorRequest | None]:
    """An agent's perception and the detector request the loop serves it (both None when ``perceive`` is off).

    Args:
        perceive: the agent's ``perceive_neighbours`` setting.
        config: the scenario's ``perception:`` settings; None: the defaults.
        shared: a perception to use instead of a new one (the ``auto`` agent's halves share one).
    """
    if not perceive:
        return None, None
    config = config if config is not None else PerceptionConfig()
    return (shared if shared is not None else NeighbourPerception.from_config(config)), config.detector_request()
