"""The KKT check of the DMPC tests' QP solutions (imported by test_dmpc_qp.py and test_dmpc_mlr_qp.py)."""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from planners.dmpc.sparse_qp.qp_result import QpSnapshot


def assert_kkt(snap: QpSnapshot, tol: float = 1e-5) -> None:
    """Stationarity, primal feasibility, dual feasibility and complementarity (OSQP sign convention).

    OSQP solves min 1/2 x^T P x + q^T x s.t. l <= A x <= u with P upper-triangular and y > 0 on an
    active upper bound, y < 0 on an active lower bound; bounds beyond +-1e29 are infinite.
    """
    x, y = snap.x, snap.y
    P_full = snap.P + snap.P.T - sp.diags(snap.P.diagonal())
    Ax = snap.A @ x
    scale = max(1.0, np.abs(snap.q).max(), np.abs(P_full @ x).max())
    # Stationarity: P x + q + A^T y = 0.
    assert np.abs(P_full @ x + snap.q + snap.A.T @ y).max() <= tol * scale
    # Primal feasibility: l <= A x <= u.
    assert np.all(Ax >= snap.l - tol) and np.all(Ax <= snap.u + tol)
    # Dual feasibility and complementarity: y+ only on active upper bounds, y- only on active lower bounds.
    y_up, y_lo = np.maximum(y, 0.0), np.maximum(-y, 0.0)
    upper_gap = np.where(snap.u < 1e29, snap.u - Ax, np.inf)
    lower_gap = np.where(snap.l > -1e29, Ax - snap.l, np.inf)
    assert np.all(y_up[np.isinf(upper_gap)] <= tol * scale)
    assert np.all(y_lo[np.isinf(lower_gap)] <= tol * scale)
    fin_u, fin_l = np.isfinite(upper_gap), np.isfinite(lower_gap)
    assert np.abs(y_up[fin_u] * upper_gap[fin_u]).max(initial=0.0) <= tol * scale
    assert np.abs(y_lo[fin_l] * lower_gap[fin_l]).max(initial=0.0) <= tol * scale
