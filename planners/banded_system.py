"""A banded linear system solved in place, compiled (numba): LU without pivoting and the two triangular solves.

MINCO's ``A(T) c = b(q)`` (:mod:`planners.minco`) is banded with lower and
upper bandwidth :data:`BANDWIDTH` = 6, so it factors and solves in O(n)
(GCOPTER's ``BandedSystem``). The matrix is stored by diagonals,
``A[i, j]`` at ``ab[i, j - i + BANDWIDTH]`` in an (n, 2 BANDWIDTH + 1)
array; :func:`band_lu` overwrites it with ``L`` (unit lower, below the
diagonal) and ``U`` (on and above it). The right-hand sides are (n, 3), one
column per axis. No pivoting: MINCO's matrix is factored in its row order.
"""

from __future__ import annotations

from numba import njit

__all__ = ["BANDWIDTH", "band_lu", "band_solve", "band_solve_adj"]

BANDWIDTH = 6  # lower and upper bandwidth of A
_BW = BANDWIDTH


@njit(cache=True)
def band_lu(ab):
    """In-place LU (no pivoting) of a banded matrix, ``A[i, j]`` stored at ``ab[i, j - i + 6]``."""
    n = ab.shape[0]
    for k in range(n):
        piv = ab[k, _BW]
        i_max = min(k + _BW, n - 1)
        j_max = min(k + _BW, n - 1)
        for i in range(k + 1, i_max + 1):
            if ab[i, k - i + _BW] != 0.0:
                ab[i, k - i + _BW] /= piv  # L[i, k] = A[i, k] / U[k, k]
        for j in range(k + 1, j_max + 1):
            akj = ab[k, j - k + _BW]
            if akj != 0.0:
                for i in range(k + 1, i_max + 1):
                    lik = ab[i, k - i + _BW]
                    if lik != 0.0:
                        ab[i, j - i + _BW] -= lik * akj  # A[i, j] -= L[i, k] U[k, j]


@njit(cache=True)
def _eliminate(b, i, k, factor):
    """Row operation of the triangular solves: ``b[i] -= factor b[k]`` on (n, 3) ``b`` (skipped for a zero factor)."""
    if factor != 0.0:
        for d in range(3):
            b[i, d] -= factor * b[k, d]


@njit(cache=True)
def band_solve(ab, b):
    """Solve ``A x = b`` in place on ``b`` (n, 3) with the factors from :func:`band_lu`."""
    n = ab.shape[0]
    for i in range(n):  # L y = b (unit lower)
        for k in range(max(0, i - _BW), i):
            _eliminate(b, i, k, ab[i, k - i + _BW])  # L[i, k]
    for i in range(n - 1, -1, -1):  # U x = y
        for k in range(i + 1, min(n, i + _BW + 1)):
            _eliminate(b, i, k, ab[i, k - i + _BW])  # U[i, k]
        for d in range(3):
            b[i, d] /= ab[i, _BW]


@njit(cache=True)
def band_solve_adj(ab, b):
    """Solve ``A^T x = b`` in place on ``b`` (n, 3): ``U^T z = b`` then ``L^T x = z``."""
    n = ab.shape[0]
    for i in range(n):  # U^T z = b (lower triangular, diagonal of U)
        for k in range(max(0, i - _BW), i):
            _eliminate(b, i, k, ab[k, i - k + _BW])  # U[k, i]
        for d in range(3):
            b[i, d] /= ab[i, _BW]
    for i in range(n - 1, -1, -1):  # L^T x = z (unit upper)
        for k in range(i + 1, min(n, i + _BW + 1)):
            _eliminate(b, i, k, ab[k, i - k + _BW])  # L[k, i]

