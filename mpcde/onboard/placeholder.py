"""The PLACEHOLDER stack (``planner.kind: min_jerk_line``, ``--mode placeholder``).

A minimum-jerk straight line to the goal (:mod:`planners.min_jerk_line`); it
keeps the latest frame and the neighbours' latest broadcast plans and plans
nothing around them: the baseline every other stack must beat.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from mpcde.onboard.base import AgentCounters, OnboardAgent
from perception.types import Detection
from planners.min_jerk_line import MinJerkLine
from sim.types import FlatOutputReference, PlanMessage, PoseEstimate, RadioMessage, RgbdFrame

__all__ = ["Agent"]


@dataclass
class Agent(OnboardAgent):
    """One drone's onboard stack with the PLACEHOLDER planner (``planner.kind: min_jerk_line``).

    Attributes:
        drone_id: index of the drone.
        goal_world: (3,) goal [m].
        cruise_speed_mps: placeholder line's peak speed [m/s].
        start_delay_s: hover time before departure [s].
    """

    drone_id: int
    goal_world: np.ndarray
    cruise_speed_mps: float
    start_delay_s: float
    plan: MinJerkLine | None = None
    latest_frame: RgbdFrame | None = None
    latest_estimate: PoseEstimate | None = None
    neighbour_plans: dict[int, PlanMessage] = field(default_factory=dict)
    counters: AgentCounters = field(default_factory=AgentCounters)

    def on_pose_estimate(self, estimate: PoseEstimate) -> None:
        """Take the drone's own pose estimate; plans once, from the first one."""
        self.latest_estimate = estimate
        if self.plan is None:
            self.plan = MinJerkLine.plan(estimate.pos_world, self.goal_world, estimate.time_s + self.start_delay_s, self.cruise_speed_mps)

    def on_frame(self, frame: RgbdFrame, detections: list[Detection] | None = None) -> None:
        """Take one camera frame (the placeholder does not perceive; ``detections`` is None)."""
        self.latest_frame = frame
        self.counters.frames += 1

    def on_radio(self, messages: list[RadioMessage]) -> None:
        """Take the radio inbox; keeps each neighbour's newest plan."""
        for m in messages:
            self.counters.messages += 1
            if isinstance(m.payload, PlanMessage):
                old = self.neighbour_plans.get(m.sender_id)
                if old is None or m.payload.time_s > old.time_s:
                    self.neighbour_plans[m.sender_id] = m.payload
                    self.counters.plans += 1

    def _round_message(self, time_s: float, horizon_s: float = 3.0, n_samples: int = 16) -> PlanMessage | None:
        """This drone's plan to broadcast: samples over ``horizon_s`` from ``time_s``."""
        if self.plan is None:
            return None
        t = time_s + np.linspace(0.0, horizon_s, n_samples)
        p, v, _ = self.plan.sample(t)
        return PlanMessage(sender_id=self.drone_id, time_s=time_s, times_s=t, pos_world=p, vel_world=v)

    def reference(self, time_s: float) -> FlatOutputReference:
        """Controller reference at ``time_s`` [s] (hover where it is until planned)."""
        if self.plan is None:
            est = self.latest_estimate
            return FlatOutputReference.hover(est.pos_world if est is not None else np.zeros(3))
        return self.plan.reference(time_s)
