"""What one DMPC QP round returns: :class:`DmpcResult`, and on failure :class:`DmpcSolveError` with a :class:`QpSnapshot`.

Produced by :class:`planners.dmpc.qp.DmpcProblem` (which re-exports these names).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from planners.dmpc.types import DmpcPlan

__all__ = ["DmpcResult", "DmpcSolveError", "QpSnapshot"]


@dataclass(frozen=True)
class QpSnapshot:
    """The QP as OSQP last saw it, with its solution (for KKT checks and error reports).

    Attributes:
        P: (n, n) upper-triangular CSC cost matrix.
        q: (n,) linear cost.
        A: (m, n) CSC constraint matrix.
        l: (m,) lower bounds (-1e30 = -inf).
        u: (m,) upper bounds (1e30 = inf).
        x: (n,) primal solution (None before a solve).
        y: (m,) dual solution, OSQP sign convention (y > 0 on active upper bounds).
        status: OSQP status string.
    """

    P: sp.csc_matrix
    q: np.ndarray
    A: sp.csc_matrix
    l: np.ndarray
    u: np.ndarray
    x: np.ndarray | None
    y: np.ndarray | None
    status: str


class DmpcSolveError(RuntimeError):
    """OSQP did not solve the DMPC QP (infeasible, iteration limit...).

    Attributes:
        status: OSQP status string.
        snapshot: the :class:`QpSnapshot` that failed.
    """

    def __init__(self, status: str, snapshot: QpSnapshot) -> None:
        super().__init__(f"DMPC QP not solved: OSQP status {status!r}")
        self.status = status
        self.snapshot = snapshot


@dataclass(frozen=True)
class DmpcResult:
    """Solution of one DMPC round.

    Attributes:
        plan: the new plan from t_now (K+1 samples, the first is x0).
        pos_world: (K, 3) predicted positions p[1..K] [m].
        vel_world: (K, 3) predicted velocities v[1..K] [m/s].
        acc_world: (K, 3) accelerations [m/s^2]: the inputs u[0..K-1] (double) or a[1..K] (triple).
        inputs: (K, 3) optimal inputs u[0..K-1] (acceleration [m/s^2] or jerk [m/s^3]).
        cost: J at the solution (all terms, constants included).
        iterations: OSQP iterations.
        status: OSQP status string ("solved" or "solved inaccurate").
        solve_time_s: wall time [s] of everything OSQP does this round: the data
            update (including the KKT refactorisation when A or P changed),
            the warm start (shifting the previous solution included) and the solve.
        osqp_solve_time_s: OSQP's own solve-phase time [s] (C code only, no refactorisation).
        update_time_s: wall time [s] spent in Python building this round's
            constraints and cost (before handing them to OSQP).
        n_collision_constraints: active collision rows (on demand: planes at k_c; bvc: K x neighbours).
        conflict_time_s: on demand: absolute time [s] of the first predicted
            conflict that was constrained (NaN if none, and always for bvc).
        slack: (n_collision_constraints,) on-demand slacks s = -alpha [m] (empty for bvc).
        n_obstacle_rows: obstacle half-space rows kept this round (after culling).
        refactorised: whether this round changed A or P, so that OSQP
            refactorised its KKT system (Ruiz equilibration included) before
            solving; a round with the same constraint matrix as the last solve
            reuses the factorisation and pays only the iterations.
    """

    plan: DmpcPlan
    pos_world: np.ndarray
    vel_world: np.ndarray
    acc_world: np.ndarray
    inputs: np.ndarray
    cost: float
    iterations: int
    status: str
    solve_time_s: float
    osqp_solve_time_s: float
    update_time_s: float
    n_collision_constraints: int
    conflict_time_s: float
    slack: np.ndarray
    n_obstacle_rows: int = 0
    refactorised: bool = False
