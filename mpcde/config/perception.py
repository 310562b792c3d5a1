"""The ``perception:`` section of a scenario: every perceiving drone's detector, tracker and back-projection."""

from __future__ import annotations

from dataclasses import dataclass, field

from perception.backprojection_config import BackprojectionConfig
from perception.tracker_config import TrackerConfig
from sim.checks import ConfigError

__all__ = ["DetectorRequest", "PerceptionConfig"]


@dataclass(frozen=True)
class DetectorRequest:
    """What an agent asks of the detector (its ``detector_request`` attribute).

    Attributes:
        weights: checkpoint path; None for the shipped weights.
        score_threshold: keep detections scoring >= this; None: the checkpoint's own.
        field: the scenario field that set ``weights`` (named in the error if they do not load).
        precision: the network's arithmetic, "auto", "float32" or "bfloat16"
            (:func:`perception.detector.detector.resolve_precision`).
    """

    weights: str | None = None
    score_threshold: float | None = None
    field: str = "detector_weights"
    precision: str = "auto"



@dataclass(frozen=True)
class PerceptionConfig:
    """Neighbour perception of every drone (the ``perception:`` mapping of a scenario file).

    Attributes:
        detector_weights: detector checkpoint; None: the shipped weights.
        detector_score_threshold: keep detections scoring >= this; None: the checkpoint's own.
        detector_precision: arithmetic of the detector's forward pass: "float32",
            "bfloat16", or "auto" (bfloat16 where the CPU has bfloat16 dot-product
            instructions, float32 elsewhere). Its time and its precision and recall
            against float32: docs/results/detector.md#bfloat16-against-float32;
            metrics.json records the one used.
        tracker: neighbour tracker settings (MP-CDE Sec. IV-B, Table I).
        backprojection: detection back-projection settings (Eq. 7-8); its pose-noise
            terms are replaced by the scenario's ``pose_estimate`` white noise.
    """

    detector_weights: str | None = None
    detector_score_threshold: float | None = None
    detector_precision: str = "auto"
    tracker: TrackerConfig = field(default_factory=TrackerConfig)
    backprojection: BackprojectionConfig = field(default_factory=BackprojectionConfig)

    def __post_init__(self) -> None:
        thr = self.detector_score_threshold
        if thr is not None and not (isinstance(thr, (int, float)) and 0.0 <= thr <= 1.0):
            raise ConfigError("detector_score_threshold", thr, "a number in [0, 1] or null")
        if self.detector_precision not in ("auto", "float32", "bfloat16"):
            raise ConfigError("detector_precision", self.detector_precision, "allowed 'auto', 'float32' or 'bfloat16'")

    def detector_request(self) -> DetectorRequest:
        """What the loop's batched detector loads for an agent with this perception."""
        return DetectorRequest(self.detector_weights, self.detector_score_threshold, "perception.detector_weights", self.detector_precision)
