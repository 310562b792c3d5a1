"""The two statistics a sweep report rests on: Wilson's interval for a success rate and McNemar's exact test for paired cells.

* :func:`wilson_interval`: the score interval of a binomial proportion,
  p_hat = k/n, z the normal quantile (1.96 at 95 %),
  centre = (p_hat + z^2/2n) / (1 + z^2/n),
  half width = z sqrt(p_hat (1 - p_hat)/n + z^2/4n^2) / (1 + z^2/n)
  (Wilson 1927). Unlike the normal approximation it stays inside [0, 1] and
  is not degenerate at 0 or n successes, which small sweeps hit.
* :func:`mcnemar_exact`: two cells flown on the same seeds; of the pairs
  where exactly one succeeded, b went to the first and c to the second.
  Under "no difference" b ~ Binomial(b + c, 1/2); the two-sided exact
  p-value is min(1, 2 P(X <= min(b, c))) (McNemar 1947, exact form), which
  scipy's ``binomtest(min(b, c), b + c).pvalue`` equals.
"""

from __future__ import annotations

import math

from scipy.stats import binom, norm

__all__ = ["mcnemar_exact", "wilson_interval"]


def wilson_interval(successes: int, n: int, confidence: float = 0.95) -> tuple[float, float]:
    """(low, high) Wilson score interval of ``successes`` out of ``n``; (0, 1) when ``n`` is 0."""
    if n == 0:
        return 0.0, 1.0
    z = float(norm.ppf(0.5 + confidence / 2))
    p = successes / n
    denom = 1 + z * z / n
    centre = (p + z * z / (2 * n)) / denom
    half = z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / denom
    return max(0.0, centre - half), min(1.0, centre + half)


def mcnemar_exact(b: int, c: int) -> float:
    """Two-sided exact McNemar p-value for ``b`` pairs won only by the first cell and ``c`` only by the second (1 when b + c = 0)."""
    if b + c == 0:
        return 1.0
    return float(min(1.0, 2.0 * binom.cdf(min(b, c), b + c, 0.5)))
