"""Cooperative formation DMPC solved by decentralized ADMM (Stomberg et al., Algorithm 2).

Each drone i runs one :class:`AdmmFormationAgent` holding only what it has
onboard: its own state and reference, its neighbours' ids and desired offsets
d_ij (desired p_i - p_j, world frame ENU [m]), and the messages it received.
Per MPC step (paper Algorithm 1, Steps 3-6)::

    agent.start_step(state, reference, t)      # measure x_i(t); warm start (Sec. 5.1)
    repeat l_max times (Algorithm 2):
        copies = agent.local_step()            # Step 3 (Eq. 4a, OSQP) + Step 4 (send w_ji to j)
        means  = agent.average(copies_in)      # Step 5 (average own p with received copies) + Step 6
        agent.update_multipliers(means_in)     # Step 7 (form zbar_i) + Step 8 (Eq. 4c)
    result = agent.result()                    # plan; apply result.input_now on [t, t + h)

:func:`solve_admm_round` is that loop over an ideal synchronous network (paper
Assumption 1: every message delivered, in order), for simulation, tests and
benchmarks; a real swarm replaces only the routing.

**Why Steps 4-7 are Eq. (4b).** With E z = 0 denoting the consensus
constraints w_ji = p_j (Eq. 2d), (4b) is zbar^{l+1} = argmin_{E zbar = 0} L_rho(z^{l+1}, zbar, gamma^l)
= Proj_{ker E}(z^{l+1} + gamma^l / rho). Every gamma^l lies in range(E'),
which is Eq. (5): it holds for gamma^0 (0, or a shifted warm start, below),
and (4c) adds rho (z - Proj(z)), which lies in range(E') again. So (4b) is
Proj_{ker E}(z^{l+1}), and ker E is "every copy of p_j equals p_j": the
projection replaces each position trajectory and all its copies by their
mean (Step 5) and leaves every other component (v, u, s) as it is.

**Warm start** (paper Sec. 5.1). zbar^0 and gamma^0 are the previous step's
final zbar and gamma shifted by one step (:func:`planners.dmpc.admm.ocp.shift_decision`;
the new last step of zbar's position trajectories is extrapolated linearly,
of everything else, gamma included, repeated). Every holder of a
trajectory shifts it the same way, so each group of gamma entries (a p_j and
its copies) still sums to zero and v, u, s entries stay zero: Eq. (5) holds.
The paper's first step uses zbar^0 = gamma^0 = 0; a zero position is the
world origin here, so our cold start uses gamma^0 = 0 and zbar^0 = the
drone's free response (u = 0 after the fixed u[0]) with each copy w_ji put
at p_i - d_ij, where j would be in formation (no message needed). OSQP is
warm-started too: within a step from its previous solve, across steps from
the shifted primal and dual solution.

**Remark 1** (computational delay) is ``delay_compensation`` (default on, as
in the paper): u_i[0] is fixed to the input being applied on [t, t + h),
which the previous step decided as its u_i[1], so a round may use the whole
step h; the applied input is always ``result.input_now``. The first step
fixes u_i[0] = 0 (or ``input_now_world``).

Measured (Tables 2-3 analogue, distance to the optimum, sweep): docs/results/admm_formation.md#benchmark-output.

**dSQP** (Algorithm 3, ``config.solver == "dsqp"``). With the Gauss-Newton
Hessian (Remark 4) and a quadratic f_i, dSQP's QP (6) is the ADMM QP with the
minimum-distance rows of Eq. 8 linearised at the SQP iterate
(:mod:`planners.dmpc.admm.local_qp`). Its inner ADMM (Steps 4-13) is
Algorithm 2 on the step Delta z = z - z^q with Delta zbar^0 = 0; in absolute
variables that is zbar^0 = z^q, the averaging and the multiplier update
unchanged (the projection onto ker E is linear and z^q is in it), and Step 14,
z^{q+1} = z^q + Delta zbar, is the current zbar; gamma is carried across SQP
iterations (Step 14). So an MPC step runs q_max l_max ADMM iterations, and
every l_max of them (at the start of each SQP iteration) the drone
re-linearises the distance rows of the pairs it holds
(:func:`planners.dmpc.admm.distance.owned_partners`) at its zbar, which the
last averaging made consensual. In a cold step (no warm start) the copies are
guesses (each neighbour where it would be in formation), so the first SQP
iteration leaves the rows free and linearises from the second on. The
messages are ADMM's: nothing more per SQP iteration. Eq. 7's dynamic
stopping test needs network-wide norms and is not run onboard: q_max and
l_max are fixed, as in the paper's experiments (Sec. 5.3).

Left out: lost or late messages (Assumption 1 is
assumed here, :func:`solve_admm_round` is the ideal network;
:mod:`mpcde.onboard.admm` flies over a lossy radio with
:meth:`AdmmFormationAgent.add_to_copy_multiplier`); the triple integrator.
"""

from __future__ import annotations

import time
from collections import defaultdict
from collections.abc import Mapping, Sequence

import numpy as np

from planners.dmpc.admm.config import AdmmFormationConfig
from planners.dmpc.admm.distance import owned_partners
from planners.dmpc.admm.local_qp import LocalAdmmQp
from planners.dmpc.admm.ocp import DroneLayout, shift_decision, shift_dual
from planners.dmpc.admm.types import AdmmStepResult, CopyMessage, MeanMessage
from planners.dmpc.model import rollout

__all__ = ["AdmmFormationAgent", "solve_admm_round"]


class AdmmFormationAgent:
    """One drone's side of the formation ADMM (onboard: own data and received messages only).

    Args:
        drone_id: this drone's id i.
        config: the :class:`AdmmFormationConfig` (the same on every drone).
        neighbour_offsets: {j: d_ij (3,)} for every neighbour j (coupling =
            communication graph, Assumption 1), d_ij = desired p_i - p_j [m].
    """

    def __init__(
        self, drone_id: int, config: AdmmFormationConfig, neighbour_offsets: Mapping[int, np.ndarray]
    ) -> None:
        self.drone_id = int(drone_id)
        if self.drone_id in neighbour_offsets:
            raise ValueError(f"neighbour_offsets: drone {self.drone_id} lists itself as a neighbour")
        self.config = config
        partners = owned_partners(self.drone_id, neighbour_offsets) if config.solver == "dsqp" else ()
        self._qp = LocalAdmmQp(config, self.drone_id, dict(neighbour_offsets), partners)
        self._cold = True  # the current step started without a warm start
        self._offsets = {int(j): np.asarray(d, float).reshape(3) for j, d in neighbour_offsets.items()}
        self._z: np.ndarray | None = None  # z_i^l (n_i,)
        self._zbar: np.ndarray | None = None  # zbar_i^l (n_i,)
        self._gamma: np.ndarray | None = None  # gamma_i^l (n_i,)
        self._y: np.ndarray | None = None  # OSQP dual of the last local solve (m_i,)
        self._xbar_own: np.ndarray | None = None  # xbar_i^{l+1} (3K,) between Steps 5 and 7
        self._state = np.zeros(6)
        self._t0_s = 0.0
        self._phase = "idle"  # idle -> local -> average -> update -> local ...
        self._bounds_pending = False
        self._reset_history()

    # ------------------------------------------------------------------ properties
    @property
    def layout(self) -> DroneLayout:
        """Where p, v, u, s and each copy w_ji lie in z_i."""
        return self._qp.layout

    @property
    def neighbour_ids(self) -> tuple[int, ...]:
        """Sorted ids of the neighbours."""
        return self._qp.layout.neighbour_ids

    @property
    def local_qp(self) -> LocalAdmmQp:
        """The drone's local QP (4a) (OSQP set up once)."""
        return self._qp

    @property
    def iteration(self) -> int:
        """ADMM iterations completed in the current MPC step."""
        return len(self._primal)

    @property
    def z(self) -> np.ndarray:
        """(n_i,) z_i^l, the last local QP solution (copy)."""
        return self._require(self._z, "z").copy()

    @property
    def zbar(self) -> np.ndarray:
        """(n_i,) zbar_i^l (copy)."""
        return self._require(self._zbar, "zbar").copy()

    @property
    def gamma(self) -> np.ndarray:
        """(n_i,) gamma_i^l (copy)."""
        return self._require(self._gamma, "gamma").copy()

    def _require(self, value: np.ndarray | None, name: str) -> np.ndarray:
        if value is None:
            raise RuntimeError(f"drone {self.drone_id}: no {name} yet (call start_step and run an iteration)")
        return value

    def _reset_history(self) -> None:
        self._primal: list[float] = []
        self._dual: list[float] = []
        self._qp_s: list[float] = []
        self._book_s: list[float] = []
        self._osqp_iter: list[int] = []
        self._rho_updates = 0
        self._max_iter_hits = 0

    # ------------------------------------------------------------------ MPC step
    def start_step(
        self,
        state_world: np.ndarray,
        reference_world: np.ndarray,
        t_now_s: float = 0.0,
        input_now_world: np.ndarray | None = None,
    ) -> None:
        """Algorithm 1 Step 3: a new MPC step from the measured state; sets zbar^0, gamma^0.

        Args:
            state_world: (6,) x_i(t) = [p (3) m, v (3) m/s], world frame.
            reference_world: (K, 3) r_i[1..K], the drone's own reference at
                t + k h, k = 1..K [m].
            t_now_s: absolute time t [s] (labels the plan).
            input_now_world: (3,) u_i(t) [m/s^2] being applied on [t, t + h),
                which u[0] is fixed to with ``delay_compensation`` (Remark 1);
                None = u[1] of the last local solution of the previous step
                (0 in the first step). Ignored without delay compensation.
        """
        cfg, lay = self.config, self.layout
        K = cfg.horizon_steps
        state = np.asarray(state_world, float)
        ref = np.asarray(reference_world, float)
        if state.shape != (6,) or not np.all(np.isfinite(state)):
            raise ValueError(f"state_world shape {state.shape}: a finite (6,) [p, v]")
        if ref.shape != (K, 3) or not np.all(np.isfinite(ref)):
            raise ValueError(f"reference_world shape {ref.shape}: a finite ({K}, 3)")
        u_now = None
        if cfg.delay_compensation:
            if input_now_world is not None:
                u_now = np.asarray(input_now_world, float).reshape(3)
            else:
                u_now = np.zeros(3) if self._z is None else self._z[lay.inp][3:6].copy()  # previous u[1]
        self._qp.set_step(state, ref, u_now)
        warm = cfg.warm_start and self._zbar is not None and self._z is not None and self._y is not None
        if warm:
            zbar = shift_decision(self._zbar, lay, extrapolate_positions=True)  # zbar^0: shifted (Sec. 5.1)
            gamma = shift_decision(self._gamma, lay, extrapolate_positions=False)  # gamma^0: shifted, Eq. (5) kept
            self._qp.warm_start(shift_decision(self._z, lay, True), shift_dual(self._y, K))
        else:
            inputs = np.zeros((K, 3))
            if u_now is not None:
                inputs[0] = u_now
            states = rollout("double", cfg.step_s, state, inputs)[1:]  # free response x[1..K]
            zbar = np.zeros(lay.size)
            zbar[lay.pos], zbar[lay.vel], zbar[lay.inp] = states[:, :3].ravel(), states[:, 3:].ravel(), inputs.ravel()
            for j, d in self._offsets.items():
                zbar[lay.copy(j)] = (states[:, :3] - d).ravel()  # where j would be in formation
            gamma = np.zeros(lay.size)  # satisfies Eq. (5)
            self._qp.warm_start(zbar, np.zeros(self._qp.A.shape[0]))
        self._zbar, self._gamma = zbar, gamma
        self._cold = not warm
        self._state, self._t0_s = state.copy(), float(t_now_s)
        self._bounds_pending = True
        self._phase = "local"
        self._reset_history()

    # ------------------------------------------------------------------ ADMM iteration
    def local_step(self) -> list[CopyMessage]:
        """Step 3 (Eq. 4a: local QP with OSQP) and Step 4 (send each copy w_ji to its owner j)."""
        self._expect("local")
        t0 = time.perf_counter()
        if self._qp.distance is not None and self.iteration % self.config.l_max == 0:  # dSQP Step 3: linearise at z^q
            self._qp.linearise(self._zbar, free=self._cold and self.iteration == 0)
        sol, y = self._qp.solve(self._gamma, self._zbar, update_bounds=self._bounds_pending)
        t1 = time.perf_counter()
        self._bounds_pending = False
        self._z, self._y = sol.z, y
        self._osqp_iter.append(sol.iterations)
        self._rho_updates += sol.rho_updates
        self._max_iter_hits += int(sol.hit_max_iter)
        K, it = self.config.horizon_steps, self.iteration + 1
        lay = self.layout
        out = [CopyMessage(self.drone_id, j, it, sol.z[lay.copy(j)].reshape(K, 3)) for j in lay.neighbour_ids]
        self._qp_s.append(t1 - t0)
        self._book_s.append(time.perf_counter() - t1)
        self._phase = "average"
        return out

    def average(self, received: Sequence[CopyMessage]) -> list[MeanMessage]:
        """Step 5 (xbar_i = mean of the own p_i and every neighbour's copy of it) and Step 6 (send it).

        Args:
            received: one :class:`CopyMessage` from each neighbour, addressed
                to this drone, of the current iteration.
        """
        self._expect("average")
        t0 = time.perf_counter()
        copies = self._one_per_neighbour(received, CopyMessage)
        lay = self.layout
        total = self._z[lay.pos].copy()
        for j in lay.neighbour_ids:
            total += copies[j].pos_world.ravel()
        xbar = total / (len(lay.neighbour_ids) + 1)  # xbar_i = (x_i + sum_j w_ij) / (|N_out| + 1)
        self._xbar_own = xbar
        K, it = self.config.horizon_steps, self.iteration + 1
        out = [MeanMessage(self.drone_id, j, it, xbar.reshape(K, 3)) for j in lay.neighbour_ids]
        self._book_s[-1] += time.perf_counter() - t0
        self._phase = "update"
        return out

    def update_multipliers(self, received: Sequence[MeanMessage]) -> None:
        """Step 7 (zbar_i = col(xbar_i, v_i, u_i, s_i, xbar_j for j)) and Step 8 (Eq. 4c).

        Args:
            received: one :class:`MeanMessage` from each neighbour, of the current iteration.
        """
        self._expect("update")
        t0 = time.perf_counter()
        means = self._one_per_neighbour(received, MeanMessage)
        lay, rho = self.layout, self.config.rho
        zbar = self._z.copy()  # v, u, s: the projection leaves them (they appear once)
        zbar[lay.pos] = self._xbar_own
        for j in lay.neighbour_ids:
            zbar[lay.copy(j)] = means[j].pos_world.ravel()
        diff = self._z - zbar
        self._primal.append(float(np.linalg.norm(diff)))  # ||z_i - zbar_i||
        self._dual.append(rho * float(np.linalg.norm(zbar - self._zbar)))  # rho ||zbar^{l+1} - zbar^l||
        self._gamma = self._gamma + rho * diff  # gamma^{l+1} = gamma^l + rho (z^{l+1} - zbar^{l+1})  (4c)
        self._zbar = zbar
        self._book_s[-1] += time.perf_counter() - t0
        self._phase = "local"

    def add_to_copy_multiplier(self, j: int, delta_world: np.ndarray) -> None:
        """gamma_i's block of the copy w_ji += ``delta_world`` (K, 3): a Step 8 (4c) term applied late.

        For a lossy network (:mod:`mpcde.onboard.admm`): a drone that missed
        xbar_j^l left its copy's block out of Step 8 in iteration l (zbar = its
        own copy there); adding rho (w_ji^l - xbar_j^l) once it learns
        xbar_j^l restores Eq. (5) for j's trajectory. Allowed in any phase of
        a started step (Step 3 reads gamma).
        """
        gamma = self._require(self._gamma, "gamma")
        delta = np.asarray(delta_world, float)
        if delta.shape != (self.config.horizon_steps, 3) or not np.all(np.isfinite(delta)):
            raise ValueError(f"delta_world shape {delta.shape}: a finite ({self.config.horizon_steps}, 3)")
        gamma[self.layout.copy(j)] += delta.ravel()

    def _expect(self, phase: str) -> None:
        if self._phase != phase:
            raise RuntimeError(f"drone {self.drone_id}: called in phase {self._phase!r}, expected {phase!r}")

    def _one_per_neighbour(self, received: Sequence, kind: type) -> dict:
        it = self.iteration + 1
        by_sender = {}
        for m in received:
            if not isinstance(m, kind) or m.receiver != self.drone_id or m.iteration != it:
                sender, receiver = getattr(m, "sender", None), getattr(m, "receiver", None)
                raise ValueError(
                    f"drone {self.drone_id}: unexpected message {type(m).__name__}(sender={sender}, "
                    f"receiver={receiver}, iteration={getattr(m, 'iteration', None)}) in iteration {it}"
                )
            if m.sender in by_sender:
                raise ValueError(f"drone {self.drone_id}: two {kind.__name__}s from drone {m.sender}")
            by_sender[m.sender] = m
        missing = set(self.neighbour_ids) - set(by_sender)
        extra = set(by_sender) - set(self.neighbour_ids)
        if missing or extra:
            raise ValueError(
                f"drone {self.drone_id}: {kind.__name__}s missing from {sorted(missing)}, "
                f"from non-neighbours {sorted(extra)} (Assumption 1: every message delivered)"
            )
        K = self.config.horizon_steps
        for m in by_sender.values():
            if m.pos_world.shape != (K, 3):
                raise ValueError(f"drone {self.drone_id}: message from {m.sender} has shape {m.pos_world.shape}")
        return by_sender

    # ------------------------------------------------------------------ result
    def result(self) -> AdmmStepResult:
        """The plan of the current MPC step (own part of z_i^l, Algorithm 2 Step 11) and its figures."""
        if self._z is None or not self._primal:
            raise RuntimeError(f"drone {self.drone_id}: no ADMM iteration completed in this step")
        lay, K = self.layout, self.config.horizon_steps
        z = self._z
        pos = np.vstack([self._state[:3], z[lay.pos].reshape(K, 3)])
        vel = np.vstack([self._state[3:], z[lay.vel].reshape(K, 3)])
        acc = z[lay.inp].reshape(K, 3).copy()
        return AdmmStepResult(
            drone_id=self.drone_id,
            t0_s=self._t0_s,
            h_s=self.config.step_s,
            pos_world=pos,
            vel_world=vel,
            acc_world=acc,
            slack=max(float(z[lay.slack]), 0.0),
            iterations=self.iteration,
            primal_residual=np.array(self._primal),
            dual_residual=np.array(self._dual),
            qp_solve_s=np.array(self._qp_s),
            bookkeeping_s=np.array(self._book_s),
            osqp_iterations=np.array(self._osqp_iter),
            osqp_rho_updates=self._rho_updates,
            osqp_max_iter_hits=self._max_iter_hits,
            local_cost=self._qp.objective(z),
        )


def solve_admm_round(agents: Sequence[AdmmFormationAgent], l_max: int | None = None) -> list[AdmmStepResult]:
    """Algorithm 2 for one MPC step: ``l_max`` iterations over an ideal synchronous network (Assumption 1).

    Every agent must have had :meth:`AdmmFormationAgent.start_step` called
    for this step. Messages are passed to their receivers unchanged and
    without loss. Calling it again in the same step continues the
    iterations (the results then count all of them).

    Args:
        agents: one agent per drone, unique ids; the neighbour lists must be
            symmetric (j is a neighbour of i iff i is one of j).
        l_max: iterations to run (default: ``config.iterations_per_step`` of the
            first agent: l_max, or q_max l_max with dSQP).

    Returns:
        one :class:`AdmmStepResult` per agent, in the order of ``agents``.
    """
    by_id = {a.drone_id: a for a in agents}
    if len(by_id) != len(agents):
        raise ValueError("agents: two agents share a drone id")
    for a in agents:
        for j in a.neighbour_ids:
            if j not in by_id or a.drone_id not in by_id[j].neighbour_ids:
                raise ValueError(f"agents: drone {a.drone_id} lists {j} as a neighbour but not the reverse")
    iterations = agents[0].config.iterations_per_step if l_max is None else int(l_max)
    if iterations < 1:
        raise ValueError(f"l_max={l_max!r}: an integer >= 1")
    for _ in range(iterations):
        inbox: dict[int, list] = defaultdict(list)
        for a in agents:  # Steps 3-4
            for m in a.local_step():
                inbox[m.receiver].append(m)
        mean_inbox: dict[int, list] = defaultdict(list)
        for a in agents:  # Steps 5-6
            for m in a.average(inbox[a.drone_id]):
                mean_inbox[m.receiver].append(m)
        for a in agents:  # Steps 7-8
            a.update_multipliers(mean_inbox[a.drone_id])
    return [a.result() for a in agents]
