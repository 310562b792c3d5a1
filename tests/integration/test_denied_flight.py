"""The MP-CDE (denied) stack flies a drone through the dense forest on what its camera saw."""

import numpy as np
import pytest

from mpcde.config.scenario import load_scenario
from mpcde.flight.loop import prepare_run, run_scenario
from sim.obstacles import distance_to_obstacles


@pytest.mark.slow
def test_forest_dense_reaches_its_goal_without_touching_a_tree():
    prepared = prepare_run(load_scenario("forest_dense", {"seed": 1}))
    line = np.linspace(prepared.starts[0], prepared.goals[0], 400)
    assert distance_to_obstacles(line, prepared.obstacles).min() < 0.1, "the straight line must be blocked, or this tests nothing"
    result = run_scenario(prepared)
    m = result.metrics
    assert m["success"] is True and m["collisions"] == 0
    assert m["min_obstacle_distance_m"] > 0.1  # clearance beyond the 0.1 m robot radius
    agent = m["agents"][0]
    assert agent["replans"] >= 10 and agent["brakes"] == 0
    # the agent is built from its goal and settings only (no obstacle list): its map is its camera's
    assert m["frames_received"] > 100
