"""A fixed sparsity pattern built block by block, for OSQP's matrix updates (:mod:`planners.dmpc.qp`).

OSQP factorises the KKT system's pattern once at setup; later rounds may only
change values (``update(Ax=...)`` in CSC data order). The DMPC QP therefore
lays out every row it may ever need, with explicit zeros where a slot is
unused, and must know where each block's entries land in CSC order to write
new values there. :class:`SparsePattern` collects COO blocks, keeps explicit
zeros when converting, and returns the COO -> CSC index map.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

__all__ = ["SparsePattern"]


class SparsePattern:
    """COO entries accumulated block by block; dynamic blocks remember where they land in CSC data."""

    def __init__(self) -> None:
        self.rows: list[np.ndarray] = []
        self.cols: list[np.ndarray] = []
        self.vals: list[np.ndarray] = []
        self.count = 0

    def add(self, rows: np.ndarray, cols: np.ndarray, vals: np.ndarray) -> slice:
        """Append entries; returns their slice in COO order."""
        self.rows.append(np.asarray(rows, int).ravel())
        self.cols.append(np.asarray(cols, int).ravel())
        self.vals.append(np.asarray(vals, float).ravel())
        start = self.count
        self.count += self.rows[-1].size
        return slice(start, self.count)

    def to_csc(self, shape: tuple[int, int]) -> tuple[sp.csc_matrix, np.ndarray]:
        """(CSC matrix with explicit zeros kept, coo_to_csc (nnz,) index map).

        ``matrix.data[coo_to_csc[s]] = v`` writes the values of the block
        whose slice :meth:`add` returned as ``s``.

        Raises:
            ValueError: a (row, col) position was added twice (CSC conversion
                would sum the two entries and the map would lose one).
        """
        rows, cols = np.concatenate(self.rows), np.concatenate(self.cols)
        tag = sp.coo_matrix((np.arange(1, self.count + 1, dtype=float), (rows, cols)), shape=shape).tocsc()
        if tag.nnz != self.count:
            raise ValueError(f"entries: {self.count - tag.nnz} duplicate (row, col) positions: each may be added once")
        coo_to_csc = np.empty(self.count, int)
        coo_to_csc[tag.data.astype(int) - 1] = np.arange(self.count)
        data = np.concatenate(self.vals)[tag.data.astype(int) - 1]
        return sp.csc_matrix((data, tag.indices, tag.indptr), shape=shape), coo_to_csc
