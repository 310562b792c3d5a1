"""The onboard agent of one drone: what it sees, what it decides.

An agent receives only what the drone itself would have: its camera frames
(:class:`sim.types.RgbdFrame`, no segmentation), its own pose estimate
(:class:`sim.types.PoseEstimate`) and its radio inbox
(:class:`sim.types.RadioMessage`). It never receives another drone's ground
truth: tests/unit/test_import_rules.py holds the onboard room's imports to
this, and tests/integration/test_fly.py checks what the loop hands an agent.

:class:`OnboardAgent` is the interface every stack implements. The stacks:
:mod:`mpcde.onboard.placeholder` (a blind line), :mod:`mpcde.onboard.denied` (MP-CDE),
:mod:`mpcde.onboard.dmpc` (DMPC) and :mod:`mpcde.onboard.auto` (both, with the
fallback between them); :mod:`mpcde.onboard.factory` picks one per ``planner.kind``.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Protocol

from perception.types import Detection
from sim.types import FlatOutputReference, PoseEstimate, RadioMessage, RgbdFrame

__all__ = ["AgentCounters", "OnboardAgent"]


class OnboardAgent(Protocol):
    """What the loop may call on an onboard agent, and all it may hand it.

    Inputs are only the drone's own pose estimate, its own camera frames (with
    the boxes its own detector found in that frame, for an agent that sets
    ``detector_request``; the loop runs the drones' detectors in one batch,
    :mod:`mpcde.onboard.detection`) and its radio inbox; outputs are a
    controller reference and a broadcast payload. Every planner stack
    (placeholder, DMPC, MP-CDE) implements this.
    """

    drone_id: int
    counters: "AgentCounters"

    def on_pose_estimate(self, estimate: PoseEstimate) -> None: ...

    def on_frame(self, frame: RgbdFrame, detections: list[Detection] | None = None) -> None: ...

    def on_radio(self, messages: list[RadioMessage]) -> None: ...

    def outgoing(self, time_s: float) -> Any | None: ...

    def reference(self, time_s: float) -> FlatOutputReference: ...


@dataclass
class AgentCounters:
    """What the agent has received (for reports)."""

    frames: int = 0
    messages: int = 0
    plans: int = 0


