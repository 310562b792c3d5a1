"""Fly the stored reference flights and write them to data/reference/ (run after an intended change of behaviour).

Usage: ``.venv/bin/python scripts/reference_flights.py`` (about a minute).
``tests/integration/test_reference_flights.py`` flies the same flights and
compares them with the stored files; regenerate only when a change of the
flights is intended, and say why in the commit message.
"""

from __future__ import annotations

import json
from pathlib import Path

import mpcde  # isort: skip  (before numpy: the portable numerics profile, docs/design.md section 15)
import numpy as np

ROOT = Path(__file__).resolve().parents[1]
OUT = ROOT / "data" / "reference"

# name -> (scenario, mode, seed, duration [s], cameras); fixed before the first run
FLIGHTS = {
    "crossing_comm": ("crossing", "comm", 0, 4.0, False),
    "forest_swarm_denied": ("forest_swarm", "denied", 0, 1.5, True),
}
# the metrics compared exactly (counts) and to a tolerance (distances)
COUNT_KEYS = ("collisions", "drone_drone_collisions", "drone_obstacle_collisions", "frames_received", "frames_rendered")
DISTANCE_KEYS = ("min_inter_drone_distance_m", "min_obstacle_distance_m")


def fly_reference(name: str) -> tuple[dict, dict[str, np.ndarray]]:
    """The flight ``name`` of :data:`FLIGHTS`: (selected metrics, state log arrays)."""
    scenario, mode, seed, duration_s, cameras = FLIGHTS[name]
    r = mpcde.fly(scenario, mode=mode, seed=seed, duration_s=duration_s, cameras=cameras)
    m = r.metrics
    metrics = {k: m[k] for k in COUNT_KEYS + DISTANCE_KEYS if k in m}
    log = r.log.arrays
    return metrics, {k: log[k] for k in ("time_s", "pos_world", "vel_world", "yaw")}


def main() -> None:
    OUT.mkdir(parents=True, exist_ok=True)
    for name in FLIGHTS:
        metrics, log = fly_reference(name)
        np.savez_compressed(OUT / f"{name}.npz", **log)
        (OUT / f"{name}.json").write_text(json.dumps({"flight": FLIGHTS[name], "metrics": metrics}, indent=1) + "\n")
        print(f"{name}: {metrics}")


if __name__ == "__main__":
    main()
