"""Collision causes (mpcde/evals/collision_causes.py) on flights whose cause is known by construction (slow: real flights)."""

from __future__ import annotations

import pytest

from mpcde.config.scenario import load_scenario
from mpcde.evals.collision_causes import CAUSES, explain_flight

pytestmark = pytest.mark.slow


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


def test_a_clean_flight_has_no_causes_and_every_cause_is_named():
    cfg = load_scenario("crossing", {"duration_s": 6.0}, planner_kind="mpcde")
    metrics, causes = explain_flight(cfg)
    assert metrics["collisions"] == 0 and causes == []
    assert len(set(CAUSES)) == len(CAUSES)
