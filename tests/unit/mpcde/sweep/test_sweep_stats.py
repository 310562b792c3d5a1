"""Wilson intervals and McNemar's exact test against values computed by hand and by scipy."""

from __future__ import annotations

import math

import pytest
from scipy.stats import binomtest

from mpcde.sweep.stats import mcnemar_exact, wilson_interval


def _wilson_by_hand(k: int, n: int, z: float = 1.959963984540054) -> tuple[float, float]:
    p = k / n
    centre = (p + z * z / (2 * n)) / (1 + z * z / n)
    half = z / (1 + z * z / n) * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n))
    return centre - half, centre + half


@pytest.mark.parametrize("k, n", [(0, 5), (1, 5), (8, 10), (10, 10), (37, 200), (199, 200)])
def test_wilson_matches_the_closed_form(k, n):
    assert wilson_interval(k, n) == pytest.approx(tuple(min(max(v, 0.0), 1.0) for v in _wilson_by_hand(k, n)), abs=1e-12)


def test_wilson_known_values_and_edges():
    assert wilson_interval(8, 10) == pytest.approx((0.4902, 0.9433), abs=1e-4)  # the textbook example
    low, high = wilson_interval(0, 10)
    assert low == 0.0 and high == pytest.approx(0.2775, abs=1e-4)  # not degenerate at 0 successes
    assert wilson_interval(0, 0) == (0.0, 1.0)
    assert wilson_interval(20, 40, confidence=0.99)[0] < wilson_interval(20, 40)[0]  # wider at higher confidence


@pytest.mark.parametrize("b, c", [(0, 0), (1, 7), (7, 1), (5, 5), (0, 12), (3, 9), (40, 25)])
def test_mcnemar_exact_equals_the_two_sided_binomial_test(b, c):
    expected = 1.0 if b + c == 0 else binomtest(min(b, c), b + c, 0.5).pvalue
    assert mcnemar_exact(b, c) == pytest.approx(expected, rel=1e-12)


def test_mcnemar_by_hand():
    # b = 1, c = 7: 2 * P(X <= 1), X ~ Bin(8, 1/2) = 2 * (1 + 8) / 256
    assert mcnemar_exact(1, 7) == pytest.approx(18 / 256, rel=1e-12)
    assert mcnemar_exact(0, 12) == pytest.approx(2 / 4096, rel=1e-12)
