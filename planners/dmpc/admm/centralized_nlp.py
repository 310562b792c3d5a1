"""The non-convex formation OCP with minimum distances, for all drones at once: the reference dSQP is scored against.

Stomberg et al. Sec. 5.2 compare dSQP's applied input with "the local
optimum u* found when solving the OCP in centralized fashion via IPOPT"
(Fig. 8). This is that OCP: the cost J and constraints of
:mod:`planners.dmpc.admm.centralized` (dynamics, initial condition with
Remark 1's fixed u_i[0], hard input box, soft position and speed boxes with
one slack per drone and the k = 1 rows free, Remark 2) plus Eq. 8 for every
pair the coupling graph holds, softened by the slack of the drone that holds
it (the higher id, as :func:`planners.dmpc.admm.distance.owned_partners`):

    ||Theta^-1 (p_o[k] - p_m[k])|| >= d - s_o,   k = 2..K.

It is solved by IPOPT through CasADi (the paper's solver; ``pip install
mpcde[nlp]``), with exact derivatives from CasADi's algorithmic
differentiation, from a guess (the previous solution shifted, or the plans
dSQP flew): the problem is non-convex and IPOPT returns the local optimum
near it, so a residual against it means "against the optimum on the same
side". The squared distance is used inside (``||.||^2 >= (d - s)^2`` with
``d - s >= 0``), which has the same feasible set and smooth derivatives where
the plans coincide.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from planners.dmpc.admm.config import AdmmFormationConfig
from planners.dmpc.formation_graph import FormationGraph
from planners.dmpc.model import discrete_model

__all__ = ["CentralizedNlpSolution", "centralized_formation_nlp"]


@dataclass(frozen=True)
class CentralizedNlpSolution:
    """IPOPT's local optimum of the non-convex formation OCP.

    Attributes:
        pos_world: (N, K+1, 3) p_i[0..K] [m]; vel_world: (N, K+1, 3) [m/s];
        acc_world: (N, K, 3) u_i[0..K-1] [m/s^2]; slack: (N,) s_i.
        cost: J at the solution; status: IPOPT's return status;
        success: IPOPT reported convergence; iterations: IPOPT iterations;
        solve_s: wall time of the solve [s].
    """

    pos_world: np.ndarray
    vel_world: np.ndarray
    acc_world: np.ndarray
    slack: np.ndarray
    cost: float
    status: str
    success: bool
    iterations: int
    solve_s: float


def centralized_formation_nlp(
    config: AdmmFormationConfig,
    graph: FormationGraph,
    states_world: np.ndarray,
    references_world: np.ndarray,
    inputs_now_world: np.ndarray,
    guess_acc_world: np.ndarray | None = None,
    tolerance: float = 1e-9,
) -> CentralizedNlpSolution:
    """Solve the OCP of the module docstring for one MPC step.

    Args:
        config: the settings (weights, limits, box, d_min_m, downwash; the
            distance constraints are on for every edge of ``graph``).
        graph: slots and coupling edges (d_ij = slot_i - slot_j).
        states_world: (N, 6) [p, v] of every drone.
        references_world: (N, K, 3) r_i[1..K] [m].
        inputs_now_world: (N, 3) u_i(t) [m/s^2], u_i[0] (Remark 1).
        guess_acc_world: (N, K, 3) inputs to start IPOPT from (rolled out
            from the states); None: u[0] then zeros.
        tolerance: IPOPT's ``tol``.

    Raises:
        ImportError: CasADi is not installed (``pip install mpcde[nlp]``).
    """
    import casadi as ca

    K, N, h = config.horizon_steps, graph.num_drones, config.step_s
    A, B = discrete_model("double", h)
    x0 = np.asarray(states_world, float).reshape(N, 6)
    refs = np.asarray(references_world, float).reshape(N, K, 3)
    u_now = np.asarray(inputs_now_world, float).reshape(N, 3)
    w_g, w_f = config.tracking_weights(), config.formation_weights()
    theta_inv2 = np.array([1.0, 1.0, 1.0 / config.downwash**2])
    lim = config.limits
    opti = ca.Opti()
    U = [opti.variable(K, 3) for _ in range(N)]
    S = opti.variable(N)
    P = []
    cost = 0
    for i in range(N):
        x = ca.DM(x0[i])
        rows = []
        for k in range(K):
            x = ca.mtimes(ca.DM(A), x) + ca.mtimes(ca.DM(B), U[i][k, :].T)
            rows.append(x.T)
            if k >= 1:  # x[1] is data with u[0] fixed: its soft rows are free (planners.dmpc.admm.ocp)
                for c in range(3):
                    opti.subject_to(opti.bounded(config.pos_min_world[c] - S[i], x[c], config.pos_max_world[c] + S[i]))
                for c in range(3, 6):
                    opti.subject_to(opti.bounded(-lim.v_max_mps - S[i], x[c], lim.v_max_mps + S[i]))
        X = ca.vertcat(*rows)  # (K, 6): x[1..K]
        P.append(X[:, 0:3])
        opti.subject_to(U[i][0, :] == ca.DM(u_now[i]).T)  # Remark 1
        opti.subject_to(opti.bounded(-lim.a_max_mps2, ca.vec(U[i]), lim.a_max_mps2))
        err = P[i] - ca.DM(refs[i])
        cost += ca.sum1(ca.DM(w_g) * ca.sum2(err**2)) + config.weight_input * ca.sumsqr(U[i]) + config.weight_slack * S[i] ** 2
    opti.subject_to(S >= 0)
    owners = set()
    for (i, j), d in zip(graph.edges, graph.offsets_array()):  # i < j
        diff = P[i] - P[j] - ca.DM(np.tile(d, (K, 1)))
        cost += ca.sum1(ca.DM(w_f) * ca.sum2(diff**2))
        o, m = j, i  # the higher id holds the pair (owned_partners)
        owners.add(o)
        delta = P[o] - P[m]
        for k in range(1, K):  # k = 2..K
            opti.subject_to(ca.sum2(ca.DM(theta_inv2).T * delta[k, :] ** 2) >= (config.d_min_m - S[o]) ** 2)
    for o in sorted(owners):
        opti.subject_to(S[o] <= config.d_min_m)
    opti.minimize(cost)
    guess = np.zeros((N, K, 3)) if guess_acc_world is None else np.asarray(guess_acc_world, float).reshape(N, K, 3)
    for i in range(N):
        g = guess[i].copy()
        g[0] = u_now[i]
        opti.set_initial(U[i], np.clip(g, -lim.a_max_mps2, lim.a_max_mps2))
    opti.set_initial(S, 0.0)
    opti.solver("ipopt", {"print_time": False}, {"print_level": 0, "sb": "yes", "tol": tolerance, "max_iter": 3000})
    t0 = time.perf_counter()
    try:
        sol = opti.solve()
        success, value = True, sol.value
    except RuntimeError:  # not converged: report IPOPT's last iterate and its status
        success, value = False, opti.debug.value
    solve_s = time.perf_counter() - t0
    stats = opti.stats()
    acc = np.stack([np.asarray(value(U[i])).reshape(K, 3) for i in range(N)])
    slack = np.asarray(value(S)).reshape(N)
    pos, vel = np.empty((N, K + 1, 3)), np.empty((N, K + 1, 3))
    for i in range(N):
        x = x0[i]
        pos[i, 0], vel[i, 0] = x[:3], x[3:]
        for k in range(K):
            x = A @ x + B @ acc[i, k]
            pos[i, k + 1], vel[i, k + 1] = x[:3], x[3:]
    return CentralizedNlpSolution(
        pos, vel, acc, slack, float(value(cost)), str(stats.get("return_status", "")), bool(success and stats.get("success", True)),
        int(stats.get("iter_count", 0)), solve_s,
    )  # fmt: skip
