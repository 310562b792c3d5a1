"""The communicating MINCO swarm (``planner.kind: minco_comm``): MP-CDE's planner fed by the radio, not the camera.

MP-CDE compares its denied swarm with EGO-Swarm (Zhou et al., ICRA 2021),
whose drones broadcast their trajectories and plan against the ones they
receive (Sec. V-B 3, Fig. 6). This package's analogue keeps everything of the
denied stack that is not about neighbours, with the same parameters (the
scenario's ``denied`` section): the own depth map, the A* front end, MINCO
with the swarm term, replanning. What changes:

* neighbours are the plans other drones broadcast (every radio round, each
  drone sends its current MINCO trajectory sampled every
  ``SAMPLE_S`` over ``HORIZON_S``), each kept for ``plan_memory_s`` after it
  was sent and extrapolated at constant velocity past its horizon; no
  detector, no tracker;
* the heading follows travel (``denied.active_yaw`` off): EGO-Swarm has no
  active perception;
* depth hits within :data:`EXCLUSION_M` of a neighbour's broadcast position
  are not mapped (``denied.map.neighbour_exclusion_m``, at least that), as
  EGO-Swarm removes the swarm's bodies from its map with the trajectories it
  receives: without a detector nothing else would keep a neighbour out of
  the map.

With ``radio.view_gated`` and ``radio.delay_s`` this is the paper's
view-gated EGO-Swarm and its R-MADER-like delayed variant. Onboard it sees
its own frames (for the map), its own estimate and its radio inbox.
"""

from __future__ import annotations

from dataclasses import replace
from typing import Any

import numpy as np

from mpcde.config.denied import DeniedAgentConfig
from mpcde.onboard.base import AgentCounters, OnboardAgent
from mpcde.onboard.budget import ComputeBudget
from mpcde.onboard.denied import DeniedAgent
from mpcde.onboard.dmpc import plan_prediction
from perception.types import Detection, NeighborPrediction
from sim.types import FlatOutputReference, PlanMessage, PoseEstimate, RadioMessage, RgbdFrame

__all__ = ["EXCLUSION_M", "HORIZON_S", "PLAN_MEMORY_S", "SAMPLE_S", "MincoCommAgent"]

HORIZON_S = 3.0
"""Length [s] of the broadcast plan."""
SAMPLE_S = 0.1
"""Spacing [s] of the broadcast plan's samples."""
PLAN_MEMORY_S = 1.0
"""A received plan is planned against until this long [s] after it was sent."""
EXCLUSION_M = 0.4
"""Depth hits this near [m] a neighbour's broadcast position are not mapped (the 0.1 m body plus prediction error)."""


class MincoCommAgent(OnboardAgent):
    """One drone of the communicating MINCO swarm (module docstring).

    Args:
        drone_id: the drone.
        goal_world: (3,) its goal [m].
        config: the denied stack's settings (neighbour perception and active yaw are turned off here).
        budget: the run's compute budget.
    """

    def __init__(self, drone_id: int, goal_world: np.ndarray, config: DeniedAgentConfig, budget: ComputeBudget | None = None) -> None:
        self.drone_id = drone_id
        own = replace(
            config, perceive_neighbours=False, active_yaw=False, flight_level_spacing_m=float("inf"),
            map=replace(config.map, neighbour_exclusion_m=max(config.map.neighbour_exclusion_m, EXCLUSION_M)),
        )  # fmt: skip
        self.denied = DeniedAgent(drone_id, goal_world, own, None, budget=budget, neighbour_source=self._neighbours)
        self.counters = AgentCounters()
        self.detector_request = None
        self.perception = None
        self.maps_frames = True
        self.plans: dict[int, PlanMessage] = {}
        self.plans_received = 0

    def on_pose_estimate(self, estimate: PoseEstimate) -> None:
        """The MINCO stack takes its own estimate."""
        self.denied.on_pose_estimate(estimate)

    def on_frame(self, frame: RgbdFrame, detections: list[Detection] | None = None) -> None:
        """Map the frame and replan if due (no detections: neighbours come from the radio)."""
        self.counters.frames += 1
        self.denied.on_frame(frame, None)

    def on_radio(self, messages: list[RadioMessage]) -> None:
        """Keep each neighbour's newest plan."""
        for plan in self._payloads(messages, PlanMessage):
            old = self.plans.get(plan.sender_id)
            if old is None or plan.time_s > old.time_s:
                self.plans[plan.sender_id] = plan
                self.plans_received += 1

    def _neighbours(self, t: float, count: bool = True) -> list[NeighborPrediction]:
        """The plans heard within :data:`PLAN_MEMORY_S`, as exact radio predictions."""
        return [plan_prediction(j, m) for j, m in sorted(self.plans.items()) if t - m.time_s <= PLAN_MEMORY_S]

    def _round_message(self, time_s: float) -> PlanMessage | None:
        """The own plan over the next :data:`HORIZON_S` (the hover point before the first plan; None before an estimate)."""
        d = self.denied
        if d.latest_estimate is None:
            return None
        times = time_s + SAMPLE_S * np.arange(int(round(HORIZON_S / SAMPLE_S)) + 1)
        if d.trajectory is None:
            pos = np.repeat(np.asarray(d.hover_world, float)[None], times.size, axis=0)
            vel = np.zeros_like(pos)
        else:
            tau = np.clip(times - d.trajectory.t0_s, 0.0, d.trajectory.total_duration)
            pos, vel = d.trajectory.pos(tau), d.trajectory.vel(tau)
        return PlanMessage(sender_id=self.drone_id, time_s=time_s, times_s=times, pos_world=pos, vel_world=vel)

    def reference(self, time_s: float) -> FlatOutputReference:
        """The MINCO trajectory's reference, heading along travel."""
        return self.denied.reference(time_s)

    def extra_metrics(self) -> dict[str, Any]:
        """The MINCO stack's statistics and the plans heard."""
        return {**self.denied.extra_metrics(), "plans_received": self.plans_received}
