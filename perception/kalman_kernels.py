"""Compiled (numba) kernels of the tracker's hot path: predict, gate, update, adapt.

The same mathematics as :mod:`perception.kalman_cv` (MP-CDE Eq. 9-11, the
reading of Eq. 11 stated there) and the gating of :mod:`perception.tracker`,
written as loops over tracks and 3x3 / 6x6 blocks so that one tracker frame is
two compiled calls instead of a few dozen small numpy operations. Tests hold
them to the filterpy reference (:class:`perception.kalman_cv.KalmanCV`) to 1e-9.

Symbols, inside each function: ``x = [p, v]`` (6,) the state [m, m/s], ``P``
(6, 6) its covariance, ``F = [[I, dt I], [0, I]]`` the transition (Eq. 9),
``G = [dt^2/2 I; dt I]`` the acceleration gain, ``A`` (3, 3) the adaptive
acceleration covariance, ``H = [I, 0]`` (Eq. 10), ``R`` (3, 3) the measurement
covariance, ``S = H P H^T + R``, ``K = P H^T S^-1`` the gain.

Compiled on first use and cached on disk (``cache=True``); the first call in a
fresh environment costs a few seconds of compilation (3.7 s here, on a shared 2-core machine).
"""

from __future__ import annotations

import numpy as np
from numba import njit

__all__ = ["gate_pairs", "predict_tracks", "trivial_assignment", "update_tracks"]


@njit(cache=True)
def _inv3(S: np.ndarray, out: np.ndarray) -> None:
    """``out = S^-1`` for one symmetric positive definite (3, 3) ``S`` (adjugate over determinant)."""
    a, b, c = S[0, 0], S[0, 1], S[0, 2]
    d, e, f = S[1, 0], S[1, 1], S[1, 2]
    g, h, i = S[2, 0], S[2, 1], S[2, 2]
    c00, c01, c02 = e * i - f * h, f * g - d * i, d * h - e * g
    inv_det = 1.0 / (a * c00 + b * c01 + c * c02)
    out[0, 0], out[1, 0], out[2, 0] = c00 * inv_det, c01 * inv_det, c02 * inv_det
    out[0, 1], out[1, 1], out[2, 1] = (c * h - b * i) * inv_det, (a * i - c * g) * inv_det, (b * g - a * h) * inv_det
    out[0, 2], out[1, 2], out[2, 2] = (b * f - c * e) * inv_det, (c * d - a * f) * inv_det, (a * e - b * d) * inv_det


@njit(cache=True)
def predict_tracks(
    x: np.ndarray,
    P: np.ndarray,
    acc_cov: np.ndarray,
    sigma_acc2: float,
    dt_s: float,
    coast_s: np.ndarray,
    coast_pos_m2ps: float,
    coast_vel_m2ps3: float,
) -> None:
    """Predict every track by ``dt_s`` in place (MP-CDE Eq. 9) with DWNA noise and coasting inflation.

    ``x = F x``, ``P = F P F^T + G (sigma_acc2 I + A) G^T + coast diag(c_p I, c_v I)``.

    Args:
        x: (n, 6) states, overwritten.
        P: (n, 6, 6) covariances, overwritten.
        acc_cov: (n, 3, 3) adaptive acceleration covariances ``A`` [m^2/s^4].
        sigma_acc2: fixed white-noise acceleration variance per axis [m^2/s^4].
        dt_s: prediction interval [s] (>= 0).
        coast_s: (n,) coasting time accrued in this interval [s] (0: no inflation).
        coast_pos_m2ps, coast_vel_m2ps3: linear inflation rates of the
            position [m^2/s] and velocity [m^2/s^3] variances per axis.
    """
    n = x.shape[0]
    g_p, g_v = 0.5 * dt_s * dt_s, dt_s
    for k in range(n):
        for a in range(3):
            x[k, a] += dt_s * x[k, a + 3]  # p = p + dt v
        Pk = P[k]
        # F P F^T by blocks: Ppp' = Ppp + dt (Ppv + Pvp) + dt^2 Pvv, Ppv' = Ppv + dt Pvv, Pvv' = Pvv
        for a in range(3):
            for b in range(3):
                Pk[a, b] += dt_s * (Pk[a, b + 3] + Pk[a + 3, b]) + dt_s * dt_s * Pk[a + 3, b + 3]
        for a in range(3):
            for b in range(3):
                Pk[a, b + 3] += dt_s * Pk[a + 3, b + 3]
                Pk[a + 3, b] += dt_s * Pk[a + 3, b + 3]
        for a in range(3):
            for b in range(3):
                A = acc_cov[k, a, b] + (sigma_acc2 if a == b else 0.0)
                Pk[a, b] += g_p * g_p * A  # Q = G A G^T
                Pk[a, b + 3] += g_p * g_v * A
                Pk[a + 3, b] += g_v * g_p * A
                Pk[a + 3, b + 3] += g_v * g_v * A
        c = coast_s[k]
        if c > 0.0:
            for a in range(3):
                Pk[a, a] += c * coast_pos_m2ps  # P += (t - t_hold_start) diag(c_p I, c_v I)
                Pk[a + 3, a + 3] += c * coast_vel_m2ps3


@njit(cache=True)
def gate_pairs(
    x: np.ndarray, P: np.ndarray, z: np.ndarray, R: np.ndarray, d2: np.ndarray, S_inv: np.ndarray
) -> None:
    """Squared Mahalanobis distance of every (track, measurement) pair, in place.

    ``nu = z - H x``, ``S = H P H^T + R``, ``d2 = nu^T S^-1 nu``.

    Args:
        x: (n, 6) predicted states; P: (n, 6, 6) their covariances.
        z: (m, 3) measured positions [m]; R: (m, 3, 3) their covariances [m^2].
        d2: (n, m) output, squared distances [-].
        S_inv: (n, m, 3, 3) output, ``S^-1`` of each pair.
    """
    n, m = x.shape[0], z.shape[0]
    S = np.empty((3, 3))
    for i in range(n):
        for j in range(m):
            for a in range(3):
                for b in range(3):
                    S[a, b] = P[i, a, b] + R[j, a, b]  # S = H P H^T + R
            Si = S_inv[i, j]
            _inv3(S, Si)
            nu0, nu1, nu2 = z[j, 0] - x[i, 0], z[j, 1] - x[i, 1], z[j, 2] - x[i, 2]  # nu = z - H x
            d2[i, j] = (
                nu0 * (Si[0, 0] * nu0 + Si[0, 1] * nu1 + Si[0, 2] * nu2)
                + nu1 * (Si[1, 0] * nu0 + Si[1, 1] * nu1 + Si[1, 2] * nu2)
                + nu2 * (Si[2, 0] * nu0 + Si[2, 1] * nu1 + Si[2, 2] * nu2)
            )  # d2 = nu^T S^-1 nu


@njit(cache=True)
def trivial_assignment(d2: np.ndarray, gate: float, rows: np.ndarray, cols: np.ndarray) -> int:
    """The optimal assignment when every gated pair is alone in its row and its column, else -1.

    If each track has at most one measurement inside ``gate`` and each
    measurement at most one track, the gated pairs are disjoint and the
    Hungarian solution on the gated cost (pairs outside the gate rejected)
    is exactly those pairs, whatever their costs. ``d2`` (n, m); ``rows``
    and ``cols`` (min(n, m),) outputs, filled with the pairs in increasing
    track order. Returns the number of pairs, or -1 when the gated graph has
    a conflict and the caller must solve the assignment.
    """
    n, m = d2.shape
    col_used = np.zeros(m, dtype=np.bool_)
    count = 0
    for i in range(n):
        found = -1
        for j in range(m):
            if d2[i, j] <= gate:
                if found >= 0 or col_used[j]:
                    return -1
                found = j
        if found >= 0:
            col_used[found] = True
            rows[count], cols[count] = i, found
            count += 1
    return count


@njit(cache=True)
def update_tracks(
    x: np.ndarray,
    P: np.ndarray,
    P_post: np.ndarray,
    acc_cov: np.ndarray,
    last_update_s: np.ndarray,
    rows: np.ndarray,
    cols: np.ndarray,
    z: np.ndarray,
    R: np.ndarray,
    S_inv: np.ndarray,
    time_s: float,
    adapt: np.ndarray,
    alpha: float,
    acc_var_max: float,
    scale: float,
) -> None:
    """Update the matched tracks in place (MP-CDE Eq. 10, Joseph form) and adapt ``A`` (Eq. 11).

    For each pair ``(i, j) = (rows[p], cols[p])``: ``y = z_j - H x_i``,
    ``K = P H^T S^-1``, ``x = x + K y``, ``P = (I - K H) P (I - K H)^T + K R K^T``.
    Where ``adapt[p]`` (and the time since the track's last update ``dt > 0``):
    ``M = H F(dt) P_post F(dt)^T H^T + R``, ``q = y^T M^-1 y``, ``w = K_v y``,
    ``A_hat = min(c max(0, 1 - 1/q) / dt^2, a_max / |w|^2) w w^T`` and
    ``A = alpha A_hat + (1 - alpha) A`` (see :func:`perception.kalman_cv.adapt_acc_cov_batch`).
    Then ``P_post = P`` and ``last_update_s = time_s`` for the track.

    Args:
        x: (n, 6), P: (n, 6, 6), P_post: (n, 6, 6) previous posteriors,
            acc_cov: (n, 3, 3) [m^2/s^4], last_update_s: (n,) [s]; updated in place.
        rows, cols: (k,) matched track and measurement indices.
        z: (m, 3) measured positions [m]; R: (m, 3, 3) covariances [m^2].
        S_inv: (n, m, 3, 3) inverse innovation covariances from :func:`gate_pairs`.
        time_s: time of the measurements [s].
        adapt: (k,) whether each pair's track adapts ``A`` (adaptive filter, enough hits).
        alpha: EMA factor (MP-CDE Table I: 0.3); acc_var_max: cap on trace(A_hat)
            [m^2/s^4]; scale: factor ``c`` on ``A_hat`` [-].
    """
    K = np.empty((6, 3))
    y = np.empty(3)
    KH_P = np.empty((6, 6))
    M = np.empty((3, 3))
    M_inv = np.empty((3, 3))
    w = np.empty(3)
    for p in range(rows.shape[0]):
        i, j = rows[p], cols[p]
        Pi, Si = P[i], S_inv[i, j]
        for a in range(3):
            y[a] = z[j, a] - x[i, a]  # y = z - H x
        for r in range(6):
            for a in range(3):
                K[r, a] = Pi[r, 0] * Si[0, a] + Pi[r, 1] * Si[1, a] + Pi[r, 2] * Si[2, a]  # K = P H^T S^-1
        for r in range(6):
            x[i, r] += K[r, 0] * y[0] + K[r, 1] * y[1] + K[r, 2] * y[2]  # x = x + K y
        # Joseph form: P' = P - K H P - P H^T K^T + K (H P H^T + R) K^T
        for r in range(6):
            for c in range(6):
                KH_P[r, c] = K[r, 0] * Pi[0, c] + K[r, 1] * Pi[1, c] + K[r, 2] * Pi[2, c]  # (K H P)[r, c]
        for r in range(3):
            for c in range(3):
                M[r, c] = Pi[r, c] + R[j, r, c]  # S = H P H^T + R (reused as scratch)
        for r in range(6):
            for c in range(r, 6):
                ksk = 0.0
                for a in range(3):
                    ksk += K[r, a] * (K[c, 0] * M[a, 0] + K[c, 1] * M[a, 1] + K[c, 2] * M[a, 2])
                v = Pi[r, c] - KH_P[r, c] - KH_P[c, r] + ksk  # P = (I-KH)P(I-KH)' + KRK'
                Pi[r, c] = v
                Pi[c, r] = v
        if adapt[p]:
            dt = time_s - last_update_s[i]
            if dt > 0.0:
                Pq = P_post[i]
                for r in range(3):
                    for c in range(3):
                        # M = H F P F^T H^T + R = Ppp + dt (Ppv + Pvp) + dt^2 Pvv + R
                        M[r, c] = Pq[r, c] + dt * (Pq[r, c + 3] + Pq[r + 3, c]) + dt * dt * Pq[r + 3, c + 3] + R[j, r, c]
                _inv3(M, M_inv)
                q = 0.0
                for r in range(3):
                    q += y[r] * (M_inv[r, 0] * y[0] + M_inv[r, 1] * y[1] + M_inv[r, 2] * y[2])  # q = nu^T M^-1 nu
                ww = 0.0
                for r in range(3):
                    w[r] = K[r + 3, 0] * y[0] + K[r + 3, 1] * y[1] + K[r + 3, 2] * y[2]  # w = K_v nu
                    ww += w[r] * w[r]
                coef = scale * (1.0 - 1.0 / max(q, 1.0)) / (dt * dt)  # max(0, 1 - 1/q) c / dt^2
                coef = min(coef, acc_var_max / (ww + 1e-300))  # cap trace(A_hat)
                for r in range(3):
                    for c in range(3):
                        acc_cov[i, r, c] = alpha * coef * w[r] * w[c] + (1.0 - alpha) * acc_cov[i, r, c]  # EMA
        for r in range(6):
            for c in range(6):
                P_post[i, r, c] = Pi[r, c]
        last_update_s[i] = time_s
