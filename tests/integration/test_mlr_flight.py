"""MLR-DMPC in the full simulator (physics + SE(3) controller, cameras off): six drones swap on a 3 m circle.

Drones 0 and 1 host the two compute units (:mod:`mpcde.onboard.mlr`); 15 s
simulated at most. With an ideal radio all arrive without recovery; with 20 %
Bernoulli loss all arrive after recovery requests and tracker deprecations,
with no QP failure and no reference jump. Measured figures:
docs/results/mlr_dmpc.md#in-the-physics-loop-six-drones-swap-on-a-3-m-circle.
"""

from dataclasses import replace

import pytest
from agent_metrics import agent_total, without_wall_clock  # tests/integration/agent_metrics.py

from mpcde.cli import main
from mpcde.config.scenario import load_scenario
from mpcde.flight.loop import prepare_run, run_scenario


def _swap(loss: float = 0.0, seed: int = 0) -> dict:
    drones = {"layout": "antipodal", "count": 6, "radius_m": 3.0}
    cfg = load_scenario("antipodal", {"duration_s": 15.0, "seed": seed, "drones": drones})
    cfg = replace(cfg, planner=replace(cfg.planner, kind="mlr"), run=replace(cfg.run, cameras=False))
    if loss:
        cfg = replace(cfg, radio=replace(cfg.radio, loss_model="bernoulli", loss_probability=loss))
    return run_scenario(prepare_run(cfg)).metrics


@pytest.mark.slow
def test_six_drone_swap_with_ideal_radio_arrives_without_collision_and_repeats_exactly(record_property):
    m = _swap()
    record_property("min_distance_m", m["min_inter_drone_distance_m"])
    record_property("mission_time_s", m["mission_time_s"])
    assert m["success"] and m["arrived"] == 6 and m["collisions"] == 0
    assert m["min_inter_drone_distance_m"] > 0.4  # planned d̂_min = 0.45 m between references
    hosts = [a for a in m["agents"] if a["compute_unit"] is not None]
    assert [a["drone_id"] for a in hosts] == [0, 1] and all(a["computations"] > 0 for a in hosts)
    assert agent_total(m, "recovery_requests") == 0 and agent_total(m, "qp_failures") == 0
    assert max(a["max_reference_jump_m"] for a in m["agents"]) < 1e-6
    assert hosts[0]["qp_solve_ms_median"] > 0
    assert without_wall_clock(_swap()) == without_wall_clock(m)


@pytest.mark.slow
def test_six_drone_swap_with_twenty_percent_loss_recovers_and_arrives_without_collision(record_property):
    m = _swap(loss=0.2, seed=1)
    record_property("min_distance_m", m["min_inter_drone_distance_m"])
    record_property("recovery_requests", agent_total(m, "recovery_requests"))
    assert m["radio"]["lost"]["loss"] > 0
    assert m["arrived"] == 6 and m["collisions"] == 0
    assert m["min_inter_drone_distance_m"] > 0.4
    assert agent_total(m, "recovery_requests") > 0 and agent_total(m, "recovery_replies") > 0
    assert agent_total(m, "deprecated_trackers") > 0 and agent_total(m, "rounds_with_mlr") > 0
    assert max(a["max_reference_jump_m"] for a in m["agents"]) < 1e-6  # MLR-DMPC never jumps a reference


def test_too_many_compute_units_is_one_line_exit_2_and_writes_nothing(tmp_path, capsys):
    path = tmp_path / "bad.yaml"
    path.write_text("drones:\n  layout: antipodal\n  count: 3\nmlr:\n  num_compute_units: 3\n")
    out = tmp_path / "run"
    code = main(["fly", str(path), "--mode", "mlr", "--out", str(out), "--quiet", "--no-cameras"])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1 and "mlr.num_compute_units=3" in err[0]
    assert not out.exists()


def test_an_obstacle_scenario_in_mlr_mode_is_one_line_exit_2(tmp_path, capsys):
    out = tmp_path / "run"
    code = main(["fly", "forest_sparse", "--mode", "mlr", "--out", str(out), "--quiet", "--no-cameras"])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1 and "world.obstacle_density_per_100m2" in err[0] and "obstacle" in err[0]
    assert not out.exists()
