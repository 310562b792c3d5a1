"""The formation OCP (Stomberg et al. Eq. 1) for all drones as ONE QP: the reference ADMM must converge to.

Decision variables: every drone's own part (p_i, v_i, u_i, s_i) of
:mod:`planners.dmpc.admm.ocp` stacked, without copies. Cost (1a), with
w_g, w_f the stage/terminal weights of :class:`AdmmFormationConfig`::

    J = sum_i [ sum_{k=1}^{K} w_g[k] ||p_i[k] - r_i[k]||^2 + r sum_{k=0}^{K-1} ||u_i[k]||^2 + c s_i^2 ]
      + sum_{edges (i,j)} sum_{k=1}^{K} w_f[k] ||(p_i[k] - p_j[k]) - d_ij||^2

subject to each drone's constraints Z_i (dynamics (1b), initial condition
(1c) incl. u_i[0] = u_i(t) with Remark 1, hard input box (1e), soft state box
(1d) with one slack per drone, Remark 2). There is no coupled constraint (1f):
the drones couple through the cost only, as in the paper's Sec. 5.1.

:class:`CentralizedFormationQp` builds P and A once and per MPC step
updates q and the bounds only (the fair timing baseline of
``benchmarks/bench_admm.py``); :func:`centralized_formation_qp` builds and
solves once (tests). :func:`formation_cost` evaluates J directly from plans
(not from the QP's matrices), so it checks the QP assembly too, and scores
ADMM's plans against the optimum.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, replace

import numpy as np
import osqp
import scipy.sparse as sp

from planners.dmpc.admm.config import AdmmFormationConfig
from planners.dmpc.admm.ocp import DroneLayout, own_bounds, own_constraint_matrix, own_cost
from planners.dmpc.formation_graph import FormationGraph

__all__ = [
    "CentralizedFormationQp",
    "CentralizedFormationSolution",
    "CentralizedQpError",
    "centralized_formation_qp",
    "formation_cost",
]

_ACCEPTED = (osqp.SolverStatus.OSQP_SOLVED,)


class CentralizedQpError(RuntimeError):
    """OSQP did not solve the centralized formation QP.

    Attributes:
        status: OSQP's status string.
    """

    def __init__(self, status: str) -> None:
        super().__init__(f"centralized formation QP not solved: OSQP status {status!r}")
        self.status = status


@dataclass(frozen=True)
class CentralizedFormationSolution:
    """The optimum of the centralized OCP (1).

    Attributes:
        pos_world: (N, K+1, 3) p_i[0..K] [m] (p_i[0] measured).
        vel_world: (N, K+1, 3) v_i[0..K] [m/s].
        acc_world: (N, K, 3) u_i[0..K-1] [m/s^2].
        slack: (N,) s_i.
        cost: J of the solution by :func:`formation_cost`.
        objective: OSQP's objective plus the constant terms (equals ``cost``
            when the QP is assembled right).
        status: OSQP status string.
        iterations: OSQP iterations.
        setup_s: wall time [s] before OSQP's solve: updating q and the bounds
            (and, from :func:`centralized_formation_qp`, building the matrices
            and OSQP's setup, i.e. its KKT factorisation).
        solve_s: wall time [s] of OSQP's solve.
        primal: (N, 9K+1) OSQP's solution, per drone (p, v, u, s) as in
            :class:`planners.dmpc.admm.ocp.DroneLayout` (for a warm start).
        dual: (N, 21K+1) OSQP's dual solution per drone's rows (for a warm start).
    """

    pos_world: np.ndarray
    vel_world: np.ndarray
    acc_world: np.ndarray
    slack: np.ndarray
    cost: float
    objective: float
    status: str
    iterations: int
    setup_s: float
    solve_s: float
    primal: np.ndarray
    dual: np.ndarray


def formation_cost(
    config: AdmmFormationConfig,
    graph: FormationGraph,
    references_world: np.ndarray,
    pos_world: np.ndarray,
    acc_world: np.ndarray,
    slack: np.ndarray,
) -> float:
    """J of the module docstring, evaluated from plans.

    Args:
        config: the settings (weights).
        graph: slots and edges (d_ij).
        references_world: (N, K, 3) r_i[1..K] [m].
        pos_world: (N, K+1, 3) p_i[0..K] [m] (p_i[0] does not enter).
        acc_world: (N, K, 3) u_i[0..K-1] [m/s^2].
        slack: (N,) s_i.
    """
    p = np.asarray(pos_world, float)[:, 1:]
    w_g, w_f = config.tracking_weights(), config.formation_weights()
    J = float(np.sum(w_g[None, :] * np.sum((p - references_world) ** 2, axis=-1)))
    J += config.weight_input * float(np.sum(np.asarray(acc_world) ** 2))
    J += config.weight_slack * float(np.sum(np.asarray(slack, float) ** 2))
    for (i, j), d in zip(graph.edges, graph.offsets_array()):
        J += float(np.sum(w_f * np.sum((p[i] - p[j] - d) ** 2, axis=-1)))
    return J


class CentralizedFormationQp:
    """The centralized formation QP, built and set up in OSQP once, re-solved per MPC step.

    P (the cost's Hessian: weights and graph) and A (every drone's Z_i) are
    fixed; :meth:`solve` updates q (references, offsets) and the bounds
    (states, u(t)) only, as the local QPs do, so it is the fair centralized
    baseline for timing too.

    Args:
        config: the settings (``delay_compensation`` fixes u_i[0], Remark 1).
        graph: the formation (N drones).
        eps: OSQP eps_abs = eps_rel (default tight: the reference optimum).
        max_iter: OSQP iteration limit.
        polish: OSQP solution polishing.
    """

    def __init__(
        self,
        config: AdmmFormationConfig,
        graph: FormationGraph,
        eps: float = 1e-9,
        max_iter: int = 200000,
        polish: bool = True,
    ) -> None:
        t0 = time.perf_counter()
        self.config, self.graph = config, graph
        K, N = config.horizon_steps, graph.num_drones
        self.layout = DroneLayout(K)
        n_own = self.layout.own_size
        A = sp.block_diag([own_constraint_matrix(config)] * N, format="csc")
        H_own, _, _ = own_cost(config, np.zeros((K, 3)))
        H = sp.block_diag([H_own] * N, format="lil")
        w_f = np.repeat(config.formation_weights(), 3)
        for i, j in graph.edges:
            # w_f ||p_i - p_j - d||^2 -> Hessian 2 w_f [I, -I; -I, I] on (p_i, p_j)
            pi, pj = i * n_own + np.arange(3 * K), j * n_own + np.arange(3 * K)
            H[pi, pi] += 2.0 * w_f
            H[pj, pj] += 2.0 * w_f
            H[pi, pj] += -2.0 * w_f
            H[pj, pi] += -2.0 * w_f
        lo, hi = self._bounds(np.zeros((N, 6)), np.zeros((N, 3)))
        self._solver = osqp.OSQP()
        self._solver.setup(
            sp.triu(sp.csc_matrix(H), format="csc"), np.zeros(N * n_own), A, lo, hi, verbose=False,
            eps_abs=eps, eps_rel=eps, max_iter=max_iter, polishing=polish,
        )  # fmt: skip
        self._n, self._m = N * n_own, A.shape[0]
        self.setup_s = time.perf_counter() - t0

    def _bounds(self, states: np.ndarray, inputs_now: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        pairs = [
            own_bounds(self.config, x, u if self.config.delay_compensation else None)
            for x, u in zip(states, inputs_now)
        ]
        return np.concatenate([p[0] for p in pairs]), np.concatenate([p[1] for p in pairs])

    def _linear_cost(self, refs: np.ndarray) -> tuple[np.ndarray, float]:
        cfg, K = self.config, self.config.horizon_steps
        n_own = self.layout.own_size
        g, const = np.zeros(self._n), 0.0
        for i in range(self.graph.num_drones):
            _, g_i, c_i = own_cost(cfg, refs[i])
            g[i * n_own : (i + 1) * n_own] = g_i
            const += c_i
        w_f = np.repeat(cfg.formation_weights(), 3)
        for (i, j), d in zip(self.graph.edges, self.graph.offsets_array()):
            d_k = np.tile(d, K)  # gradient -2 w_f d on p_i, +2 w_f d on p_j; constant w_f ||d||^2
            g[i * n_own : i * n_own + 3 * K] -= 2.0 * w_f * d_k
            g[j * n_own : j * n_own + 3 * K] += 2.0 * w_f * d_k
            const += float(np.sum(w_f * d_k**2))
        return g, const

    def solve(
        self,
        states_world: np.ndarray,
        references_world: np.ndarray,
        inputs_now_world: np.ndarray | None = None,
        warm_start: tuple[np.ndarray, np.ndarray] | None = None,
    ) -> CentralizedFormationSolution:
        """Solve the OCP (1) from the given states (``setup_s`` of the result: updating q and bounds).

        Args:
            states_world: (N, 6) x_i(t) = [p, v] [m, m/s].
            references_world: (N, K, 3) r_i[1..K] [m].
            inputs_now_world: (N, 3) u_i(t) [m/s^2] that u_i[0] is fixed to with
                ``delay_compensation`` (None = zeros); ignored otherwise.
            warm_start: (primal (N, 9K+1), dual (N, 21K+1)) to start OSQP from,
                e.g. a previous solution shifted by one step; None = a cold start (zeros).

        Raises:
            CentralizedQpError: OSQP did not report "solved".
        """
        t0 = time.perf_counter()
        cfg, lay = self.config, self.layout
        K, N = cfg.horizon_steps, self.graph.num_drones
        states = np.asarray(states_world, float).reshape(N, 6)
        refs = np.asarray(references_world, float).reshape(N, K, 3)
        u_now = np.zeros((N, 3)) if inputs_now_world is None else np.asarray(inputs_now_world, float).reshape(N, 3)
        g, const = self._linear_cost(refs)
        lo, hi = self._bounds(states, u_now)
        self._solver.update(q=g, l=lo, u=hi)
        if warm_start is None:
            x_ws, y_ws = np.zeros(self._n), np.zeros(self._m)
        else:
            x_ws, y_ws = np.asarray(warm_start[0], float).ravel(), np.asarray(warm_start[1], float).ravel()
        self._solver.warm_start(x=x_ws, y=y_ws)
        t1 = time.perf_counter()
        res = self._solver.solve(raise_error=False)
        t2 = time.perf_counter()
        if res.info.status_val not in _ACCEPTED:
            raise CentralizedQpError(str(res.info.status))
        x = np.asarray(res.x).reshape(N, -1)
        pos = np.concatenate([states[:, None, :3], x[:, lay.pos].reshape(N, K, 3)], axis=1)
        vel = np.concatenate([states[:, None, 3:], x[:, lay.vel].reshape(N, K, 3)], axis=1)
        acc = x[:, lay.inp].reshape(N, K, 3)
        slack = np.maximum(x[:, lay.slack], 0.0)
        return CentralizedFormationSolution(
            pos_world=pos,
            vel_world=vel,
            acc_world=acc,
            slack=slack,
            cost=formation_cost(cfg, self.graph, refs, pos, acc, slack),
            objective=float(res.info.obj_val) + const,
            status=str(res.info.status),
            iterations=int(res.info.iter),
            setup_s=t1 - t0,
            solve_s=t2 - t1,
            primal=x,
            dual=np.asarray(res.y).reshape(N, -1),
        )


def centralized_formation_qp(
    config: AdmmFormationConfig,
    graph: FormationGraph,
    states_world: np.ndarray,
    references_world: np.ndarray,
    inputs_now_world: np.ndarray | None = None,
    eps: float = 1e-9,
    max_iter: int = 200000,
    polish: bool = True,
    warm_start: tuple[np.ndarray, np.ndarray] | None = None,
) -> CentralizedFormationSolution:
    """Build the centralized formation QP and solve it once (:class:`CentralizedFormationQp`).

    Arguments as :class:`CentralizedFormationQp` and its :meth:`~CentralizedFormationQp.solve`;
    the result's ``setup_s`` here includes building the matrices and OSQP's setup.
    """
    problem = CentralizedFormationQp(config, graph, eps=eps, max_iter=max_iter, polish=polish)
    sol = problem.solve(states_world, references_world, inputs_now_world, warm_start)
    return replace(sol, setup_s=problem.setup_s + sol.setup_s)
