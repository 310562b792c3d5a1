"""Tests of the constant-velocity Kalman filter and its adaptive process noise (MP-CDE Eq. 9-11)."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.linalg
from scipy.stats import chi2

from perception.kalman_cv import (
    KalmanCV,
    adapt_acc_cov_batch,
    noise_gain,
    predict_batch,
    process_noise,
    transition_matrix,
    update_batch,
)

SIGMA_M = 0.05  # measurement noise std per axis [m]


@pytest.fixture
def rng() -> np.random.Generator:
    return np.random.default_rng(1234)


def _filter(pos, adaptive=False, sigma_acc=0.5, t0=0.0, vel_std=2.0, adapt_after=1) -> KalmanCV:
    cov = SIGMA_M**2 * np.eye(3)
    return KalmanCV(np.asarray(pos, float), cov, t0, vel_std, sigma_acc, adaptive, 0.3, 20.0, 1.0, adapt_after)


def test_transition_composes_and_noise_is_the_dwna_closed_form():
    assert np.allclose(transition_matrix(0.3) @ transition_matrix(0.2), transition_matrix(0.5))
    dt, A = 0.04, np.diag([1.0, 2.0, 3.0])
    Q = process_noise(dt, A)
    assert np.allclose(Q[:3, :3], dt**4 / 4 * A)
    assert np.allclose(Q[:3, 3:], dt**3 / 2 * A)
    assert np.allclose(Q[3:, 3:], dt**2 * A)
    assert noise_gain(dt).shape == (6, 3)


def test_without_process_noise_the_filter_is_the_batch_least_squares_line(rng):
    """Q = 0: the posterior is the least-squares fit of p0 + v t with the birth prior (closed form)."""
    times = np.arange(0, 20) * 0.04
    p0, v = np.array([1.0, -2.0, 0.5]), np.array([0.7, 0.1, -0.3])
    z = p0 + v * times[:, None] + rng.normal(0, SIGMA_M, (times.size, 3))
    kf = _filter(z[0], sigma_acc=1e-12)
    for t, zk in zip(times[1:], z[1:]):
        kf.predict(t)
        kf.update(zk, SIGMA_M**2 * np.eye(3))
    # information form, per axis: state [p(T), v] with p(t) = p(T) + v (t - T)
    T = times[-1]
    Hs = np.stack([np.ones_like(times), times - T], axis=1)
    prior_info = np.diag([0.0, 1 / 2.0**2])  # velocity prior N(0, 2^2); the birth position counts as a measurement
    info = Hs.T @ Hs / SIGMA_M**2 + prior_info
    cov = np.linalg.inv(info)
    for axis in range(3):
        est = cov @ (Hs.T @ z[:, axis] / SIGMA_M**2)
        assert kf.x[axis] == pytest.approx(est[0], abs=1e-8)
        assert kf.x[3 + axis] == pytest.approx(est[1], abs=1e-8)
        assert kf.P[axis, axis] == pytest.approx(cov[0, 0], rel=1e-6)
        assert kf.P[3 + axis, 3 + axis] == pytest.approx(cov[1, 1], rel=1e-6)


@pytest.mark.parametrize("vel", [np.zeros(3), np.array([1.5, -0.5, 0.2])])
def test_stationary_and_constant_velocity_targets_converge(rng, vel):
    for adaptive in (False, True):
        kf = _filter([0.0, 0.0, 1.0], adaptive=adaptive)
        for k in range(1, 200):
            t = 0.04 * k
            kf.predict(t)
            kf.update(np.array([0.0, 0.0, 1.0]) + vel * t + rng.normal(0, SIGMA_M, 3), SIGMA_M**2 * np.eye(3))
        truth = np.concatenate([np.array([0.0, 0.0, 1.0]) + vel * t, vel])
        assert np.linalg.norm(kf.x[:3] - truth[:3]) < 0.05
        assert np.linalg.norm(kf.x[3:] - truth[3:]) < 0.2


def test_nees_on_a_linear_gaussian_cv_target_lies_in_the_chi2_band():
    """Truth from the DWNA model the KF assumes: Monte Carlo average NEES inside its 95 % band."""
    rng = np.random.default_rng(7)
    runs, steps, dt, sigma_a = 200, 100, 0.04, 1.0
    R = np.broadcast_to(SIGMA_M**2 * np.eye(3), (runs, 3, 3))
    acc = np.broadcast_to(sigma_a**2 * np.eye(3), (runs, 3, 3))
    G = noise_gain(dt)
    truth = np.concatenate([rng.normal(0, 1, (runs, 3)), rng.normal(0, 2.0, (runs, 3))], axis=1)
    x = np.zeros((runs, 6))
    x[:, :3] = truth[:, :3] + rng.normal(0, SIGMA_M, (runs, 3))
    P = np.zeros((runs, 6, 6))
    P[:, :3, :3] = R
    P[:, 3:, 3:] = 4.0 * np.eye(3)
    F = transition_matrix(dt)
    lo, hi = chi2.ppf([0.025, 0.975], 6 * runs) / runs
    inside = 0
    for _ in range(steps):
        truth = truth @ F.T + rng.normal(0, sigma_a, (runs, 3)) @ G.T
        x, P = predict_batch(x, P, dt, acc)
        x, P, _, _ = update_batch(x, P, truth[:, :3] + rng.normal(0, SIGMA_M, (runs, 3)), R)
        e = x - truth
        nees = np.mean(np.einsum("ni,ni->n", e, np.linalg.solve(P, e[..., None])[..., 0]))
        inside += lo <= nees <= hi
    assert inside >= 0.9 * steps  # 95 % expected


def test_filterpy_reference_and_batch_path_agree(rng):
    """Same measurements, variable dt and R, adaptation on: filterpy per track == batch numpy to 1e-9."""
    n = 4
    starts = rng.normal(0, 2, (n, 3))
    filters = [_filter(s, adaptive=True) for s in starts]
    for f in filters:
        f.kf.P[:3, :3] = SIGMA_M**2 * np.eye(3)
    x = np.concatenate([starts, np.zeros((n, 3))], axis=1)
    P = np.stack([f.P for f in filters])
    P_post = P.copy()
    acc = np.zeros((n, 3, 3))
    t, t_last = 0.0, np.zeros(n)
    for k in range(60):
        dt = rng.uniform(0.03, 0.05)
        t += dt
        for f in filters:
            f.predict(t)
        x, P = predict_batch(x, P, dt, acc + 0.25 * np.eye(3))
        if k % 7 == 3:
            continue  # a missed frame
        std = rng.uniform(0.02, 0.1, n)
        R = std[:, None, None] ** 2 * np.eye(3)
        z = starts + np.sin(t) * np.array([1.0, 2.0, 0.3]) + rng.normal(0, 1, (n, 3)) * std[:, None]
        for f, zj, Rj in zip(filters, z, R):
            f.update(zj, Rj)
        x, P, y, K = update_batch(x, P, z, R)
        acc = adapt_acc_cov_batch(acc, y, K, P_post, R, t - t_last, 0.3, 400.0)
        P_post, t_last = P.copy(), np.full(n, t)
        for j, f in enumerate(filters):
            np.testing.assert_allclose(f.x, x[j], atol=1e-9)
            np.testing.assert_allclose(f.P, P[j], atol=1e-9)
            np.testing.assert_allclose(f.acc_cov, acc[j], atol=1e-9)
            np.testing.assert_allclose(f.kf.x_post[:, 0], x[j], atol=1e-9)
    assert max(np.trace(f.acc_cov) for f in filters) > 0  # the adaptation did run


def test_adaptation_is_the_positive_part_of_the_eq11_excess_in_the_metric_of_M(rng):
    """Closed form A_hat = K_v D+ K_v^T / dt^2 against a generalized eigen-decomposition of D = nu nu^T - M."""
    n, dt = 5, 0.04
    B = rng.normal(size=(n, 6, 6))
    P_prev = B @ np.swapaxes(B, 1, 2) * 0.01 + 1e-3 * np.eye(6)
    R = 0.003 * np.eye(3)[None].repeat(n, 0)
    nu = rng.normal(0, 0.3, (n, 3))
    K = rng.normal(0, 1, (n, 6, 3))
    A = adapt_acc_cov_batch(np.zeros((n, 3, 3)), nu, K, P_prev, R, np.full(n, dt), alpha=1.0, acc_var_max=1e12)
    F = transition_matrix(dt)
    for j in range(n):
        M = (F @ P_prev[j] @ F.T)[:3, :3] + R[j]
        D = np.outer(nu[j], nu[j]) - M  # Eq. 11 in measurement space
        w, V = scipy.linalg.eigh(D, M)  # D V = M V diag(w), V^T M V = I
        Mv = M @ V
        D_plus = (Mv * np.maximum(w, 0)) @ Mv.T
        assert np.sum(w > 0) <= 1  # rank one minus positive definite
        expected = K[j, 3:] @ D_plus @ K[j, 3:].T / dt**2
        np.testing.assert_allclose(A[j], expected, rtol=1e-9, atol=1e-12)


def test_consistent_innovations_let_the_adaptive_part_decay_by_one_minus_alpha():
    A0 = np.diag([4.0, 1.0, 2.0])[None]
    P_prev = np.eye(6)[None] * 0.01
    R = 0.01 * np.eye(3)[None]
    out = adapt_acc_cov_batch(A0, np.zeros((1, 3)), np.ones((1, 6, 3)), P_prev, R, np.array([0.04]), 0.3, 400.0)
    np.testing.assert_allclose(out[0], 0.7 * A0[0])


def test_adaptive_q_grows_on_a_manoeuvre_and_settles_after_it(rng):
    """Straight at 2 m/s, a 2 s turn at 2 m/s^2, straight again: trace(A) rises in the turn and falls back."""
    dt, v = 0.04, 2.0
    kf = _filter([0.0, 0.0, 1.0], adaptive=True, adapt_after=3)
    pos, heading, t = np.array([0.0, 0.0, 1.0]), 0.0, 0.0
    trace = []
    for k in range(1, 250):  # 10 s: turn from 4 s to 6 s
        t = k * dt
        rate = 1.0 if 4.0 <= t < 6.0 else 0.0  # v * rate = 2 m/s^2
        heading += rate * dt
        pos = pos + v * dt * np.array([np.cos(heading), np.sin(heading), 0.0])
        kf.predict(t)
        kf.update(pos + rng.normal(0, SIGMA_M, 3), SIGMA_M**2 * np.eye(3))
        trace.append(np.trace(kf.acc_cov))
    trace = np.array(trace)
    times = np.arange(1, 250) * dt
    before = np.median(trace[(times > 2.5) & (times < 4.0)])
    during = np.max(trace[(times > 4.0) & (times < 6.2)])
    after = np.median(trace[(times > 8.0)])
    assert during > 5 * before
    assert during > 1.0  # at least about (1 m/s^2)^2 of acceleration variance
    assert after < 0.3 * during


def test_predict_rejects_going_back_in_time():
    kf = _filter([0.0, 0.0, 0.0], t0=1.0)
    with pytest.raises(ValueError, match="time_s"):
        kf.predict(0.5)
