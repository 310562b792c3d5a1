"""One drone's share of the formation OCP (Stomberg et al. Eq. 1-2): layout of z_i, constraints Z_i, own cost.

Partially separable form (paper Eq. 2). Drone i's decision vector is, with
K = ``horizon_steps`` and N_i its neighbours (in- = out-neighbours, Assumption 1),

    z_i = col(p_i, v_i, u_i, s_i, w_ji for j in N_i)                   (n_i = 9K + 1 + 3K |N_i|)

* p_i = (p[1], ..., p[K]) (3K,) planned positions, world frame (ENU) [m];
* v_i = (v[1], ..., v[K]) (3K,) velocities [m/s];
* u_i = (u[0], ..., u[K-1]) (3K,) accelerations [m/s^2] (double integrator,
  :func:`planners.dmpc.model.discrete_model`), u[k] held on [t + k h, t + (k+1) h);
* s_i (1,) the one slack of paper Remark 2;
* w_ji (3K,) drone i's copy of neighbour j's positions p_j[1..K] [m] (Sec. 2.3).

p[0], v[0] (the measured state) are not variables: they enter the first
dynamics rows' bounds. Its local cost f_i(z_i) = 1/2 z_i' H_i z_i + g_i' z_i + c_i is

    sum_k w_g[k] ||p[k] - r_i[k]||^2 + r sum_k ||u[k]||^2 + c s_i^2
    + sum_{j in N_i} sum_k (w_f[k] / 2) ||(p[k] - w_ji[k]) - d_ij||^2,

k = 1..K for positions, with d_ij = desired p_i - p_j (:mod:`planners.dmpc.formation_graph`).
**Edge split.** The centralized OCP (1a) holds w_f ||(p_i - p_j) - d_ij||^2
once per undirected edge {i, j}. Each end holds half of it against its copy:
i holds (w_f/2) ||p_i - w_ji - d_ij||^2 and j holds (w_f/2) ||p_j - w_ij - d_ji||^2
with d_ji = -d_ij, which is (w_f/2) ||w_ij - p_j - d_ij||^2. On the consensus set
(w_ji = p_j, w_ij = p_i, paper Eq. 2d) the two halves add up to the edge's term,
so sum_i f_i equals the centralized cost (1a) exactly (the k = 0 terms of (1a)
are constants and left out).

Local constraints Z_i (Eq. 2b-2c), rows of A_i z_i in [l_i, u_i]:

    x[k+1] - A x[k] - B u[k] = 0,  x[0] = (p0, v0) -> bounds of step 0     (1b, 1c)   6K rows
    -a_max_mps2 <= u[k] <= a_max_mps2   (hard; u[0] = u(t) with Remark 1)             (1e)       3K rows
    p[k] + s >= p_min,  p[k] - s <= p_max                                    (1d, soft) 6K rows
    v[k] + s >= -v_max_mps, v[k] - s <= v_max_mps                                    (1d, soft) 6K rows
    s >= 0                                                                   (Remark 2)    1 row

With Remark 1 (u[0] fixed to u(t)) the state x[1] = A x0 + B u(t) is data, not
a decision, so the soft rows of k = 1 are left free (bounds -inf..inf, in
every step: their type never changes). Kept, they would do two harmful things:
a violation at k = 1 (e.g. the drone is already faster than v_max_mps) would force
the ONE slack up and so relax every other state constraint of the horizon by
as much, for free; and OSQP needed thousands of iterations for such a QP
(measured: docs/results/admm_formation.md#development-measurements-scripts-not-kept).

Shared by the ADMM subproblem (:mod:`planners.dmpc.admm.local_qp`, which adds
the copies' formation terms) and the centralized QP
(:mod:`planners.dmpc.admm.centralized`, which adds each edge once), so both
solve the same OCP.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp

from planners.dmpc.admm.config import AdmmFormationConfig
from planners.dmpc.model import discrete_model

__all__ = [
    "DroneLayout",
    "own_bounds",
    "own_constraint_matrix",
    "own_cost",
    "shift_decision",
    "shift_dual",
    "shift_trajectory",
]

_INF = 1e30  # OSQP_INFTY: a bound beyond it is no bound


@dataclass(frozen=True)
class DroneLayout:
    """Where each block of z_i lies (module docstring); the own part (p, v, u, s) comes first.

    Attributes:
        horizon_steps: K.
        neighbour_ids: sorted ids j of the copies w_ji, in their order in z_i.
    """

    horizon_steps: int
    neighbour_ids: tuple[int, ...] = field(default=())

    @property
    def own_size(self) -> int:
        """9K + 1: p, v, u (3K each) and s."""
        return 9 * self.horizon_steps + 1

    @property
    def size(self) -> int:
        """n_i = 9K + 1 + 3K |N_i|."""
        return self.own_size + 3 * self.horizon_steps * len(self.neighbour_ids)

    @property
    def pos(self) -> slice:
        """p[1..K] (3K,)."""
        return slice(0, 3 * self.horizon_steps)

    @property
    def vel(self) -> slice:
        """v[1..K] (3K,)."""
        K = self.horizon_steps
        return slice(3 * K, 6 * K)

    @property
    def inp(self) -> slice:
        """u[0..K-1] (3K,)."""
        K = self.horizon_steps
        return slice(6 * K, 9 * K)

    @property
    def slack(self) -> int:
        """Index of s."""
        return 9 * self.horizon_steps

    def copy(self, j: int) -> slice:
        """w_ji (3K,): the copy of neighbour ``j``'s positions."""
        K, m = self.horizon_steps, self.neighbour_ids.index(j)
        start = self.own_size + 3 * K * m
        return slice(start, start + 3 * K)

    def position_blocks(self) -> list[slice]:
        """Slices of every position trajectory in z_i: own p first, then the copies."""
        return [self.pos] + [self.copy(j) for j in self.neighbour_ids]


def own_constraint_matrix(config: AdmmFormationConfig) -> sp.csc_matrix:
    """A_own (21K + 1, 9K + 1): the rows of Z_i on the own part (p, v, u, s), module docstring order."""
    K, h = config.horizon_steps, config.step_s
    A, B = discrete_model("double", h)
    lay = DroneLayout(K)
    n = lay.own_size
    rows, cols, vals = [], [], []

    def put(r0: int, c_idx: np.ndarray, block: np.ndarray) -> None:
        rr, cc = np.nonzero(block)
        rows.append(r0 + rr)
        cols.append(c_idx[cc])
        vals.append(block[rr, cc])

    pos_idx = np.arange(3 * K)
    vel_idx = 3 * K + np.arange(3 * K)
    inp_idx = 6 * K + np.arange(3 * K)
    for k in range(K):  # x[k+1] - A x[k] - B u[k] = 0   (1b)
        x_next = np.r_[pos_idx[3 * k : 3 * k + 3], vel_idx[3 * k : 3 * k + 3]]
        put(6 * k, x_next, np.eye(6))
        if k > 0:  # x[0] is data: A x0 goes into the bounds
            put(6 * k, np.r_[pos_idx[3 * k - 3 : 3 * k], vel_idx[3 * k - 3 : 3 * k]], -A)
        put(6 * k, inp_idx[3 * k : 3 * k + 3], -B)
    r = 6 * K
    put(r, inp_idx, np.eye(3 * K))  # u box (1e)
    r += 3 * K
    s_col = np.array([lay.slack])
    for idx, sign in ((pos_idx, 1.0), (pos_idx, -1.0), (vel_idx, 1.0), (vel_idx, -1.0)):  # soft boxes (1d)
        put(r, idx, np.eye(3 * K))
        put(r, s_col, np.full((3 * K, 1), sign))  # p + s >= p_min / p - s <= p_max (same for v)
        r += 3 * K
    put(r, s_col, np.ones((1, 1)))  # s >= 0
    r += 1
    return sp.csc_matrix(
        (np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))), shape=(r, n)
    )


def own_bounds(
    config: AdmmFormationConfig, state_world: np.ndarray, input_now_world: np.ndarray | None
) -> tuple[np.ndarray, np.ndarray]:
    """(l, u) (21K + 1,) of :func:`own_constraint_matrix` for the measured state.

    Args:
        config: the settings.
        state_world: (6,) x0 = [p0 (3) m, v0 (3) m/s].
        input_now_world: (3,) u(t) [m/s^2] to fix u[0] to (paper Eq. 1c, Remark 1),
            or None to leave u[0] free within the box.
    """
    K, h = config.horizon_steps, config.step_s
    A, _ = discrete_model("double", h)
    x0 = np.asarray(state_world, float).reshape(6)
    lo = np.empty(21 * K + 1)
    hi = np.empty(21 * K + 1)
    lo[: 6 * K] = hi[: 6 * K] = 0.0
    lo[:6] = hi[:6] = A @ x0  # x[1] - B u[0] = A x0   (1c)
    r = 6 * K
    lo[r : r + 3 * K], hi[r : r + 3 * K] = -config.limits.a_max_mps2, config.limits.a_max_mps2
    if input_now_world is not None:
        lo[r : r + 3] = hi[r : r + 3] = np.asarray(input_now_world, float).reshape(3)  # u[0] = u(t)
    r += 3 * K
    p_min, p_max = np.tile(config.pos_min_world, K), np.tile(config.pos_max_world, K)
    for low, high in ((p_min, _INF), (-_INF, p_max), (-config.limits.v_max_mps, _INF), (-_INF, config.limits.v_max_mps)):
        lo[r : r + 3 * K], hi[r : r + 3 * K] = low, high
        if input_now_world is not None:  # x[1] is data with u[0] fixed: its soft rows are left free
            lo[r : r + 3], hi[r : r + 3] = -_INF, _INF
        r += 3 * K
    lo[r], hi[r] = 0.0, _INF
    return lo, hi


def own_cost(config: AdmmFormationConfig, reference_world: np.ndarray) -> tuple[sp.csc_matrix, np.ndarray, float]:
    """(H_own (9K+1, 9K+1), g_own (9K+1,), c_own) of the tracking, input and slack terms.

    1/2 z' H z + g' z + c = sum_k w_g[k] ||p[k] - r[k]||^2 + r sum_k ||u[k]||^2 + c s^2.

    Args:
        config: the settings.
        reference_world: (K, 3) r_i[1..K], the drone's own reference positions [m].
    """
    K = config.horizon_steps
    ref = np.asarray(reference_world, float).reshape(K, 3)
    w_g = np.repeat(config.tracking_weights(), 3)
    diag = np.r_[2.0 * w_g, np.zeros(3 * K), np.full(3 * K, 2.0 * config.weight_input), 2.0 * config.weight_slack]
    g = np.zeros(9 * K + 1)
    g[: 3 * K] = -2.0 * w_g * ref.ravel()  # w_g ||p - r||^2 = w_g (p'p - 2 r'p + r'r)
    return sp.diags(diag, format="csc"), g, float(np.sum(w_g * ref.ravel() ** 2))


def shift_trajectory(values: np.ndarray, extrapolate: bool) -> np.ndarray:
    """One step of receding horizon on a (3K,) trajectory: step k <- k+1.

    The new last step repeats the old last one, or extrapolates it linearly
    (2 x[K] - x[K-1]) if ``extrapolate`` (used for positions).
    """
    x = values.reshape(-1, 3)
    out = np.empty_like(x)
    out[:-1] = x[1:]
    out[-1] = 2.0 * x[-1] - x[-2] if extrapolate and x.shape[0] > 1 else x[-1]
    return out.ravel()


def shift_decision(values: np.ndarray, layout: DroneLayout, extrapolate_positions: bool) -> np.ndarray:
    """A z_i-shaped vector (layout.size,) one step on (warm start, paper Sec. 5.1).

    Every trajectory block (p, v, u and each copy) is shifted by
    :func:`shift_trajectory`, positions (own and copies) extrapolated if
    ``extrapolate_positions``; s is kept. Also works on the own part alone
    (``values`` of size ``layout.own_size`` with a layout without neighbours).
    """
    out = values.copy()
    for block in layout.position_blocks():
        out[block] = shift_trajectory(values[block], extrapolate=extrapolate_positions)
    for block in (layout.vel, layout.inp):
        out[block] = shift_trajectory(values[block], extrapolate=False)
    return out


def shift_dual(y: np.ndarray, horizon_steps: int) -> np.ndarray:
    """OSQP's dual of :func:`own_constraint_matrix`'s rows (21K+1,) shifted by one step per row block.

    Dynamics (6 rows per step), input box and the four soft boxes (3 per
    step): step k <- k+1, the last step kept; the slack row kept.
    """
    K = int(horizon_steps)
    out = y.copy()
    r = 0
    for per_step in (6, 3, 3, 3, 3, 3):
        block = out[r : r + per_step * K].reshape(K, per_step)
        block[:-1] = block[1:].copy()
        r += per_step * K
    return out
