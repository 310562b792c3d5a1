"""Every hot-path benchmark still runs to the end (slow): a benchmark that breaks with the code it measures is caught here.

Timings are printed by the scripts and never asserted. The three whole-flight
benchmarks (sim, sweep, env) are left to ``mpcde bench``; they fly minutes.
"""

from __future__ import annotations

import os
import subprocess
import sys

import pytest

from mpcde.evals.bench import BENCHMARKS, benchmarks_dir

pytestmark = pytest.mark.slow

_FLIGHTS = {"sim", "sweep", "env"}


@pytest.mark.parametrize("bench", [b for b in BENCHMARKS if b.name not in _FLIGHTS], ids=lambda b: b.name)
def test_benchmark_runs_to_the_end(bench):
    script = benchmarks_dir() / f"bench_{bench.name}.py"
    env = {**os.environ, "OMP_NUM_THREADS": "2"}
    proc = subprocess.run([sys.executable, str(script), *bench.quick_args], capture_output=True, text=True, timeout=300, env=env)
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert proc.stdout.strip()
