"""MLR-DMPC's kinematic circle swap under Bernoulli loss: arrivals, collisions and recovery traffic per seed.

Usage: ``.venv/bin/python scripts/mlr_loss_sweep.py LOSS SEEDS [DURATION_S] [N_UAVS]``, e.g.
``scripts/mlr_loss_sweep.py 0.1 0,1,2,3,4,5,6,7,8,9`` (about 2 s per run on one core). The environment
variable ``MLRKW`` passes extra :class:`planners.dmpc.mlr.config.MlrConfig` fields as JSON, e.g.
``MLRKW='{"lazy_recovery": false, "precise_cu_loss": false}'`` for the protocol before issue 29's fixes.
``MLRRADIO`` passes :class:`sim.radio.RadioConfig` fields as JSON and replaces the Bernoulli channel (LOSS is
then only the row's label), e.g. ``MLRRADIO='{"loss_model": "gilbert_elliott"}'`` for bursty loss.
The setup is ``fig4_swap`` of :mod:`mpcde.evals.mlr`: ``circle_swap(n, jitter 0.05 m)``, 3 compute units.
Prints one JSON row per seed and a summary line (docs/results/mlr_dmpc.md).
"""

from __future__ import annotations

import json
import os
import sys
import time

import numpy as np

from mpcde.evals.mlr import circle_swap
from mpcde.evals.mlr_swarm import MlrSwarmConfig, run_mlr_swarm
from planners.dmpc.mlr.config import MlrConfig
from sim.radio import RadioConfig


def main(argv: list[str]) -> None:
    loss, seeds = float(argv[0]), [int(s) for s in argv[1].split(",")]
    duration = float(argv[2]) if len(argv) > 2 else 35.0
    n = int(argv[3]) if len(argv) > 3 else 16
    extra = json.loads(os.environ.get("MLRKW", "{}"))
    rows = []
    for seed in seeds:
        start, goal = circle_swap(n=n, jitter_m=0.05, seed=seed)
        radio = RadioConfig(loss_model="bernoulli", loss_probability=loss) if loss > 0 else RadioConfig()
        if os.environ.get("MLRRADIO"):
            radio = RadioConfig(**json.loads(os.environ["MLRRADIO"]))
        cfg = MlrSwarmConfig(mlr=MlrConfig(n_uavs=n, n_cus=3, **extra), seed=seed, duration_s=duration, radio=radio)
        t0 = time.perf_counter()
        r = run_mlr_swarm(cfg, start, [goal])
        row = {
            "loss": loss, "seed": seed, "arrival_s": r.arrival_time_s, "collisions": r.collisions, "min_distance_m": round(r.min_distance_m, 3),
            "rounds_with_mlr": r.rounds_with_mlr, "deprecated": r.deprecated_trackers, "requests": r.recovery_requests, "qp_solves": r.qp_solves,
            "uavs_at_goal": int((np.linalg.norm(r.positions_world[-1] - goal, axis=1) < 0.1).sum()), "wall_s": round(time.perf_counter() - t0, 1),
        }  # fmt: skip
        rows.append(row)
        print(json.dumps(row), flush=True)
    arrived = [r["arrival_s"] for r in rows if np.isfinite(r["arrival_s"])]
    print(f"loss {loss:.2f}: arrived {len(arrived)}/{len(rows)}, mean arrival {np.mean(arrived) if arrived else float('nan'):.1f} s, "
          f"collisions {sum(r['collisions'] for r in rows)}, UAVs at goal {np.mean([r['uavs_at_goal'] for r in rows]):.1f} of {n}")


if __name__ == "__main__":
    main(sys.argv[1:])
