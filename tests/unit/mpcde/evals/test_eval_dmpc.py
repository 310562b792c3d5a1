"""eval-dmpc writes the results schema (a tiny short run), flies what each row says, and rejects bad methods."""

import json

import numpy as np
import pytest

import mpcde.evals.dmpc as eval_dmpc
from mpcde.config.dmpc import DmpcAgentConfig
from mpcde.evals.dmpc import FLOWN_KEYS, ROW_KEYS, format_table, formation_error, run_eval_dmpc


@pytest.fixture(scope="module")
def antipodal(tmp_path_factory):
    """A 1 s eval of antipodal (no obstacles): its folder and rows."""
    out = tmp_path_factory.mktemp("eval_dmpc")
    run_eval_dmpc(out, scenarios=("antipodal",), seeds=(0,), progress=False, duration_s=1.0)
    return out, json.loads((out / "results.json").read_text())["rows"]


def test_short_eval_writes_exactly_the_schema(antipodal):
    out, rows = antipodal
    assert len(rows) == 2
    for row in rows:
        assert tuple(sorted(row)) == tuple(sorted(ROW_KEYS)) and tuple(row["flown"]) == FLOWN_KEYS
        assert row["qp_ms_median"] > 0 and row["qp_ms_mean"] > 0 and row["collisions"] == 0
        assert row["iterations_mean"] > 0 and 0 <= row["refactor_share"] <= 1
    assert {r["method"] for r in rows} == {"on_demand", "bvc"}
    assert all(r["obstacles"] is None and r["min_obstacle_clearance_m"] is None for r in rows)  # none there
    text = (out / "results.txt").read_text()
    assert text.startswith(format_table({"rows": rows}).splitlines()[0])
    assert "Table 1 on antipodal" in text and "average acceleration" in text
    assert (out / "results.png").stat().st_size > 0


def test_each_method_row_flies_its_own_qp_read_back_from_the_agents(antipodal):
    # the flown QP, as the agents' QPs report it, not the label: the committing default once turned every row into BVC
    _, rows = antipodal
    by = {r["method"]: r for r in rows}
    flown = [tuple(r["flown"].values()) for r in rows]
    assert len(set(flown)) == len(rows), f"two method rows flew the same QP: {flown}"
    for method, row in by.items():
        assert row["flown"] == {"collision_mode": method, "obstacle_avoidance": None, "terminal_halt": False, "commit_when_unheard": False}
    # and the QPs' own statistics tell them apart: BVC has a plane per neighbour and step in every round,
    # on-demand rows only at predicted conflicts, and BVC's planes move every round (a refactorisation each)
    assert by["bvc"]["collision_rows_mean"] > by["on_demand"]["collision_rows_mean"]
    assert by["bvc"]["refactor_share"] > by["on_demand"]["refactor_share"]


def test_a_row_that_flies_another_qp_than_its_label_is_refused_before_writing(tmp_path, monkeypatch):
    # the shape of the old silent override: every row flown with buffered Voronoi planes, whatever its label
    replanning = DmpcAgentConfig.replanning
    monkeypatch.setattr(DmpcAgentConfig, "replanning", lambda self, collision_mode="on_demand": replanning(self, "bvc"))
    with pytest.raises(RuntimeError, match="antipodal on_demand: the agents flew"):
        run_eval_dmpc(tmp_path / "out", scenarios=("antipodal",), seeds=(0,), progress=False, duration_s=0.4)
    assert not (tmp_path / "out").exists()


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
    assert [(r["flown"]["collision_mode"], r["flown"]["obstacle_avoidance"]) for r in rows] == [
        ("on_demand", "on_demand"), ("bvc", "every_step"), ("on_demand", "every_step")
    ]  # read back from the agents' QPs
    assert all(r["min_obstacle_clearance_m"] is not None for r in rows)
    text = (tmp_path / "results.txt").read_text()
    assert "BVC / on-demand (on_demand obstacles)" in text and "BVC / on-demand (every_step obstacles)" in text
    assert "Table 1 on formation_square" in text


def test_table1_sets_the_five_metrics_beside_the_paper():
    row = {"scenario": "s", "obstacles": None, "path_length_m": 20.0, "mean_speed_mps": 0.8, "mean_accel_mps2": 0.5, "mission_time_s": None}
    rows = [{**row, "method": "on_demand", "qp_ms_mean": 0.1}, {**row, "method": "bvc", "qp_ms_mean": 0.3}]
    lines = eval_dmpc.table1(rows, "s")
    qp = next(line for line in lines if line.startswith("average QP solve time"))
    assert qp.split()[-6:] == ["0.100", "3.94", "0.300", "12.91", "3.00", "3.28"]
    mission = next(line for line in lines if line.startswith("total mission time"))
    assert mission.split()[4:] == ["-", "27.66", "-", "30.65", "-", "1.11"]  # no mission time without arrival
    assert eval_dmpc.table1(rows[:1], "s") == []
