"""The communicating MINCO swarm (planner.kind minco_comm, mpcde/onboard/minco_comm.py): slow, real flights."""

from __future__ import annotations

import pytest

import mpcde

pytestmark = pytest.mark.slow


def test_crossing_drones_avoid_each_other_on_broadcast_plans_alone():
    """crossing: the two drones' paths meet at the centre and neither sees the other (constant 45 deg bearing, outside
    the 85 deg field of view), so only the radio plans keep them apart; no detector runs."""
    r = mpcde.fly("crossing", mode="minco_comm", duration_s=16.0)
    m = r.metrics
    assert m["success"] and m["collisions"] == 0 and m["min_inter_drone_distance_m"] > 0.4
    assert all(a["plans_received"] > 20 for a in m["agents"])
    assert m["detector_precision"] is None and m["radio"]["delivered"] > 0


def test_without_the_radio_the_same_stack_is_blind_to_its_neighbour():
    """The same flight with the radio out: the plans never arrive and the drones come much closer (no detector)."""
    cfg = mpcde.load_scenario("crossing", mode="minco_comm", duration_s=16.0)
    from dataclasses import replace

    blind = mpcde.fly(replace(cfg, radio=replace(cfg.radio, blackout=True))).metrics
    heard = mpcde.fly(cfg).metrics
    assert all(a["plans_received"] == 0 for a in blind["agents"])
    assert blind["min_inter_drone_distance_m"] < heard["min_inter_drone_distance_m"] - 0.2
