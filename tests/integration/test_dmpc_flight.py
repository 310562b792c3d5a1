"""DMPC over the simulated radio in the full simulator (physics + SE(3) controller, cameras off).

The eight-drone swap on its fixed seed, with an ideal radio and with 20 %
Bernoulli loss, arrives without collision; one drone through
formation_square's obstacles keeps clear of them with on-demand and with
every-step obstacle rows.
"""

from dataclasses import replace

import pytest

from mpcde.cli import main
from mpcde.config.scenario import load_scenario
from mpcde.flight.loop import prepare_run, run_scenario


def _swap(loss: float, seed: int = 0):
    cfg = load_scenario("antipodal", {"duration_s": 20.0, "seed": seed})
    cfg = replace(cfg, planner=replace(cfg.planner, kind="dmpc"), run=replace(cfg.run, cameras=False))
    if loss:
        cfg = replace(cfg, radio=replace(cfg.radio, loss_model="bernoulli", loss_probability=loss))
    return run_scenario(prepare_run(cfg)).metrics


@pytest.mark.slow
def test_eight_drone_swap_with_ideal_radio_arrives_without_collision(record_property):
    m = _swap(0.0)
    record_property("min_distance_m", m["min_inter_drone_distance_m"])
    assert m["arrived"] == 8 and m["collisions"] == 0 and m["success"]
    # buffered Voronoi planes deadlock a symmetric swap; the right-hand rule turns it into a roundabout
    assert sum(a["deadlock_turns"] for a in m["agents"]) > 0
    assert sum(a["fallbacks"] for a in m["agents"]) <= 2  # a fallback flies the last plan to its halt


@pytest.mark.slow
def test_plain_dmpc_swap_replans_every_round_without_fallback():
    cfg = load_scenario("antipodal", {"duration_s": 20.0, "seed": 0})
    cfg = replace(cfg, planner=replace(cfg.planner, kind="dmpc"), run=replace(cfg.run, cameras=False), dmpc=cfg.dmpc.replanning())
    m = run_scenario(prepare_run(cfg)).metrics
    assert m["arrived"] == 8 and m["collisions"] == 0
    assert sum(a["fallbacks"] for a in m["agents"]) == 0 and sum(a["commits"] + a["deadlock_turns"] for a in m["agents"]) == 0


@pytest.mark.slow
def test_eight_drone_swap_with_twenty_percent_loss_completes(record_property):
    m = _swap(0.2)
    record_property("min_distance_m", m["min_inter_drone_distance_m"])
    assert m["arrived"] == 8
    assert sum(a["stale_plans"] for a in m["agents"]) > 0  # the loss really happened
    assert m["collisions"] == 0  # holds for this seed; not guaranteed by the method


@pytest.mark.slow
@pytest.mark.parametrize("obstacles", ["on_demand", "every_step"])
def test_single_drone_through_the_formation_obstacles_touches_none(obstacles, record_property):
    # formation_square's obstacle field, one drone on the centre line (through the box and past two trees).
    drones = {"layout": "explicit", "starts": [[-9.8, 0.0, 1.5]], "goals": [[9.8, 0.0, 1.5]]}
    cfg = load_scenario("formation_square", {"duration_s": 25.0, "seed": 0, "drones": drones})
    dmpc = cfg.dmpc.replanning() if obstacles == "on_demand" else cfg.dmpc  # committing needs every-step rows
    cfg = replace(cfg, dmpc=replace(dmpc, qp=replace(dmpc.qp, obstacle_avoidance=obstacles)), run=replace(cfg.run, cameras=False))
    m = run_scenario(prepare_run(cfg)).metrics
    record_property("min_obstacle_clearance_m", m["min_obstacle_distance_m"])
    assert m["arrived"] == 1 and m["drone_obstacle_collisions"] == 0
    assert m["min_obstacle_distance_m"] > 0.1  # planned 0.25 m beyond the robot radius
    agent = m["agents"][0]
    assert agent["obstacle_avoidance"] == obstacles and agent["fallbacks"] == 0
    if obstacles == "on_demand":
        assert 0 < agent["obstacle_row_rounds"] < agent["solves"]  # rows only in some rounds


def test_invalid_dmpc_parameter_is_one_line_exit_2(tmp_path, capsys):
    path = tmp_path / "bad.yaml"
    path.write_text("planner:\n  kind: dmpc\ndmpc:\n  qp:\n    limits:\n      v_max_mps: -1.0\n")
    out = tmp_path / "run"
    code = main(["fly", str(path), "--out", str(out), "--quiet", "--no-cameras"])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1 and "dmpc.qp.limits.v_max_mps" in err[0]
    assert not out.exists()
