"""ADMM formation DMPC in the physics loop (``planner.kind: admm``, ``mpcde fly --mode admm``; Stomberg et al.).

The planner is :mod:`planners.dmpc.admm.formation` (Algorithm 2: per MPC step
``l_max`` ADMM iterations, each a local QP, copies sent to the neighbours,
means sent back); :func:`planners.dmpc.admm.formation.solve_admm_round` runs
it over an ideal network. This module flies it on the simulated quadrotors,
over :mod:`sim.radio`. Choices:

* **Radio sub-rounds.** Every exchange of Algorithm 2 is one radio round, so
  the radio runs at 2 l_max / h (``admm.l_max = 5``, ``admm.step_s = 0.2 s``:
  50 Hz; :attr:`AdmmAgentConfig.radio_rate_hz`, which the scenario sets or
  checks). Sub-round n falls at n h / (2 l_max); MPC step s covers the
  sub-rounds n = 2 l_max s .. 2 l_max (s + 1) - 1, phase r = n mod 2 l_max.
  The loop reads every inbox before anyone broadcasts, so what a drone sends
  in sub-round n is read in n + 1 (``radio.delay_s`` < one sub-round). In
  ``outgoing(t)`` at phase r:

  - r = 0: finish step s - 1 (Steps 7-8 with the means of its last
    iteration, then its plan, :meth:`AdmmFormationAgent.result`); start step s
    (:meth:`AdmmFormationAgent.start_step` from the own state and reference)
    and broadcast the copies of iteration 1 (Steps 3-4);
  - r odd: average the copies of iteration (r + 1) / 2 (Step 5), broadcast the
    mean (Step 6);
  - r even > 0: Steps 7-8 with the means of iteration r / 2, then Steps 3-4 of
    iteration r / 2 + 1.

  One :class:`planners.dmpc.admm.types.AdmmBundle` per drone and sub-round
  holds the copies (one per neighbour) or the means.
* **Delay compensation (paper Remark 1).** The plan of step s is ready at
  (s + 1) h; it fixes u[0] to the input already applied on [s h, (s + 1) h)
  (the previous plan's) and decides u[1]. So :meth:`AdmmAgent.reference`
  flies the plan of step s from (s + 1) h to (s + 2) h: its state at (s + 1) h
  is the one the previous plan led to, and the reference is continuous when
  the step started from the plan's state. Before the first plan (at h) the
  reference is a hover at the start.
* **State.** A step starts from the pose estimate extrapolated to s h, or
  from the reference's state at s h (the own plan's, or the start hover
  before the first) while the estimate agrees with it within
  ``state_tolerance_m`` / ``state_tolerance_mps``: the DMPC agent's rule,
  :mod:`planners.dmpc.start_state` (so that estimate noise does not jolt every
  plan, and a drifted estimate does not ratchet the drone off its goal).
* **Own reference r_i.** A straight line from the start (the first pose
  estimate) to the goal at ``planner.cruise_speed_mps``, leaving at the first
  step at or after ``planner.start_delay_s``; before that the start itself,
  so the drones hover while the first steps warm the ADMM up. (Chosen over
  the goal itself: a goal 10 m away would drive every drone at v_max_mps from
  the first step and leave the formation term to fight the tracking term.)
* **Formation.** The goals are the formation: d_ij = goal_i - goal_j, the
  desired p_i - p_j (the planner's sign; DMPC's ``formation_offsets`` are
  p_j - p_i), over the ``admm.graph`` edges (complete or ring). Each drone is
  told the goals, its neighbours and nothing else: it never reads another
  drone's state, only its own pose estimate and its inbox.

**Lost and late messages** (the paper's Assumption 1 does not hold on this
radio). The rules keep the multipliers consistent, paper Eq. (5): for every
drone j, the entries of gamma on p_j (j's own and every copy of it) sum to
zero, which is what makes Steps 5-7 the exact consensus step (4b)
(:mod:`planners.dmpc.admm.formation`); a rule that breaks it (e.g. averaging
with a neighbour's last received copy) leaves the multipliers a bias that
never decays (what it did under loss: docs/results/admm_formation.md#a-loss-rule-that-broke-eq-5-dropped).

1. A copy that did not reach its owner j is left out of j's average
   (xbar_j is the mean of p_j and the copies received), and j's means bundle
   says whose copies it averaged. A holder whose copy was left out takes no
   Step 8 on it in this iteration (zbar = its own copy, gamma unchanged).
   The group's sum stays zero.
2. A holder that missed xbar_j^l also takes no Step 8 on its copy of p_j
   (zbar = its own copy) and remembers w_ji^l. Every means bundle of j
   repeats j's means of the last l_max iterations; when one arrives with
   xbar_j^l, the holder adds the Step 8 term it skipped,
   rho (w_ji^l - xbar_j^l) (shifted one step if it came in the next MPC step,
   as the warm start shifts gamma), and the sum is zero again. A bundle whose
   repeats span iteration l without xbar_j^l tells that j never computed it
   (its step was aborted): then no term is due, as j skipped its Step 8 too.
   Missed means not resolved within that window are counted
   (``unresolved_means``: each may leave one term of Eq. (5) off).
3. A message of an earlier sub-round (late) is not used as its iteration's
   message (counted ``late_messages``); a late means bundle still repairs.
   The scenario check keeps ``radio.delay_s`` below a sub-round, but rounds
   fire on physics ticks (at 240 Hz a 50 Hz sub-round is 4 or 5 ticks), so a
   delay above 4 ticks (16.7 ms) makes some messages late.

A local QP that OSQP fails on ends the drone's step (``qp_failures``); it
keeps flying its last plan and starts afresh in the next step, its
neighbours treating its silence as lost messages.

No collision avoidance and no obstacles: the OCP has neither, so the scenario
check refuses obstacles and starts that are not in the goals' formation
(:class:`mpcde.config.scenario.ScenarioConfig`).

Measured (``formation_open``, ideal and lossy radio, against DMPC):
docs/results/admm_formation.md#the-admm-agent-in-the-physics-loop-formation_open.
"""

from __future__ import annotations

import math
from collections import deque
from typing import Any

import numpy as np

from mpcde.config.admm import AdmmAgentConfig
from mpcde.onboard.admm_stats import AdmmRoundStats
from mpcde.onboard.base import AgentCounters, SampledPlanAgent
from planners.dmpc.admm.formation import AdmmFormationAgent
from planners.dmpc.admm.local_qp import AdmmLocalQpError
from planners.dmpc.admm.ocp import shift_trajectory
from planners.dmpc.admm.types import AdmmBundle, AdmmStepResult, CopyMessage, MeanMessage, MeanRecord
from planners.dmpc.plan_sampler import PlanSampler
from planners.dmpc.start_state import plan_start_state
from sim.types import PoseEstimate, RadioMessage, RgbdFrame

__all__ = ["AdmmAgent", "AdmmRoundStats"]

_EPS_S = 1e-6  # rounds fire at the first physics tick at or after their time: floor((t + eps) / T_sub)


class AdmmAgent(SampledPlanAgent):
    """One drone of the ADMM formation swarm (a :class:`mpcde.onboard.base.SampledPlanAgent`); see the module docstring.

    Args:
        drone_id: i, index of the drone.
        goals_world: (N, 3) every drone's goal [m]: the formation (and drone i's goal).
        config: the scenario's ``admm:`` settings.
        arena_size_m: (x, y) arena extent [m] (the soft position box).
        start_delay_s: the own reference leaves the start at the first step at or after this [s].
        cruise_speed_mps: speed of the own reference along its line [m/s].
    """

    def __init__(
        self, drone_id: int, goals_world: np.ndarray, config: AdmmAgentConfig, arena_size_m: tuple[float, float],
        start_delay_s: float = 0.0, cruise_speed_mps: float = 1.0,
    ) -> None:  # fmt: skip
        goals = np.asarray(goals_world, float).reshape(-1, 3)
        if not 0 <= drone_id < goals.shape[0]:
            raise ValueError(f"drone_id={drone_id!r}: an integer in [0, {goals.shape[0] - 1}]")
        self.drone_id = int(drone_id)
        self.config = config
        self.planner_config = config.planner_config(arena_size_m)
        self.formation = config.formation(goals)
        # d_ij = c_i - c_j = goal_i - goal_j: desired p_i - p_j (FormationGraph's and the planner's sign)
        self.admm = AdmmFormationAgent(self.drone_id, self.planner_config, self.formation.offsets_of(self.drone_id))
        self.neighbour_ids = self.admm.neighbour_ids
        self.goal_world = goals[self.drone_id].copy()
        self.cruise_speed_mps = float(cruise_speed_mps)
        h = config.step_s
        self.departure_s = math.ceil(float(start_delay_s) / h - 1e-9) * h  # the first step at or after the delay
        self.counters = AgentCounters()
        self.stats = AdmmRoundStats()
        self.latest_estimate: PoseEstimate | None = None
        self.start_world: np.ndarray | None = None
        self.yaw = 0.0
        self.plan: AdmmStepResult | None = None
        self._sampler: PlanSampler | None = None
        self._inbox: list[AdmmBundle] = []
        self._last_round: int | None = None
        self._step: int | None = None  # the MPC step in progress (the coordinates of the planner's gamma)
        self._broken = False  # the step in progress cannot go on (failed QP, missed sub-round)
        self._history: deque[MeanRecord] = deque(maxlen=config.iterations_per_step)  # own means sent, the latest first
        self._pending: dict[tuple[int, int, int], np.ndarray] = {}  # (j, step, iteration) missed -> w_ji then

    # ------------------------------------------------------------------ inputs
    def on_frame(self, frame: RgbdFrame, detections: list | None = None) -> None:
        """Take one camera frame (the ADMM agent does not perceive; counted only)."""
        self.counters.frames += 1

    def on_radio(self, messages: list[RadioMessage]) -> None:
        """Take this sub-round's inbox: the other drones' ADMM bundles, read by the next :meth:`outgoing`."""
        self._inbox = self._payloads(messages, AdmmBundle)

    # ------------------------------------------------------------------ sub-rounds
    def round_index(self, time_s: float) -> int:
        """n of the sub-round at ``time_s`` [s] (it falls at n h / (2 l_max), or the first physics tick after)."""
        return int(math.floor((time_s + _EPS_S) / self.config.sub_round_s))

    def _round_message(self, time_s: float) -> AdmmBundle | None:
        """Sub-round n at ``time_s`` [s]: the phase's ADMM work (module docstring) and the bundle to broadcast."""
        if self.latest_estimate is None:
            return None
        n = self.round_index(time_s)
        if self._last_round is not None:
            if n <= self._last_round:
                return None  # this sub-round was run already
            if n > self._last_round + 1:
                self.stats.skipped_rounds += n - self._last_round - 1
                self._broken = True
        self._last_round = n
        s, r = divmod(n, self.config.rounds_per_step)
        inbox, self._inbox = self._inbox, []
        self._repair(inbox)
        if r == 0:
            return self._next_step(s, inbox)
        if self._step != s or self._broken:
            return None  # the step was not started or cannot go on: the inbox is dropped
        if r % 2 == 1:  # Steps 5-6
            return self._average(s, (r + 1) // 2, inbox)
        self._update(s, r // 2, inbox)  # Steps 7-8, then 3-4 of the next iteration
        return self._local_step(s, r // 2 + 1)

    def _next_step(self, s: int, inbox: list[AdmmBundle]) -> AdmmBundle | None:
        """Phase 0: finish step s - 1 with its last means, adopt its plan, start step s."""
        cfg = self.config
        if self._step is not None and self._step == s - 1 and not self._broken:
            self._update(s - 1, cfg.iterations_per_step, inbox)
            self._adopt(self.admm.result(), s * cfg.step_s)
        elif self._step is not None:
            self.stats.aborted_steps += 1  # its last means (in the inbox) are dropped
        t0 = s * cfg.step_s
        x0 = self._state(t0)
        self.admm.start_step(x0, self.own_reference(t0), t0, self._input_at(t0))
        self._step, self._broken = s, False
        oldest = s - 1 if cfg.warm_start else s  # a cold start zeroes gamma: nothing older to repair
        for key in [k for k in self._pending if k[1] < oldest]:
            del self._pending[key]
            self.stats.unresolved_means += int(cfg.warm_start)
        return self._local_step(s, 1)

    def _local_step(self, s: int, it: int) -> AdmmBundle | None:
        """Steps 3-4 of iteration ``it``: the local QP, the copies to broadcast (None if OSQP failed)."""
        try:
            copies = self.admm.local_step()
        except AdmmLocalQpError:
            self.stats.qp_failures += 1
            self._broken = True
            return None
        return AdmmBundle(self.drone_id, s, it, copies=tuple(copies)) if copies else None

    def _expected(self, inbox: list[AdmmBundle], kind: str, s: int, it: int) -> dict[int, AdmmBundle]:
        """The neighbours' bundles of (kind, step s, iteration it) with a message to this drone; counts late ones."""
        out = {}
        for b in inbox:
            if b.sender_id not in self.neighbour_ids or b.message_for(self.drone_id) is None:
                continue
            if b.kind == kind and b.step_index == s and b.iteration == it:
                out[b.sender_id] = b
            else:
                self.stats.late_messages += 1
        return out

    def _average(self, s: int, it: int, inbox: list[AdmmBundle]) -> AdmmBundle | None:
        """Steps 5-6 (rule 1): average the own trajectory with the copies received, broadcast the mean."""
        K, lay, me = self.config.horizon_steps, self.admm.layout, self.drone_id
        got = {j: b.message_for(me) for j, b in self._expected(inbox, "copies", s, it).items()}
        xbar = (self.admm.z[lay.pos].reshape(K, 3) + sum(m.pos_world for m in got.values())) / (1 + len(got))
        # a lost copy is counted as the mean itself, which leaves the mean the average of the others
        copies = [got[j] if j in got else CopyMessage(j, me, it, xbar) for j in self.neighbour_ids]
        self.stats.copies_received += len(got)
        self.stats.copies_missing += len(self.neighbour_ids) - len(got)
        means = self.admm.average(copies)
        if not means:
            return None
        averaged = tuple(sorted(got))
        bundle = AdmmBundle(me, s, it, means=tuple(means), averaged=averaged, history=tuple(self._history))
        self._history.appendleft(MeanRecord(s, it, means[0].pos_world, averaged))
        return bundle

    def _update(self, s: int, it: int, inbox: list[AdmmBundle]) -> None:
        """Steps 7-8 (rules 1-2): zbar from the means that averaged this drone's copies, the multiplier update."""
        K, lay, me = self.config.horizon_steps, self.admm.layout, self.drone_id
        bundles = self._expected(inbox, "means", s, it)
        z = self.admm.z
        means = []
        for j in self.neighbour_ids:
            own_copy = z[lay.copy(j)].reshape(K, 3)
            b = bundles.get(j)
            pos = own_copy  # no Step 8 on this copy: z - zbar = 0 there
            if b is None:
                self.stats.means_missing += 1
                self._pending[(j, s, it)] = own_copy
            else:
                self.stats.means_received += 1
                if me in b.averaged:
                    pos = b.message_for(me).pos_world
                else:
                    self.stats.not_averaged += 1
            means.append(MeanMessage(j, me, it, pos))
        self.admm.update_multipliers(means)

    def _repair(self, inbox: list[AdmmBundle]) -> None:
        """Rule 2: the Step 8 terms of missed means that a bundle now repeats."""
        if not self._pending:
            return
        K, rho, l_max = self.config.horizon_steps, self.config.rho, self.config.iterations_per_step
        for b in inbox:
            if b.kind != "means":
                continue
            records = {(rec.step_index, rec.iteration): rec for rec in b.mean_records()}
            latest = b.step_index * l_max + b.iteration - 1  # iterations counted over the steps
            for key in [k for k in self._pending if k[0] == b.sender_id]:
                _, s, it = key
                rec = records.get((s, it))
                if rec is None and not latest - l_max <= s * l_max + it - 1 < latest:
                    continue  # not covered by this bundle's repeats
                w = self._pending.pop(key)
                self.stats.resolved_means += 1
                if rec is None or self.drone_id not in rec.averaged:
                    continue  # never computed, or it left this copy out: no Step 8 term was due
                delta = rho * (w - rec.pos_world)  # gamma += rho (w_ji^l - xbar_j^l)   (4c)
                if s == self._step - 1:  # the warm start has shifted gamma since
                    delta = shift_trajectory(delta.ravel(), extrapolate=False).reshape(K, 3)
                self.admm.add_to_copy_multiplier(b.sender_id, delta)

    # ------------------------------------------------------------------ step inputs and plan
    def _plan_knot(self, time_s: float) -> int | None:
        """k with ``time_s`` = t0 + k h of the current plan (0 <= k <= K), or None."""
        if self.plan is None:
            return None
        u = (time_s - self.plan.t0_s) / self.plan.h_s
        k = int(round(u))
        return k if abs(u - k) < 1e-6 and 0 <= k <= self.config.horizon_steps else None

    def _state(self, t0_s: float) -> np.ndarray:
        """x_i(t0) (6,) [p m, v m/s]: the estimate extrapolated to ``t0_s``, or the reference's state if they agree.

        Before the first plan the reference is the hover at the start.
        """
        pos, vel = self.latest_estimate.extrapolated(t0_s)
        k = self._plan_knot(t0_s)
        if self.plan is None:
            plan_pos, plan_vel = self.start_world, np.zeros(3)
        elif k is not None:
            plan_pos, plan_vel = self.plan.pos_world[k], self.plan.vel_world[k]
        else:
            plan_pos, plan_vel, _ = self._sampler.sample(t0_s)
        cfg = self.config
        pos, vel, from_plan = plan_start_state(pos, vel, plan_pos, plan_vel, cfg.state_tolerance_m, cfg.state_tolerance_mps)
        if not from_plan:
            self.stats.state_resets += 1
        return np.r_[pos, vel]

    def _input_at(self, t0_s: float) -> np.ndarray:
        """(3,) u(t0) [m/s^2], the input the reference applies on [t0, t0 + h) (Remark 1); 0 without a plan."""
        k = self._plan_knot(t0_s)
        if k is not None and k < self.config.horizon_steps:
            return self.plan.acc_world[k].copy()
        return np.zeros(3)

    def own_reference(self, t0_s: float) -> np.ndarray:
        """(K, 3) r_i[1..K] [m] of the step at ``t0_s`` [s]: the line to the goal, or the start before departure."""
        K, h = self.config.horizon_steps, self.config.step_s
        start = self.start_world
        if t0_s < self.departure_s - 1e-9:
            return np.tile(start, (K, 1))
        to_goal = self.goal_world - start
        length = float(np.linalg.norm(to_goal))
        if length < 1e-9:
            return np.tile(start, (K, 1))
        t = t0_s + h * np.arange(1, K + 1)
        along = np.clip(self.cruise_speed_mps * (t - self.departure_s), 0.0, length)
        return start + along[:, None] * (to_goal / length)

    def _adopt(self, result: AdmmStepResult, time_s: float) -> None:
        """Fly ``result`` from ``time_s`` [s] on; record the step's figures."""
        old = self.reference_state(time_s)[0]
        self.plan = result
        self._sampler = PlanSampler(result.as_dmpc_plan())
        jump = float(np.linalg.norm(self._sampler.sample(time_s)[0] - old))
        st = self.stats
        st.max_reference_jump_m = max(st.max_reference_jump_m, jump)
        st.steps += 1
        st.iterations += result.iterations
        st.qp_solve_s.extend(float(v) for v in result.qp_solve_s)
        st.admm_s.append(result.admm_time_s)
        st.osqp_iterations.extend(int(v) for v in result.osqp_iterations)
        st.osqp_max_iter_hits += result.osqp_max_iter_hits
        st.primal_residual.append(float(result.primal_residual[-1]))
        st.max_slack = max(st.max_slack, float(result.slack))

    # ------------------------------------------------------------------ metrics
    def extra_metrics(self) -> dict[str, Any]:
        """This drone's ADMM statistics (the loop adds them to ``metrics.json`` under ``agents``).

        Times in ms are wall-clock; ``qp_solve_ms`` lists every local QP so an
        evaluation can pool them across drones.
        """
        s = self.stats
        qp_ms = np.asarray(s.qp_solve_s) * 1e3

        def stat(values: list | np.ndarray, q: float) -> float | None:
            return float(np.percentile(values, q)) if len(values) else None

        return {
            "drone_id": self.drone_id,
            "planner": "admm",
            "graph": self.config.graph,
            "neighbours": list(self.neighbour_ids),
            "steps": s.steps,
            "aborted_steps": s.aborted_steps,
            "iterations": s.iterations,
            "qp_failures": s.qp_failures,
            "skipped_rounds": s.skipped_rounds,
            "copies_received": s.copies_received,
            "means_received": s.means_received,
            "copies_missing": s.copies_missing,
            "means_missing": s.means_missing,
            "not_averaged": s.not_averaged,
            "resolved_means": s.resolved_means,
            "unresolved_means": s.unresolved_means,
            "late_messages": s.late_messages,
            "state_resets": s.state_resets,
            "max_reference_jump_m": s.max_reference_jump_m,
            "primal_residual_median_m": stat(s.primal_residual, 50),
            "primal_residual_final_m": s.primal_residual[-1] if s.primal_residual else None,
            "max_slack": s.max_slack,
            "osqp_iterations_median": stat(s.osqp_iterations, 50),
            "osqp_iterations_max": max(s.osqp_iterations) if s.osqp_iterations else None,
            "osqp_max_iter_hits": s.osqp_max_iter_hits,
            "qp_ms_median": stat(qp_ms, 50),
            "qp_ms_p95": stat(qp_ms, 95),
            "admm_step_ms_median": stat(np.asarray(s.admm_s) * 1e3, 50),
            "qp_solve_ms": [round(float(v), 5) for v in qp_ms],
        }
