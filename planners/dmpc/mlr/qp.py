"""The QP a CU solves for one UAV in MLR-DMPC (DMPC-Swarm Eq. 13a-13f, 14, 15).

Decision variables: the jerk inputs U = [u_0; ...; u_{h_s-1}] (3 h_s,) of the
new trajectory of UAV i, which starts at t_0 = (k + 1) T (one round of
latency) from x0 = x̃_i(2T | k-1), the state at t_0 of the sole trajectory in
D_i(k) (Eq. 13b). With the triple integrator stacked over the input steps,
x_{kappa+1} = A x_kappa + B u_kappa (:mod:`planners.dmpc.model`)::

    min  sum_{kappa=1}^{h_s} ||x(kappa T_s) - x_target||_Q^2 + sum_{kappa=0}^{h_s-1} ||u_kappa||_R^2   (13a)
    s.t. |u_kappa| <= j_max_mps3                                        (13c, per axis)
         p_min <= p(kappa T_s) <= p_max, |v|, |a| <= v_max_mps, a_max_mps2    (13d, T_b = T_s, per axis)
         v(H T) = 0, a(H T) = 0                                     (13e, terminal halt)
         for every other UAV j, every candidate p̃_j in D_j(k), h = 1..h_c, t_h = t_0 + h T_c:
         n0^T Theta^-1 [p̃_j(t_h) - p_i(t_h)] >= (d̂ + ||n||)/2  if j in A_ET(k), else d̂   (13f, 15)
         (d̂ plus a small margin, clipped at ||n||: :func:`time_varying_bvc`)

with n = Theta^-1 [p̃_j(t_h) - p̂_i(t_h)] (Eq. 14) from UAV i's current
trajectory p̂_i and n0 = n / ||n||; x_target = [p_target, 0, 0]. The cost's
sum runs over the input grid (T_o = T_s, h_o = h_s; the paper leaves T_o
open). The shifted current trajectory (inputs shifted by one round, zero
jerk appended) meets every constraint (Theorem 1's feasibility argument), so
the solver is warm-started from it (duals zero).

With ``soft_rotation`` (Appendix B4) every other trajectory r gets a slack
0 <= eps_r <= ``soft_max_m`` that tightens its rows (right-hand side + eps_r)
and that the cost rewards, -w_r eps_r + ``soft_weight_quadratic`` eps_r^2, with
w_r larger for a UAV to the right (:meth:`MlrProblem._soft_rewards`); eps = 0
gives the rows above, so the guarantees stand.

Build, then solve: :class:`MlrProblem` sets OSQP up once with a FIXED sparsity
pattern sized for (N - 1) x ``max_candidates`` x h_c BVC rows; a round fills
the rows it needs (structural entries of the rest stay, with value 0 and
bounds (-inf, inf)) and updates q, l, u and Ax.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np
import osqp
import scipy.sparse as sp

from planners.dmpc.mlr.config import MlrConfig
from planners.dmpc.mlr.trajectory import ReferenceTrajectory, TrajectoryId
from planners.dmpc.model import discrete_model, stacked_state_matrices
from planners.dmpc.sparse_qp.pattern import SparsePattern
from planners.dmpc.sparse_qp.qp_result import DmpcSolveError, QpSnapshot

__all__ = ["BvcRows", "MlrProblem", "MlrQpResult", "time_varying_bvc"]

_INF = 1e30  # OSQP_INFTY
_EPS_M = 1e-9
_ACCEPTED = (osqp.SolverStatus.OSQP_SOLVED, osqp.SolverStatus.OSQP_SOLVED_INACCURATE)


@dataclass(frozen=True)
class BvcRows:
    """Half-spaces a^T p_i(t_h) >= b of Eq. 15 for R other trajectories at h_c check times.

    Attributes:
        normal: (R, h_c, 3) a = -Theta^-1 n0.
        offset: (R, h_c) b [m].
        plane_distance_m: (R, h_c) scaled distance of the plane from p̃_j:
            (d̂ + ||n||)/2 (midway) or d̂ (relaxed).
    """

    normal: np.ndarray
    offset: np.ndarray
    plane_distance_m: np.ndarray


def time_varying_bvc(
    own_pos_world: np.ndarray,
    others_pos_world: np.ndarray,
    midway: np.ndarray,
    d_hat_m: float,
    downwash: float,
    margin_m: float = 0.0,
) -> BvcRows:
    """The separating planes of Eq. 14-15 between UAV i and each other trajectory.

    With ``margin_m`` = m the plane distances are min((d̂ + m + ||n||)/2, ||n||)
    (midway) and min(d̂ + m, ||n||) (relaxed): Eq. 15 with d̂ + m, clipped at
    ||n|| so that UAV i's current trajectory always meets its own planes.
    Whenever ||n|| >= d̂ + m (Theorem 1's invariant, which the previous solves
    establish up to OSQP's tolerance, well below m) the clip is inactive and
    this is exactly Eq. 15; without the clip, a pair left at d̂ - 1e-4 by the
    solver's tolerance made the next QP primal infeasible (observed in the
    16-UAV swap), although Theorem 1 says the shifted trajectory is feasible.

    Args:
        own_pos_world: (h_c, 3) p̂_i(t_h), UAV i's current trajectory at the check times [m].
        others_pos_world: (R, h_c, 3) p̃_j(t_h), every candidate of every other UAV [m].
        midway: (R,) True where j is in A_ET(k) (plane midway, Eq. 15 first
            case), False where j keeps its trajectory (relaxed plane at d̂ from j).
        d_hat_m: d̂_min [m].
        downwash: c of Theta = diag(1, 1, c).
        margin_m: m >= 0 added to d̂ in the constraint [m] (see above).
    """
    theta_inv = np.array([1.0, 1.0, 1.0 / downwash])
    others = np.asarray(others_pos_world, float).reshape(-1, own_pos_world.shape[0], 3)
    n = (others - own_pos_world[None]) * theta_inv  # n_ij = Theta^-1 (p̃_j - p̂_i), Eq. 14
    norm = np.linalg.norm(n, axis=-1)
    tiny = norm < _EPS_M
    if np.any(tiny):  # coincident positions (never after a feasible start): any fixed direction
        n = np.where(tiny[..., None], np.array([1.0, 0.0, 0.0]), n)
    n0 = n / np.maximum(np.linalg.norm(n, axis=-1), _EPS_M)[..., None]
    mid = np.asarray(midway, bool).reshape(-1, 1)
    d = d_hat_m + margin_m
    dist = np.minimum(np.where(mid, 0.5 * (d + norm), d), norm)  # Eq. 15 right-hand side, clipped at ||n||
    # n0^T Theta^-1 (p̃_j - p) >= dist  <=>  (-Theta^-1 n0)^T p >= dist - n0^T Theta^-1 p̃_j
    normal = -n0 * theta_inv
    offset = dist - np.einsum("rhd,rhd->rh", n0 * theta_inv, others)
    return BvcRows(normal, offset, dist)


@dataclass(frozen=True)
class MlrQpResult:
    """One solved QP (13).

    Attributes:
        trajectory: the new reference (meta as given, starts at t_0).
        cost: value of (13a) at the solution (without its constant x0 term).
        iterations: OSQP iterations.
        status: OSQP status string.
        solve_time_s: wall time of the OSQP update + solve [s].
        build_time_s: wall time of building the rows [s].
        n_bvc_rows: BVC rows used, R h_c.
    """

    trajectory: ReferenceTrajectory
    cost: float
    iterations: int
    status: str
    solve_time_s: float
    build_time_s: float
    n_bvc_rows: int


class MlrProblem:
    """The QP (13) of one CU, built once with a fixed sparsity pattern, re-solved for any UAV.

    Sparse form: z = [x_1; ...; x_{h_s}; u_0; ...; u_{h_s-1}] (9 h_s + 3 h_s,) with the
    dynamics x_{kappa+1} = A x_kappa + B u_kappa as equality rows, rather than the
    condensed form (U only, positions cubic in the jerk), which OSQP solved far more
    slowly (measured: docs/results/mlr_dmpc.md#qp-weights-tolerance-and-form); this one has a diagonal cost and BVC
    rows of 3 entries (at a knot) or 12. The trajectory is rolled out from the solver's
    inputs U (exact dynamics), and U gets the minimum-norm correction that makes the
    terminal halt (13e) exact, so that a halted trajectory stays put after its horizon;
    the correction is of the size of OSQP's tolerance.

    Args:
        config: the :class:`MlrConfig`.
    """

    def __init__(self, config: MlrConfig) -> None:
        self.config = cfg = config
        hs, hc = cfg.n_inputs, cfg.n_checks
        Ts = cfg.input_step_s
        self._A1, self._B1 = A, B = discrete_model("triple", Ts)
        self._nx, self._n_u = 9 * hs, 3 * hs
        slots = (cfg.n_uavs - 1) * cfg.max_candidates
        self._n_eps = slots if cfg.soft_rotation else 0  # Appendix B4: one slack per other trajectory
        n = self._nx + self._n_u + self._n_eps
        self._n = n
        self._max_rows_bvc = (cfg.n_uavs - 1) * cfg.max_candidates * hc
        # Check time t_h = t_0 + h T_c. At a knot (t_h = t_0 + (m+1) T_s) p(t_h) is the position of
        # x_{m+1}; inside input interval m at offset tau in (0, T_s) it is C A(tau) x_m + C B(tau) u_m
        # (x_0 is data). Knot rows have 3 entries, which OSQP handles better than 12.
        s = cfg.check_step_s * np.arange(1, hc + 1)
        m = np.ceil(s / Ts - 1e-9).astype(int) - 1
        tau = s - m * Ts
        self._check_const = np.zeros((hc, 3, 9))  # p(t_h) = G_h z[cols_h] + const_h x_0
        checks: list[tuple[np.ndarray, np.ndarray]] = []  # (cols_h, G_h (3, n_h))
        def xcol(k: int) -> int:  # first column of x_k, k = 1..h_s
            return 9 * (k - 1)

        def ucol(k: int) -> int:  # first column of u_k, k = 0..h_s-1
            return self._nx + 3 * k

        pat = SparsePattern()
        row = 0
        eye9 = np.eye(9)
        for k in range(hs):  # dynamics: x_{k+1} - A x_k - B u_k = (A x_0 if k = 0 else 0)
            blocks = [(xcol(k + 1), eye9), (ucol(k), -B)]
            if k:
                blocks.append((xcol(k), -A))
            for c0, blk in blocks:
                r, c = np.nonzero(np.abs(blk) > 0)
                pat.add(row + r, c0 + c, blk[r, c])
            row += 9
        self._row_state = row  # 13d/13e: identity on every x_k
        pat.add(row + np.arange(self._nx), np.arange(self._nx), np.ones(self._nx))
        row += self._nx
        self._row_jerk = row  # 13c: identity on every u_k
        pat.add(row + np.arange(self._n_u), self._nx + np.arange(self._n_u), np.ones(self._n_u))
        row += self._n_u
        self._row_bvc = row  # 13f: one block of h_c rows per other trajectory
        for h in range(hc):
            if abs(tau[h] - Ts) < 1e-9:  # at knot x_{m+1}
                checks.append((np.arange(xcol(m[h] + 1), xcol(m[h] + 1) + 3), np.eye(3)))
                continue
            A_t, B_t = discrete_model("triple", tau[h])
            cols, G = np.arange(ucol(m[h]), ucol(m[h]) + 3), B_t[:3]
            if m[h] >= 1:
                cols, G = np.r_[np.arange(xcol(m[h]), xcol(m[h]) + 9), cols], np.hstack([A_t[:3], G])
            else:
                self._check_const[h] = A_t[:3]
            checks.append((cols, G))
        self._checks = checks
        r_one = np.concatenate([np.full(c.size, h) for h, (c, _) in enumerate(checks)])
        c_one = np.concatenate([c for c, _ in checks])
        rows = (np.arange(slots)[:, None] * hc + r_one[None, :]).ravel()
        self._bvc_slice = pat.add(row + rows, np.tile(c_one, slots), np.zeros(rows.size))
        self._eps_col = self._nx + self._n_u
        if self._n_eps:  # B4: a^T p(t_h) - eps_s >= b on every row of slot s
            pat.add(row + np.arange(slots * hc), self._eps_col + np.repeat(np.arange(slots), hc), np.full(slots * hc, -1.0))
        row += self._max_rows_bvc
        self._row_eps = row  # B4: 0 <= eps_s <= soft_max_m (eps_s = 0 on unused slots)
        if self._n_eps:
            pat.add(row + np.arange(slots), self._eps_col + np.arange(slots), np.ones(slots))
            row += slots
        self._n_rows = row
        A_mat, self._coo_to_csc = pat.to_csc((row, n))
        self._Ax = A_mat.data.copy()
        self._A = A_mat

        w = np.r_[np.full(3, cfg.weight_pos), np.full(3, cfg.weight_vel), np.full(3, cfg.weight_acc)]
        self._Qbar = np.tile(w, hs)  # diagonal of blockdiag(Q), (9 h_s,)
        diag = 2.0 * np.r_[self._Qbar, np.full(self._n_u, cfg.weight_jerk), np.full(self._n_eps, cfg.soft_weight_quadratic)]
        self._P = sp.diags(diag).tocsc()  # diagonal, stays upper triangular
        self._l = np.full(row, -_INF)
        self._u = np.full(row, _INF)
        self._osqp = osqp.OSQP()
        self._osqp.setup(
            self._P, np.zeros(n), A_mat, self._l, self._u, verbose=False, eps_abs=cfg.osqp_eps_abs,
            eps_rel=cfg.osqp_eps_rel, max_iter=cfg.osqp_max_iter, polishing=cfg.osqp_polish, warm_starting=True,
            adaptive_rho_interval=25,
        )  # fmt: skip
        self._snapshot: QpSnapshot | None = None
        self._check_offsets_s = s
        # Terminal [v; a](H T) = G_x x_0 + G_u U, for the exact halt after the solve.
        A0_x, L_x = stacked_state_matrices(A, B, hs)
        self._G_x, self._G_u = A0_x[-6:], L_x[-6:]
        self._G_u_pinv = np.linalg.pinv(self._G_u)

    @property
    def max_bvc_rows(self) -> int:
        """Rows reserved for Eq. 13f: (N - 1) x max_candidates x h_c."""
        return self._max_rows_bvc

    @property
    def bvc_row_start(self) -> int:
        """Index of the first Eq. 13f row in the constraint matrix (for tests)."""
        return self._row_bvc

    def snapshot(self) -> QpSnapshot | None:
        """The QP and solution of the last :meth:`solve` (None before the first)."""
        return self._snapshot

    def check_times(self, t_start_s: float) -> np.ndarray:
        """(h_c,) absolute check times t_0 + h T_c [s]."""
        return float(t_start_s) + self._check_offsets_s

    def solve(
        self,
        own: ReferenceTrajectory,
        t_start_s: float,
        target_world: np.ndarray,
        others_pos_world: np.ndarray,
        others_midway: np.ndarray,
        meta: TrajectoryId,
    ) -> MlrQpResult:
        """Solve (13) for the UAV whose current trajectory is ``own``.

        Args:
            own: the sole trajectory in D_i(k) (Alg. 1 Line 17).
            t_start_s: t_0 = (k + 1) T [s].
            target_world: (3,) p_i,target [m].
            others_pos_world: (R, h_c, 3) every candidate of every other UAV at
                :meth:`check_times` [m]; R <= (N - 1) max_candidates.
            others_midway: (R,) whether each candidate's UAV is in A_ET(k).
            meta: metadata of the new trajectory, (k, w).

        Raises:
            DmpcSolveError: OSQP returned no solution (carries the QP).
            ValueError: more candidates than rows reserved.
        """
        t0 = time.perf_counter()
        cfg = self.config
        hs, hc = cfg.n_inputs, cfg.n_checks
        x0 = own.states_at(np.array([t_start_s]))[0]  # x̃_i(2T | k-1), Eq. 13b
        others = np.asarray(others_pos_world, float).reshape(-1, hc, 3)
        R = others.shape[0]
        if R * hc > self._max_rows_bvc:
            raise ValueError(f"others_pos_world: {R} trajectories, at most {self._max_rows_bvc // hc}")
        l, u = self._l, self._u
        l[:9] = u[:9] = self._A1 @ x0  # x_1 - B u_0 = A x_0 (13b); other dynamics rows stay 0
        l[9:self._row_state] = u[9:self._row_state] = 0.0
        lo = np.r_[np.asarray(cfg.pos_min_world), np.full(3, -cfg.limits.v_max_mps), np.full(3, -cfg.limits.a_max_mps2)]
        hi = np.r_[np.asarray(cfg.pos_max_world), np.full(3, cfg.limits.v_max_mps), np.full(3, cfg.limits.a_max_mps2)]
        rs = slice(self._row_state, self._row_jerk)
        l[rs], u[rs] = np.tile(lo, hs), np.tile(hi, hs)  # 13d (T_b = T_s)
        last = self._row_jerk - 6  # v, a of the last state: 13e, f̂(x(HT + T), 0) = 0
        l[last:self._row_jerk] = u[last:self._row_jerk] = 0.0
        rj = slice(self._row_jerk, self._row_bvc)
        l[rj], u[rj] = -cfg.limits.j_max_mps3, cfg.limits.j_max_mps3  # 13c
        rb = slice(self._row_bvc, self._row_bvc + self._max_rows_bvc)
        l[rb], u[rb] = -_INF, _INF
        n_slots = self._max_rows_bvc // hc
        normal = np.zeros((n_slots, hc, 3))  # unused slots: zero coefficients, bounds (-inf, inf)
        if R:
            own_pos = own.positions_at(self.check_times(t_start_s))
            rows = time_varying_bvc(own_pos, others, others_midway, cfg.d_hat_min_m, cfg.downwash, cfg.bvc_margin_m)
            normal[:R] = rows.normal
            const = np.einsum("rhd,hdn,n->rh", rows.normal, self._check_const, x0)  # a^T C A(tau) x_0 (data)
            l[self._row_bvc:self._row_bvc + R * hc] = (rows.offset - const).ravel()  # Eq. 15: a^T p(t_h) >= b
        # a^T G_h on each row's columns, in the pattern's order (slot-major, then check h).
        packed = np.concatenate([normal[:, h] @ G for h, (_, G) in enumerate(self._checks)], axis=1)
        self._Ax[self._coo_to_csc[self._bvc_slice]] = packed.ravel()
        target = np.zeros(9)
        target[:3] = np.asarray(target_world, float).reshape(3)
        q = np.zeros(self._n)
        q[:self._nx] = -2.0 * self._Qbar * np.tile(target, hs)  # 13a: ||x - x_t||_Q^2 linear term
        if self._n_eps:  # B4: reward extra clearance, more from a UAV to the right (Chen et al. 2023)
            re = slice(self._row_eps, self._row_eps + self._n_eps)
            l[re], u[re] = 0.0, 0.0
            u[self._row_eps:self._row_eps + R] = cfg.soft_max_m
            q[self._eps_col:self._eps_col + R] = -self._soft_rewards(x0[:3], target, others[:, 0])
        x_ws = self._warm_start(own, t_start_s)
        t1 = time.perf_counter()
        self._osqp.update(q=q, l=l, u=u, Ax=self._Ax)
        self._osqp.warm_start(x=x_ws, y=np.zeros(self._n_rows))
        res = self._osqp.solve(raise_error=False)
        t2 = time.perf_counter()
        A = sp.csc_matrix((self._Ax.copy(), self._A.indices, self._A.indptr), shape=self._A.shape)
        status = str(res.info.status)
        x = None if res.x is None else np.array(res.x)
        y = None if res.y is None else np.array(res.y)
        self._snapshot = QpSnapshot(self._P, q.copy(), A, l.copy(), u.copy(), x, y, status)
        if res.info.status_val not in _ACCEPTED:
            raise DmpcSolveError(status, self._snapshot)
        U = x[self._nx:self._nx + self._n_u]
        U = U - self._G_u_pinv @ (self._G_x @ x0 + self._G_u @ U)  # minimum-norm fix: 13e exactly
        U = U.reshape(hs, 3)
        traj = ReferenceTrajectory(meta, float(t_start_s), x0, U, cfg.input_step_s)
        X = traj.knots[1:].ravel()
        cost = float(np.sum(self._Qbar * (X - np.tile(target, hs)) ** 2) + cfg.weight_jerk * np.sum(U**2))
        return MlrQpResult(traj, cost, int(res.info.iter), status, t2 - t1, t1 - t0, R * hc)

    def _soft_rewards(self, own_pos: np.ndarray, target: np.ndarray, others_first: np.ndarray) -> np.ndarray:
        """(R,) B4's reward per metre of extra clearance from each other trajectory.

        ``soft_weight_right`` when the other trajectory's first check point lies
        to the right of UAV i's horizontal direction to its target, else
        ``soft_weight``: each UAV keeps more room to its right, so two UAVs
        that meet turn around each other the same way (Chen et al. 2023).
        """
        cfg = self.config
        heading = target[:2] - own_pos[:2]
        rel = others_first[:, :2] - own_pos[None, :2]
        right = heading[0] * rel[:, 1] - heading[1] * rel[:, 0] < 0.0  # z of heading x rel < 0
        return np.where(right, cfg.soft_weight_right, cfg.soft_weight)

    def _warm_start(self, own: ReferenceTrajectory, t_start_s: float) -> np.ndarray:
        """(n,) ``own`` shifted to t_0 (zero jerk after its end): Theorem 1's feasible candidate; slacks 0."""
        U = self._shifted_inputs(own, t_start_s).reshape(-1, 3)
        x0 = own.states_at(np.array([t_start_s]))[0]
        X = rollout_states(self._A1, self._B1, x0, U)
        return np.r_[X.ravel(), U.ravel(), np.zeros(self._n_eps)]

    def _shifted_inputs(self, own: ReferenceTrajectory, t_start_s: float) -> np.ndarray:
        """(3 h_s,) ``own``'s inputs from t_0 on, zero jerk after its end (Theorem 1's candidate)."""
        hs = self.config.n_inputs
        shift = int(round((t_start_s - own.t_start_s) / own.input_step_s))
        out = np.zeros((hs, 3))
        tail = own.inputs[shift:shift + hs] if 0 <= shift < own.inputs.shape[0] else np.zeros((0, 3))
        out[: tail.shape[0]] = tail
        return out.ravel()


def rollout_states(A: np.ndarray, B: np.ndarray, x0: np.ndarray, U: np.ndarray) -> np.ndarray:
    """x_1..x_K (K, n) of x_{k+1} = A x_k + B u_k from ``x0`` (n,) under ``U`` (K, 3)."""
    out = np.empty((U.shape[0], A.shape[0]))
    x = x0
    for k, u in enumerate(U):
        x = A @ x + B @ u  # x_{k+1} = A x_k + B u_k
        out[k] = x
    return out
