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

from abc import ABC, abstractmethod
from dataclasses import dataclass
from typing import Any

from mpcde.config.perception import DetectorRequest
from perception.types import Detection
from sim.types import FlatOutputReference, PoseEstimate, RadioMessage, RgbdFrame

__all__ = ["AgentCounters", "OnboardAgent"]


class OnboardAgent(ABC):
    """The interface of every onboard stack: all the loop calls, and all it hands an agent.

    Inputs are only the drone's own pose estimate (:meth:`on_pose_estimate`),
    its own camera frames with the boxes its own detector found in them
    (:meth:`on_frame`; the loop runs the drones' detectors in one batch for
    the agents whose ``detector_request`` is set, :mod:`mpcde.onboard.detection`)
    and its radio inbox (:meth:`on_radio`). At each radio round the loop calls
    :meth:`plan_round` (the stack's planning due at that round: a DMPC solve,
    an MLR round, an ADMM sub-round, the ``auto`` mode switch) and then
    :meth:`outgoing` (what that round broadcasts, computed by ``plan_round``).
    Between rounds it reads :meth:`reference` at the controller's rate. A stack
    that plans on frames instead (MP-CDE, Alg. 1) does so in ``on_frame``.

    Attributes:
        drone_id: index of the drone.
        counters: what the agent has received.
        detector_request: what the loop's batched detector loads for this
            agent; None: no detections (the frame comes with ``detections=None``).
        perception: the agent's neighbour tracks
            (:class:`mpcde.onboard.perception.NeighbourPerception`), which the
            loop scores against the truth for the metrics; None: it tracks nothing.
    """

    drone_id: int
    counters: "AgentCounters"
    detector_request: DetectorRequest | None = None
    perception: Any | None = None

    @abstractmethod
    def on_pose_estimate(self, estimate: PoseEstimate) -> None:
        """Take the drone's own pose estimate (the VIO stand-in's, at every camera tick)."""

    @abstractmethod
    def on_frame(self, frame: RgbdFrame, detections: list[Detection] | None = None) -> None:
        """Take one of the drone's own camera frames and its own detector's boxes on it (None: no detector)."""

    @abstractmethod
    def on_radio(self, messages: list[RadioMessage]) -> None:
        """Take this round's radio inbox (messages of earlier rounds that arrived)."""

    def plan_round(self, time_s: float) -> None:
        """Do the planning due at the radio round at ``time_s`` [s]; :meth:`outgoing` returns its broadcast."""
        self._outbox = self._round_message(time_s)

    def outgoing(self, time_s: float) -> Any | None:
        """What this round broadcasts (computed by :meth:`plan_round`; None: nothing). Computes nothing."""
        message, self._outbox = getattr(self, "_outbox", None), None
        return message

    @abstractmethod
    def _round_message(self, time_s: float) -> Any | None:
        """The stack's round at ``time_s`` [s]: plan, and return the payload to broadcast (None: nothing)."""

    @abstractmethod
    def reference(self, time_s: float) -> FlatOutputReference:
        """The controller's reference at ``time_s`` [s]."""

    def extra_metrics(self) -> dict[str, Any] | None:
        """This drone's statistics for ``metrics.json`` (under ``agents``); None: none."""
        return None


@dataclass
class AgentCounters:
    """What the agent has received (for reports)."""

    frames: int = 0
    messages: int = 0
    plans: int = 0


