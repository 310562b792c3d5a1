"""MetricsAccumulator: collision counting and the collision event log on hand-made states."""

from __future__ import annotations

import numpy as np

from mpcde.flight.metrics import MetricsAccumulator
from sim.ground_truth import TrueState

R = 0.1  # robot radius [m]: a drone-drone collision is a centre distance below 0.2 m


def _state(t: float, pos: np.ndarray, contact=(False, False, False)) -> TrueState:
    n = pos.shape[0]
    quat = np.tile([0.0, 0.0, 0.0, 1.0], (n, 1))
    return TrueState(t, pos, np.zeros((n, 3)), quat, np.tile(np.eye(3), (n, 1, 1)), np.zeros((n, 3)),
                     np.asarray(contact, bool), np.zeros(n, bool))


def test_events_are_logged_once_per_entry_in_time_order():
    goals = np.array([[5.0, 0, 1], [5.0, 1, 1], [-5.0, 0, 1]])
    acc = MetricsAccumulator(goals, (), R, 0.1)
    gaps = [1.0, 0.15, 0.12, 0.5, 0.18, 1.0]  # drones 0 and 1: in, stay in, out, in again, out
    contact = [False, False, True, True, False, True]  # drone 2 touches twice
    for k, (g, c) in enumerate(zip(gaps, contact)):
        pos = np.array([[0.0, 0, 1], [0.0, g, 1], [-3.0, 0, 1]])
        acc.update(_state(0.1 * (k + 1), pos, (False, False, c)), 0.1)
    m = acc.result(1.0, np.zeros(3, bool))
    assert m["drone_drone_collisions"] == 2 and m["drone_obstacle_collisions"] == 2 and m["collisions"] == 4
    ev = m["collision_events"]
    assert [(e["kind"], e["drones"]) for e in ev] == [("drone", [0, 1]), ("obstacle", [2]), ("drone", [0, 1]), ("obstacle", [2])]
    np.testing.assert_allclose([e["time_s"] for e in ev], [0.2, 0.3, 0.5, 0.6])
    np.testing.assert_allclose([e["distance_m"] for e in ev if e["kind"] == "drone"], [0.15, 0.18])
    assert m["min_inter_drone_distance_m"] == 0.12


def test_no_events_without_collisions():
    acc = MetricsAccumulator(np.array([[1.0, 0, 1], [1.0, 2, 1]]), (), R, 0.1)
    acc.update(_state(0.1, np.array([[0.0, 0, 1], [0.0, 2, 1]]), (False, False)), 0.1)
    m = acc.result(1.0, np.zeros(2, bool))
    assert m["collision_events"] == [] and m["collisions"] == 0
