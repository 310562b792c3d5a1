"""Static-obstacle rows of the DMPC QP: every step, or on demand (on-demand DMPC Sec. 3.4).

Obstacles reach the QP as half-spaces on the drone's own position, one per
obstacle o and horizon step k (k = 1..K, index k-1 in the arrays)::

    n_ok^T p[k] >= c_ok          (the free side; n_ok need not be unit)

e.g. the agent's tangent planes of the obstacle footprint at the point nearest
to the previous plan, pushed out by the obstacle safety radius r_obs
(:func:`mpcde.onboard.dmpc.obstacle_half_spaces`). For such a plane, with n unit,

    clearance_ok = n_ok^T p̄[k] - c_ok = (surface distance of p̄[k]) - r_obs,

so the planes carry the paper's obstacle goal ||p_o - p_i|| >= r_obs (on-demand
DMPC design goal 4) linearised at the previous plan p̄ (the footprint is
convex, so the plane separates all of it: meeting the plane meets the goal).

Two ways to put them into the QP (``DmpcConfig.obstacle_avoidance``):

* ``every_step``: a hard row n_ok^T p[k] >= c_ok for every obstacle and step
  (the conventional form; K rows per obstacle, new values every round).
* ``on_demand``: the paper's mechanism, which covers "the assumed trajectories
  of neighbors AND known obstacle positions" (on-demand DMPC Sec. 3.4 and
  Conclusion). The own previous plan, shifted to this round's times, is
  checked against each obstacle; its first conflict step k_c is the first k
  with clearance_ok < ``conflict_margin_m``. Only then ONE row is added for
  that obstacle, at k_c (``on_demand_time = "first_conflict"``) or at the
  deepest point of the conflict run that starts at k_c
  (``"closest_approach"``, the default, for the same reason as for neighbours:
  at k_c the plane faces the oncoming drone and is met by a small delay, at
  the deepest point it faces sideways and steers round the obstacle). The
  paper writes the step as "k_c - 1" because its k_c counts in the previous
  round's prediction; the previous plan here is evaluated at the current
  round's times, so step k_c here is the same absolute time.
  The row is HARD (no slack), unlike the paper's soft neighbour rows: an
  obstacle does not move out of the way, a soft row would let a heavy-enough
  cost push the plan into it, and the every-step rows it replaces are hard
  too, so the two modes differ only in WHICH rows they keep. The QP has
  ``max_obstacle_planes`` fixed slots (fixed sparsity, one dense row over the
  inputs each); an unused slot has coefficients 0 and bounds (-inf, inf), so a
  round without an obstacle conflict leaves OSQP's matrix unchanged.

Both modes cull rows that the QP's own velocity and input limits already imply
(:mod:`planners.dmpc.reach`): the feasible set is exactly the same.

Measured, with the variants tried and dropped: docs/results/dmpc_obstacles.md.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from planners.dmpc.config import DmpcConfig
from planners.dmpc.reach import implied_half_spaces, reach_boxes

__all__ = ["ObstacleConflicts", "ObstacleRows", "obstacle_conflicts", "obstacle_rows", "stack_obstacles"]

_NO_ROW = -1e30  # OSQP_INFTY: "no lower bound"


@dataclass(frozen=True)
class ObstacleConflicts:
    """Predicted obstacle conflicts of the own previous plan, one entry per conflicting obstacle.

    Attributes:
        obstacle_index: (n,) obstacle indices, increasing.
        first_step: (n,) 0-based index of each obstacle's first conflict step
            (step k_c = first_step + 1 of t_now + k h).
        step_index: (n,) 0-based step at which the row constrains p.
        clearance_m: (n,) clearance n^T p̄ - c / ||n|| at ``step_index`` [m] (< margin).
    """

    obstacle_index: np.ndarray
    first_step: np.ndarray
    step_index: np.ndarray
    clearance_m: np.ndarray

    @property
    def count(self) -> int:
        """Number of conflicting obstacles n."""
        return int(self.obstacle_index.size)


def obstacle_conflicts(
    own_pos_world: np.ndarray,
    normals: np.ndarray,
    offsets: np.ndarray,
    margin_m: float,
    constrain_at: str = "closest_approach",
) -> ObstacleConflicts:
    """First predicted conflict of the own previous plan with each obstacle (module docstring).

    Args:
        own_pos_world: (K, 3) own previous plan at t_now + k h, k = 1..K [m].
        normals: (O, K, 3) half-space normals n_ok (any length; rows of zeros = no obstacle).
        offsets: (O, K) offsets c_ok [m] (-inf or below -1e29 = no plane).
        margin_m: conflict when the clearance is below this [m] (>= 0).
        constrain_at: ``"first_conflict"`` (row at k_c) or ``"closest_approach"``
            (row at the smallest clearance of the conflict run starting at k_c).

    Returns:
        The conflicting obstacles, their first conflict and constrained steps.
    """
    if constrain_at not in ("first_conflict", "closest_approach"):
        raise ValueError(f"constrain_at={constrain_at!r}: one of first_conflict, closest_approach")
    normals = np.asarray(normals, float)
    offsets = np.asarray(offsets, float)
    norm = np.linalg.norm(normals, axis=-1)  # (O, K)
    valid = (norm > 0) & (offsets > _NO_ROW)
    clearance = np.full(offsets.shape, np.inf)
    proj = np.einsum("okd,kd->ok", normals, np.asarray(own_pos_world, float))
    clearance[valid] = (proj[valid] - offsets[valid]) / norm[valid]  # n^T p̄[k] - c, per unit normal
    conflict = clearance < margin_m
    hit = np.flatnonzero(conflict.any(axis=1))
    first = np.argmax(conflict[hit], axis=1)  # k_c - 1 per conflicting obstacle
    step = first.copy()
    if constrain_at == "closest_approach" and hit.size:
        K = offsets.shape[1]
        k = np.arange(K)[None, :]
        after = ~conflict[hit] & (k > first[:, None])  # first non-conflict step after k_c ends the run
        end = np.where(after.any(axis=1), np.argmax(after, axis=1), K)
        in_run = (k >= first[:, None]) & (k < end[:, None])
        step = np.argmin(np.where(in_run, clearance[hit], np.inf), axis=1)
    return ObstacleConflicts(hit, first, step, clearance[hit, step] if hit.size else np.zeros(0))


def stack_obstacles(
    obstacles: Sequence[tuple[np.ndarray, np.ndarray | float]] | None, slots: int, K: int
) -> tuple[np.ndarray, np.ndarray]:
    """(normal, offset) pairs -> normals (slots, K, 3) and offsets (slots, K) [m] (-inf where unused).

    Args:
        obstacles: pairs with normal (3,) or (K, 3) and offset scalar or (K,).
        slots: number of obstacle slots O.
        K: horizon steps.
    """
    obstacles = list(obstacles or [])
    if len(obstacles) > slots:
        raise ValueError(f"obstacles: {len(obstacles)} planes given, max_obstacle_planes={slots}")
    normals, offsets = np.zeros((slots, K, 3)), np.full((slots, K), -np.inf)
    for i, (nrm, off) in enumerate(obstacles):
        normals[i] = np.broadcast_to(np.asarray(nrm, float), (K, 3))
        offsets[i] = np.broadcast_to(np.asarray(off, float), (K,))
    return normals, offsets


@dataclass(frozen=True)
class ObstacleRows:
    """Values of the QP's obstacle rows  coef U >= lower  for one round.

    Attributes:
        coef: (O K, 3K) every step (row o K + k) or (O, 3K) on demand (row = slot) coefficients
            n^T Lambda_p[k] (zeros in unused rows).
        lower: (O K,) or (O,) bounds c - n^T A0_p[k] x0 [m] (-1e30 in unused rows).
        count: rows in use.
        conflicts: the on-demand conflicts (None with ``every_step``).
    """

    coef: np.ndarray
    lower: np.ndarray
    count: int
    conflicts: ObstacleConflicts | None


def obstacle_rows(
    config: DmpcConfig,
    obstacles: Sequence[tuple[np.ndarray, np.ndarray | float]] | None,
    x0: np.ndarray,
    free_pos_world: np.ndarray,
    Lambda_pos_blocks: np.ndarray,
    own_prev_world: np.ndarray,
    cull_margin_m: float,
) -> ObstacleRows:
    """The round's obstacle rows in ``config.obstacle_mode`` (module docstring), culled.

    With p[k] = A0_p[k] x0 + Lambda_p[k] U (on-demand DMPC Eq. 10) the row
    n^T p[k] >= c becomes n^T Lambda_p[k] U >= c - n^T A0_p[k] x0. A row is
    culled (left unused) when the QP's box constraints imply it with
    ``cull_margin_m`` to spare (:func:`planners.dmpc.reach.implied_half_spaces`).

    Args:
        config: the QP's settings (K, max_obstacle_planes, obstacle_mode, conflict_margin_m, on_demand_time).
        obstacles: (normal, offset) pairs, at most ``max_obstacle_planes`` (see :func:`stack_obstacles`).
        x0: (6,) or (9,) initial state [m, m/s(, m/s^2)].
        free_pos_world: (K, 3) free response A0_p x0 [m].
        Lambda_pos_blocks: (K, 3, 3K) Lambda_p per step.
        own_prev_world: (K, 3) own previous plan at the round's steps [m] (on-demand conflict check).
        cull_margin_m: spare required to cull a row [m].
    """
    K, O = config.horizon_steps, config.max_obstacle_planes
    normals, offsets = stack_obstacles(obstacles, O, K)
    used = offsets > _NO_ROW
    if config.obstacle_culling and used.any():
        used &= ~implied_half_spaces(normals, offsets, reach_boxes(config, x0), cull_margin_m)
    if config.obstacle_mode == "every_step":
        normals = np.where(used[..., None], normals, 0.0)
        coef = np.einsum("okd,kdc->okc", normals, Lambda_pos_blocks).reshape(O * K, -1)
        lower = offsets - np.einsum("okd,kd->ok", normals, free_pos_world)  # c - n^T A0_p[k] x0
        return ObstacleRows(coef, np.where(used, lower, _NO_ROW).ravel(), int(used.sum()), None)
    conflicts = obstacle_conflicts(own_prev_world, normals, offsets, config.conflict_margin_m, config.on_demand_time)
    coef, lower = np.zeros((O, Lambda_pos_blocks.shape[2])), np.full(O, _NO_ROW)
    keep = used[conflicts.obstacle_index, conflicts.step_index]  # a culled row cannot be active
    o, k = conflicts.obstacle_index[keep], conflicts.step_index[keep]
    n = keep.sum()
    if n:
        nrm = normals[o, k]  # (n, 3)
        coef[:n] = np.einsum("nd,ndc->nc", nrm, Lambda_pos_blocks[k])  # n^T Lambda_p[k_c]
        lower[:n] = offsets[o, k] - np.einsum("nd,nd->n", nrm, free_pos_world[k])  # c - n^T A0_p[k_c] x0
    return ObstacleRows(coef, lower, int(n), conflicts)
