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
fallback between them); :mod:`mpcde.stacks.build` picks one per ``planner.kind``.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from dataclasses import dataclass
from typing import Any

import numpy as np

from mpcde.config.perception import DetectorRequest
from perception.types import Detection
from planners.dmpc.plan_sampler import PlanSampler, sample_or_hover
from sim.rotations import rotation_from_quat_xyzw, yaw_from_rotation
from sim.types import FlatOutputReference, PoseEstimate, RadioMessage, RgbdFrame

__all__ = ["AgentCounters", "OnboardAgent", "PlanFollowingAgent", "SampledPlanAgent"]


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
        maps_frames: whether the agent integrates every frame into a map of its own
            (MP-CDE's stacks): the heaviest per-frame work then stays in the flight's
            main process, so by default the loop leaves it a core of its own and
            renders (and detects) on the others (:class:`mpcde.flight.session.FlightSession`).
    """

    drone_id: int
    counters: "AgentCounters"
    detector_request: DetectorRequest | None = None
    perception: Any | None = None
    maps_frames: bool = False

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

    def _payloads(self, messages: list[RadioMessage], kind: type) -> list[Any]:
        """Count the inbox ``messages`` and return the payloads of type ``kind`` that other drones sent."""
        self.counters.messages += len(messages)
        return [m.payload for m in messages if isinstance(m.payload, kind) and m.payload.sender_id != self.drone_id]


class PlanFollowingAgent(OnboardAgent):
    """A stack that flies a planned state at a fixed heading (the DMPC family: DMPC, ADMM, MLR-DMPC).

    Attributes:
        yaw: the heading [rad] the drone keeps (its first pose estimate's, or the one a hand-over sets).
    """

    yaw: float

    @abstractmethod
    def reference_state(self, time_s: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Position [m], velocity [m/s], acceleration [m/s^2] (3,) of the reference at ``time_s`` [s]."""

    def reference(self, time_s: float) -> FlatOutputReference:
        """Controller reference at ``time_s`` [s]: :meth:`reference_state` at the heading ``yaw``, no yaw rate."""
        pos, vel, acc = self.reference_state(time_s)
        return FlatOutputReference(pos_world=pos, vel_world=vel, acc_world=acc, yaw=self.yaw, yaw_rate=0.0)


class SampledPlanAgent(PlanFollowingAgent):
    """A :class:`PlanFollowingAgent` whose reference is its current :class:`planners.dmpc.types.DmpcPlan`
    (DMPC, ADMM), sampled by ``_sampler``; before the first plan it hovers at the start.

    Attributes:
        latest_estimate: the drone's newest pose estimate (None before the first).
        start_world: (3,) [m] position of the first pose estimate, which also fixes ``yaw``.
        _sampler: the current plan's :class:`planners.dmpc.plan_sampler.PlanSampler` (None: no plan yet).
    """

    latest_estimate: PoseEstimate | None
    start_world: np.ndarray | None
    _sampler: PlanSampler | None

    def on_pose_estimate(self, estimate: PoseEstimate) -> None:
        """Take the drone's own pose estimate (the first fixes the start and the heading)."""
        if self.latest_estimate is None:
            self.start_world = np.asarray(estimate.pos_world, float).copy()
            self.yaw = float(yaw_from_rotation(rotation_from_quat_xyzw(estimate.quat_xyzw)))
        self.latest_estimate = estimate

    def reference_state(self, time_s: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Position [m], velocity [m/s], acceleration [m/s^2] (3,) of the current plan at ``time_s`` [s]
        (a hover at the start before the first plan)."""
        return sample_or_hover(self._sampler, self.start_world, time_s)


@dataclass
class AgentCounters:
    """What the agent has received (for reports)."""

    frames: int = 0
    messages: int = 0
    plans: int = 0


