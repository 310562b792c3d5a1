"""Collision causes (mpcde/evals/collision_causes.py): flights whose cause is known by construction (slow: real flights), and the classifier on recorded deliveries."""

from __future__ import annotations

from collections import deque

import numpy as np
import pytest

from mpcde.config.scenario import load_scenario
from mpcde.evals.collision_causes import BEFORE_S, CAUSES, _classify, _Recorder, _Tick, explain_flight


@pytest.mark.slow
def test_blind_lines_that_cross_collide_without_ever_detecting_each_other():
    """The placeholder flies straight lines through each other and runs no detector: the drones face each other
    (in view) and nothing is ever detected, so the cause is a late (never) detection, both ways."""
    cfg = load_scenario("crossing", {"duration_s": 8.0}, planner_kind="min_jerk_line")
    metrics, causes = explain_flight(cfg)
    assert metrics["drone_drone_collisions"] >= 1 and len(causes) == metrics["collisions"]
    first = causes[0]
    assert first.kind == "drone" and first.cause == "late detection"
    assert all(d["cause"] == "late detection" and d["in_view_frames"] > 0 and d["detected_frames"] == 0 for k, d in first.detail.items() if "->" in k)
    assert first.detail["ref_distance_m"] < 0.3  # the lines themselves meet: not the controller's doing


@pytest.mark.slow
def test_a_clean_flight_has_no_causes_and_every_cause_is_named():
    cfg = load_scenario("crossing", {"duration_s": 6.0}, planner_kind="mpcde")
    metrics, causes = explain_flight(cfg)
    assert metrics["collisions"] == 0 and causes == []
    assert len(set(CAUSES)) == len(CAUSES)


def _ticks(braking_at: dict[float, list[int]]) -> _Recorder:
    """A recorder with one delivery per listed time for two drones that never saw each other."""
    rec = _Recorder.__new__(_Recorder)
    rec.n, rec.ticks = 2, deque()
    early = np.zeros((3, 2, 2), bool)
    early[:, 0, 1] = True  # at 1 s, long before the look-back, drone 0 saw, detected and tracked drone 1
    rec.history_t, rec.history = [1.0], [early]
    for t, braking in sorted(braking_at.items()):
        b = np.zeros(2, bool)
        b[braking] = True
        modes = ["observing" if t < 4.97 else "exploring", None]  # drone 0's yaw planner switches just before the event
        rec.ticks.append(_Tick(t, np.zeros((2, 2), int), np.zeros((2, 2), bool), np.full((2, 2), np.inf), [[], []], [None, None], b, np.zeros(2, bool), modes, np.array([[0.0, 90.0 + t], [-100.0, 0.0]]),
                              np.array([[0, 2], [1, 0]]), np.array([1.5, 1.5 + (5.0 - t)]), np.array([[np.nan, 30.0 + t], [np.nan, np.nan]])))  # fmt: skip
        rec.history_t.append(t)
        rec.history.append(np.zeros((3, 2, 2), bool))  # in the look-back, neither saw the other
    return rec


@pytest.mark.parametrize(("braking_before", "cause"), [([0], "fallback"), ([], "never in view")])
def test_fallback_is_a_brake_already_on_before_the_event_not_one_that_reacts_to_it(braking_before, cause):
    """A drone braking at the event but not BEFORE_S earlier reacted to a late sight: the perception checks name it."""
    t = 5.0
    rec = _ticks({t - BEFORE_S - 0.04: braking_before, t - 0.1: [0], t: [0]})
    future = deque((s, np.array([[0.0, 0.0, 1.5], [0.15, 0.0, 1.5]])) for s in np.arange(4.5, 6.01, 0.04))
    out = _classify({"time_s": t, "kind": "drone", "drones": [0, 1]}, None, rec, future, None, 0.1, None)
    assert out.cause == cause
    if cause == "never in view":  # what each drone's yaw planner did in the look-back, per delivery
        assert out.detail["0->1"]["yaw_modes"] == {"exploring": 0.33, "observing": 0.67}
        assert "yaw_modes" not in out.detail["1->0"] and out.detail["1->0"]["tracks_before"] == 0
        assert out.detail["0->1"]["off_axis_deg"] == {"nearest": round(90.0 + t - BEFORE_S - 0.04, 1), "last": 95.0}
        assert out.detail["1->0"]["off_axis_deg"] == {"nearest": 100.0, "last": 100.0}
        assert out.detail["0->1"]["last_known_s_before"] == {"in_view": 4.0, "detected": 4.0, "tracked": 4.0}
        assert out.detail["1->0"]["last_known_s_before"] == {"in_view": None, "detected": None, "tracked": None}
        # where each truly was for the other's camera, their height difference, the bearing from travel
        assert out.detail["0->1"]["where"] == {"outside vertical view": 1.0}
        assert out.detail["1->0"]["where"] == {"outside horizontal view": 1.0}
        assert out.detail["0->1"]["dz_m"] == {"max_abs": round(BEFORE_S + 0.04, 2), "last": 0.0}
        assert out.detail["1->0"]["dz_m"] == {"max_abs": round(BEFORE_S + 0.04, 2), "last": -0.0}
        assert out.detail["0->1"]["travel_off_deg"] == {"min": round(30.0 + t - BEFORE_S - 0.04, 1), "max": 35.0, "last": 35.0}
        assert "travel_off_deg" not in out.detail["1->0"]  # drone 1 never moved
