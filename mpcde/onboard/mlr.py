"""MLR-DMPC in the physics loop (``planner.kind: mlr``, ``mpcde fly --mode mlr``; DMPC-Swarm Sec. 4).

The algorithm is :mod:`planners.dmpc.mlr` (compute units, Alg. 1; UAVs, Eq. 10;
information trackers, Alg. 2; event trigger, App. A; QP, Eq. 13); the
kinematic round-based driver of the paper's experiments is
:mod:`mpcde.evals.mlr_swarm`. This module flies it on the simulated quadrotors.
Choices, where the paper's setting (separate CU nodes, a synchronous
round-robin radio) and the loop differ:

* **Drones host the compute units.** The paper's M CUs are separate radio
  nodes beside the N UAVs. The loop's radio has only the N drones as nodes, so
  the first M drones (M = ``mlr.num_compute_units``, 1 <= M < N) each run one
  CU onboard: drone w hosts CU w. Every drone runs the UAV part.
* **One payload per drone and round.** Each round the drone broadcasts one
  :class:`planners.dmpc.mlr.types.MlrBundle`: its UAV state message, its
  recovery replies and, on a host, its CU's message. The parts of a bundle are
  lost together. A drone does not hear its own broadcast, so the host hands
  its CU its own UAV's messages and its UAV its own CU's message onboard.
* **Rounds.** The radio round (``1 / radio.rate_hz``) is the MLR round T; round
  k is the radio round at t = kT. ``on_radio`` keeps the bundles received;
  ``outgoing(t)`` runs round k with the bundles of round k - 1 (others, late
  ones, are dropped and counted; ``radio.delay_s < T`` keeps them on time):
  the UAV switches its reference at kT when a CU sent it a new trajectory
  (Eq. 10), the hosted CU runs Alg. 1, and the bundle goes out. A trajectory a
  CU computes in round k starts at (k + 1) T, when its UAV, having received
  it, switches to it.
* **Initial trajectories (Remark 2).** Each drone's initial trajectory is a
  hover at its first pose estimate. The CUs know the others' only from the
  radio: a bundle carries its drone's initial trajectory as long as the drone
  follows it. All CUs start together in round k0, the first round at or after
  ``planner.start_delay_s`` (at least round 1); a CU that by then has not
  heard every initial trajectory starts in the first round in which it has,
  with every tracker deprecated (``joined_late``: it recovers them like after
  a loss). No CU computes before k0, so every drone hovers at its start during
  the start delay; the first trajectories are computed in k0 + 1 (round k0
  has no priorities of a previous round to unify) and flown from (k0 + 2) T.
* **Assumption 1.** The CUs plan from the exchanged trajectories only; the
  physical drone's tracking error is not fed back (the state message carries
  the drone's pose estimate, which Alg. 1 does not use). The onboard agent
  never reads another drone's ground truth: only its own pose estimate and
  its inbox. Targets are the scenario's goals (known to every CU at start,
  then announced in the state messages).
* **Reference.** :meth:`MlrAgent.reference` samples the current reference
  trajectory (position, velocity and acceleration of Eq. 12) for the SE(3)
  controller. Yaw: held at the heading of the first pose estimate (the world
  spawns each drone facing its goal), yaw rate 0, as the DMPC agent does.
* **No obstacles.** MLR-DMPC has no obstacle constraints; the scenario check
  refuses ``planner.kind: mlr`` with static obstacles
  (:class:`mpcde.config.scenario.ScenarioConfig`). The flying box of the QP is the
  arena, shrunk by ``arena_margin_m``, between the heights of ``altitude_range_m``.

Faults: a host drone that fails (or whose radio is out) leaves its CU's slot
empty; the other CUs then find a slot unaccounted for every round, keep every
tracker deprecated and compute nothing, so the swarm hovers on its last
trajectories (which end in the terminal halt, Eq. 13e): safe, no progress.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from mpcde.config.mlr import MlrAgentConfig
from mpcde.onboard.base import AgentCounters, PlanFollowingAgent
from planners.dmpc.mlr.compute_unit import ComputeUnit, CuStepReport, summarize_reports
from planners.dmpc.mlr.config import MlrConfig
from planners.dmpc.mlr.trajectory import ReferenceTrajectory
from planners.dmpc.mlr.types import CuTrajectoryMessage, MlrBundle
from planners.dmpc.mlr.uav import Uav, initial_trajectory
from sim.rotations import rotation_from_quat_xyzw, yaw_from_rotation
from sim.types import PoseEstimate, RadioMessage, RgbdFrame

__all__ = ["MlrAgent", "MlrAgentConfig"]

@dataclass
class MlrRoundStats:
    """What one agent's rounds did (for :meth:`MlrAgent.extra_metrics`).

    Attributes:
        rounds: rounds run (``outgoing`` calls with a bundle).
        switches: reference switches (Eq. 10).
        max_reference_jump_m: largest position jump of the reference at a switch [m]
            (MLR-DMPC's switches are continuous: ~0).
        replies: recovery replies sent.
        late_bundles: bundles received after their round (dropped).
        cu_reports: the hosted CU's reports, one per round it ran.
        cu_start_round: the round its CU started (None: no CU, or not started).
    """

    rounds: int = 0
    switches: int = 0
    max_reference_jump_m: float = 0.0
    replies: int = 0
    late_bundles: int = 0
    cu_reports: list[CuStepReport] = field(default_factory=list)
    cu_start_round: int | None = None


class MlrAgent(PlanFollowingAgent):
    """One drone of the MLR-DMPC swarm: its UAV and, on drones 0..M-1, a CU (a :class:`mpcde.onboard.base.PlanFollowingAgent`).

    Args:
        drone_id: i, index of the drone.
        goals_world: (N, 3) every drone's goal [m] (the UAVs' targets, known to the CUs at start).
        config: the MLR-DMPC settings (:meth:`MlrAgentConfig.planner_config`).
        start_delay_s: hover at the start until this time [s]; the CUs start in
            the first round at or after it (see the module docstring).
        ignore_message_loss: the hosted CU runs the Sec. 5.4 baseline.
    """

    def __init__(
        self, drone_id: int, goals_world: np.ndarray, config: MlrConfig, start_delay_s: float = 0.0,
        ignore_message_loss: bool = False,
    ) -> None:  # fmt: skip
        goals = np.asarray(goals_world, float).reshape(-1, 3)
        if goals.shape[0] != config.n_uavs:
            raise ValueError(f"goals_world: {goals.shape[0]} goals for n_uavs={config.n_uavs}")
        if not 0 <= drone_id < config.n_uavs:
            raise ValueError(f"drone_id={drone_id!r}: an integer in [0, {config.n_uavs - 1}]")
        self.drone_id = int(drone_id)
        self.config = config
        self.goals_world = goals
        self.ignore_message_loss = bool(ignore_message_loss)
        self.cu_index = self.drone_id if self.drone_id < config.n_cus else None
        self.start_round = max(1, math.ceil(float(start_delay_s) / config.round_s - 1e-9))  # k0
        self.counters = AgentCounters()
        self.stats = MlrRoundStats()
        self.latest_estimate: PoseEstimate | None = None
        self.yaw = 0.0
        self.initial: ReferenceTrajectory | None = None
        self.uav: Uav | None = None
        self.cu: ComputeUnit | None = None
        self.initials: dict[int, ReferenceTrajectory] = {}  # what the hosted CU has heard (Remark 2)
        self._received: list[MlrBundle] = []
        self._sent: MlrBundle | None = None

    # ------------------------------------------------------------------ inputs
    def on_pose_estimate(self, estimate: PoseEstimate) -> None:
        """Take the drone's own pose estimate; the first fixes the initial trajectory and the heading."""
        if self.uav is None:
            self.initial = initial_trajectory(self.config, estimate.pos_world, float(estimate.time_s))
            self.uav = Uav(self.drone_id, self.initial, self.goals_world[self.drone_id])
            self.yaw = float(yaw_from_rotation(rotation_from_quat_xyzw(estimate.quat_xyzw)))
            self.initials[self.drone_id] = self.initial
        self.latest_estimate = estimate

    def on_frame(self, frame: RgbdFrame, detections: list | None = None) -> None:
        """Take one camera frame (MLR-DMPC does not perceive; counted only)."""
        self.counters.frames += 1

    def on_radio(self, messages: list[RadioMessage]) -> None:
        """Take this round's inbox: keep the MLR bundles of the other drones for :meth:`outgoing`."""
        self._received = self._payloads(messages, MlrBundle)
        for b in self._received:
            if isinstance(b.cu_message, CuTrajectoryMessage) and b.cu_message.trajectory is not None:
                self.counters.plans += 1

    # ------------------------------------------------------------------ round
    def round_index(self, time_s: float) -> int:
        """k of the round at ``time_s`` [s] (the loop's radio rounds fall on kT)."""
        return int(round(time_s / self.config.round_s))

    def _round_message(self, time_s: float) -> MlrBundle | None:
        """Round k at ``time_s`` = kT: the UAV's switch (Eq. 10), the hosted CU's Alg. 1, the bundle to broadcast."""
        if self.uav is None:
            return None
        k = self.round_index(time_s)
        received = [b for b in self._received if b.round_index == k - 1]
        self.stats.late_bundles += len(self._received) - len(received)
        self._received = []
        heard = [m for b in received for m in b.messages()]
        own = self._sent if self._sent is not None and self._sent.round_index == k - 1 else None
        # the drone's own messages of round k - 1 reach its UAV and its CU onboard (no radio)
        own_cu = [own.cu_message] if own is not None and own.cu_message is not None else []
        own_uav = [own.state, *own.replies] if own is not None else []

        old = self.uav.reference
        pos, vel = self.latest_estimate.extrapolated(time_s)
        out, switched = self.uav.step(k, heard + own_cu, pos, vel)
        if switched:
            self.stats.switches += 1
            t0 = max(float(time_s), self.uav.reference.t_start_s)
            jump = np.linalg.norm(old.positions_at([t0])[0] - self.uav.reference.positions_at([t0])[0])
            self.stats.max_reference_jump_m = max(self.stats.max_reference_jump_m, float(jump))
        state, replies = out[0], tuple(out[1:])
        self.stats.replies += len(replies)

        cu_message = None
        if self.cu_index is not None:
            cu_message = self._cu_round(k, received, heard + own_uav)
        following_initial = self.uav.reference.meta == self.initial.meta
        bundle = MlrBundle(state, replies, cu_message, self.initial if following_initial else None)
        self._sent = bundle
        self.stats.rounds += 1
        return bundle

    def _cu_round(self, k: int, received: list[MlrBundle], inbox: list[object]) -> object | None:
        """The hosted CU's round k (Alg. 1), started once every initial trajectory is known; its message or None."""
        for b in received:
            if b.initial is not None:
                self.initials.setdefault(b.sender_id, b.initial)
        n = self.config.n_uavs
        if self.cu is None and k >= self.start_round and len(self.initials) == n:
            initial = [self.initials[i] for i in range(n)]
            self.cu = ComputeUnit(
                self.config, self.cu_index, initial, self.goals_world, self.ignore_message_loss,
                first_round=self.start_round, joined_late=k > self.start_round,
            )  # fmt: skip
            self.stats.cu_start_round = k
        if self.cu is None:
            return None
        msg, report = self.cu.step(k, inbox)
        self.stats.cu_reports.append(report)
        return msg

    # ------------------------------------------------------------------ reference
    def reference_state(self, time_s: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Position [m], velocity [m/s], acceleration [m/s^2] (3,) of the reference at ``time_s`` [s] (Eq. 12)."""
        if self.uav is None:
            pos = self.latest_estimate.pos_world if self.latest_estimate is not None else np.zeros(3)
            return np.array(pos, float), np.zeros(3), np.zeros(3)
        ref = self.uav.reference
        x = ref.states_at(np.array([max(float(time_s), ref.t_start_s)]))[0]
        return x[:3], x[3:6], x[6:9]

    # ------------------------------------------------------------------ metrics
    def extra_metrics(self) -> dict[str, Any]:
        """This drone's MLR-DMPC statistics (the loop adds them to ``metrics.json`` under ``agents``).

        The CU keys (:func:`planners.dmpc.mlr.compute_unit.summarize_reports`)
        are 0 / None on a drone without a CU. ``qp_solve_ms`` lists every
        solved QP's OSQP time [ms] so that an evaluation can pool them.
        """
        s = self.stats
        summary = summarize_reports(s.cu_reports)
        cu = {k: (None if isinstance(v, float) and math.isnan(v) else v) for k, v in summary.items()}
        return {
            "drone_id": self.drone_id,
            "planner": "mlr",
            "compute_unit": self.cu_index,
            "cu_start_round": s.cu_start_round,
            "ignore_message_loss": self.ignore_message_loss,
            "rounds": s.rounds,
            "reference_switches": s.switches,
            "max_reference_jump_m": s.max_reference_jump_m,
            "recovery_replies": s.replies,
            "late_bundles": s.late_bundles,
            **cu,
            "qp_solve_ms": [round(r.qp.solve_time_s * 1e3, 5) for r in s.cu_reports if r.qp is not None],
        }
