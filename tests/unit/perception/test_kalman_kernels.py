"""Tests of the compiled tracker kernels against the numpy batch path and filterpy (MP-CDE Eq. 9-11)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.optimize import linear_sum_assignment

from perception.kalman_cv import KalmanCV, adapt_acc_cov_batch, predict_batch, update_batch
from perception.kalman_kernels import gate_pairs, predict_tracks, trivial_assignment, update_tracks


@pytest.fixture
def rng() -> np.random.Generator:
    return np.random.default_rng(2024)


def _spd(rng, n, dim, scale):
    B = rng.normal(size=(n, dim, dim))
    return scale * (B @ np.swapaxes(B, 1, 2) + dim * np.eye(dim))


def test_predict_kernel_matches_the_batch_path_with_inflation(rng):
    n, dt = 5, 0.04
    x, P, A = rng.normal(size=(n, 6)), _spd(rng, n, 6, 0.01), _spd(rng, n, 3, 0.5)
    coast = np.array([0.0, 0.04, 0.0, 0.1, 0.2])
    rates = np.diag([0.1] * 3 + [1.0] * 3)
    x_ref, P_ref = predict_batch(x, P, dt, A + 0.25 * np.eye(3), coast[:, None, None] * rates)
    predict_tracks(x, P, A, 0.25, dt, coast, 0.1, 1.0)
    np.testing.assert_allclose(x, x_ref, atol=1e-12)
    np.testing.assert_allclose(P, P_ref, atol=1e-12)


def test_gate_kernel_is_the_mahalanobis_distance(rng):
    n, m = 4, 3
    x, P = rng.normal(size=(n, 6)), _spd(rng, n, 6, 0.02)
    z, R = rng.normal(size=(m, 3)), _spd(rng, m, 3, 0.01)
    d2, S_inv = np.empty((n, m)), np.empty((n, m, 3, 3))
    gate_pairs(x, P, z, R, d2, S_inv)
    for i in range(n):
        for j in range(m):
            S = P[i, :3, :3] + R[j]
            nu = z[j] - x[i, :3]
            np.testing.assert_allclose(S_inv[i, j], np.linalg.inv(S), rtol=1e-10)
            assert d2[i, j] == pytest.approx(nu @ np.linalg.solve(S, nu), rel=1e-10)


def test_update_kernel_agrees_with_filterpy_to_1e9_over_a_run(rng):
    """Predict, gate, update and adapt for 4 tracks over 80 frames with misses: kernel == filterpy per track."""
    n, sigma_m = 4, 0.05
    starts = rng.normal(0, 2, (n, 3))
    filters = [KalmanCV(s, sigma_m**2 * np.eye(3), 0.0, 2.0, 0.5, True, 0.3, 20.0, 1.0, 3) for s in starts]
    x = np.concatenate([starts, np.zeros((n, 3))], axis=1)
    P = np.stack([f.P for f in filters])
    P_post, A, last, hits = P.copy(), np.zeros((n, 3, 3)), np.zeros(n), np.ones(n, dtype=np.int64)
    t = 0.0
    for k in range(80):
        dt = rng.uniform(0.03, 0.05)
        t += dt
        for f in filters:
            f.predict(t)
        predict_tracks(x, P, A, 0.25, dt, np.zeros(n), 0.0, 0.0)
        seen = np.flatnonzero(rng.random(n) > 0.2)
        std = rng.uniform(0.02, 0.1, seen.size)
        R = std[:, None, None] ** 2 * np.eye(3)
        z = starts[seen] + np.sin(2 * t) * np.array([1.0, 2.0, 0.3]) + rng.normal(0, 1, (seen.size, 3)) * std[:, None]
        d2, S_inv = np.empty((n, seen.size)), np.empty((n, seen.size, 3, 3))
        gate_pairs(x, P, z, R, d2, S_inv)
        cols = np.arange(seen.size)
        update_tracks(x, P, P_post, A, last, seen, cols, z, R, S_inv, t, hits[seen] >= 3, 0.3, 400.0, 1.0)
        hits[seen] += 1
        for j, i in enumerate(seen):
            filters[i].update(z[j], R[j])
        for i, f in enumerate(filters):
            np.testing.assert_allclose(x[i], f.x, atol=1e-9)
            np.testing.assert_allclose(P[i], f.P, atol=1e-9)
            np.testing.assert_allclose(A[i], f.acc_cov, atol=1e-9)
    assert max(np.trace(f.acc_cov) for f in filters) > 0  # the adaptation ran


def test_update_kernel_matches_the_numpy_batch_update_and_adaptation(rng):
    n = 6
    x, P, P_prev = rng.normal(size=(n, 6)), _spd(rng, n, 6, 0.01), _spd(rng, n, 6, 0.01)
    A0, R = _spd(rng, n, 3, 0.3), _spd(rng, n, 3, 0.002)
    z = x[:, :3] + rng.normal(0, 0.5, (n, 3))
    x_ref, P_ref, y, K = update_batch(x, P, z, R)
    dt = np.full(n, 0.04)
    A_ref = adapt_acc_cov_batch(A0, y, K, P_prev, R, dt, 0.3, 400.0, 2.0)
    d2, S_inv = np.empty((n, n)), np.empty((n, n, 3, 3))
    gate_pairs(x, P, z, R, d2, S_inv)
    A, last, idx = A0.copy(), np.full(n, -0.04), np.arange(n)
    update_tracks(x, P, P_prev, A, last, idx, idx, z, R, S_inv, 0.0, np.ones(n, dtype=bool), 0.3, 400.0, 2.0)
    np.testing.assert_allclose(x, x_ref, atol=1e-10)
    np.testing.assert_allclose(P, P_ref, atol=1e-10)
    np.testing.assert_allclose(A, A_ref, atol=1e-10)
    np.testing.assert_array_equal(P_prev, P)  # the new posterior is kept for the next adaptation
    np.testing.assert_array_equal(last, 0.0)


def test_trivial_assignment_equals_the_hungarian_solution_or_declines(rng):
    gate = 9.0
    solved = declined = 0
    for _ in range(300):
        n, m = rng.integers(1, 7, size=2)
        d2 = rng.exponential(20.0, (n, m))
        rows, cols = np.empty(min(n, m), dtype=np.int64), np.empty(min(n, m), dtype=np.int64)
        k = trivial_assignment(d2, gate, rows, cols)
        r, c = linear_sum_assignment(np.where(d2 <= gate, d2, 1e6))
        ok = d2[r, c] <= gate
        if k < 0:
            declined += 1
            gated = d2 <= gate
            assert (gated.sum(axis=1) > 1).any() or (gated.sum(axis=0) > 1).any()
            continue
        solved += 1
        assert sorted(zip(rows[:k], cols[:k])) == sorted(zip(r[ok], c[ok]))
    assert solved > 50 and declined > 50
