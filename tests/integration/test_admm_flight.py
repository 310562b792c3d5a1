"""ADMM formation DMPC in the full simulator (physics + SE(3) controller, cameras off): ``formation_open``.

Four drones take up a 1.6 m square from starts scattered by up to 0.36 m and
fly it 10 m (:mod:`mpcde.onboard.admm`; the radio at 50 Hz, one sub-round per
ADMM exchange). With an ideal radio all arrive in formation, no message
missing; with 20 % Bernoulli loss they arrive alike, and the missed means are
resolved later. Measured figures:
docs/results/admm_formation.md#the-admm-agent-in-the-physics-loop-formation_open.
"""

from dataclasses import replace

import pytest
import yaml
from agent_metrics import agent_total, without_wall_clock  # tests/integration/agent_metrics.py

from mpcde.cli import main
from mpcde.config.scenario import load_scenario
from mpcde.flight.loop import prepare_run, run_scenario


def _fly(loss: float = 0.0, seed: int = 0) -> dict:
    cfg = load_scenario("formation_open", {"seed": seed}, planner_kind="admm")
    cfg = replace(cfg, run=replace(cfg.run, cameras=False))
    if loss:
        cfg = replace(cfg, radio=replace(cfg.radio, loss_model="bernoulli", loss_probability=loss))
    return run_scenario(prepare_run(cfg)).metrics


@pytest.mark.slow
def test_the_square_formation_arrives_in_formation_without_collision_and_repeats_exactly(record_property):
    m = _fly()
    record_property("formation_error_final_m", m["formation_error_final_m"])
    record_property("mission_time_s", m["mission_time_s"])
    assert m["success"] and m["arrived"] == 4 and m["collisions"] == 0
    assert m["min_inter_drone_distance_m"] > 1.2  # the square's side is 1.6 m
    assert m["formation_error_final_m"] < 0.005 and m["formation_error_max_m"] > 0.4  # from the scattered start
    assert m["radio"]["lost"] == {}
    assert agent_total(m, "copies_missing") == agent_total(m, "means_missing") == agent_total(m, "late_messages") == 0
    assert all(a["planner"] == "admm" and a["steps"] > 40 and a["qp_ms_median"] > 0 for a in m["agents"])
    assert agent_total(m, "aborted_steps") == agent_total(m, "qp_failures") == 0
    assert max(a["max_reference_jump_m"] for a in m["agents"]) < 1e-3
    assert without_wall_clock(_fly()) == without_wall_clock(m)


@pytest.mark.slow
def test_with_twenty_percent_loss_the_formation_still_arrives_and_the_losses_are_counted(record_property):
    m = _fly(loss=0.2, seed=1)
    record_property("means_missing", agent_total(m, "means_missing"))
    assert m["radio"]["lost"]["loss"] > 1000
    assert m["success"] and m["arrived"] == 4 and m["collisions"] == 0
    assert m["formation_error_final_m"] < 0.005
    assert agent_total(m, "copies_missing") > 500 and agent_total(m, "means_missing") > 500 and agent_total(m, "not_averaged") > 500
    assert agent_total(m, "resolved_means") >= agent_total(m, "means_missing") - 5 and agent_total(m, "unresolved_means") <= 5
    assert agent_total(m, "aborted_steps") == 0


def test_fly_mode_admm_writes_the_derived_radio_rate_and_the_agents_figures(tmp_path):
    out = tmp_path / "run"
    assert main(["fly", "formation_open", "--mode", "admm", "--duration", "1.0", "--out", str(out), "--quiet",
                 "--no-cameras"]) == 0  # fmt: skip
    config = yaml.safe_load((out / "config.yaml").read_text())
    assert config["planner"]["kind"] == "admm" and config["radio"]["rate_hz"] == pytest.approx(50.0)
    metrics = yaml.safe_load((out / "metrics.json").read_text())
    assert [a["steps"] for a in metrics["agents"]] == [4] * 4 and "formation_error_final_m" in metrics


def test_the_same_file_flies_dmpc_at_its_own_radio_rate():
    cfg = load_scenario("formation_open", planner_kind="dmpc")
    assert cfg.radio.rate_hz == pytest.approx(5.0) and cfg.dmpc.formation_from_goals
    assert prepare_run(cfg).obstacles == ()


@pytest.mark.parametrize(
    ("scenario", "field"),
    [("forest_sparse", "world.obstacle_density_per_100m2"), ("crossing", "drones.starts[0]")],
)
def test_a_scenario_admm_cannot_fly_is_one_line_exit_2_and_writes_nothing(scenario, field, tmp_path, capsys):
    out = tmp_path / "run"
    code = main(["fly", scenario, "--mode", "admm", "--out", str(out), "--quiet", "--no-cameras"])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1 and err[0].startswith(f"mpcde: error: {field}=") and "admm" in err[0]
    assert not out.exists()
