"""Where every row of the DMPC QP's constraint matrix sits (:mod:`planners.dmpc.qp`).

OSQP factorises the KKT pattern once, so :class:`planners.dmpc.qp.DmpcProblem`
lays out every row it may ever need at setup (``l <= A z <= u``, z = [U; s]):

    rows            block                                       values
    pos             p[k] = A0_p x0 + Lambda_p U, k = 1..K          fixed
    vel, acc        v[k], a[k] (on-demand DMPC Eq. 10)           fixed
    jerk            u[k] (triple integrator only)                fixed
    coll            on demand: one row per neighbour slot,       per round
                    a_m^T p(t_c) + s_m; BVC: one per slot and step
    slack           0 <= s_m <= s_max (on demand only)           fixed
    obs             obstacle half-spaces: one per slot and step  per round
                    (every_step) or one per slot (on_demand)

A dynamic block's entries are written in CSC order through
``coo_to_csc[entries]`` (:class:`planners.dmpc.sparse_qp.pattern.SparsePattern`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from planners.dmpc.config import DmpcConfig
from planners.dmpc.model import PredictionMatrices
from planners.dmpc.sparse_qp.pattern import SparsePattern

__all__ = ["QpRows", "qp_rows"]


@dataclass(frozen=True)
class QpRows:
    """First rows of each block of A, the dynamic blocks' entries, and A itself on its fixed pattern.

    Attributes:
        pos, vel, acc, jerk: first rows of the box blocks (3K rows each; ``jerk`` -1 for the double integrator).
        coll: first collision row; ``n_coll`` of them (M on demand, M K for BVC).
        coll_entries: COO slice of the collision rows' U coefficients.
        slack_coef_entries: COO slice of the on-demand rows' slack coefficients (None for BVC).
        slack: first row of the slack bounds (-1 for BVC).
        obs: first obstacle row; the obstacle rows run to ``n``.
        obs_steps: K (a row per obstacle slot and step) or 1 (a row per slot, on demand).
        obs_mask: (obs_steps, 3K) which input columns an obstacle row holds.
        obs_entries: COO slice of the obstacle rows (None without obstacle slots).
        n: number of rows.
        A: the (n, 3K + slack) CSC matrix, explicit zeros kept.
        coo_to_csc: (nnz,) COO -> CSC index map of A's data.
        n_u: number of input variables (3K); the slack variables follow them.
        step_blocks: the row blocks indexed by horizon step: (first row, number of blocks, rows per step).
        on_demand: whether the collision rows are on demand (one per neighbour slot) or BVC.
    """

    pos: int
    vel: int
    acc: int
    jerk: int
    coll: int
    n_coll: int
    coll_entries: slice
    slack_coef_entries: slice | None
    slack: int
    obs: int
    obs_steps: int
    obs_mask: np.ndarray
    obs_entries: slice | None
    n: int
    A: sp.csc_matrix
    coo_to_csc: np.ndarray
    n_u: int
    step_blocks: tuple[tuple[int, int, int], ...]
    on_demand: bool

    def shifted_warm_start(self, x_last: np.ndarray, y_last: np.ndarray, n_coll: int, n_obs: int) -> tuple[np.ndarray, np.ndarray]:
        """The previous primal (n,) and dual (m,) solutions shifted by one step (the receding horizon), for OSQP's warm start.

        Inputs u[1..K-1] become u[0..K-2] and u[K-1] is repeated; the
        multipliers of every step-indexed row block (position, velocity and
        acceleration boxes, BVC planes, obstacle planes) shift the same way.
        On-demand rows (one per neighbour or obstacle slot, not per step) keep
        their multipliers; unused on-demand slots (the first ``n_coll``
        neighbour and ``n_obs`` obstacle slots are used) start at 0.
        """
        K, n_u = self.n_u // 3, self.n_u
        x = x_last.copy()
        x[: n_u - 3] = x_last[3:n_u]  # u[k] <- u[k+1]; u[K-1] kept
        y = y_last.copy()
        for row0, blocks, per_step in self.step_blocks:
            block = y[row0 : row0 + blocks * K * per_step].reshape(blocks, K * per_step)
            block[:, :-per_step] = block[:, per_step:].copy()  # step k <- step k+1; step K kept
        if self.on_demand:
            x[n_u + n_coll :] = 0.0
            y[self.coll + n_coll : self.coll + self.n_coll] = 0.0
        if self.obs_steps == 1:
            y[self.obs + n_obs : self.n] = 0.0
        return x, y


def qp_rows(cfg: DmpcConfig, mats: PredictionMatrices, n_slack: int) -> QpRows:
    """Lay out the constraint rows for ``cfg`` (K steps, M neighbour and O obstacle slots) and prediction ``mats``."""
    K, M, O = cfg.horizon_steps, cfg.max_neighbours, cfg.max_obstacle_planes
    n_u = 3 * K
    lower = np.arange(n_u)[None, :] < 3 * (np.arange(K)[:, None] + 1)  # (K, 3K): inputs 0..k-1 reach p[k]
    pat = SparsePattern()
    row = 0

    def add_dense(block: np.ndarray) -> int:
        nonlocal row
        r, c = np.nonzero(np.abs(block) > 0)
        pat.add(row + r, c, block[r, c])
        row += block.shape[0]
        return row - block.shape[0]

    pos, vel, acc = add_dense(mats.Lambda_pos), add_dense(mats.Lambda_vel), add_dense(mats.Lambda_acc)
    jerk = add_dense(np.eye(n_u)) if cfg.model == "triple" else -1
    coll, slack_coef_entries, slack = row, None, -1
    if cfg.collision_mode == "on_demand":
        coll_entries = pat.add(row + np.repeat(np.arange(M), n_u), np.tile(np.arange(n_u), M), np.zeros(M * n_u))
        slack_coef_entries = pat.add(row + np.arange(M), n_u + np.arange(M), np.zeros(M))
        slack = row + M
        pat.add(slack + np.arange(M), n_u + np.arange(M), np.ones(M))
        row, n_coll = slack + M, M
    else:
        kk, cc = np.nonzero(lower)
        coll_entries = pat.add(row + (np.arange(M)[:, None] * K + kk[None, :]).ravel(), np.tile(cc, M), np.zeros(M * kk.size))
        row, n_coll = row + M * K, M * K
    # Obstacle rows: x, y input columns only for vertical planes (a third fewer entries to factorise);
    # every_step: one row per obstacle and step (lower-triangular), on_demand: one dense row per slot.
    obs = row
    xy = (np.arange(n_u) % 3 != 2)[None, :] if cfg.vertical_obstacle_planes else True
    obs_steps = K if cfg.obstacle_mode == "every_step" else 1
    obs_mask = (lower if obs_steps == K else np.ones((1, n_u), bool)) & xy
    obs_entries = None
    if O:
        kk, cc = np.nonzero(obs_mask)
        obs_entries = pat.add(row + (np.arange(O)[:, None] * obs_steps + kk[None, :]).ravel(), np.tile(cc, O), np.zeros(O * kk.size))
        row += O * obs_steps
    A, coo_to_csc = pat.to_csc((row, n_u + n_slack))
    step_blocks = [(pos, 1, 3), (vel, 1, 3), (acc, 1, 3)] + ([(jerk, 1, 3)] if jerk >= 0 else [])
    if cfg.collision_mode == "bvc":
        step_blocks.append((coll, M, 1))
    if O and obs_steps == K:
        step_blocks.append((obs, O, 1))
    return QpRows(
        pos=pos, vel=vel, acc=acc, jerk=jerk, coll=coll, n_coll=n_coll, coll_entries=coll_entries,
        slack_coef_entries=slack_coef_entries, slack=slack, obs=obs, obs_steps=obs_steps, obs_mask=obs_mask,
        obs_entries=obs_entries, n=row, A=A, coo_to_csc=coo_to_csc, n_u=n_u, step_blocks=tuple(step_blocks),
        on_demand=cfg.collision_mode == "on_demand",
    )  # fmt: skip
