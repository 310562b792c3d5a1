"""The per-drone DMPC quadratic program (on-demand DMPC Sec. 3; BVC baseline, DMPC-Swarm Eq. 14-15).

Decision variables z = [U; s]: the stacked inputs U = [u[0]; ...; u[K-1]] (3K,)
(acceleration for the double integrator, jerk for the triple one) and, in
on-demand mode, one slack s_m >= 0 [m] per neighbour slot. With the prediction
P = A0_p x0 + Lambda_p U (on-demand DMPC Eq. 10, :mod:`planners.dmpc.model`)::

    min  sum_{k=K-theta+1}^{K} q_g ||p[k] - p_goal||^2                      (F_e, goal)
       + sum_{j in F} sum_{k=1}^{K} q_f ||p[k] - (p_j[k] - d_ij)||^2          (F_f, formation)
       + sum_{k=0}^{K-1} q_Theta ||u[k] - u[k-1]||^2                          (F_Theta, smoothness)
       + sum_m zeta s_m^2 + xi s_m                                            (F_v, slack)
    s.t. p_min <= p[k] <= p_max,  |v[k]| <= v_max_mps,  |a| <= a_max_mps2  (|j| <= j_max_mps3)   (box, per axis)
         on demand: a_m^T p(t_c) + s_m >= b_m,  0 <= s_m <= s_max                  (Sec. 3.4)
         bvc:       a_mk^T p[k] >= b_mk  for every neighbour m and step k            (Eq. 15)
         obstacles: n_ok^T p[k] >= c_ok  every step, or on demand only at the        (half-spaces,
                    first predicted conflict of each obstacle (one row per slot)     planners.dmpc.obstacle)
         optional terminal halt: v[K] = 0 (a[K] = 0)                                (DMPC-Swarm Eq. 13e)

with d_ij the desired offset p_j - p_i (on-demand DMPC design goal 2), u[-1] the input applied in the previous
round (read from the previous plan),
and p(t_c) the position at the on-demand plane's time, affine in U like p[k]
(t_c on a grid of h / ``conflict_substeps``; the closest approach of the
conflict that starts at the first conflict k_c, or k_c itself with
``on_demand_time="first_conflict"``; see :mod:`planners.dmpc.collision`).
Neighbours are read at the round's times from their :class:`NeighborPrediction` (a received plan, possibly
stale: its tail extrapolates at constant velocity).
If more neighbours are given than ``max_neighbours`` slots, the nearest are kept (on demand: nearest at the
conflict; BVC: nearest over the horizon). Written for OSQP as  min 1/2 z^T P z + q^T z  s.t.  l <= A z <= u.

Build, then solve: :class:`DmpcProblem` sets OSQP up once with a FIXED sparsity
pattern sized for every row it may need (:mod:`planners.dmpc.sparse_qp.qp_layout`;
an unused row keeps its entries at 0 with bounds (-inf, inf)). Each round updates only
``q``, ``l``, ``u`` and ``Ax`` (``Px`` when the number of formation neighbours changes)
and warm-starts from the previous primal and dual solution shifted by one step.

Speed. On-demand rows change only in rounds with a conflict, and an unused slot (neighbour or obstacle) keeps its last
coefficients with bounds (-inf, inf), so most on-demand rounds need no KKT refactorisation; BVC planes and every-step
obstacle planes change every round. P's pattern holds only its structural nonzeros (the cost is separable by axis:
goal, formation and smoothness weigh x, y and z alike and apart), since explicit zeros would enter qdldl's
factorisation. An unused on-demand slot's slack is pinned at 0 with price 0 (same optimum; otherwise its bound carries
the multiplier xi of the linear price and slows ADMM). The QP stays condensed (dense in U); obstacle rows that the
velocity and input limits already imply are culled (:meth:`DmpcProblem._fill_obstacles`); OSQP's Python wrapper is
bypassed (:mod:`planners.dmpc.sparse_qp.osqp_core`); ``osqp_scaling = 4`` because OSQP re-runs its Ruiz equilibration
in every refactorisation. Measured, with the alternatives tried:
docs/results/dmpc_qp.md#why-the-qp-is-built-as-it-is-issue-6s-speed-goals-2026-11-22-to-2026-11-25.
"""

from __future__ import annotations

import time
from collections.abc import Mapping, Sequence
from types import SimpleNamespace

import numpy as np
import osqp
import scipy.sparse as sp

from perception.types import NeighborPrediction
from planners.dmpc.collision import bvc_planes, ellipsoidal_distance, on_demand_constraints
from planners.dmpc.config import DmpcConfig
from planners.dmpc.model import fine_position_matrices, prediction_matrices, stacked_state_matrices
from planners.dmpc.obstacle import ObstacleConflicts, obstacle_rows
from planners.dmpc.sampling import hermite_positions, sample_predictions
from planners.dmpc.sparse_qp.osqp_core import solver_core
from planners.dmpc.sparse_qp.pattern import SparsePattern
from planners.dmpc.sparse_qp.qp_layout import qp_rows
from planners.dmpc.sparse_qp.qp_result import DmpcResult, DmpcSolveError, QpSnapshot
from planners.dmpc.types import DmpcPlan

__all__ = ["DmpcProblem", "DmpcResult", "DmpcSolveError", "QpSnapshot"]

_INF = 1e30  # OSQP_INFTY
_CULL_MARGIN_M = 0.01  # an obstacle row is culled only if the reach boxes clear it by this [m]
_ACCEPTED = (osqp.SolverStatus.OSQP_SOLVED, osqp.SolverStatus.OSQP_SOLVED_INACCURATE)


class DmpcProblem:
    """One drone's DMPC QP, built once (fixed sparsity) and re-solved every round.

    Args:
        config: the :class:`DmpcConfig`.
    """

    def __init__(self, config: DmpcConfig) -> None:
        self.config = config
        cfg = config
        K, M, O = cfg.horizon_steps, cfg.max_neighbours, cfg.max_obstacle_planes
        self.matrices = prediction_matrices(cfg.model, cfg.step_s, K)
        mats = self.matrices
        self._n_u = 3 * K
        self._n_slack = M if cfg.collision_mode == "on_demand" else 0
        n = self._n_u + self._n_slack
        self._Lambda_pos_blocks = mats.Lambda_pos.reshape(K, 3, 3 * K)
        self._state_matrices = stacked_state_matrices(mats.A, mats.B, K)  # x[1..K] for the result
        S = cfg.conflict_substeps
        A0_fine, Lambda_fine = fine_position_matrices(cfg.model, cfg.step_s, K, S)
        self._A0_fine_blocks = A0_fine.reshape(K * S, 3, -1)  # p(t_now + j h / S), j = 1..K S
        self._Lambda_fine_blocks = Lambda_fine.reshape(K * S, 3, 3 * K)
        self._lower_mask = np.arange(3 * K)[None, :] < 3 * (np.arange(K)[:, None] + 1)  # (K, 3K): inputs 0..k-1 reach p[k]
        self._rows = rows = qp_rows(cfg, mats, self._n_slack)
        A, row = rows.A, rows.n
        self._Ax = A.data.copy()
        self._Ax_sent = A.data.copy()  # what OSQP holds

        # Cost Hessian pieces (on U), P = 2 (goal + formation + smoothness) + slack.
        goal_rows = slice(3 * (K - cfg.goal_steps), 3 * K)
        L_goal = mats.Lambda_pos[goal_rows]
        self._goal_rows = goal_rows
        D = np.eye(3 * K) - np.eye(3 * K, k=-3)  # (D U)_k = u[k] - u[k-1], u[-1] enters through q
        self._D = D
        self._H_base = 2.0 * cfg.weight_goal * L_goal.T @ L_goal + 2.0 * cfg.weight_smoothness * D.T @ D
        self._H_form = 2.0 * cfg.weight_formation * mats.Lambda_pos.T @ mats.Lambda_pos
        # The cost is separable by axis (goal, formation and smoothness act on x, y, z alike and alone), so
        # P's U block has no cross-axis entries: its pattern holds only the structural nonzeros, not the
        # dense triangle (explicit zeros would enter the KKT factorisation's fill).
        structural = np.triu((self._H_base != 0.0) | (self._H_form != 0.0))
        iu = np.nonzero(structural)
        self._P_triu = iu
        n_s = self._n_slack
        P_pat = SparsePattern()  # dense U block (upper triangle) + slack diagonal; values set in _assemble_P
        slack = self._n_u + np.arange(n_s)
        P_pat.add(np.r_[iu[0], slack], np.r_[iu[1], slack], np.zeros(iu[0].size + n_s))
        self._P_pattern, self._P_coo_to_csc = P_pat.to_csc((n, n))
        P = self._assemble_P(0)
        self._n_form = 0

        self._l = np.full(row, -_INF)
        self._u = np.full(row, _INF)
        self._osqp = osqp.OSQP()
        self._osqp.setup(
            P, np.zeros(n), A, self._l, self._u,
            verbose=False, eps_abs=cfg.osqp_eps_abs, eps_rel=cfg.osqp_eps_rel,
            max_iter=cfg.osqp_max_iter, polishing=cfg.osqp_polish,
            adaptive_rho_interval=25, warm_starting=True, check_termination=cfg.osqp_check_termination,
            scaling=cfg.osqp_scaling,
        )  # fmt: skip
        self._P, self._A = P, A
        self._core = solver_core(self._osqp)
        self._q = np.zeros(n)
        self._x_last: np.ndarray | None = None  # previous primal solution (None after a failure)
        self._y_last: np.ndarray | None = None  # previous dual solution
        self._snapshot: QpSnapshot | None = None
        self._obstacle_conflicts: ObstacleConflicts | None = None
        self._coll_coef, self._slack_coef = np.zeros((M, 3 * K)), np.zeros(M)  # on-demand slot values
        self._obs_coef = np.zeros((O, 3 * K))  # on-demand obstacle slot values

    # ------------------------------------------------------------------ build
    def _assemble_P(self, n_form: int) -> sp.csc_matrix:
        """Upper-triangular CSC P for ``n_form`` formation neighbours (dense U block + slack diagonal).

        A new matrix on the fixed pattern (a :class:`QpSnapshot` may hold the previous one).
        """
        H = self._H_base + n_form * self._H_form
        vals = np.r_[H[self._P_triu], np.full(self._n_slack, 2.0 * self.config.weight_slack_quadratic)]
        data = np.empty_like(vals)
        data[self._P_coo_to_csc] = vals
        pat = self._P_pattern
        return sp.csc_matrix((data, pat.indices, pat.indptr), shape=pat.shape)

    def _set_dynamic(self, sl: slice, values: np.ndarray) -> None:
        self._Ax[self._rows.coo_to_csc[sl]] = values

    @property
    def obstacle_conflicts(self) -> ObstacleConflicts | None:
        """The last round's on-demand obstacle conflicts (None before one, or with ``every_step``)."""
        return self._obstacle_conflicts

    def snapshot(self) -> QpSnapshot | None:
        """The QP and solution of the last :meth:`solve` (None before the first)."""
        return self._snapshot

    @staticmethod
    def _own_previous(
        t_s: np.ndarray, t_now_s: float, x0: np.ndarray, previous_plan: DmpcPlan | None
    ) -> np.ndarray:
        """Own previous plan at times ``t_s`` (n,) -> (n, 3); constant velocity from x0 without one."""
        if previous_plan is None:
            return x0[:3] + x0[3:6] * (t_s - t_now_s)[:, None]
        plan = previous_plan
        return hermite_positions(plan.times_s[None], plan.pos_world[None], plan.vel_world[None], t_s)[0]

    def _previous_input(self, t_now_s: float, previous_plan: DmpcPlan | None) -> np.ndarray:
        """u[-1]: the input the previous plan held on [t_now - h, t_now) (zeros without one)."""
        h = self.config.step_s
        if previous_plan is None or not (previous_plan.t0_s <= t_now_s - 0.5 * h < previous_plan.t_end_s):
            return np.zeros(3)
        if self.config.model == "double":
            return previous_plan.acceleration(t_now_s - 0.5 * h)
        return (previous_plan.acceleration(t_now_s) - previous_plan.acceleration(t_now_s - h)) / h  # jerk

    # ------------------------------------------------------------------ solve
    def solve(
        self,
        x0: np.ndarray,
        goal: np.ndarray,
        neighbour_plans: Sequence[NeighborPrediction],
        previous_plan: DmpcPlan | None,
        formation_offsets: Mapping[int, np.ndarray] | None = None,
        *,
        t_now_s: float,
        obstacles: Sequence[tuple[np.ndarray, np.ndarray | float]] | None = None,
    ) -> DmpcResult:
        """Solve one DMPC round from state ``x0`` at time ``t_now_s``.

        Args:
            x0: (6,) ``[p, v]`` (double) or (9,) ``[p, v, a]`` (triple), world [m, m/s, m/s^2].
            goal: (3,) goal position p_goal in world [m].
            neighbour_plans: predictions of the other drones (radio plans or
                tracks), evaluated at t_now + k h, k = 1..K (a stale plan is
                used as it is: its tail extrapolates at constant velocity).
            previous_plan: this drone's previous plan (any start time; it is
                evaluated at the current round's times), or None (then a
                constant-velocity guess from x0).
            formation_offsets: desired p_j - p_i (3,) [m] by neighbour id; only
                neighbours present in ``neighbour_plans`` count.
            t_now_s: current absolute time [s] (the plan's t0).
            obstacles: static obstacle half-spaces ``(normal, offset)`` with
                normal (3,) or (K, 3) and offset scalar or (K,), meaning
                normal^T p[k] >= offset [m]; at most ``max_obstacle_planes``.
                Every step, or on demand only at each obstacle's first
                predicted conflict of ``previous_plan`` (``obstacle_avoidance``).

        Raises:
            DmpcSolveError: OSQP did not return a solution (carries the QP).
            ValueError: bad shapes or too many obstacle planes.
        """
        t_start = time.perf_counter()
        cfg, mats = self.config, self.matrices
        K, M, h = cfg.horizon_steps, cfg.max_neighbours, cfg.step_s
        x0 = np.asarray(x0, float)
        if x0.shape != (cfg.state_dim,):
            raise ValueError(f"x0 shape {x0.shape}: expected ({cfg.state_dim},) for model {cfg.model!r}")
        goal = np.asarray(goal, float).reshape(3)
        S = cfg.conflict_substeps
        t_fine = float(t_now_s) + (h / S) * np.arange(1, K * S + 1)  # check times; every S-th is a sample
        own_prev_fine = self._own_previous(t_fine, float(t_now_s), x0, previous_plan)
        own_prev = own_prev_fine[S - 1 :: S]
        nb_ids = [p.neighbor_id for p in neighbour_plans]
        t_eval = np.r_[float(t_now_s), t_fine]
        nb_all = sample_predictions(neighbour_plans, t_eval)  # (M, K S + 1, 3), one vectorised evaluation
        nb_now, nb_fine = nb_all[:, 0], nb_all[:, 1:]
        nb_pos = nb_fine[:, S - 1 :: S]  # (M, K, 3) at t_now + k h

        free_pos = (mats.A0_pos @ x0).reshape(K, 3)  # A0_p x0
        l, u = self._l, self._u
        # Box constraints (on-demand DMPC Sec. 3.4 (1)): P_min - A0 x0 <= Lambda U <= P_max - A0 x0.
        rp = slice(self._rows.pos, self._rows.pos + 3 * K)
        l[rp] = (np.asarray(cfg.pos_min_world)[None] - free_pos).ravel()
        u[rp] = (np.asarray(cfg.pos_max_world)[None] - free_pos).ravel()
        rv = slice(self._rows.vel, self._rows.vel + 3 * K)
        free_vel = mats.A0_vel @ x0
        l[rv], u[rv] = -cfg.limits.v_max_mps - free_vel, cfg.limits.v_max_mps - free_vel
        ra = slice(self._rows.acc, self._rows.acc + 3 * K)
        free_acc = mats.A0_acc @ x0
        l[ra], u[ra] = -cfg.limits.a_max_mps2 - free_acc, cfg.limits.a_max_mps2 - free_acc
        if cfg.terminal_halt:  # v[K] = 0 (a[K] = 0): DMPC-Swarm Eq. 13e
            last = slice(self._rows.vel + 3 * K - 3, self._rows.vel + 3 * K)
            l[last] = u[last] = -free_vel[-3:]
            if cfg.model == "triple":
                last = slice(self._rows.acc + 3 * K - 3, self._rows.acc + 3 * K)
                l[last] = u[last] = -free_acc[-3:]
        if cfg.model == "triple":
            rj = slice(self._rows.jerk, self._rows.jerk + 3 * K)
            l[rj], u[rj] = -cfg.limits.j_max_mps3, cfg.limits.j_max_mps3

        # Collision rows.
        slack_cols = np.arange(self._n_slack)
        n_coll, conflict_time_s = 0, float("nan")
        rc = slice(self._rows.coll, self._rows.coll + self._rows.n_coll)
        l[rc], u[rc] = -_INF, _INF
        if cfg.collision_mode == "on_demand":
            cons = on_demand_constraints(
                own_prev_fine, nb_fine, cfg.r_min_m, cfg.downwash, cfg.conflict_margin_m,
                cfg.neighbourhood_factor, x0[:3], nb_now, cfg.on_demand_time,
            )  # fmt: skip
            keep = np.argsort(cons.distance_m)[:M]  # nearest first if more than the slots
            n_coll = keep.size
            # Unused slots keep their last coefficients (their bounds are -inf..inf and their slack is
            # pinned at 0, so they constrain nothing): a round whose conflicts end leaves A unchanged.
            coef, slack_coef = self._coll_coef, self._slack_coef
            if n_coll:
                conflict_time_s = float(t_fine[cons.step_index])  # first conflicting check time
                j_c = cons.time_index[keep]  # (n,) constrained check times
                a = cons.normal[keep]
                coef[:n_coll] = np.einsum("nd,ndc->nc", a, self._Lambda_fine_blocks[j_c])  # a^T Lambda_p(t_c) U
                slack_coef[:n_coll] = cons.sigma[keep]  # + sigma s  (s = -alpha)
                free_c = self._A0_fine_blocks[j_c] @ x0  # A0_p(t_c) x0, (n, 3)
                # a^T Lambda U + s >= b - a^T A0 x0   (on-demand DMPC Sec. 3.4)
                l[self._rows.coll : self._rows.coll + n_coll] = cons.offset[keep] - np.einsum("nd,nd->n", a, free_c)
            self._set_dynamic(self._rows.coll_entries, coef.ravel())
            self._set_dynamic(self._rows.slack_coef_entries, slack_coef)
            rs = slice(self._rows.slack, self._rows.slack + M)
            l[rs], u[rs] = 0.0, cfg.slack_max_m
            # An unused slot's slack is pinned to 0 (and priced 0 below): the same optimum, but
            # its bound no longer carries the multiplier xi = 5e4 that the linear price put on
            # it, which slowed ADMM (measured:
            # docs/results/dmpc_qp.md#why-the-qp-is-built-as-it-is-issue-6s-speed-goals-2026-11-22-to-2026-11-25).
            u[self._rows.slack + n_coll : self._rows.slack + M] = 0.0
        else:
            chosen = self._nearest(own_prev, nb_pos, M)
            coef = np.zeros((M, K, 3 * K))
            if chosen.size:
                planes = bvc_planes(own_prev, nb_pos[chosen], cfg.r_min_m, cfg.downwash, x0[:3], nb_now[chosen])
                m = chosen.size
                coef[:m] = np.einsum("mkd,kdc->mkc", planes.normal, self._Lambda_pos_blocks)
                rhs = planes.offset - np.einsum("mkd,kd->mk", planes.normal, free_pos)  # b - a^T A0 x0, Eq. 15
                l[self._rows.coll : self._rows.coll + m * K] = rhs.ravel()
                n_coll = m * K
            self._set_dynamic(self._rows.coll_entries, coef[:, self._lower_mask].ravel())

        n_obs = 0
        if cfg.max_obstacle_planes:
            n_obs = self._fill_obstacles(obstacles, free_pos, x0, own_prev)
        elif obstacles:
            raise ValueError(f"obstacles: {len(obstacles)} planes given but max_obstacle_planes=0")

        # Linear cost q.
        q = self._q
        goal_err = (np.tile(goal, K) - mats.A0_pos @ x0)[self._goal_rows]
        q_u = -2.0 * cfg.weight_goal * mats.Lambda_pos[self._goal_rows].T @ goal_err  # F_e
        u_prev = self._previous_input(float(t_now_s), previous_plan)
        e = np.zeros(3 * K)
        e[:3] = u_prev
        q_u -= 2.0 * cfg.weight_smoothness * self._D.T @ e  # F_Theta with u[-1]
        form_targets = self._formation_targets(nb_ids, nb_pos, formation_offsets)
        if form_targets.shape[0]:
            resid = (form_targets - free_pos[None]).reshape(form_targets.shape[0], -1).sum(axis=0)
            q_u -= 2.0 * cfg.weight_formation * mats.Lambda_pos.T @ resid  # F_f
        q[: self._n_u] = q_u
        q[self._n_u :] = cfg.weight_slack_linear  # F_v linear part
        q[self._n_u + n_coll :] = 0.0  # unused slots (pinned at 0 above)

        update = {"q": q, "l": l, "u": u}
        if not np.array_equal(self._Ax, self._Ax_sent):  # unchanged A (no conflicts twice): no refactorisation
            update["Ax"] = self._Ax
            self._Ax_sent = self._Ax.copy()
        if form_targets.shape[0] != self._n_form:
            self._n_form = form_targets.shape[0]
            self._P = self._assemble_P(self._n_form)
            update["Px"] = self._P.data
        t_solve = time.perf_counter()
        if self._x_last is not None:
            x_ws, y_ws = self._rows.shifted_warm_start(self._x_last, self._y_last, n_coll, n_obs)
        else:
            x_ws, y_ws = np.zeros(self._P.shape[0]), np.zeros(self._rows.n)
        res = self._run_osqp(update, x_ws, y_ws)
        t_end = time.perf_counter()
        A = sp.csc_matrix((self._Ax.copy(), self._A.indices, self._A.indptr), shape=self._A.shape)
        status = str(res.info.status)
        self._snapshot = QpSnapshot(self._P, q.copy(), A, l.copy(), u.copy(), res.x, res.y, status)
        if res.info.status_val not in _ACCEPTED:
            self._x_last = self._y_last = None
            raise DmpcSolveError(status, self._snapshot)
        self._x_last, self._y_last = res.x, res.y
        return self._result(
            res, x0, goal, float(t_now_s), e, form_targets, n_coll, conflict_time_s,
            t_solve - t_start, t_end - t_solve, n_obs, "Ax" in update or "Px" in update,
        )  # fmt: skip

    def _run_osqp(self, update: dict[str, np.ndarray], x_ws: np.ndarray, y_ws: np.ndarray) -> SimpleNamespace:
        """Update OSQP's data, warm-start and solve (:mod:`planners.dmpc.sparse_qp.osqp_core`); returns ``x``, ``y`` (copies) and ``info``."""
        core = self._core
        core.update_data_vec(q=update["q"], l=update["l"], u=update["u"])
        if "Ax" in update or "Px" in update:
            core.update_data_mat(P_x=update.get("Px"), P_i=None, A_x=update.get("Ax"), A_i=None)
        core.warm_start(x_ws, y_ws)
        core.solve()
        return SimpleNamespace(x=np.array(core.solution.x), y=np.array(core.solution.y), info=core.info)

    def _nearest(self, own_prev: np.ndarray, nb_pos: np.ndarray, count: int) -> np.ndarray:
        """Indices of the ``count`` neighbours closest (over the horizon) to the own previous plan."""
        if nb_pos.shape[0] <= count:
            return np.arange(nb_pos.shape[0])
        d = ellipsoidal_distance(own_prev[None] - nb_pos, self.config.downwash).min(axis=1)
        return np.sort(np.argsort(d)[:count])

    def _formation_targets(
        self, nb_ids: list[int], nb_pos: np.ndarray, offsets: Mapping[int, np.ndarray] | None
    ) -> np.ndarray:
        """(F, K, 3) formation targets p_j[k] - d_ij for neighbours with a desired offset."""
        if not offsets or self.config.weight_formation == 0.0:
            return np.zeros((0, self.config.horizon_steps, 3))
        rows = [nb_pos[i] - np.asarray(offsets[j], float).reshape(1, 3) for i, j in enumerate(nb_ids) if j in offsets]
        return np.array(rows).reshape(-1, self.config.horizon_steps, 3)

    def _fill_obstacles(
        self, obstacles: Sequence | None, free_pos: np.ndarray, x0: np.ndarray, own_prev: np.ndarray
    ) -> int:
        """Obstacle rows (every step or on demand, :func:`planners.dmpc.obstacle.obstacle_rows`); returns the number used.

        Culled rows (implied by the box constraints with ``_CULL_MARGIN_M`` to
        spare; the margin covers the box rows being met only to OSQP's
        tolerance) are left unused: exactly the same feasible set. Both
        collision modes share this code (a fair comparison).
        """
        if self.config.vertical_obstacle_planes and any(np.any(np.asarray(n, float)[..., 2] != 0.0) for n, _ in obstacles or []):
            raise ValueError("obstacles: a normal with a z component, but vertical_obstacle_planes=True")
        rows = obstacle_rows(self.config, obstacles, x0, free_pos, self._Lambda_pos_blocks, own_prev, _CULL_MARGIN_M)
        self._obstacle_conflicts = rows.conflicts
        coef = rows.coef
        if self._rows.obs_steps == 1:  # on demand: unused slots keep their last coefficients (bounds -inf..inf),
            self._obs_coef[: rows.count] = coef[: rows.count]  # so a round whose conflicts end leaves A unchanged
            coef = self._obs_coef
        mask = np.broadcast_to(self._rows.obs_mask, (self.config.max_obstacle_planes,) + self._rows.obs_mask.shape)
        self._set_dynamic(self._rows.obs_entries, coef.reshape(mask.shape)[mask])
        self._l[self._rows.obs : self._rows.n] = rows.lower
        self._u[self._rows.obs : self._rows.n] = _INF
        return rows.count

    def _result(
        self, res, x0: np.ndarray, goal: np.ndarray, t_now_s: float, e: np.ndarray, form_targets: np.ndarray,
        n_coll: int, conflict_time_s: float, t_update: float, t_solve: float, n_obs: int = 0, refactorised: bool = False,
    ) -> DmpcResult:  # fmt: skip
        """Unpack OSQP's result ``res`` into a :class:`DmpcResult` (states rolled out, J evaluated term by term).

        ``e`` (3K,) is the smoothness offset [u[-1]; 0...], ``form_targets`` (F, K, 3) the formation targets.
        """
        cfg = self.config
        K = cfg.horizon_steps
        U = res.x[: self._n_u]
        s = res.x[self._n_u :]
        A0_x, Lambda_x = self._state_matrices
        states = np.vstack([x0, (A0_x @ x0 + Lambda_x @ U).reshape(K, -1)])  # x[0..K]
        inputs = U.reshape(K, 3)
        pos, vel = states[:, :3], states[:, 3:6]
        if cfg.model == "double":
            acc_samples = np.vstack([inputs, np.zeros((1, 3))])  # a on [t_k, t_k+1) = u[k]; tail 0
            acc_world = inputs.copy()
        else:
            acc_samples = states[:, 6:9]
            acc_world = states[1:, 6:9]
        plan = DmpcPlan(t_now_s, cfg.step_s, pos.copy(), vel.copy(), acc_samples)
        # J = F_e + F_f + F_Theta + F_v, evaluated directly.
        cost = cfg.weight_goal * np.sum((pos[K - cfg.goal_steps + 1 :] - goal) ** 2)
        if form_targets.shape[0]:
            cost += cfg.weight_formation * np.sum((pos[None, 1:] - form_targets) ** 2)
        cost += cfg.weight_smoothness * np.sum((self._D @ U - e) ** 2)
        cost += np.sum(cfg.weight_slack_quadratic * s**2 + cfg.weight_slack_linear * s)
        slack = s[:n_coll].copy() if cfg.collision_mode == "on_demand" else np.zeros(0)
        return DmpcResult(
            plan=plan, pos_world=pos[1:].copy(), vel_world=vel[1:].copy(), acc_world=acc_world,
            inputs=inputs.copy(), cost=float(cost), iterations=int(res.info.iter), status=str(res.info.status),
            solve_time_s=t_solve, osqp_solve_time_s=float(res.info.solve_time), update_time_s=t_update,
            n_collision_constraints=int(n_coll), conflict_time_s=conflict_time_s, slack=slack,
            n_obstacle_rows=int(n_obs), refactorised=bool(refactorised),
        )  # fmt: skip
