"""L-BFGS with a weak-Wolfe line search (GCOPTER ``lbfgs.hpp`` style), for the MINCO optimiser.

The compiled pieces (two-loop direction, curvature-pair ring buffers,
Lewis-Overton bracketing, delta test) and :func:`lbfgs_loop`, the driver that
calls a Python cost ``fun(x, args) -> (f, g)``.
:func:`planners.trajectory_optimizer._lbfgs_compiled` is the same driver with
its compiled cost called directly (numba cannot cache a function argument).
"""

from __future__ import annotations

import numpy as np
from numba import njit

__all__ = ["delta_test", "first_step", "lbfgs_direction", "lbfgs_loop", "lbfgs_store", "line_search_step"]


@njit(cache=True)
def _two_loop(g, S, Y, rho, count, newest):
    """L-BFGS direction d = -H g by the two-loop recursion over ``count`` pairs in ring buffers S, Y (mem, n)."""
    mem = S.shape[0]
    d = -g
    alpha = np.empty(mem)
    j = newest
    for _ in range(count):
        alpha[j] = rho[j] * (S[j] @ d)
        d -= alpha[j] * Y[j]
        j = (j - 1) % mem
    if count > 0:
        d *= 1.0 / (rho[newest] * (Y[newest] @ Y[newest]))  # H0 = s'y / y'y
    j = (newest - count + 1) % mem
    for _ in range(count):
        beta = rho[j] * (Y[j] @ d)
        d += (alpha[j] - beta) * S[j]
        j = (j + 1) % mem
    return d


@njit(cache=True)
def lbfgs_direction(g, x, S, Y, rho, count, newest, g_tol):
    """Convergence test ||g||_inf <= g_tol max(1, ||x||_inf), then the search direction d and g.d
    (steepest descent and count = 0 when the quasi-Newton direction is not a descent direction)."""
    if np.max(np.abs(g)) <= g_tol * max(1.0, np.max(np.abs(x))):
        return True, g, 0.0, count
    d = _two_loop(g, S, Y, rho, count, newest)
    dg0 = g @ d
    if not dg0 < 0.0:
        return False, -g, -(g @ g), 0
    return False, d, dg0, count


@njit(cache=True)
def lbfgs_store(x, xn, g, gn, S, Y, rho, count, newest):
    """Push the pair s = xn - x, y = gn - g into the ring buffers if s.y > 0; returns (count, newest)."""
    mem = S.shape[0]
    s = xn - x
    y = gn - g
    sy = s @ y
    if sy > 1e-12 * (y @ y):
        newest = (newest + 1) % mem
        S[newest] = s
        Y[newest] = y
        rho[newest] = 1.0 / sy
        count = min(count + 1, mem)
    return count, newest


@njit(cache=True)
def line_search_step(fn, gn, d, f, dg0, step, lo, hi):
    """Lewis-Overton weak-Wolfe bracketing (c1 = 1e-4, c2 = 0.9): (accepted, give_up, next step, lo, hi)."""
    if not fn <= f + 1e-4 * step * dg0:  # sufficient decrease fails (or NaN)
        hi = step
    elif gn @ d < 0.9 * dg0:  # curvature condition fails
        lo = step
    else:
        return True, False, step, lo, hi
    step = 0.5 * (lo + hi) if hi < np.inf else 2.0 * step
    return False, hi - lo < 1e-16 * max(1.0, hi), step, lo, hi


@njit(cache=True)
def first_step(g, count):
    """Initial trial step: 1 with curvature pairs, else 1 / ||g|| (at most 1)."""
    return 1.0 if count > 0 else min(1.0, 1.0 / max(np.sqrt(g @ g), 1e-12))


@njit(cache=True)
def delta_test(past, it, f, rel_tol):
    """Record f and test whether the cost fell by at most rel_tol max(1, |f|) over the last 3 iterations."""
    past[it % 4] = f
    return it >= 3 and past[(it - 3) % 4] - f <= rel_tol * max(1.0, abs(f))


def lbfgs_loop(fun, args, x0, mem, max_iterations, g_tol, rel_tol):
    """L-BFGS (GCOPTER ``lbfgs.hpp`` style) calling ``fun(x, args) -> (f, g)`` from Python (any DistanceField).

    Stops when ||g||_inf <= g_tol max(1, ||x||_inf) or by the delta test (:func:`delta_test`).
    Returns (x, f, iterations, code, evaluations), code 0 converged, 1 iteration limit,
    2 line search stalled, 3 non-finite initial cost. :func:`planners.trajectory_optimizer._lbfgs_compiled` is the same
    driver with the compiled cost called directly (numba cannot cache a function argument).
    """
    x = x0.copy()
    f, g = fun(x, args)
    if not (np.isfinite(f) and np.all(np.isfinite(g))):
        return x, f, 0, 3, 1
    S, Y, rho, past = np.zeros((mem, x.size)), np.zeros((mem, x.size)), np.zeros(mem), np.full(4, np.inf)
    past[0] = f
    count, newest, code, k, evals = 0, mem - 1, 1, 0, 1
    for it in range(1, max_iterations + 1):
        k = it
        done, d, dg0, count = lbfgs_direction(g, x, S, Y, rho, count, newest, g_tol)
        if done:
            code, k = 0, it - 1
            break
        step, lo, hi = first_step(g, count), 0.0, np.inf
        accepted, give_up = False, False
        xn, fn, gn = x, f, g
        for _ in range(40):
            xn = x + step * d
            fn, gn = fun(xn, args)
            evals += 1
            accepted, give_up, step, lo, hi = line_search_step(fn, gn, d, f, dg0, step, lo, hi)
            if accepted or give_up:
                break
        if not accepted:
            code = 2
            break
        count, newest = lbfgs_store(x, xn, g, gn, S, Y, rho, count, newest)
        x, f, g = xn, fn, gn
        if delta_test(past, it, f, rel_tol):
            code = 0
            break
    return x, f, k, code, evals
