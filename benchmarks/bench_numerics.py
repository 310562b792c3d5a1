"""Benchmark: what the portable numerics profile costs a perceiving flight, against the CPU's native kernels.

``MPCDE_NUMERICS=portable`` (the default, mpcde/numerics.py) runs OpenBLAS,
numpy, torch and numba at x86-64-v3 and keeps the detector in float32 where
"auto" would take native bfloat16; ``native`` lets each library choose for this
CPU. Each flight runs in a fresh process (the profile applies before numpy
loads), the two profiles alternating, after one untimed flight per profile
(numba compiles and caches its kernels per target CPU). Timed inside the
process: ``mpcde.fly`` of the scenario alone, not the interpreter's start.
Printed: per profile the median wall time [s], the real-time factor, the
detector's precision and the flight's minimum inter-drone distance; then the
ratio portable / native. The distances differ between the profiles: the flight
is chaotic and the kernels round differently (docs/results/reproducibility.md#the-profile-mpcde_numerics-default-portable).

Run: ``.venv/bin/python benchmarks/bench_numerics.py [--scenario forest_swarm] [--mode denied] [--duration 8] [--repeats 3]``
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np

from mpcde.numerics import VARIABLE, X86_V3

ROOT = Path(__file__).resolve().parents[1]

CHILD = """
import json, sys, time
import mpcde
scenario, mode, duration = sys.argv[1], sys.argv[2], float(sys.argv[3])
t0 = time.perf_counter()
r = mpcde.fly(scenario, mode=mode, seed=0, duration_s=duration)
wall = time.perf_counter() - t0
m = r.metrics
print(json.dumps({"wall_s": wall, "sim_s": duration, "precision": m.get("detector_precision"),
                  "min_d": m.get("min_inter_drone_distance_m"), "numerics": m.get("numerics")}))
"""


def _flight(profile: str, args: argparse.Namespace) -> dict:
    env = {k: v for k, v in os.environ.items() if k not in X86_V3}  # each child sets its own, or none (native)
    env.update({VARIABLE: profile}, PYTHONPATH=str(ROOT), OMP_NUM_THREADS="1", OPENBLAS_NUM_THREADS="1")
    out = subprocess.run([sys.executable, "-c", CHILD, args.scenario, args.mode, str(args.duration)], env=env, capture_output=True, text=True, check=True)
    return json.loads(out.stdout.strip().splitlines()[-1])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenario", default="forest_swarm")
    parser.add_argument("--mode", default="denied")
    parser.add_argument("--duration", type=float, default=8.0, help="simulated seconds per flight")
    parser.add_argument("--repeats", type=int, default=3)
    args = parser.parse_args()
    profiles = ("native", "portable")
    for p in profiles:  # untimed: numba compiles for this profile's target CPU once
        _flight(p, args)
    runs: dict[str, list[dict]] = {p: [] for p in profiles}
    for _ in range(args.repeats):
        for p in profiles:
            runs[p].append(_flight(p, args))
    print(f"{args.scenario} --mode {args.mode}, seed 0, {args.duration:g} s simulated, median of {args.repeats} flights per profile")
    med = {}
    for p in profiles:
        walls = [r["wall_s"] for r in runs[p]]
        med[p] = float(np.median(walls))
        last = runs[p][-1]
        n = last["numerics"]
        print(f"  {p:8s}: {med[p]:6.2f} s  real-time factor {args.duration / med[p]:.2f}  detector {last['precision']}  "
              f"min distance {last['min_d']:.3f} m  (numpy v4 {n['numpy_v4']}, OpenBLAS {n['openblas_core']}, numerics {n['effective']})")  # fmt: skip
    print(f"  ratio portable / native: {med['portable'] / med['native']:.3f}")


if __name__ == "__main__":
    main()
