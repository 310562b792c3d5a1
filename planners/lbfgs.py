"""L-BFGS with a weak-Wolfe line search (GCOPTER ``lbfgs.hpp`` style), for the MINCO optimiser.

The compiled pieces (two-loop direction, curvature-pair ring buffers,
Lewis-Overton bracketing, delta test) and the driver between two cost
evaluations, written once in reverse-communication form: :func:`lbfgs_start`
makes an :class:`LbfgsState`, :func:`lbfgs_tell` takes the cost and gradient at
its ``trial`` point and says whether another is wanted, :func:`lbfgs_result`
reads the outcome. The caller owns the loop and the cost:
:func:`lbfgs_loop` calls a Python cost ``fun(x, args) -> (f, g)``, and
:func:`planners.trajectory_optimizer._lbfgs_compiled` calls its compiled cost
directly (numba cannot cache a function argument, so the cost cannot be passed in).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numba import njit

__all__ = [
    "LbfgsState",
    "delta_test",
    "first_step",
    "lbfgs_direction",
    "lbfgs_loop",
    "lbfgs_result",
    "lbfgs_start",
    "lbfgs_store",
    "lbfgs_tell",
    "line_search_step",
]


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


class LbfgsState(NamedTuple):
    """One L-BFGS run between cost evaluations (reverse communication: the caller evaluates the cost).

    :func:`lbfgs_start` makes it, :func:`lbfgs_tell` takes the cost and gradient at ``trial`` and
    moves it on, :func:`lbfgs_result` reads it. Scalars sit in two arrays so that the state is mutable
    in compiled code; index them with ``_F`` ... (``real``) and ``_COUNT`` ... (``ints``).

    Attributes:
        x: (n,) current iterate; g: (n,) gradient at x; d: (n,) search direction.
        trial: (n,) point whose cost is wanted next (x + step d in a line search).
        S, Y: (mem, n) ring buffers of the curvature pairs s = x_{k+1} - x_k, y = g_{k+1} - g_k; rho: (mem,) 1 / s.y.
        past: (4,) the last costs for the delta test.
        real: (7,) f at x, g.d, trial step, bracket lo and hi, g_tol, rel_tol.
        ints: (8,) pairs stored, newest pair, iteration, line-search trials, evaluations, code (-1 running),
            iterations reported, iteration limit.
    """

    x: np.ndarray
    g: np.ndarray
    d: np.ndarray
    trial: np.ndarray
    S: np.ndarray
    Y: np.ndarray
    rho: np.ndarray
    past: np.ndarray
    real: np.ndarray
    ints: np.ndarray


_F, _DG0, _STEP, _LO, _HI, _G_TOL, _REL_TOL = 0, 1, 2, 3, 4, 5, 6
_COUNT, _NEWEST, _IT, _TRIES, _EVALS, _CODE, _K, _MAX_IT = 0, 1, 2, 3, 4, 5, 6, 7
_MAX_TRIES = 40  # cost evaluations per line search before it counts as stalled


@njit(cache=True)
def lbfgs_start(x0, mem, max_iterations, g_tol, rel_tol):
    """A run from x0 (n,) keeping ``mem`` pairs; its first ``trial`` is x0 itself."""
    n = x0.size
    x = x0.copy()
    real = np.array([np.inf, 0.0, 0.0, 0.0, np.inf, float(g_tol), float(rel_tol)])
    ints = np.array([0, mem - 1, 0, 0, 0, -1, 0, max_iterations], dtype=np.int64)
    S, Y = np.zeros((mem, n)), np.zeros((mem, n))
    return LbfgsState(x, np.zeros(n), np.zeros(n), x.copy(), S, Y, np.zeros(mem), np.full(4, np.inf), real, ints)


@njit(cache=True)
def _next_iteration(st):
    """Begin the next iteration: convergence test, direction, first trial point; False when the run ends."""
    real, ints = st.real, st.ints
    if ints[_IT] >= ints[_MAX_IT]:
        ints[_CODE] = 1
        return False
    ints[_IT] += 1
    ints[_K] = ints[_IT]
    done, d, dg0, count = lbfgs_direction(st.g, st.x, st.S, st.Y, st.rho, ints[_COUNT], ints[_NEWEST], real[_G_TOL])
    ints[_COUNT] = count
    if done:
        ints[_CODE], ints[_K] = 0, ints[_IT] - 1
        return False
    st.d[:] = d
    real[_DG0] = dg0
    real[_STEP], real[_LO], real[_HI] = first_step(st.g, count), 0.0, np.inf
    ints[_TRIES] = 0
    st.trial[:] = st.x + real[_STEP] * st.d
    return True


@njit(cache=True)
def lbfgs_tell(st, f, g):
    """Take the cost f and gradient g (n,) at ``st.trial``; True while another point is wanted (then in ``st.trial``).

    The first call takes the start point (a non-finite cost ends the run, code 3); the later ones are
    the line search's trials (:func:`line_search_step`). An accepted trial becomes the iterate, its pair
    is stored (:func:`lbfgs_store`) and the delta test (:func:`delta_test`) may end the run (code 0).
    """
    real, ints = st.real, st.ints
    ints[_EVALS] += 1
    if ints[_IT] == 0:  # the start point
        real[_F] = f
        if not (np.isfinite(f) and np.all(np.isfinite(g))):
            ints[_CODE] = 3
            return False
        st.g[:] = g
        st.past[0] = f
        return _next_iteration(st)
    ints[_TRIES] += 1
    accepted, give_up, step, lo, hi = line_search_step(f, g, st.d, real[_F], real[_DG0], real[_STEP], real[_LO], real[_HI])
    real[_STEP], real[_LO], real[_HI] = step, lo, hi
    if accepted:
        ints[_COUNT], ints[_NEWEST] = lbfgs_store(st.x, st.trial, st.g, g, st.S, st.Y, st.rho, ints[_COUNT], ints[_NEWEST])
        st.x[:] = st.trial
        st.g[:] = g
        real[_F] = f
        if delta_test(st.past, ints[_IT], f, real[_REL_TOL]):
            ints[_CODE] = 0
            return False
        return _next_iteration(st)
    if give_up or ints[_TRIES] == _MAX_TRIES:  # no acceptable step: keep x (code 2)
        ints[_CODE] = 2
        return False
    st.trial[:] = st.x + step * st.d
    return True


@njit(cache=True)
def lbfgs_result(st):
    """(x (n,), f, iterations, code, evaluations) of a finished run; code 0 converged, 1 iteration limit,
    2 line search stalled, 3 non-finite initial cost (then f is that cost)."""
    return st.x.copy(), st.real[_F], st.ints[_K], st.ints[_CODE], st.ints[_EVALS]


def lbfgs_loop(fun, args, x0, mem, max_iterations, g_tol, rel_tol):
    """L-BFGS (GCOPTER ``lbfgs.hpp`` style) calling ``fun(x, args) -> (f, g)`` from Python (any DistanceField).

    Stops when ||g||_inf <= g_tol max(1, ||x||_inf) or by the delta test (:func:`delta_test`).
    Returns :func:`lbfgs_result`'s (x, f, iterations, code, evaluations). ``fun`` gets a fresh copy of
    each point. :func:`planners.trajectory_optimizer._lbfgs_compiled` drives the same
    :func:`lbfgs_tell` with its compiled cost (numba cannot cache a function argument).
    """
    st = lbfgs_start(x0, mem, max_iterations, g_tol, rel_tol)
    while lbfgs_tell(st, *fun(st.trial.copy(), args)):
        pass
    return lbfgs_result(st)
