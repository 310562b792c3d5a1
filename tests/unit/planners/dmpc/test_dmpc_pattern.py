"""SparsePattern: COO blocks -> CSC with explicit zeros, and the index map that writes a block's values."""

import numpy as np
import pytest

from planners.dmpc.sparse_qp.pattern import SparsePattern


def _blocks():
    pat = SparsePattern()
    fixed = pat.add([0, 1, 2], [0, 1, 2], [1.0, 2.0, 3.0])  # diagonal
    dyn = pat.add([3, 3, 3, 4], [0, 2, 3, 1], np.zeros(4))  # explicit zeros, filled later
    return pat, fixed, dyn


def test_round_trip_keeps_explicit_zeros_and_positions():
    pat, _, _ = _blocks()
    A, coo_to_csc = pat.to_csc((5, 4))
    assert A.nnz == pat.count == 7  # the four zeros are structural entries
    dense = np.zeros((5, 4))
    dense[[0, 1, 2], [0, 1, 2]] = [1.0, 2.0, 3.0]
    np.testing.assert_array_equal(A.toarray(), dense)
    assert sorted(coo_to_csc) == list(range(7))


def test_map_writes_a_block_where_it_was_added():
    pat, fixed, dyn = _blocks()
    A, coo_to_csc = pat.to_csc((5, 4))
    A.data[coo_to_csc[dyn]] = [7.0, 8.0, 9.0, 10.0]
    A.data[coo_to_csc[fixed]] *= -1.0
    expected = np.zeros((5, 4))
    expected[[0, 1, 2], [0, 1, 2]] = [-1.0, -2.0, -3.0]
    expected[[3, 3, 3, 4], [0, 2, 3, 1]] = [7.0, 8.0, 9.0, 10.0]
    np.testing.assert_array_equal(A.toarray(), expected)


def test_duplicate_position_is_rejected():
    pat = SparsePattern()
    pat.add([0, 1], [0, 1], [1.0, 1.0])
    pat.add([1], [1], [0.0])
    with pytest.raises(ValueError, match="duplicate"):
        pat.to_csc((2, 2))
