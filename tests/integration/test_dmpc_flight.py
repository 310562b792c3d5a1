"""DMPC (comm mode) in the full simulator: real physics, plans over the simulated radio."""

import json
from dataclasses import replace

import pytest

from mpcde.cli import main
from mpcde.loop import prepare_run, run_scenario
from mpcde.scenario import load_scenario


def comm(name: str, **radio) -> object:
    cfg = load_scenario(name, {"planner": {"kind": "dmpc"}})
    return replace(cfg, run=replace(cfg.run, cameras=False), radio=replace(cfg.radio, **radio))


@pytest.mark.slow
def test_eight_drone_antipodal_swap_with_an_ideal_radio_has_no_collision():
    m = run_scenario(prepare_run(comm("antipodal"))).metrics
    assert m["success"] is True and m["collisions"] == 0 and m["arrived"] == 8
    assert m["min_inter_drone_distance_m"] > 0.2


@pytest.mark.slow
def test_the_swap_still_completes_with_20_percent_bernoulli_loss():
    m = run_scenario(prepare_run(comm("antipodal", loss_model="bernoulli", loss_probability=0.2))).metrics
    assert m["radio"]["lost"]["loss"] > 0
    assert m["arrived"] == 8 and m["collisions"] == 0, m["min_inter_drone_distance_m"]


@pytest.mark.slow
def test_eval_dmpc_writes_the_table_1_schema(tmp_path):
    out = tmp_path / "ed"
    assert main(["eval-dmpc", "--out", str(out), "--scenarios", "antipodal", "--quiet"]) == 0
    rows = json.loads((out / "results.json").read_text())["rows"]
    assert {r["method"] for r in rows} == {"on_demand", "bvc"}
    keys = {"method", "scenario", "collisions", "min_distance_m", "qp_ms_median", "qp_ms_p95", "mission_time_s", "path_length_m", "mean_speed_mps", "mean_accel_mps2"}
    assert all(set(r) == keys for r in rows)


def test_invalid_dmpc_parameters_are_one_line_exit_2(tmp_path, capsys):
    bad = tmp_path / "bad.yaml"
    bad.write_text("planner: {kind: dmpc}\ndmpc:\n  qp:\n    horizon_steps: -3\n")
    assert main(["fly", str(bad), "--out", str(tmp_path / "o"), "--quiet"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "dmpc.qp" in err[0]
    assert not (tmp_path / "o").exists()
