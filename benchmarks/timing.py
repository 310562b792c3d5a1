"""The one timer of the benchmarks: median wall time of repeated calls.

Imported by the ``bench_*.py`` scripts (run as ``.venv/bin/python
benchmarks/bench_<name>.py``, so this folder is on ``sys.path``).
"""

from __future__ import annotations

import time
from typing import Callable

import numpy as np

__all__ = ["median_ms"]


def median_ms(fn: Callable[[], object], repeats: int, warmup: int = 1) -> float:
    """Median wall time [ms] of ``fn()`` over ``repeats`` calls, after ``warmup`` untimed calls
    (the first call compiles numba kernels and fills caches)."""
    for _ in range(warmup):
        fn()
    times = np.empty(repeats)
    for k in range(repeats):
        t0 = time.perf_counter()
        fn()
        times[k] = time.perf_counter() - t0
    return 1e3 * float(np.median(times))
