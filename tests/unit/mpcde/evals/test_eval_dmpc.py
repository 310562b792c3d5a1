"""eval-dmpc writes the results schema (a tiny short run) and rejects bad methods."""

import json

import numpy as np
import pytest

from mpcde.evals.dmpc import ROW_KEYS, format_table, formation_error, run_eval_dmpc


def test_short_eval_writes_exactly_the_schema(tmp_path):
    run_eval_dmpc(tmp_path, scenarios=("antipodal",), seeds=(0,), progress=False, duration_s=1.0)
    data = json.loads((tmp_path / "results.json").read_text())
    assert set(data) == {"rows"} and len(data["rows"]) == 2
    for row in data["rows"]:
        assert tuple(sorted(row)) == tuple(sorted(ROW_KEYS))
        assert row["qp_ms_median"] > 0 and row["qp_ms_mean"] > 0 and row["collisions"] == 0
    assert {r["method"] for r in data["rows"]} == {"on_demand", "bvc"}
    assert all(r["obstacles"] is None and r["min_obstacle_clearance_m"] is None for r in data["rows"])  # none there
    assert (tmp_path / "results.txt").read_text().startswith(format_table(data).splitlines()[0])
    assert (tmp_path / "results.png").stat().st_size > 0


def test_unknown_method_is_rejected_before_writing(tmp_path):
    with pytest.raises(ValueError, match="methods"):
        run_eval_dmpc(tmp_path / "out", methods=("magic",), progress=False)
    assert not (tmp_path / "out").exists()


def test_formation_error_is_zero_in_formation_and_matches_hand_value():
    goals = np.array([[0.0, 0, 0], [1.0, 0, 0]])
    offsets = goals[None] - goals[:, None]
    pos = np.stack([goals, goals + np.array([[0.0, 0, 0], [0.5, 0, 0]])])
    chi = formation_error(pos, offsets)
    assert chi[0] == pytest.approx(0.0) and chi[1] == pytest.approx(2 * 0.5**2)


def test_scenario_with_obstacles_gets_the_paired_modes_and_the_every_step_variant(tmp_path):
    run_eval_dmpc(tmp_path, scenarios=("formation_square",), seeds=(0,), progress=False, duration_s=0.6)
    rows = json.loads((tmp_path / "results.json").read_text())["rows"]
    assert [(r["method"], r["obstacles"]) for r in rows] == [
        ("on_demand", "on_demand"), ("bvc", "every_step"), ("on_demand", "every_step")
    ]
    assert all(r["min_obstacle_clearance_m"] is not None for r in rows)
    text = (tmp_path / "results.txt").read_text()
    assert "BVC / on-demand (on_demand obstacles)" in text and "BVC / on-demand (every_step obstacles)" in text
