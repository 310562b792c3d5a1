"""Constant-velocity Kalman filter of one neighbour, with adaptive process noise.

MP-CDE Sec. IV-B. The state of a neighbour is ``x = [p, v]`` (6,) in world
[m, m/s]; its transition over ``dt`` (Eq. 9) and its measurement (Eq. 10) are::

    x_k = F(dt) x_{k-1} + w,   F(dt) = [[I, dt I], [0, I]],   w ~ N(0, Q)
    z_k = H x_k + v,           H = [I, 0],                    v ~ N(0, R_k)

``R_k`` (3, 3) comes with each measurement (back-projection error grows with
range). The process noise is white-noise acceleration (DWNA)::

    Q(dt) = G (s0^2 I + A_k) G^T,   G(dt) = [dt^2/2 I; dt I]

with ``s0 = TrackerConfig.sigma_acc_mps2`` fixed, and ``A_k`` (3, 3) the
adaptive acceleration covariance (zero for the plain KF baseline).

Adaptive covariance (MP-CDE Eq. 11, our reading). The printed equation is
garbled and, as printed (``Q_k = C_nu - F P F^T - R``), mixes a 3x3 innovation
covariance with a 6x6 state covariance. We read it in measurement space, as the
covariance-matching identity ``E[nu nu^T] = H F P F^T H^T + H Q H^T + R``::

    C_k   = nu_k nu_k^T                                  (one-sample innovation covariance)
    M_k   = H F(dt) P_{k-1} F(dt)^T H^T + R_k            (what the filter predicts without Q)
    D_k   = C_k - M_k                                    (Eq. 11: the excess it did not predict)
    D_k+  = max(0, 1 - 1/q_k) nu_k nu_k^T,  q_k = nu_k^T M_k^-1 nu_k
    A_hat = c K_v D_k+ K_v^T / dt^2                      (K_v: velocity rows of the gain; c = 1)
    A_k   = alpha A_hat + (1 - alpha) A_{k-1}            (EMA, alpha = 0.3, Table I)

where ``dt`` is the time since the previous update and ``P_{k-1}`` that
update's posterior. ``D_k`` is rank one minus positive definite, so it has at
most one positive direction; ``D_k+`` is its positive part in the metric of
``M_k`` (non-zero only when the innovation is larger than ``M_k`` explains,
``q_k > 1``). It makes ``A_hat`` rank one, ``(K_v nu)(K_v nu)^T`` scaled, so
no eigen-decomposition per track is needed (the Euclidean positive part is no
more accurate and costs more; measured: docs/results/tracker.md#the-adaptive-process-noise-kalman_cvpy-mp-cde-eq-11).

The excess is mapped into the state through the gain, as in the classic
covariance-matching estimate ``Q_hat = K C K^T``, but only through its velocity
rows and read as an acceleration covariance, so the adapted ``Q`` keeps the
DWNA structure: in a sustained manoeuvre the filter corrects its velocity by
about ``a dt`` per update, so ``K_v nu / dt`` estimates the acceleration ``a``.
Why not ``A_hat = 4 D / dt^4`` (the direct DWNA reading of ``H Q H^T = D``): at
25 Hz the true ``H Q H^T`` is far below the sampling noise of one
``nu nu^T``, and the ``4 / dt^4`` factor turns that noise into tens of m/s^2
of phantom acceleration (measured: docs/results/tracker.md#the-adaptive-process-noise-kalman_cvpy-mp-cde-eq-11).
``A_hat`` is capped at trace ``sigma_acc_max_mps2^2``.

Relation to the literature: the velocity block of our ``Q = G A G^T`` is
``dt^2 A_hat = c K_v D+ K_v^T``, i.e. the covariance-matching estimate
``Q_hat = K C K^T`` of Mohamed & Schwarz (1999) applied to the Eq. 11 excess
``D+`` instead of the raw ``C``, restricted to the velocity rows. We keep
the excess form rather than the raw ``C`` or the excess smoothed before its
positive part: it is what Eq. 11 writes, and it is the one that beats the KF
at every speed (measured: docs/results/tracker.md#the-adaptive-process-noise-kalman_cvpy-mp-cde-eq-11).

Three implementations that must agree to 1e-9 (tests hold it):
:class:`KalmanCV` wraps filterpy's ``KalmanFilter`` (the reference, and the
baseline of the benchmark); :func:`predict_batch`, :func:`update_batch` and
:func:`adapt_acc_cov_batch` run every track at once in numpy; the compiled
kernels of :mod:`perception.kalman_kernels` (what the tracker uses).
"""

from __future__ import annotations

import functools

import numpy as np

__all__ = [
    "KalmanCV",
    "adapt_acc_cov_batch",
    "noise_gain",
    "predict_batch",
    "process_noise",
    "transition_matrix",
    "update_batch",
]

_I3 = np.eye(3)
_EYE6 = np.eye(6)
_H = np.hstack([_I3, np.zeros((3, 3))])
_POS_IDX, _VEL_IDX = np.arange(3), np.arange(3, 6)
_F_DT = np.zeros((6, 6))
_F_DT[_POS_IDX, _VEL_IDX] = 1.0  # F(dt) = I + dt _F_DT
_G_POS = np.vstack([_I3, np.zeros((3, 3))])  # G(dt) = dt^2/2 _G_POS + dt _G_VEL
_G_VEL = np.vstack([np.zeros((3, 3)), _I3])
_H_VEL = np.hstack([np.zeros((3, 3)), _I3])  # H F(dt) = H + dt _H_VEL


def transition_matrix(dt_s: float) -> np.ndarray:
    """Constant-velocity transition ``F(dt) = [[I, dt I], [0, I]]`` (6, 6), MP-CDE Eq. 9; ``dt_s`` in [s]."""
    F = np.eye(6)
    F[0, 3] = F[1, 4] = F[2, 5] = dt_s
    return F


def noise_gain(dt_s: float) -> np.ndarray:
    """Acceleration-to-state gain ``G(dt) = [dt^2/2 I; dt I]`` (6, 3) of the DWNA model; ``dt_s`` in [s]."""
    return np.vstack([0.5 * dt_s * dt_s * _I3, dt_s * _I3])


def process_noise(dt_s: float, acc_cov: np.ndarray) -> np.ndarray:
    """Process noise ``Q = G(dt) A G(dt)^T`` (6, 6) for an acceleration covariance ``acc_cov`` (3, 3) [m^2/s^4]."""
    G = noise_gain(dt_s)
    return G @ acc_cov @ G.T  # Q = G A G^T


def adapt_acc_cov_batch(
    acc_cov: np.ndarray,
    innovation: np.ndarray,
    gain: np.ndarray,
    P_prev_post: np.ndarray,
    R: np.ndarray,
    dt_s: np.ndarray,
    alpha: float,
    acc_var_max: float,
    scale: float = 1.0,
) -> np.ndarray:
    """Adaptive acceleration covariance by covariance matching, MP-CDE Eq. 11 (reading in the module doc).

    With ``M = H F P_{k-1} F^T H^T + R_k`` and ``q = nu^T M^-1 nu``, the
    excess ``D = nu nu^T - M`` has positive part ``max(0, 1 - 1/q) nu nu^T``
    (in the metric of ``M``), so ``A_hat = max(0, 1 - 1/q) w w^T / dt^2`` with
    ``w = K_v nu`` the velocity correction of this update.

    Args:
        acc_cov: (n, 3, 3) previous adaptive acceleration covariance ``A_{k-1}`` [m^2/s^4].
        innovation: (n, 3) innovation ``nu_k = z_k - H x_k^-`` [m].
        gain: (n, 6, 3) Kalman gain ``K_k`` of this update.
        P_prev_post: (n, 6, 6) posterior covariance ``P_{k-1}`` of the previous update.
        R: (n, 3, 3) measurement covariance ``R_k`` [m^2].
        dt_s: (n,) time since the previous update [s], > 0.
        alpha: EMA factor (MP-CDE Table I: 0.3).
        acc_var_max: cap on the trace of ``A_hat`` [m^2/s^4].
        scale: factor ``c`` on ``A_hat`` [-] (``TrackerConfig.adapt_scale``).

    Returns:
        (n, 3, 3) the smoothed ``A_k``.
    """
    dt = np.asarray(dt_s, float)
    HF = _H + dt[:, None, None] * _H_VEL  # H F(dt) = [I, dt I]
    M = HF @ P_prev_post @ np.swapaxes(HF, 1, 2) + R  # M = H F P F^T H^T + R
    q = np.einsum("ni,ni->n", innovation, np.linalg.solve(M, innovation[..., None])[..., 0])  # q = nu^T M^-1 nu
    w = (gain[:, 3:, :] @ innovation[..., None])[..., 0]  # w = K_v nu
    # D+ = max(0, 1 - 1/q) nu nu^T  (Eq. 11: [nu nu^T - H F P F^T H^T - R]_+);  A_hat = c K_v D+ K_v^T / dt^2
    coef = scale * (1.0 - 1.0 / np.maximum(q, 1.0)) / (dt * dt)  # max(0, 1 - 1/q) c / dt^2
    coef = np.minimum(coef, acc_var_max / (np.einsum("ni,ni->n", w, w) + 1e-300))  # cap trace(A_hat)
    A_hat = coef[:, None, None] * (w[:, :, None] * w[:, None, :])
    return alpha * A_hat + (1.0 - alpha) * acc_cov  # A_k = alpha A_hat + (1 - alpha) A_{k-1}


@functools.lru_cache(maxsize=64)
def _shared_f_g(dt_s: float) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """``(F, F^T, G, G^T)`` for one interval ``dt_s`` [s] (read-only, cached: frames come at a fixed rate)."""
    F, G = transition_matrix(dt_s), noise_gain(dt_s)
    out = (F, np.ascontiguousarray(F.T), G, np.ascontiguousarray(G.T))
    for a in out:
        a.flags.writeable = False
    return out


def predict_batch(
    x: np.ndarray, P: np.ndarray, dt_s: np.ndarray, acc_cov: np.ndarray, extra_cov: np.ndarray | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """Predict n tracks by ``dt`` (MP-CDE Eq. 9): ``x^- = F x``, ``P^- = F P F^T + Q (+ extra)``.

    Args:
        x: (n, 6) states ``[p, v]`` [m, m/s].
        P: (n, 6, 6) covariances.
        dt_s: (n,) prediction intervals [s] (>= 0), or one float for all.
        acc_cov: (n, 3, 3) total acceleration covariance ``s0^2 I + A`` [m^2/s^4].
        extra_cov: optional (n, 6, 6) added to ``P^-`` (the tracker's coasting inflation).

    Returns:
        ``(x_prior (n, 6), P_prior (n, 6, 6))``.
    """
    if np.ndim(dt_s) == 0:  # one interval for all tracks (the tracker's case): shared, cached F and G
        F, FT, G, GT = _shared_f_g(float(dt_s))
    else:
        dt = np.asarray(dt_s, float)[:, None, None]
        F = _EYE6 + dt * _F_DT
        G = (0.5 * dt * dt) * _G_POS + dt * _G_VEL
        FT, GT = np.swapaxes(F, -1, -2), np.swapaxes(G, -1, -2)
    x_prior = x @ FT if F.ndim == 2 else (F @ x[..., None])[..., 0]  # x = F x
    P_prior = F @ P @ FT + G @ acc_cov @ GT  # P = F P F^T + Q,  Q = G A G^T
    if extra_cov is not None:
        P_prior = P_prior + extra_cov
    return x_prior, P_prior


def update_batch(
    x_prior: np.ndarray, P_prior: np.ndarray, z: np.ndarray, R: np.ndarray, S_inv: np.ndarray | None = None
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Update n tracks with one position measurement each (MP-CDE Eq. 10), Joseph form as filterpy.

    Args:
        x_prior: (n, 6) predicted states; P_prior: (n, 6, 6) their covariances.
        z: (n, 3) measured positions [m]; R: (n, 3, 3) their covariances [m^2].
        S_inv: optional (n, 3, 3) inverse innovation covariances ``(H P H^T + R)^-1``
            when the caller already has them (the tracker's gating does).

    Returns:
        ``(x_post (n, 6), P_post (n, 6, 6), innovation (n, 3), K (n, 6, 3))``.
    """
    y = z - x_prior[:, :3]  # y = z - H x
    PHT = P_prior[:, :, :3]  # P H^T
    if S_inv is None:
        S_inv = np.linalg.inv(P_prior[:, :3, :3] + R)  # S = H P H^T + R
    K = PHT @ S_inv  # K = P H^T S^-1
    x_post = x_prior + (K @ y[..., None])[..., 0]  # x = x + K y
    I_KH = np.eye(6) - K @ _H  # I - K H
    P_post = I_KH @ P_prior @ np.swapaxes(I_KH, 1, 2) + K @ R @ np.swapaxes(K, 1, 2)  # P = (I-KH)P(I-KH)' + KRK'
    return x_post, P_post, y, K


class KalmanCV:
    """One neighbour's constant-velocity filter on filterpy's ``KalmanFilter`` (the reference path).

    Attributes:
        kf: the filterpy filter (``kf.x`` (6, 1), ``kf.P`` (6, 6), ``kf.x_prior``,
            ``kf.x_post``, ``kf.P_prior``, ``kf.P_post``, ``kf.y``, ``kf.K``).
        acc_cov: (3, 3) adaptive acceleration covariance ``A_k`` [m^2/s^4]
            (stays zero unless ``adaptive``).
        time_s: time [s] of the current state.
        last_update_s: time [s] of the last measurement update (or of birth).
        n_updates: measurements absorbed so far, the birth one included; the
            adaptation runs from the update at which ``n_updates >= adapt_after``.
    """

    def __init__(
        self,
        pos_world: np.ndarray,
        pos_cov_world: np.ndarray,
        time_s: float,
        init_vel_std_mps: float,
        sigma_acc_mps2: float,
        adaptive: bool,
        alpha: float = 0.3,
        sigma_acc_max_mps2: float = 6.0,
        adapt_scale: float = 1.0,
        adapt_after: int = 1,
    ) -> None:
        """Start a track at ``pos_world`` (3,) [m] with covariance ``pos_cov_world`` (3, 3) and zero velocity."""
        # imported here: filterpy pulls in scipy.stats, which the tracker's kernels never need
        # (docs/results/sweeps.md#overhead-of-the-machinery-issue-27s-goal--12x-back-to-back--2)
        from filterpy.kalman import KalmanFilter

        self.kf = KalmanFilter(dim_x=6, dim_z=3)
        self.kf.x = np.concatenate([np.asarray(pos_world, float), np.zeros(3)]).reshape(6, 1)
        P = np.zeros((6, 6))
        P[:3, :3] = pos_cov_world
        P[3:, 3:] = init_vel_std_mps**2 * _I3
        self.kf.P = P
        self.kf.H = _H.copy()
        self.kf.x_post, self.kf.P_post = self.kf.x.copy(), P.copy()
        self.kf.x_prior, self.kf.P_prior = self.kf.x.copy(), P.copy()
        self.acc_cov = np.zeros((3, 3))
        self.sigma_acc_mps2 = float(sigma_acc_mps2)
        self.sigma_acc_max_mps2 = float(sigma_acc_max_mps2)
        self.adaptive = bool(adaptive)
        self.alpha = float(alpha)
        self.adapt_scale = float(adapt_scale)
        self.adapt_after = int(adapt_after)
        self.n_updates = 1  # the birth measurement
        self.time_s = float(time_s)
        self.last_update_s = float(time_s)

    @property
    def x(self) -> np.ndarray:
        """State ``[p, v]`` (6,) [m, m/s] at :attr:`time_s`."""
        return self.kf.x[:, 0].copy()

    @property
    def P(self) -> np.ndarray:
        """Covariance (6, 6) of :attr:`x`."""
        return self.kf.P.copy()

    def predict(self, time_s: float, extra_cov: np.ndarray | None = None) -> None:
        """Propagate to ``time_s`` [s] (MP-CDE Eq. 9); ``extra_cov`` (6, 6) is added to the prior covariance."""
        dt = float(time_s) - self.time_s
        if dt < 0:
            raise ValueError(f"time_s={time_s!r}: >= the filter's time {self.time_s!r}")
        Q = process_noise(dt, self.sigma_acc_mps2**2 * _I3 + self.acc_cov)
        if extra_cov is not None:
            Q = Q + extra_cov
        self.kf.predict(F=transition_matrix(dt), Q=Q)  # x = F x, P = F P F^T + Q
        self.time_s = float(time_s)

    def update(self, pos_world: np.ndarray, cov_world: np.ndarray) -> None:
        """Correct with a measured position ``pos_world`` (3,) [m] of covariance ``cov_world`` (3, 3) (Eq. 10-11)."""
        P_prev_post = self.kf.P_post.copy()
        self.kf.update(np.asarray(pos_world, float).reshape(3, 1), R=np.asarray(cov_world, float))
        if self.adaptive and self.n_updates >= self.adapt_after:
            dt = self.time_s - self.last_update_s
            if dt > 0:
                self.acc_cov = adapt_acc_cov_batch(
                    self.acc_cov[None],
                    self.kf.y[:, 0][None],
                    self.kf.K[None],
                    P_prev_post[None],
                    np.asarray(cov_world, float)[None],
                    np.array([dt]),
                    self.alpha,
                    self.sigma_acc_max_mps2**2,
                    self.adapt_scale,
                )[0]
        self.last_update_s = self.time_s
        self.n_updates += 1
