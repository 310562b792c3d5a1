"""The optimiser's decision vector x = (q, tau) and the cost it minimises (MP-CDE Eq. 15).

q are the inner waypoints between the fixed head and tail, tau the free
variables of the piece durations T = sigma(tau) (GCOPTER's C^1 map onto T > 0,
:func:`_tau_to_time`). :func:`_forward` maps x to the MINCO coefficients and
samples; :func:`_backward` gives the Eq. 15 cost and its gradient by x through
the chain rule. Compiled kernels called by :mod:`planners.trajectory_optimizer`.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from planners.minco import _energy, _energy_grad, _propagate_grad, _set_parameters
from planners.trajectory_penalty import _penalty_kernel, _sample_positions

__all__ = []


@njit(cache=True)
def _tau_to_time(tau):
    T = np.empty(tau.shape[0])
    for i in range(tau.shape[0]):
        t = tau[i]
        if t > 0.0:
            T[i] = (0.5 * t + 1.0) * t + 1.0  # T = tau^2/2 + tau + 1
        else:
            T[i] = 1.0 / ((0.5 * t - 1.0) * t + 1.0)  # T = 1 / (tau^2/2 - tau + 1)
    return T


def _time_to_tau(T: np.ndarray) -> np.ndarray:
    """Inverse of :func:`_tau_to_time` for durations T (M,) [s]."""
    above = np.sqrt(np.maximum(2.0 * T - 1.0, 0.0)) - 1.0
    return np.where(T > 1.0, above, 1.0 - np.sqrt(np.maximum(2.0 / T - 1.0, 0.0)))


@njit(cache=True)
def _dtime_dtau(tau):
    """dT/dtau (M,) of :func:`_tau_to_time` at tau (M,)."""
    out = np.empty(tau.shape[0])
    for i in range(tau.shape[0]):
        t = tau[i]
        if t > 0.0:
            out[i] = t + 1.0
        else:
            den = (0.5 * t - 1.0) * t + 1.0
            out[i] = (1.0 - t) / (den * den)
    return out


@njit(cache=True)
def _forward(head, tail, x, n_q, K):
    """Decision vector -> durations (M,), coefficients (6M, 3), LU factors, sample positions."""
    q = x[:n_q].copy().reshape(-1, 3)
    T = _tau_to_time(x[n_q:])
    coeffs, ab = _set_parameters(head, tail, q, T)
    return T, coeffs, ab, _sample_positions(coeffs, T, K)


@njit(cache=True)
def _backward(
    x, n_q, T, coeffs, ab, K, t0, prm, dist, dist_grad, use_field,
    nb_t, nb_p, nb_v, nb_off, nb_tl, nb_cov, w_e, w_t, out, stats,
):  # fmt: skip
    """Eq. 15 cost and its gradient by x, given the forward pass; out (9,) gets penalty terms/statistics and energy."""
    m = T.shape[0]
    energy = _energy(coeffs, T)
    gdc = np.zeros_like(coeffs)
    gdt = np.zeros(m)
    _energy_grad(coeffs, T, gdc, gdt)
    gdc *= w_e
    gdt *= w_e
    gdt += w_t  # d(w_t sum T) / dT
    terms = out[:8]
    _penalty_kernel(
        coeffs, T, K, t0, prm, dist, dist_grad, use_field,
        nb_t, nb_p, nb_v, nb_off, nb_tl, nb_cov, gdc, gdt, terms, stats,
    )  # fmt: skip
    out[8] = energy
    gq, gT = _propagate_grad(ab, coeffs, T, gdc, gdt)
    grad = np.empty(x.shape[0])
    grad[:n_q] = gq.ravel()
    grad[n_q:] = gT * _dtime_dtau(x[n_q:])  # chain rule through T = sigma(tau)
    f = w_e * energy + w_t * np.sum(T) + terms[0] + terms[1] + terms[2] + terms[3]  # MP-CDE Eq. 15
    return f, grad
