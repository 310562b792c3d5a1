"""Minimum-distance rows of dSQP's local QPs (Stomberg et al. Sec. 3.2 and 5.2: Eq. 8, QP (6c), Remark 2).

The coupled constraint of OCP (1f) between drones o and m is

    xi(p_o[k] - p_m[k]) = ||Theta^-1 (p_o[k] - p_m[k])||_2 >= d,   Theta = diag(1, 1, c),  k = 1..K

(Eq. 8 with the package's ellipsoidal distance, DMPC-Swarm Eq. 2; c = 1 is
the paper's Euclidean norm). The paper writes the pair's constraint into the
inequalities (2c) of ONE of the two robots, on its own positions and its copy
of the other's (Sec. 5.2: "included in the subsystem inequality constraints
(2c) of robots two to four", robot i holding the pair (i, i - 1)). Here the
higher id holds every pair of the coupling graph (:func:`owned_partners`):
holding it at both ends would make the rows linearly dependent at consensus
(LICQ of Theorem 1 fails). Softened as in Remark 2 with the drone's one slack:

    h(z_o) = d - xi(p_o[k] - w_mo[k]) - s_o <= 0.

dSQP's QP (6) linearises h at the current iterate zbar (Algorithm 3 Step 3;
the Gauss-Newton Hessian of Remark 4 takes no curvature from h). xi is convex,
so its tangent at delta_bar = pbar_o[k] - wbar_mo[k] is a lower bound and the
linearised row

    a' (p_o[k] - w_mo[k]) + s_o >= d,   a = Theta^-2 delta_bar / xi(delta_bar)

(the same half-space as the on-demand DMPC's planes, :mod:`planners.dmpc.collision`)
is an inner approximation: a point that meets it meets h <= 0. Only the row's
values change from one SQP iteration to the next; its bound d does not.
Where delta_bar vanishes (the plans coincide) the direction of the current
separation is used, else +x.

**Against the means** (``distance_rows: means``, not in the paper). QP (6c)
constrains the drone's copy w_mo as well as its own p_o, and with few ADMM
iterations per step the cheapest way to meet the row is to move the copy:
the copy then sits where the formation term wants the neighbour while the
neighbour's own plan goes through (measured: docs/results/admm_formation.md#dsqp-rho-screen).
Holding the row against the latest consensus mean wbar_mo (a constant of the
QP, the average the last Step 9 sent) instead,

    a' p_o[k] + s_o >= d + a' wbar_mo[k],

puts the whole separation on the holder's own plan; it is the same tangent
at zbar, so the inner approximation holds against wbar. With Remark 1 (u[0] fixed) p[1] is data, so the
k = 1 rows are left free, as the soft box rows of :mod:`planners.dmpc.admm.ocp`.
"""

from __future__ import annotations

from collections.abc import Iterable

import numpy as np

from planners.dmpc.admm.ocp import DroneLayout
from planners.dmpc.sparse_qp.pattern import SparsePattern

__all__ = ["DistanceRows", "distance_gradient", "distance_residual", "owned_partners"]

_INF = 1e30  # OSQP_INFTY
_EPS_M = 1e-6  # below this separation [m] the direction of delta_bar is undefined


def owned_partners(drone_id: int, neighbour_ids: Iterable[int]) -> tuple[int, ...]:
    """The neighbours whose minimum-distance rows drone ``drone_id`` holds: those with a lower id (module docstring)."""
    return tuple(sorted(j for j in neighbour_ids if j < drone_id))


def distance_residual(own_world: np.ndarray, other_world: np.ndarray, d_min_m: float, downwash: float) -> np.ndarray:
    """d - xi(p_o - p_m) (n,) [m] for positions (n, 3): > 0 where the pair is closer than ``d_min_m``."""
    theta_inv = np.array([1.0, 1.0, 1.0 / downwash])
    return d_min_m - np.linalg.norm((np.asarray(own_world) - np.asarray(other_world)) * theta_inv, axis=-1)


def distance_gradient(
    own_world: np.ndarray, other_world: np.ndarray, downwash: float, fallback_world: np.ndarray | None = None
) -> np.ndarray:
    """a = d xi / d p_o = Theta^-2 delta / xi(delta) (n, 3) at delta = p_o - p_m (n, 3); -a is d xi / d p_m.

    Args:
        own_world, other_world: (n, 3) positions [m].
        downwash: c of Theta = diag(1, 1, c).
        fallback_world: (3,) direction used where delta < 1e-6 m (default +x).
    """
    theta_inv = np.array([1.0, 1.0, 1.0 / downwash])
    delta = np.asarray(own_world, float) - np.asarray(other_world, float)
    scaled = delta * theta_inv
    xi = np.linalg.norm(scaled, axis=-1)
    small = xi < _EPS_M
    if np.any(small):
        fb = np.array([1.0, 0.0, 0.0]) if fallback_world is None else np.asarray(fallback_world, float).reshape(3)
        if np.linalg.norm(fb * theta_inv) < _EPS_M:
            fb = np.array([1.0, 0.0, 0.0])
        scaled[small] = fb * theta_inv
        xi[small] = np.linalg.norm(fb * theta_inv)
    return scaled / xi[:, None] * theta_inv


class DistanceRows:
    """The K rows per held pair of drone o's local QP, laid out once, re-linearised in place (module docstring).

    Row r = first_row + m_idx K + (k - 1) for partner ``partners[m_idx]`` and
    step k: entries a on p_o[k] (3), -a on w_mo[k] (3) and 1 on s_o, bounds
    [d, inf) (k = 1 free with ``first_step_free``).

    Args:
        layout: drone o's layout of z_o (its copies include every partner).
        partners: the partners m it holds (:func:`owned_partners`).
        d_min_m: d [m].
        downwash: c of Theta.
        first_step_free: leave the k = 1 rows free (Remark 1: p[1] is data).
        against_means: hold the rows against the means wbar (constants), not
            the copies (module docstring); the entries on w_mo are then 0.
    """

    def __init__(self, layout: DroneLayout, partners: tuple[int, ...], d_min_m: float, downwash: float,
                 first_step_free: bool, against_means: bool = False) -> None:  # fmt: skip
        missing = [m for m in partners if m not in layout.neighbour_ids]
        if missing:
            raise ValueError(f"partners {missing}: not neighbours of this drone (a held pair needs a copy)")
        self.layout, self.partners = layout, tuple(partners)
        self.d_min_m, self.downwash = float(d_min_m), float(downwash)
        self.first_step_free = bool(first_step_free)
        self.against_means = bool(against_means)
        K = layout.horizon_steps
        self.count = K * len(self.partners)
        self._shift = np.zeros(self.count)  # a' wbar per row (against the means)

    def add_to(self, pattern: SparsePattern, first_row: int) -> slice:
        """Add the rows' entries (placeholder values) to ``pattern`` from ``first_row`` on; their COO slice.

        Entry order, which :meth:`values` follows: per partner, per step, 3 on
        p_o[k], 3 on w_mo[k], 1 on s_o.
        """
        lay, K = self.layout, self.layout.horizon_steps
        rows, cols = [], []
        for m_idx, m in enumerate(self.partners):
            p0, w0 = lay.pos.start, lay.copy(m).start
            for k in range(K):
                r = first_row + m_idx * K + k
                rows += [r] * 7
                cols += [p0 + 3 * k, p0 + 3 * k + 1, p0 + 3 * k + 2, w0 + 3 * k, w0 + 3 * k + 1, w0 + 3 * k + 2, lay.slack]
        vals = np.tile(np.r_[np.ones(3), -np.ones(3), 1.0], self.count)  # a = +x direction until linearised
        return pattern.add(np.array(rows, int), np.array(cols, int), vals)

    def values(self, zbar: np.ndarray, fallback_world: np.ndarray | None = None) -> np.ndarray:
        """(7 K P,) the rows' entries linearised at ``zbar`` (n_o,), in :meth:`add_to`'s order.

        Against the means it also keeps a' wbar for :meth:`bounds`.
        """
        lay, K = self.layout, self.layout.horizon_steps
        own = zbar[lay.pos].reshape(K, 3)
        out = np.empty((len(self.partners), K, 7))
        shift = np.zeros((len(self.partners), K))
        for m_idx, m in enumerate(self.partners):
            wbar = zbar[lay.copy(m)].reshape(K, 3)
            a = distance_gradient(own, wbar, self.downwash, fallback_world)
            out[m_idx, :, 0:3] = a
            out[m_idx, :, 3:6] = 0.0 if self.against_means else -a
            out[m_idx, :, 6] = 1.0
            shift[m_idx] = np.einsum("kd,kd->k", a, wbar) if self.against_means else 0.0
        self._shift = shift.ravel()
        return out.ravel()

    def bounds(self, free: bool = False) -> tuple[np.ndarray, np.ndarray]:
        """(lower, upper) (K P,): [d (+ a' wbar against the means), inf), the k = 1 rows free with
        ``first_step_free``, every row free with ``free``."""
        K = self.layout.horizon_steps
        lower = (self.d_min_m + self._shift).reshape(len(self.partners), K)
        if free:
            lower = np.full_like(lower, -_INF)
        if self.first_step_free:
            lower[:, 0] = -_INF
        return lower.ravel(), np.full(self.count, _INF)
