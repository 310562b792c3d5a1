"""Short flights compared with the stored reference runs in data/reference/ (scripts/reference_flights.py).

A change that moves a flight shows up here first. Tolerances allow for
floating-point differences between machines (BLAS, SIMD width), not for a
change of behaviour: the communicating flight (no cameras, OSQP) must match to
1 mm, the perceiving one (renders, detector, map, planners) to 5 cm.
"""

from __future__ import annotations

import importlib.util
import json
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[2]
spec = importlib.util.spec_from_file_location("reference_flights", ROOT / "scripts" / "reference_flights.py")
ref = importlib.util.module_from_spec(spec)
spec.loader.exec_module(ref)

TOLERANCE_M = {"crossing_comm": 1e-3, "forest_swarm_denied": 0.05}


@pytest.mark.slow
@pytest.mark.parametrize("name", sorted(ref.FLIGHTS))
def test_flight_matches_its_stored_reference(name):
    stored = json.loads((ROOT / "data" / "reference" / f"{name}.json").read_text())
    log = np.load(ROOT / "data" / "reference" / f"{name}.npz")
    metrics, flown = ref.fly_reference(name)
    tol = TOLERANCE_M[name]
    for k in ref.COUNT_KEYS:
        assert metrics.get(k) == stored["metrics"].get(k), k
    for k in ref.DISTANCE_KEYS:
        assert metrics[k] == pytest.approx(stored["metrics"][k], abs=tol), k
    np.testing.assert_array_equal(flown["time_s"], log["time_s"])
    np.testing.assert_allclose(flown["pos_world"], log["pos_world"], atol=tol, rtol=0)
    np.testing.assert_allclose(flown["vel_world"], log["vel_world"], atol=10 * tol, rtol=0)
