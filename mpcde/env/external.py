"""The onboard side of a drone that a learner flies: an :class:`mpcde.onboard.base.OnboardAgent` whose reference is the learner's action.

The session (:class:`mpcde.flight.session.FlightSession`) hands an
:class:`ExternalDrone` exactly what it hands a built-in stack: its own pose
estimate, its own camera frames with its own detector's boxes, and its radio
inbox. The drone keeps the newest of each for the observation
(:mod:`mpcde.env.observations`), runs the package's own tracker on its
detections when the observation has ``tracks`` (MP-CDE Sec. IV-B,
:class:`mpcde.onboard.perception.NeighbourPerception`; the session scores those
tracks for ``metrics.json`` as it scores a stack's), and flies the held action
(:class:`mpcde.env.actions.ActionHold`). It never sees another drone's ground truth.

At each radio round it broadcasts the held action as a plan
(:class:`sim.types.PlanMessage`, ``plan_samples`` samples over ``plan_horizon_s``),
so that radio-using neighbours (``comm``, ``auto``, ...) can plan around a learner,
unless broadcasting is off.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from mpcde.config.perception import PerceptionConfig
from mpcde.env.actions import ActionHold
from mpcde.onboard.base import AgentCounters, OnboardAgent
from mpcde.onboard.perception import onboard_perception
from perception.types import Detection
from sim.rotations import rotation_from_quat_xyzw, yaw_from_rotation
from sim.types import FlatOutputReference, PlanMessage, PoseEstimate, RadioMessage, RgbdFrame

__all__ = ["ExternalDrone"]


class ExternalDrone(OnboardAgent):
    """A drone flown by an environment's action.

    Args:
        drone_id: the drone's index.
        action_mode: ``"velocity"`` or ``"reference"`` (:mod:`mpcde.env.actions`).
        perceive: run the detector and the tracker on its frames (``tracks`` or
            ``detections`` observed).
        perception_config: the scenario's ``perception:`` section.
        broadcast: broadcast the held action as a plan at radio rounds.
        plan_samples, plan_horizon_s: the broadcast plan's samples and horizon [s].
    """

    def __init__(
        self, drone_id: int, action_mode: str, perceive: bool, perception_config: PerceptionConfig,
        broadcast: bool = True, plan_samples: int = 16, plan_horizon_s: float = 3.0,
    ) -> None:  # fmt: skip
        self.drone_id = drone_id
        self.counters = AgentCounters()
        self.hold = ActionHold(action_mode)
        self.perception, self.detector_request = onboard_perception(perceive, perception_config)
        self.broadcast = broadcast
        self.plan_offsets_s = np.linspace(0.0, plan_horizon_s, plan_samples)
        self.estimate: PoseEstimate | None = None
        self.frame: RgbdFrame | None = None
        self.detections: list[Detection] | None = None
        self.frame_serial = 0  # frames received so far (an observation cache key)
        self.plans: dict[int, RadioMessage] = {}  # newest plan message per sender
        self.frozen = False

    def on_pose_estimate(self, estimate: PoseEstimate) -> None:
        """Keep the newest own pose estimate."""
        self.estimate = estimate

    def on_frame(self, frame: RgbdFrame, detections: list[Detection] | None = None) -> None:
        """Keep the newest frame and its boxes; update the tracks with them."""
        self.frame, self.detections = frame, detections
        self.frame_serial += 1
        self.counters.frames += 1
        if self.perception is not None and detections is not None:
            self.perception.update(frame, detections)

    def on_radio(self, messages: list[RadioMessage]) -> None:
        """Keep each neighbour's newest plan."""
        self.counters.messages += len(messages)
        for m in messages:
            if isinstance(m.payload, PlanMessage) and m.payload.sender_id != self.drone_id:
                old = self.plans.get(m.sender_id)
                if old is None or m.payload.time_s >= old.payload.time_s:
                    self.plans[m.sender_id] = m
                    self.counters.plans += 1

    def _round_message(self, time_s: float) -> PlanMessage | None:
        """The held action over the plan horizon, broadcast so that neighbours can plan around this drone."""
        if not self.broadcast:
            return None
        t = time_s + self.plan_offsets_s
        p, v = self.hold.pos_vel_at(t)
        return PlanMessage(sender_id=self.drone_id, time_s=time_s, times_s=t, pos_world=p, vel_world=v)

    def reference(self, time_s: float) -> FlatOutputReference:
        """The held action's reference at tick ``time_s`` [s]."""
        return self.hold.reference(time_s)

    def yaw(self) -> float:
        """The heading [rad] of the own pose estimate (0 before one)."""
        if self.estimate is None:
            return 0.0
        return float(yaw_from_rotation(rotation_from_quat_xyzw(self.estimate.quat_xyzw)))

    def act(self, time_s: float, action: np.ndarray | None) -> None:
        """Hold ``action`` from ``time_s`` [s] (None: hover where the drone estimates it is)."""
        if self.frozen:
            return
        pos = self.estimate.pos_world if self.estimate is not None else np.zeros(3)
        if action is None:
            self.hold.hover(time_s, pos, self.yaw())
        elif self.hold.mode == "velocity":  # anchored at the own estimate
            self.hold.set(time_s, action, pos, self.yaw())
        else:
            self.hold.set(time_s, action, pos, 0.0)  # a reference action needs no anchor

    def freeze(self, time_s: float) -> None:
        """Terminated: hover from now on at the current reference's position and heading; actions are ignored."""
        if not self.frozen:
            ref = self.hold.reference(time_s)
            self.hold.hover(time_s, ref.pos_world, ref.yaw)
            self.frozen = True

    def extra_metrics(self) -> dict[str, Any] | None:
        """The tracker's counts when it tracks (as the built-in stacks report theirs)."""
        if self.perception is None:
            return None
        return self.perception.counts.metrics()
