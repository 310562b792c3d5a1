"""Collision-avoidance geometry of the DMPC QP: on-demand planes and buffered Voronoi cells.

Distances are ellipsoidal to account for downwash (DMPC-Swarm Eq. 2;
on-demand DMPC Sec. 3.4 with the online_dmpc ellipsoid):

    xi_ij = || Theta^-1 (p_i - p_j) ||_2,   Theta = diag(1, 1, c),   xi_ij >= r_min_m.

Every constraint here is returned in one form, a half-space on the drone's own
position at one horizon step k (k = 1..K, index k-1 in the arrays):

    a^T p_i[k] >= b          (the free side),

plus, for the soft on-demand rows, the slack scale sigma.

All functions are pure and vectorised over neighbours and steps. Inputs are
positions sampled at the same absolute times t_now + k h, k = 1..K (own previous
plan and neighbours' plans, both shifted to the current round).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = [
    "BvcPlanes",
    "OnDemandConstraints",
    "bvc_planes",
    "ellipsoidal_distance",
    "first_conflict_step",
    "on_demand_constraints",
]

_EPS_M = 1e-9


def ellipsoidal_distance(delta_world: np.ndarray, downwash: float) -> np.ndarray:
    """||Theta^-1 delta||_2 [m] for differences ``delta_world`` (..., 3) -> (...).

    Args:
        delta_world: (..., 3) position differences p_i - p_j in [m].
        downwash: c >= 1, Theta = diag(1, 1, c).
    """
    d = np.asarray(delta_world, float)
    return np.sqrt(d[..., 0] ** 2 + d[..., 1] ** 2 + (d[..., 2] / downwash) ** 2)  # ||Theta^-1 d||


def _safe_directions(scaled_delta: np.ndarray, fallback: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Unit directions and norms of ``scaled_delta`` (..., 3); ``fallback`` (..., 3) where it vanishes."""
    norm = np.linalg.norm(scaled_delta, axis=-1)
    tiny = norm < _EPS_M
    if np.any(tiny):
        scaled_delta = np.where(tiny[..., None], fallback, scaled_delta)
        norm = np.where(tiny, np.linalg.norm(scaled_delta, axis=-1), norm)
        norm = np.maximum(norm, _EPS_M)
    return scaled_delta / norm[..., None], norm


def first_conflict_step(
    own_pos_world: np.ndarray, neighbours_pos_world: np.ndarray, threshold_m: float, downwash: float
) -> int:
    """Index (0-based) of the first check time with a predicted conflict, or -1 if none.

    A conflict at index k is an ellipsoidal distance below ``threshold_m`` to any
    neighbour (on-demand DMPC Sec. 3.4: "the first collision time k_c").

    Args:
        own_pos_world: (T, 3) own previous plan at T increasing check times [m].
        neighbours_pos_world: (M, T, 3) neighbours' plans at the same times [m].
        threshold_m: r_min_m (+ margin) [m].
        downwash: c of Theta = diag(1, 1, c).
    """
    if neighbours_pos_world.shape[0] == 0:
        return -1
    dist = ellipsoidal_distance(own_pos_world[None] - neighbours_pos_world, downwash)  # (M, K)
    hit = np.any(dist < threshold_m, axis=0)
    return int(np.argmax(hit)) if np.any(hit) else -1


@dataclass(frozen=True)
class OnDemandConstraints:
    """Linearised on-demand collision constraints at one step (on-demand DMPC Sec. 3.4).

    Attributes:
        step_index: 0-based index of the first conflicting check time (with
            check times t_now + k h, k = 1..K, the paper's k_c = step_index + 1),
            -1 when no conflict is predicted (then the arrays are empty).
        neighbour_index: (n,) indices (into the neighbours array) constrained.
        time_index: (n,) check-time index at which each plane constrains p_i
            (k_c for the paper's rule; see ``linearise_at``).
        normal: (n, 3) a = nu = omega / sigma of a^T p_i[k_c] + s >= b
            (see :func:`on_demand_constraints`).
        offset: (n,) b [m].
        sigma: (n,) slack scale (dimensionless; 1 in the normalised form).
        distance_m: (n,) ellipsoidal distance xi_ij at k_c in the previous plans [m].
    """

    step_index: int
    neighbour_index: np.ndarray
    time_index: np.ndarray
    normal: np.ndarray
    offset: np.ndarray
    sigma: np.ndarray
    distance_m: np.ndarray

    @property
    def count(self) -> int:
        """Number of constraints n."""
        return int(self.neighbour_index.size)


def on_demand_constraints(
    own_pos_world: np.ndarray,
    neighbours_pos_world: np.ndarray,
    r_min_m: float,
    downwash: float,
    conflict_margin_m: float = 0.05,
    neighbourhood_factor: float = 3.0,
    own_now_world: np.ndarray | None = None,
    neighbours_now_world: np.ndarray | None = None,
    linearise_at: str = "first_conflict",
) -> OnDemandConstraints:
    """On-demand collision constraints: one soft plane per close neighbour at the first conflict.

    The paper's form (on-demand DMPC Sec. 3.4, reading of the garbled text taken
    from the online_dmpc implementation ``build_constraint.m``)::

        omega_ij^T p_i[k_c] - alpha_ij sigma_ij >= upsilon_ij,   alpha_ij <= 0,

    with, linearising xi(p) = ||Theta^-1 (p - p_j)|| at the previous plan p̄_i = p_i[k_c | k_t - 1]:

        omega_ij   = Theta^-2 (p̄_i - p_j)               (gradient times xi)
        sigma_ij   = xi_ij = ||Theta^-1 (p̄_i - p_j)||
        upsilon_ij = xi_ij (r_min_m - xi_ij) + omega_ij^T p̄_i

    i.e. xi_ij + nu^T (p - p̄_i) >= r_min_m with nu = omega / xi. Because xi(p) is
    convex, its linearisation is a lower bound, so meeting the plane with zero
    slack meets the true distance constraint. We return the *normalised* form
    (divide by sigma_ij > 0; better conditioned when xi is small)::

        a^T p_i[k_c] + s >= b,   a = nu = Theta^-2 (p̄_i - p_j) / xi,
        b = r_min_m - xi + a^T p̄_i,   s = -alpha >= 0 in [m],

    so ``sigma`` is 1. Constraints are built for every neighbour whose
    distance at k_c is below ``neighbourhood_factor * r_min_m``.

    The paper checks at the horizon samples t_now + k h; the caller may pass a
    finer grid of check times (the QP does, ``conflict_substeps``), and then
    "p_i[k_c]" is the position at the first conflicting check time.

    Args:
        own_pos_world: (T, 3) own previous plan at T check times (e.g. t_now + k h, k = 1..K) [m].
        neighbours_pos_world: (M, T, 3) neighbours' plans at the same times [m].
        r_min_m: minimum ellipsoidal distance [m].
        downwash: c of Theta = diag(1, 1, c).
        conflict_margin_m: conflict when xi < r_min_m + margin [m].
        neighbourhood_factor: constrain neighbours with xi < factor * r_min_m at k_c.
        own_now_world: (3,) current own position, used for the plane direction
            when the predicted positions coincide (optional).
        neighbours_now_world: (M, 3) neighbours' current positions (same use).
        linearise_at: ``"first_conflict"`` (the paper: every plane at k_c) or
            ``"closest_approach"``: a neighbour that conflicts at k_c is
            constrained at the deepest point (minimum distance) of its conflict
            run that starts at k_c. Reason: at k_c the separation is almost
            along the relative velocity, so the plane is met by a tiny delay and
            the plan passes through the neighbour just after k_c; the conflict
            then creeps towards the present round after round until it cannot
            be avoided (observed in the head-on swap). At the closest approach
            the plane is across the relative velocity and resolves the encounter.
    """
    empty = OnDemandConstraints(
        -1, np.zeros(0, int), np.zeros(0, int), np.zeros((0, 3)), np.zeros(0), np.zeros(0), np.zeros(0)
    )
    threshold = r_min_m + conflict_margin_m
    k_c = first_conflict_step(own_pos_world, neighbours_pos_world, threshold, downwash)
    if k_c < 0:
        return empty
    theta_inv = np.array([1.0, 1.0, 1.0 / downwash])
    dist = ellipsoidal_distance(own_pos_world[None] - neighbours_pos_world, downwash)  # (M, T)
    close = np.flatnonzero(dist[:, k_c] < neighbourhood_factor * r_min_m)
    time_index = np.full(close.size, k_c)
    if linearise_at == "closest_approach":
        tail = dist[close, k_c:]  # (n, T - k_c)
        outside = np.c_[tail >= threshold, np.ones(close.size, bool)]
        run_length = np.argmax(outside, axis=1)  # conflict run from k_c (0 if not conflicting at k_c)
        in_run = np.arange(tail.shape[1])[None, :] < run_length[:, None]
        deepest = np.argmin(np.where(in_run, tail, np.inf), axis=1)  # closest approach within the run
        time_index = np.where(run_length > 0, k_c + deepest, k_c)
    elif linearise_at != "first_conflict":
        raise ValueError(f"linearise_at={linearise_at!r}: one of first_conflict, closest_approach")
    own_c = own_pos_world[time_index]  # p̄_i at the constrained times, (n, 3)
    delta = own_c - neighbours_pos_world[close, time_index]  # p̄_i - p_j
    xi = ellipsoidal_distance(delta, downwash)
    fallback = _fallback_direction(close, own_now_world, neighbours_now_world) * theta_inv
    unit_scaled, _ = _safe_directions(delta * theta_inv, fallback)  # Theta^-1 (p̄_i - p_j) / xi
    normal = unit_scaled * theta_inv  # nu = Theta^-2 (p̄_i - p_j) / xi
    offset = r_min_m - xi + np.einsum("nd,nd->n", normal, own_c)  # b = r_min_m - xi + nu^T p̄_i
    return OnDemandConstraints(k_c, close, time_index, normal, offset, np.ones(close.size), xi)


def _fallback_direction(
    index: np.ndarray, own_now_world: np.ndarray | None, neighbours_now_world: np.ndarray | None
) -> np.ndarray:
    """(n, 3) direction used when predicted positions coincide: current separation, else +x."""
    out = np.tile(np.array([1.0, 0.0, 0.0]), (index.size, 1))
    if own_now_world is not None and neighbours_now_world is not None and index.size:
        d = np.asarray(own_now_world, float)[None] - np.asarray(neighbours_now_world, float)[index]
        ok = np.linalg.norm(d, axis=1) > _EPS_M
        out[ok] = d[ok]
    return out


@dataclass(frozen=True)
class BvcPlanes:
    """Time-varying buffered Voronoi cell of one drone (DMPC-Swarm Eq. 14-15).

    Attributes:
        normal: (M, K, 3) a of a^T p_i[k] >= b for neighbour m at step k = 1..K.
        offset: (M, K) b [m].
    """

    normal: np.ndarray
    offset: np.ndarray


def bvc_planes(
    own_pos_world: np.ndarray,
    neighbours_pos_world: np.ndarray,
    r_min_m: float,
    downwash: float,
    own_now_world: np.ndarray | None = None,
    neighbours_now_world: np.ndarray | None = None,
) -> BvcPlanes:
    """Buffered separating planes at every step against every neighbour (DMPC-Swarm Eq. 14-15).

    With p̄_i, p_j the previous plans at the same time (the round's shift taken)::

        n_ij   = Theta^-1 [p_j - p̄_i]                                  (Eq. 14)
        n0_ij^T Theta^-1 [p_j - p_i[k]] >= (r_min_m + ||n_ij||) / 2       (Eq. 15, j recomputed)

    n0 = n / ||n||. The plane lies midway between the two previous positions in
    the Theta-scaled space and is pushed r_min_m / 2 towards each drone, so if
    both drones keep to their cells their new plans are r_min_m apart. The shifted
    previous plan meets its own plane whenever ||n_ij|| >= r_min_m. Rewritten on
    the free side: a = -Theta^-1 n0, b = (r_min_m + ||n||)/2 - n0^T Theta^-1 p_j.

    Args:
        own_pos_world: (K, 3) own previous plan at t_now + k h, k = 1..K [m].
        neighbours_pos_world: (M, K, 3) neighbours' plans at the same times [m].
        r_min_m: minimum ellipsoidal distance [m].
        downwash: c of Theta = diag(1, 1, c).
        own_now_world: (3,) current own position (direction fallback, optional).
        neighbours_now_world: (M, 3) neighbours' current positions (optional).
    """
    theta_inv = np.array([1.0, 1.0, 1.0 / downwash])
    n_nb, K = neighbours_pos_world.shape[:2]
    n = (neighbours_pos_world - own_pos_world[None]) * theta_inv  # n_ij = Theta^-1 (p_j - p̄_i), Eq. 14
    fallback = -np.repeat(
        _fallback_direction(np.arange(n_nb), own_now_world, neighbours_now_world)[:, None], K, axis=1
    ) * theta_inv
    n0, _ = _safe_directions(n, fallback)
    norm = np.linalg.norm(n, axis=-1)  # ||n_ij|| (0 where the plans coincide)
    normal = -n0 * theta_inv  # a = -Theta^-1 n0
    # b = (r_min_m + ||n||) / 2 - n0^T Theta^-1 p_j   (Eq. 15)
    offset = 0.5 * (r_min_m + norm) - np.einsum("mkd,mkd->mk", n0 * theta_inv, neighbours_pos_world)
    return BvcPlanes(normal, offset)
