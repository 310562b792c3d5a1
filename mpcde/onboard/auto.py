"""The ``auto`` agent: DMPC while the radio delivers, MP-CDE when it does not (``planner.kind: auto``).

DESIGN.md section 4: "comm while the radio delivers; neighbour by neighbour it
falls back to perception tracks when that neighbour's plan is stale, and the
whole agent falls back to the denied stack when the radio is out; back again
when it returns. Perception runs in every mode, so tracks are warm when an
outage starts."

One drone runs both stacks over one perception:

* the *denied half* (:class:`mpcde.onboard.denied.DeniedAgent`) owns the
  detector's tracks and the camera map. Every frame is tracked and mapped in
  both modes (:meth:`DeniedAgent.observe`); only in ``denied`` mode does it
  also plan (heading, replanning: :meth:`DeniedAgent.plan_step`);
* the *comm half* (:class:`mpcde.onboard.dmpc.DmpcAgent`) runs the DMPC round
  at every radio round in ``comm`` mode, against the neighbours' radio plans
  fused with the same tracks (:mod:`mpcde.onboard.fusion`: a neighbour whose
  plan is older than ``fusion.stale_after_s`` is planned against by its track
  when one matches; tracks the radio does not explain are extra neighbours).

Mode switch, at each radio round t (the only clock the radio gives a drone):
the radio is *out* when nothing from any drone was sent within the last
``radio_silence_s`` (the newest send time heard; a drone cannot tell a
blackout from being alone out of range, and in both the cameras are all it
has). comm -> denied when it goes out; denied -> comm when a message arrives
again. A switch hands the reference over continuously: the stack taking over
starts from the left stack's reference state (position, velocity,
acceleration) and heading (:meth:`DeniedAgent.take_over`,
:meth:`DmpcAgent.take_over`). In ``denied`` mode the drone still broadcasts
its MINCO trajectory as a plan, so neighbours that hear it can use it.

The radio is remembered for ``plan_memory_s`` after the switch: the denied
half plans (and aims its camera) against the neighbours' last plans fused with
its tracks (:class:`RadioMemory`, the denied half's neighbour source), so a neighbour flying beside
it, which its camera has not seen, is not forgotten the moment the radio goes.

What each half knows of static obstacles is what it knows alone: the comm
half the scenario's obstacle list (the on-demand DMPC paper's known
obstacles), the denied half its own camera map. ``denied.perceive_neighbours:
false`` turns the perception off for both halves (the blind-fallback ablation).

Measured (radio_outage, against comm and denied; what was tried): docs/results/radio_outage.md.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from mpcde.config.auto import AutoAgentConfig
from mpcde.onboard.base import AgentCounters, OnboardAgent
from mpcde.onboard.denied import DeniedAgent
from mpcde.onboard.dmpc import HALT_TOLERANCE_MPS, DmpcAgent
from mpcde.onboard.fusion import fuse_neighbours
from perception.types import Detection, NeighborPrediction
from planners.dmpc import DmpcPlan
from sim.types import FlatOutputReference, PlanMessage, PoseEstimate, RadioMessage, RgbdFrame

__all__ = ["AutoAgent", "AutoAgentConfig", "RadioMemory"]

COMM, DENIED = "comm", "denied"


class RadioMemory:
    """What the ``auto`` stack's denied half plans, maps and points its camera against: tracks plus radio memory.

    Called as the denied half's neighbour source (``memory(t, count)``). The
    neighbours' last plans sent within ``plan_memory_s`` (lengthened by
    ``extra_s`` while a halting hand-over holds and turns) are fused with the
    tracks exactly as in comm mode (:func:`mpcde.onboard.fusion.fuse_neighbours`):
    a plan whose drone is tracked gives way to the track, an untracked one is
    kept (extrapolated at constant velocity past its horizon).

    Args:
        config: the scenario's ``auto:`` settings.
        comm: the DMPC half, whose radio plans are remembered.
        perception: the tracks both halves share.

    Attributes:
        extra_s: the memory's lengthening [s] (set by the hand-over).
        remembered_plans: remembered radio plans used in planning calls (summed over plans).
    """

    def __init__(self, config: AutoAgentConfig, comm: DmpcAgent, perception: Any) -> None:
        self.config, self.comm, self.perception = config, comm, perception
        self.extra_s = 0.0
        self.remembered_plans = 0

    def __call__(self, t: float, count: bool = True) -> list[NeighborPrediction]:
        """The neighbour predictions at ``t`` [s]; ``count``: tally the remembered plans used (planning calls; the map's are not)."""
        tracks = self.perception.predictions(t)
        if self.config.plan_memory_s <= 0:
            return tracks
        plans = self.comm.radio_predictions(t, self.config.plan_memory_s + self.extra_s)
        if not plans:
            return tracks
        f = self.config.fusion
        fused = fuse_neighbours(plans, tracks, t, f.stale_after_s, f.gate_m, self.comm.qp_config.limits.v_max_mps)
        if count:  # planning calls (denied mode) only; the map asks at every frame in both modes
            self.remembered_plans += fused.fresh_plans + fused.stale_plans
        return fused.predictions


class AutoAgent(OnboardAgent):
    """One drone's ``auto`` stack (implements :class:`mpcde.onboard.base.OnboardAgent`; module docstring).

    Args:
        config: the scenario's ``auto:`` settings.
        comm: the DMPC half, sharing ``denied.perception`` and fusing with it.
        denied: the MP-CDE half (the perception's tracks and the map), built with ``memory`` as its neighbour source.
        memory: the radio memory of ``comm``'s plans that the denied half plans against.
    """

    def __init__(self, config: AutoAgentConfig, comm: DmpcAgent, denied: DeniedAgent, memory: RadioMemory) -> None:
        if comm.drone_id != denied.drone_id or comm.perception is not denied.perception:
            raise ValueError("AutoAgent: comm and denied halves must be the same drone and share one perception")
        if denied.neighbour_source is not memory or memory.comm is not comm:
            raise ValueError("AutoAgent: the denied half must plan against the radio memory of the comm half")
        self.drone_id = comm.drone_id
        self.config = config
        self.comm, self.denied = comm, denied
        self.perception = denied.perception
        self.detector_request = denied.detector_request
        self.maps_frames = denied.maps_frames  # its MP-CDE half maps every frame, in either mode
        self.counters = AgentCounters()
        self.mode = COMM
        self.last_heard_s: float | None = None  # newest send time heard (None: the first estimate's time)
        self.switches: list[tuple[float, str]] = []
        self.handovers: list[tuple[float, float]] = []  # per halting hand-over: (halt reached, turn ended) [s]
        self.mode_time_s = {COMM: 0.0, DENIED: 0.0}
        self._last_round_s: float | None = None
        self.memory = memory
        # halting hand-over (config.handover "halt"): until _hold_until_s the drone flies its last DMPC plan to its
        # halt; the radio memory is lengthened by the hold and the turn that follow the switch
        self._hold_until_s = -np.inf

    # inputs ------------------------------------------------------------------
    def on_pose_estimate(self, estimate: PoseEstimate) -> None:
        """Own pose estimate, to both halves (the first starts the silence clock)."""
        if self.last_heard_s is None:
            self.last_heard_s = float(estimate.time_s)
        self.comm.on_pose_estimate(estimate)
        self.denied.on_pose_estimate(estimate)

    def on_frame(self, frame: RgbdFrame, detections: list[Detection] | None = None) -> None:
        """Track and map every frame; in ``denied`` mode, once a halting hand-over is over, also plan on it."""
        self.counters.frames += 1
        if self._holding(frame.time_s):
            self.denied.observe(frame, detections)
        else:
            self.denied.on_frame(frame, detections)

    def on_radio(self, messages: list[RadioMessage]) -> None:
        """This round's inbox: to the DMPC half; any message from another drone restarts the silence clock."""
        self.counters.messages += len(messages)
        self.comm.on_radio(messages)
        for m in messages:
            if m.sender_id != self.drone_id:
                self.last_heard_s = max(self.last_heard_s or -np.inf, float(m.send_time_s))

    # round -------------------------------------------------------------------
    def _round_message(self, time_s: float) -> PlanMessage | None:
        """Choose the mode at this round, then run it: the DMPC round, or broadcast the MINCO plan."""
        t = float(time_s)
        if self._last_round_s is not None:
            self.mode_time_s[self.mode] += t - self._last_round_s
        self._last_round_s = t
        self._choose_mode(t)
        if self.mode == COMM:
            self.comm.plan_round(t)
            return self.comm.outgoing(t)
        plan = self._denied_plan(t)
        if plan is None:
            return None
        return PlanMessage(sender_id=self.drone_id, time_s=t, times_s=plan.times_s, pos_world=plan.pos_world, vel_world=plan.vel_world)

    def radio_out(self, time_s: float) -> bool:
        """Whether nothing was heard from any drone within ``radio_silence_s`` of ``time_s`` [s]."""
        heard = self.last_heard_s if self.last_heard_s is not None else float(time_s)
        return float(time_s) - heard > self.config.radio_silence_s + 1e-9  # rounds sit on a float grid

    def _choose_mode(self, t: float) -> None:
        out = self.radio_out(t)
        if self.mode == COMM and out:
            self._hand_over_to_denied(t)
            self._switch(t, DENIED)
        elif self.mode == DENIED and not out:
            plan = self._denied_plan(t)
            if plan is not None:
                self.comm.take_over(plan, self.reference(t).yaw)
            self._hold_until_s, self.memory.extra_s = -np.inf, 0.0
            self._switch(t, COMM)

    def _hand_over_to_denied(self, t: float) -> None:
        """comm -> denied at ``t`` [s], as ``config.handover`` says (:class:`AutoAgentConfig`).

        ``continue``: the denied half starts from the DMPC reference's state and replans at once.
        ``halt``: the drone flies its last broadcast DMPC plan to that plan's halt (DMPC-Swarm Eq. 13e: the
        plan its neighbours remember; without a halting plan, the denied half's stopping piece), turns the
        camera once round there, and only then plans; the radio memory is lengthened by the time from the
        switch to the turn's end.
        """
        plan = self.comm.plan
        t_halt = _halt_time(plan) if self.config.handover == "halt" and plan is not None else None
        if t_halt is not None:
            self._hold_until_s = max(t_halt, t)
            halt = self.comm.reference_state(self._hold_until_s)[0]
            turn = self.denied.look_around_at(self._hold_until_s, halt, self.comm.yaw)
        else:
            pva = np.stack(self.comm.reference_state(t))
            turn = self.denied.take_over(t, pva, self.comm.yaw, look_around=self.config.handover == "halt")
        if turn is not None:
            self.memory.extra_s = turn[1] - t
            self.handovers.append(turn)

    def _switch(self, t: float, mode: str) -> None:
        self.mode = mode
        self.switches.append((t, mode))

    def _denied_plan(self, t: float) -> DmpcPlan | None:
        """The denied half's reference sampled on the DMPC grid t + k h, k = 0..K (None before an estimate)."""
        if self.denied.latest_estimate is None:
            return None
        cfg = self.comm.qp_config
        times = t + cfg.step_s * np.arange(cfg.horizon_steps + 1)
        pva = np.stack([self._state_at(tk) for tk in times])  # (K+1, 3, 3)
        return DmpcPlan(t0_s=t, h_s=cfg.step_s, pos_world=pva[:, 0], vel_world=pva[:, 1], acc_world=pva[:, 2])

    def _holding(self, t: float) -> bool:
        """Whether at ``t`` [s] the DMPC half flies the drone: in ``comm`` mode, or in ``denied`` mode while the
        drone still flies its last DMPC plan to its halt (``handover: halt``); the denied half then only observes."""
        return self.mode == COMM or t < self._hold_until_s - 1e-9

    def _state_at(self, t: float) -> np.ndarray:
        """(3, 3) position, velocity, acceleration of the reference flown at ``t`` [s] (:meth:`_holding`)."""
        return np.stack(self.comm.reference_state(t)) if self._holding(t) else self.denied.state_at(t)

    # output ------------------------------------------------------------------
    def reference(self, time_s: float) -> FlatOutputReference:
        """Controller reference at ``time_s`` [s] from the half that flies now (DMPC while a hand-over holds)."""
        return self.comm.reference(time_s) if self._holding(time_s) else self.denied.reference(time_s)

    def extra_metrics(self) -> dict[str, Any]:
        """Mode shares and switches, and each half's own statistics."""
        return {
            "drone_id": self.drone_id,
            "planner": "auto",
            "mode_time_s": {k: round(v, 3) for k, v in self.mode_time_s.items()},
            "mode_switches": len(self.switches),
            "remembered_plans": self.memory.remembered_plans,
            "switches": [{"time_s": round(t, 3), "to": m} for t, m in self.switches],
            "halting_handovers": [{"halt_s": round(a, 3), "turn_end_s": round(b, 3)} for a, b in self.handovers],
            "dmpc": self.comm.extra_metrics(),
            "denied": self.denied.extra_metrics(),
        }


def _halt_time(plan: DmpcPlan) -> float | None:
    """The first sample time [s] of ``plan`` from which it is at rest (every later sample's velocity below
    :data:`mpcde.onboard.dmpc.HALT_TOLERANCE_MPS` on every axis); None when it does not end at rest."""
    moving = np.any(np.abs(plan.vel_world) >= HALT_TOLERANCE_MPS, axis=1)  # (K+1,)
    if moving[-1]:
        return None
    last_moving = np.flatnonzero(moving)
    return float(plan.times_s[last_moving[-1] + 1 if last_moving.size else 0])
