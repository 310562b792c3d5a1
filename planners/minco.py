"""MINCO for s = 3: minimum-jerk piecewise quintics parameterised by points and times.

MP-CDE Sec. IV-C, Eq. 13-14 (after Wang et al., "Geometrically Constrained
Trajectory Optimization for Multicopters", the GCOPTER ``MINCO_S3NU`` class).
A trajectory of ``M`` pieces ``p_i(t) = c_i^T beta(t)``, ``t in [0, T_i]``,
``beta(t) = (1, t, ..., t^5)^T``, ``c_i in R^{6x3}``, is the unique minimiser of
the control effort ``J = int ||p'''(t)||^2 dt`` that passes through the inner
points ``q_1..q_{M-1}`` at the joints and meets the head and tail position,
velocity and acceleration. Its coefficients ``c = M(q, T)`` solve ``A(T) c = b(q)``
with ``A`` banded (lower and upper bandwidth 6), so the map costs O(M)
(:mod:`planners.banded_system`):

* rows 0..2: head p, v, a;
* per joint i (between piece i and i+1): continuity of jerk and snap, position
  equal to ``q_i``, continuity of position, velocity and acceleration;
* rows 6M-3..6M-1: tail p, v, a.

At the joints the pieces are C^4 (position to snap equal), the optimality
conditions of the minimum-jerk problem.

Gradients (GCOPTER ``propogateGrad``): for a cost ``K(c, T)`` with partial
gradients ``dK/dc`` (6M, 3) and ``dK/dT`` (M,), ``A c = b`` gives
``G = A^{-T} dK/dc``, ``dK/dq_i = G[6i+5]`` and
``dK/dT_i = dK/dT_i|_c - tr(G^T (dA/dT_i) c)``.

Everything runs in numba-compiled kernels (``cache=True``); ``benchmarks/bench_minco.py``
measures them against a vectorised numpy/scipy version (figures: docs/results/minco.md#compiled-kernels-against-numpyscipy).
Time convention: :class:`MincoTrajectory` evaluates at times from its own
start, ``t in [0, sum T]`` (clipped); ``t0_s`` holds the absolute start time [s],
so a caller with absolute time ``t_abs`` asks ``traj.pos(t_abs - traj.t0_s)``.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from planners.banded_system import BANDWIDTH, band_lu, band_solve, band_solve_adj

__all__ = ["MincoS3", "MincoTrajectory", "minco_s3"]

_BW = BANDWIDTH  # lower and upper bandwidth of A (planners.banded_system)


@njit(cache=True)
def _set_parameters(head, tail, q, T):
    """Build ``A(T)``, ``b(q)`` (module docstring), factor A and solve: returns (coeffs (6M, 3), ab)."""
    m = T.shape[0]
    n = 6 * m
    ab = np.zeros((n, 2 * _BW + 1))
    b = np.zeros((n, 3))
    ab[0, _BW] = 1.0  # p_1(0) = head p
    ab[1, _BW] = 1.0  # p_1'(0) = head v
    ab[2, _BW] = 2.0  # p_1''(0) = head a
    for d in range(3):
        b[0, d] = head[0, d]
        b[1, d] = head[1, d]
        b[2, d] = head[2, d]
    for i in range(m - 1):
        t1 = T[i]
        t2 = t1 * t1
        t3 = t2 * t1
        t4 = t2 * t2
        t5 = t4 * t1
        r = 6 * i + 3
        c0 = 6 * i
        # jerk continuity: 6 c3 + 24 c4 T + 60 c5 T^2 - 6 c3' = 0
        ab[r, c0 + 3 - r + _BW] = 6.0
        ab[r, c0 + 4 - r + _BW] = 24.0 * t1
        ab[r, c0 + 5 - r + _BW] = 60.0 * t2
        ab[r, c0 + 9 - r + _BW] = -6.0
        # snap continuity: 24 c4 + 120 c5 T - 24 c4' = 0
        r += 1
        ab[r, c0 + 4 - r + _BW] = 24.0
        ab[r, c0 + 5 - r + _BW] = 120.0 * t1
        ab[r, c0 + 10 - r + _BW] = -24.0
        # p_i(T_i) = q_i
        r += 1
        for j, v in enumerate((1.0, t1, t2, t3, t4, t5)):
            ab[r, c0 + j - r + _BW] = v
        for d in range(3):
            b[r, d] = q[i, d]
        # position continuity p_i(T_i) - p_{i+1}(0) = 0
        r += 1
        for j, v in enumerate((1.0, t1, t2, t3, t4, t5)):
            ab[r, c0 + j - r + _BW] = v
        ab[r, c0 + 6 - r + _BW] = -1.0
        # velocity continuity
        r += 1
        for j, v in enumerate((1.0, 2.0 * t1, 3.0 * t2, 4.0 * t3, 5.0 * t4)):
            ab[r, c0 + 1 + j - r + _BW] = v
        ab[r, c0 + 7 - r + _BW] = -1.0
        # acceleration continuity
        r += 1
        for j, v in enumerate((2.0, 6.0 * t1, 12.0 * t2, 20.0 * t3)):
            ab[r, c0 + 2 + j - r + _BW] = v
        ab[r, c0 + 8 - r + _BW] = -2.0
    t1 = T[m - 1]
    t2 = t1 * t1
    t3 = t2 * t1
    t4 = t2 * t2
    t5 = t4 * t1
    c0 = 6 * (m - 1)
    r = n - 3
    for j, v in enumerate((1.0, t1, t2, t3, t4, t5)):
        ab[r, c0 + j - r + _BW] = v
    r = n - 2
    for j, v in enumerate((1.0, 2.0 * t1, 3.0 * t2, 4.0 * t3, 5.0 * t4)):
        ab[r, c0 + 1 + j - r + _BW] = v
    r = n - 1
    for j, v in enumerate((2.0, 6.0 * t1, 12.0 * t2, 20.0 * t3)):
        ab[r, c0 + 2 + j - r + _BW] = v
    for d in range(3):
        b[n - 3, d] = tail[0, d]
        b[n - 2, d] = tail[1, d]
        b[n - 1, d] = tail[2, d]
    band_lu(ab)
    band_solve(ab, b)
    return b, ab


@njit(cache=True)
def _energy(coeffs, T):
    """Control effort ``sum_i int_0^T_i ||p_i'''||^2 dt`` in closed form."""
    e = 0.0
    for i in range(T.shape[0]):
        t1 = T[i]
        t2 = t1 * t1
        t3 = t2 * t1
        c33 = c34 = c44 = c35 = c45 = c55 = 0.0
        for d in range(3):
            c3 = coeffs[6 * i + 3, d]
            c4 = coeffs[6 * i + 4, d]
            c5 = coeffs[6 * i + 5, d]
            c33 += c3 * c3
            c34 += c3 * c4
            c44 += c4 * c4
            c35 += c3 * c5
            c45 += c4 * c5
            c55 += c5 * c5
        # 36 c3.c3 T + 144 c3.c4 T^2 + 192 c4.c4 T^3 + 240 c3.c5 T^3 + 720 c4.c5 T^4 + 720 c5.c5 T^5
        e += 36.0 * c33 * t1 + 144.0 * c34 * t2 + (192.0 * c44 + 240.0 * c35) * t3
        e += 720.0 * (c45 * t2 * t2 + c55 * t2 * t3)
    return e


@njit(cache=True)
def _energy_grad(coeffs, T, gdc, gdt):
    """Add the partial gradients of the energy by coefficients to ``gdc`` (6M, 3) and by times to ``gdt`` (M,)."""
    for i in range(T.shape[0]):
        t1 = T[i]
        t2 = t1 * t1
        t3 = t2 * t1
        t4 = t2 * t2
        t5 = t4 * t1
        for d in range(3):
            c3 = coeffs[6 * i + 3, d]
            c4 = coeffs[6 * i + 4, d]
            c5 = coeffs[6 * i + 5, d]
            gdc[6 * i + 3, d] += 72.0 * c3 * t1 + 144.0 * c4 * t2 + 240.0 * c5 * t3
            gdc[6 * i + 4, d] += 144.0 * c3 * t2 + 384.0 * c4 * t3 + 720.0 * c5 * t4
            gdc[6 * i + 5, d] += 240.0 * c3 * t3 + 720.0 * c4 * t4 + 1440.0 * c5 * t5
            gdt[i] += (
                36.0 * c3 * c3
                + 288.0 * c3 * c4 * t1
                + 576.0 * c4 * c4 * t2
                + 720.0 * c3 * c5 * t2
                + 2880.0 * c4 * c5 * t3
                + 3600.0 * c5 * c5 * t4
            )


@njit(cache=True)
def _propagate_grad(ab, coeffs, T, gdc, gdt):
    """GCOPTER ``propogateGrad``: partial gradients (by c (6M, 3), by T (M,)) -> (by q (M-1, 3), by T (M,))."""
    m = T.shape[0]
    n = 6 * m
    adj = gdc.copy()
    band_solve_adj(ab, adj)  # G = A^{-T} dK/dc
    gq = np.empty((m - 1, 3))
    for i in range(m - 1):
        for d in range(3):
            gq[i, d] = adj[6 * i + 5, d]  # dK/dq_i = G[6i+5]
    gt = gdt.copy()
    for i in range(m):
        t1 = T[i]
        t2 = t1 * t1
        t3 = t2 * t1
        t4 = t2 * t2
        r0 = 6 * i + 3 if i < m - 1 else n - 3
        for d in range(3):
            c1 = coeffs[6 * i + 1, d]
            c2 = coeffs[6 * i + 2, d]
            c3 = coeffs[6 * i + 3, d]
            c4 = coeffs[6 * i + 4, d]
            c5 = coeffs[6 * i + 5, d]
            vel = c1 + 2.0 * c2 * t1 + 3.0 * c3 * t2 + 4.0 * c4 * t3 + 5.0 * c5 * t4
            acc = 2.0 * c2 + 6.0 * c3 * t1 + 12.0 * c4 * t2 + 20.0 * c5 * t3
            jer = 6.0 * c3 + 24.0 * c4 * t1 + 60.0 * c5 * t2
            if i < m - 1:
                snp = 24.0 * c4 + 120.0 * c5 * t1
                crk = 120.0 * c5
                # dK/dT_i -= G[rows of joint i] . (dA/dT_i c)[rows]
                gt[i] -= (
                    adj[r0, d] * snp
                    + adj[r0 + 1, d] * crk
                    + adj[r0 + 2, d] * vel
                    + adj[r0 + 3, d] * vel
                    + adj[r0 + 4, d] * acc
                    + adj[r0 + 5, d] * jer
                )
            else:
                gt[i] -= adj[r0, d] * vel + adj[r0 + 1, d] * acc + adj[r0 + 2, d] * jer
    return gq, gt


@njit(cache=True)
def _energy_and_grad(head, tail, q, T):
    """One fused MINCO evaluation: coefficients, energy, its gradient by q (M-1, 3) and T (M,)."""
    coeffs, ab = _set_parameters(head, tail, q, T)
    e = _energy(coeffs, T)
    gdc = np.zeros_like(coeffs)
    gdt = np.zeros(T.shape[0])
    _energy_grad(coeffs, T, gdc, gdt)
    gq, gt = _propagate_grad(ab, coeffs, T, gdc, gdt)
    return e, gq, gt


@njit(cache=True)
def _evaluate(coeffs, T, t, order):
    """Derivative ``order`` (0..3) of the trajectory at times ``t`` (n,) from its start -> (n, 3)."""
    m = T.shape[0]
    out = np.empty((t.shape[0], 3))
    for k in range(t.shape[0]):
        tk = max(t[k], 0.0)
        i = 0
        while i < m - 1 and tk > T[i]:
            tk -= T[i]
            i += 1
        tk = min(tk, T[i])
        for d in range(3):
            acc = 0.0
            for j in range(5, order - 1, -1):  # Horner on the order-th derivative
                f = 1.0
                for r in range(order):
                    f *= j - r
                acc = acc * tk + f * coeffs[6 * i + j, d]
            out[k, d] = acc
    return out


@njit(cache=True)
def _pos_vel_acc(coeffs, T, t):
    """Position, velocity and acceleration (3, 3) at one time ``t`` from the start (one piece lookup, one Horner pass)."""
    m = T.shape[0]
    tk = max(t, 0.0)
    i = 0
    while i < m - 1 and tk > T[i]:
        tk -= T[i]
        i += 1
    tk = min(tk, T[i])
    out = np.zeros((3, 3))
    for d in range(3):
        p = 0.0
        v = 0.0
        a = 0.0
        for j in range(5, -1, -1):  # p, p', p'' by Horner together: a <- a t + 2 v, v <- v t + p, p <- p t + c_j
            a = a * tk + 2.0 * v
            v = v * tk + p
            p = p * tk + coeffs[6 * i + j, d]
        out[0, d], out[1, d], out[2, d] = p, v, a
    return out


class MincoTrajectory:
    """A MINCO trajectory: piece durations, coefficients and evaluation at times.

    Attributes:
        coefficients: (6M, 3) coefficients, row ``6 i + j`` is ``c_{i,j}`` of
            ``p_i(t) = sum_j c_{i,j} t^j`` [m / s^j].
        durations: (M,) piece durations [s].
        t0_s: absolute start time [s] (the trajectory's own times run from 0).
    """

    def __init__(self, coefficients: np.ndarray, durations: np.ndarray, t0_s: float = 0.0):
        self.coefficients = coefficients
        self.durations = durations
        self.t0_s = float(t0_s)

    @property
    def num_pieces(self) -> int:
        """Number of pieces M."""
        return int(self.durations.shape[0])

    @property
    def total_duration(self) -> float:
        """Sum of the durations [s]."""
        return float(np.sum(self.durations))

    def _at(self, t: np.ndarray | float, order: int) -> np.ndarray:
        scalar = np.ndim(t) == 0
        out = _evaluate(self.coefficients, self.durations, np.atleast_1d(np.asarray(t, float)), order)
        return out[0] if scalar else out

    def pos(self, t: np.ndarray | float) -> np.ndarray:
        """Position [m] at times ``t`` (n,) [s] from the start (clipped to [0, total]) -> (n, 3)."""
        return self._at(t, 0)

    def vel(self, t: np.ndarray | float) -> np.ndarray:
        """Velocity [m/s] at times ``t`` (n,) [s] from the start -> (n, 3)."""
        return self._at(t, 1)

    def acc(self, t: np.ndarray | float) -> np.ndarray:
        """Acceleration [m/s^2] at times ``t`` (n,) [s] from the start -> (n, 3)."""
        return self._at(t, 2)

    def pos_vel_acc(self, t: float) -> np.ndarray:
        """(3, 3) rows position [m], velocity [m/s], acceleration [m/s^2] at one time ``t`` [s] from the start.

        The same values as :meth:`pos`, :meth:`vel` and :meth:`acc` (to rounding) in one compiled
        call: what a 240 Hz reference reads six times per tick.
        """
        return _pos_vel_acc(self.coefficients, self.durations, float(t))

    def jerk(self, t: np.ndarray | float) -> np.ndarray:
        """Jerk [m/s^3] at times ``t`` (n,) [s] from the start -> (n, 3)."""
        return self._at(t, 3)

    def energy(self) -> float:
        """Control effort ``int ||jerk||^2 dt`` [m^2/s^5], closed form."""
        return float(_energy(self.coefficients, self.durations))

    def inner_points(self) -> np.ndarray:
        """(M-1, 3) positions [m] at the joints."""
        return self.pos(np.cumsum(self.durations)[:-1]).reshape(-1, 3)


class MincoS3:
    """MINCO s = 3 with non-uniform times (GCOPTER ``MINCO_S3NU``), one object reused across evaluations.

    Usage: ``set_conditions(head, tail, M)`` once, then per evaluation
    ``set_parameters(q, T)``, ``energy()``, ``energy_partial_grad_by_coeffs()``,
    ``energy_partial_grad_by_times()``, and ``propagate_grad(gdc, gdt)`` for the
    sum of the partial gradients of every cost term.
    """

    def __init__(self) -> None:
        self.head_pva = np.zeros((3, 3))
        self.tail_pva = np.zeros((3, 3))
        self.num_pieces = 0
        self.coefficients = np.zeros((0, 3))
        self.durations = np.zeros(0)
        self._ab = np.zeros((0, 2 * _BW + 1))

    def set_conditions(self, head_pva: np.ndarray, tail_pva: np.ndarray, num_pieces: int) -> None:
        """Fix head and tail (3, 3) [rows p [m], v [m/s], a [m/s^2]] and the number of pieces M >= 1."""
        if int(num_pieces) < 1:
            raise ValueError(f"num_pieces={num_pieces!r}: must be >= 1")
        self.head_pva = np.ascontiguousarray(head_pva, dtype=float).reshape(3, 3)
        self.tail_pva = np.ascontiguousarray(tail_pva, dtype=float).reshape(3, 3)
        self.num_pieces = int(num_pieces)

    def set_parameters(self, inner_points: np.ndarray, durations: np.ndarray) -> None:
        """Solve for the coefficients from inner points (M-1, 3) [m] and durations (M,) [s], O(M)."""
        self.durations = durations
        self.coefficients, self._ab = _set_parameters(self.head_pva, self.tail_pva, inner_points, durations)

    def energy(self) -> float:
        """Control effort of the current trajectory [m^2/s^5]."""
        return _energy(self.coefficients, self.durations)

    def energy_partial_grads(self) -> tuple[np.ndarray, np.ndarray]:
        """Partial gradients of the energy by coefficients (6M, 3) and by times (M,)."""
        gdc = np.zeros_like(self.coefficients)
        gdt = np.zeros(self.num_pieces)
        _energy_grad(self.coefficients, self.durations, gdc, gdt)
        return gdc, gdt

    def energy_partial_grad_by_coeffs(self) -> np.ndarray:
        """Partial gradient of the energy by coefficients (6M, 3)."""
        return self.energy_partial_grads()[0]

    def energy_partial_grad_by_times(self) -> np.ndarray:
        """Partial gradient of the energy by times (M,)."""
        return self.energy_partial_grads()[1]

    def propagate_grad(self, grad_by_coeffs: np.ndarray, grad_by_times: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Total gradients by inner points (M-1, 3) and by times (M,) of a cost with the given partials."""
        return _propagate_grad(self._ab, self.coefficients, self.durations, grad_by_coeffs, grad_by_times)

    def trajectory(self, t0_s: float = 0.0) -> MincoTrajectory:
        """The current trajectory, starting at absolute time ``t0_s`` [s]."""
        return MincoTrajectory(self.coefficients.copy(), self.durations.copy(), t0_s)


def minco_s3(
    head_pva: np.ndarray, tail_pva: np.ndarray, inner_points: np.ndarray, durations: np.ndarray, t0_s: float = 0.0
) -> MincoTrajectory:
    """Minimum-jerk trajectory through ``inner_points`` with the given piece durations (MP-CDE Eq. 13-14).

    Args:
        head_pva: (3, 3) start position [m], velocity [m/s], acceleration [m/s^2] (rows).
        tail_pva: (3, 3) end position, velocity, acceleration (rows).
        inner_points: (M-1, 3) positions [m] at the joints (may be (0, 3)).
        durations: (M,) positive piece durations [s].
        t0_s: absolute start time [s] stored on the trajectory.
    """
    q = np.ascontiguousarray(inner_points, dtype=float).reshape(-1, 3)
    T = np.ascontiguousarray(durations, dtype=float).reshape(-1)
    if T.size < 1 or q.shape[0] != T.size - 1:
        raise ValueError(f"inner_points={q.shape!r}: must be (M-1, 3) for durations of shape (M,) = {T.shape}")
    if not np.all(T > 0.0) or not np.all(np.isfinite(T)):
        raise ValueError(f"durations={T!r}: must be finite and > 0")
    minco = MincoS3()
    minco.set_conditions(head_pva, tail_pva, T.size)
    minco.set_parameters(q, T)
    return minco.trajectory(t0_s)
