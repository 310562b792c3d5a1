"""MINCO s = 3: boundary conditions, C^4 joints, energy, gradients, and the minimum-jerk QP."""

from __future__ import annotations

from math import factorial

import numpy as np
import pytest

from planners.minco import MincoS3, minco_s3


@pytest.fixture
def rng():
    return np.random.default_rng(20261122)


def _random_problem(rng, m):
    head = rng.normal(size=(3, 3))
    tail = rng.normal(size=(3, 3))
    q = rng.normal(scale=2.0, size=(m - 1, 3))
    T = rng.uniform(0.4, 1.6, m)
    return head, tail, q, T


def _derivative(coeffs_piece: np.ndarray, t: float, order: int) -> np.ndarray:
    """order-th derivative of one piece (6, 3) at local time t, straight from the coefficients."""
    out = np.zeros(3)
    for j in range(order, 6):
        out += factorial(j) / factorial(j - order) * coeffs_piece[j] * t ** (j - order)
    return out


@pytest.mark.parametrize("m", [1, 2, 5, 12])
def test_boundary_conditions_and_inner_points_hold(rng, m):
    head, tail, q, T = _random_problem(rng, m)
    traj = minco_s3(head, tail, q, T)
    end = T.sum()
    for row, fn in enumerate((traj.pos, traj.vel, traj.acc)):
        np.testing.assert_allclose(fn(0.0), head[row], atol=1e-9)
        np.testing.assert_allclose(fn(end), tail[row], atol=1e-8)
    if m > 1:
        np.testing.assert_allclose(traj.inner_points(), q, atol=1e-9)
    assert traj.coefficients.shape == (6 * m, 3) and traj.num_pieces == m


def test_pieces_join_with_continuous_position_to_snap(rng):
    """s = 3 optimality: the joints are C^{2s-2} = C^4; crackle (5th) jumps in general."""
    head, tail, q, T = _random_problem(rng, 6)
    c = minco_s3(head, tail, q, T).coefficients
    crackle_jump = 0.0
    for i in range(5):
        left, right = c[6 * i : 6 * i + 6], c[6 * i + 6 : 6 * i + 12]
        for order in range(5):
            a, b = _derivative(left, T[i], order), _derivative(right, 0.0, order)
            np.testing.assert_allclose(a, b, atol=1e-8 * (1 + np.abs(a).max()))
        crackle_jump = max(crackle_jump, np.abs(_derivative(left, T[i], 5) - _derivative(right, 0.0, 5)).max())
    assert crackle_jump > 1e-3


def test_evaluation_matches_coefficients_and_is_clipped(rng):
    head, tail, q, T = _random_problem(rng, 4)
    traj = minco_s3(head, tail, q, T, t0_s=5.0)
    t = np.array([0.1, T[0] + 0.3, T[:3].sum() + 0.2])
    pieces = [0, 1, 3]
    local = [0.1, 0.3, 0.2]
    for fn, order in ((traj.pos, 0), (traj.vel, 1), (traj.acc, 2), (traj.jerk, 3)):
        out = fn(t)
        for k in range(3):
            expected = _derivative(traj.coefficients[6 * pieces[k] : 6 * pieces[k] + 6], local[k], order)
            np.testing.assert_allclose(out[k], expected, atol=1e-10)
    np.testing.assert_allclose(traj.pos(-1.0), head[0], atol=1e-12)
    np.testing.assert_allclose(traj.pos(T.sum() + 3.0), traj.pos(T.sum()), atol=1e-12)
    assert traj.t0_s == 5.0


def test_fused_position_velocity_acceleration_equals_the_coefficients(rng):
    """pos_vel_acc (one compiled pass) against the derivatives straight from the coefficients, clipping included."""
    head, tail, q, T = _random_problem(rng, 4)
    traj = minco_s3(head, tail, q, T)
    for t, piece, local in ((0.1, 0, 0.1), (T[0] + 0.3, 1, 0.3), (T[:3].sum() + 0.2, 3, 0.2), (-1.0, 0, 0.0), (T.sum() + 2.0, 3, T[3])):
        expected = np.stack([_derivative(traj.coefficients[6 * piece : 6 * piece + 6], local, o) for o in range(3)])
        np.testing.assert_allclose(traj.pos_vel_acc(t), expected, atol=1e-10)


def test_energy_matches_numeric_integration_of_squared_jerk(rng):
    head, tail, q, T = _random_problem(rng, 5)
    traj = minco_s3(head, tail, q, T)
    nodes, weights = np.polynomial.legendre.leggauss(8)  # exact for degree 15 >= 4 (squared quadratic jerk)
    starts = np.concatenate([[0.0], np.cumsum(T)[:-1]])
    numeric = 0.0
    for s, dur in zip(starts, T):
        t = s + 0.5 * dur * (nodes + 1.0)
        numeric += 0.5 * dur * np.sum(weights * np.sum(traj.jerk(t) ** 2, axis=1))
    # and a plain Riemann sum as an independent cross-check
    t_fine = np.linspace(0.0, T.sum(), 200001)
    riemann = np.trapezoid(np.sum(traj.jerk(t_fine) ** 2, axis=1), t_fine)
    assert traj.energy() == pytest.approx(numeric, rel=1e-10)
    assert traj.energy() == pytest.approx(riemann, rel=1e-4)


def _energy_and_grads(head, tail, q, T):
    minco = MincoS3()
    minco.set_conditions(head, tail, T.size)
    minco.set_parameters(q, T)
    gdc, gdt = minco.energy_partial_grads()
    gq, gt = minco.propagate_grad(gdc, gdt)
    return minco.energy(), gq, gt


def test_energy_gradient_matches_finite_differences(rng):
    head, tail, q, T = _random_problem(rng, 5)
    _, gq, gt = _energy_and_grads(head, tail, q, T)
    h = 1e-6
    for i in range(q.shape[0]):
        for d in range(3):
            qp, qm = q.copy(), q.copy()
            qp[i, d] += h
            qm[i, d] -= h
            fd = (_energy_and_grads(head, tail, qp, T)[0] - _energy_and_grads(head, tail, qm, T)[0]) / (2 * h)
            assert gq[i, d] == pytest.approx(fd, rel=1e-6, abs=1e-6)
    for i in range(T.size):
        Tp, Tm = T.copy(), T.copy()
        Tp[i] += h
        Tm[i] -= h
        fd = (_energy_and_grads(head, tail, q, Tp)[0] - _energy_and_grads(head, tail, q, Tm)[0]) / (2 * h)
        assert gt[i] == pytest.approx(fd, rel=1e-6, abs=1e-6)


def test_propagated_gradient_of_a_coefficient_cost_matches_finite_differences(rng):
    """K(c, T) = sum W * c^2 + v . T^2: checks propagate_grad independently of the energy formulas."""
    head, tail, q, T = _random_problem(rng, 4)
    W = rng.normal(size=(24, 3))
    v = rng.normal(size=4)

    def cost(q_, T_):
        minco = MincoS3()
        minco.set_conditions(head, tail, T_.size)
        minco.set_parameters(q_, T_)
        c = minco.coefficients
        return float(np.sum(W * c**2) + v @ T_**2), minco.propagate_grad(2 * W * c, 2 * v * T_)

    _, (gq, gt) = cost(q, T)
    h = 1e-6
    x = np.concatenate([q.ravel(), T])
    g = np.concatenate([gq.ravel(), gt])
    for k in range(x.size):
        xp, xm = x.copy(), x.copy()
        xp[k] += h
        xm[k] -= h
        fd = (cost(xp[:9].reshape(3, 3), xp[9:])[0] - cost(xm[:9].reshape(3, 3), xm[9:])[0]) / (2 * h)
        assert g[k] == pytest.approx(fd, rel=1e-6, abs=1e-6)


def _dense_min_jerk_qp(head, tail, q, T):
    """Minimum-jerk coefficients from a dense equality-constrained QP solved through its KKT system.

    min sum_i int_0^T_i ||p_i'''||^2  s.t. head/tail p, v, a; p_i(T_i) = q_i; p, v, a continuous.
    (Only C^2 is imposed; C^4 at the joints must come out of the optimality.)
    """
    m = T.size
    n = 6 * m
    H = np.zeros((n, n))
    rows = []
    rhs = []

    def basis(t, order):
        return np.array([factorial(j) / factorial(j - order) * t ** (j - order) if j >= order else 0.0 for j in range(6)])

    for i in range(m):
        for a in range(3, 6):
            for b in range(3, 6):
                ka = factorial(a) / factorial(a - 3)
                kb = factorial(b) / factorial(b - 3)
                p = a + b - 6 + 1
                H[6 * i + a, 6 * i + b] = ka * kb * T[i] ** p / p
    for order in range(3):
        r = np.zeros(n)
        r[:6] = basis(0.0, order)
        rows.append(r)
        rhs.append(head[order])
        r = np.zeros(n)
        r[n - 6 :] = basis(T[-1], order)
        rows.append(r)
        rhs.append(tail[order])
    for i in range(m - 1):
        r = np.zeros(n)
        r[6 * i : 6 * i + 6] = basis(T[i], 0)
        rows.append(r)
        rhs.append(q[i])
        for order in range(3):
            r = np.zeros(n)
            r[6 * i : 6 * i + 6] = basis(T[i], order)
            r[6 * i + 6 : 6 * i + 12] = -basis(0.0, order)
            rows.append(r)
            rhs.append(np.zeros(3))
    A = np.array(rows)
    b = np.array(rhs)
    kkt = np.block([[2 * H, A.T], [A, np.zeros((A.shape[0], A.shape[0]))]])
    sol = np.linalg.solve(kkt, np.vstack([np.zeros((n, 3)), b]))
    return sol[:n]


@pytest.mark.parametrize("m", [1, 3, 7])
def test_minco_equals_the_dense_minimum_jerk_qp(rng, m):
    head, tail, q, T = _random_problem(rng, m)
    expected = _dense_min_jerk_qp(head, tail, q, T)
    got = minco_s3(head, tail, q, T).coefficients
    np.testing.assert_allclose(got, expected, rtol=1e-7, atol=1e-7 * np.abs(expected).max())


@pytest.mark.parametrize(
    "q_shape, durations",
    [((2, 3), [1.0, 1.0]), ((1, 3), [1.0, 0.0]), ((1, 3), [1.0, np.nan]), ((0, 3), [])],
)
def test_invalid_inputs_raise_value_error(q_shape, durations):
    with pytest.raises(ValueError):
        minco_s3(np.zeros((3, 3)), np.zeros((3, 3)), np.zeros(q_shape), np.array(durations, float))
