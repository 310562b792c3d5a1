"""One drone's neighbour perception: its detections -> 3-D measurements -> Kalman tracks.

MP-CDE Sec. IV-B wired onboard: each camera frame's detections (the drone's
own detector on the drone's own frame, :class:`mpcde.onboard_detection.BatchedDetector`)
are back-projected with the frame's depth and the drone's *estimated* camera
pose (Eq. 7-8, :func:`perception.backprojection.backproject`) and fed to the
adaptive-covariance multi-target tracker (Eq. 9-12,
:class:`perception.tracker.MultiTargetTracker`). The planners read the
tracks as :class:`perception.types.NeighborPrediction` (confirmed and coasting
tracks; ``stamp_s`` is the time each was last seen).

The back-projection's pose-noise terms are the drone's own localisation
white noise (the uncertainty its VIO reports), as in ``mpcde eval-tracking``'s
pipeline source. Nothing here sees another drone's ground truth.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Sequence

from perception.backprojection import BackprojectionConfig, backproject
from perception.tracker import MultiTargetTracker
from perception.tracker_config import TrackerConfig
from perception.types import Detection, NeighborPrediction
from sim.types import RgbdFrame

__all__ = ["NeighbourPerception", "PerceptionCounts"]


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


class NeighbourPerception:
    """Back-projection + tracker of one drone (MP-CDE Sec. IV-B).

    Args:
        tracker: tracker settings (MP-CDE Table I defaults).
        backprojection: depth window and covariance model of Eq. 7-8.
    """

    def __init__(self, tracker: TrackerConfig, backprojection: BackprojectionConfig) -> None:
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
