"""mpcde.paper.swarm_modes (`mpcde paper modes`) counts contacts by kind and averages the yaw modes from a store's rows
(issue 28)."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from sweep_stores import mpcde, write_store  # tests/unit/mpcde/paper/sweep_stores.py

from mpcde.paper import swarm_modes


def _agent(explore: float, observe: float, track: float, replans: int) -> dict:
    return {"yaw_mode_fraction": {"exploring": explore, "observing": observe, "tracking": track}, "yaw_replans": replans}


def _metrics(ok: bool, dd: int, do: int, mission: float | None, agents: list[dict]) -> dict:
    return {"success": ok, "drone_drone_collisions": dd, "drone_obstacle_collisions": do, "mission_time_s": mission, "agents": agents}


def _store(folder: Path, rows: list[dict]) -> Path:
    """A two-cell store (speed 0.5 and 2.0) as `mpcde sweep` writes it, every row key present."""
    return write_store(folder, [["planner.cruise_speed_mps", [0.5, 2.0]]], rows, {"duration_s": 100}, base="forest_swarm", seeds=40)


def _rows() -> list[dict]:
    a, b = _agent(0.5, 0.5, 0.0, 10), _agent(0.0, 0.0, 1.0, 20)
    return [
        {"cell": 0, "seed": 0, "metrics": _metrics(True, 0, 0, 40.0, [a, b])},
        {"cell": 0, "seed": 1, "metrics": _metrics(False, 2, 0, 50.0, [a, a])},  # two contacts, all arrived
        {"cell": 0, "seed": 2, "metrics": None},  # a failed flight: left out
        {"cell": 0, "seed": 3, "metrics": _metrics(False, 0, 2, None, [b, {"yaw_mode_fraction": None}])},  # one drone stuck
        {"cell": 0, "seed": 35, "metrics": _metrics(False, 0, 1, None, [b, b])},  # beyond --seeds 30
        {"cell": 1, "seed": 0, "metrics": _metrics(True, 0, 0, 10.0, [b, {"yaw_replans": 4}])},  # a drone with no yaw plan
    ]


def test_cells_count_flights_with_each_contact_and_average_modes_over_drones(tmp_path):
    slow, fast = swarm_modes.cell_lines(_store(tmp_path / "s", _rows()))
    assert (slow["flights"], slow["ok"], slow["drone_drone"], slow["drone_obstacle"]) == (4, 1, 1, 2)  # flights, not contacts
    assert slow["shares"]["tracking"] == pytest.approx(4 / 7)  # b on 4 of the 7 drone-flights with a yaw plan
    assert slow["shares"]["exploring"] == pytest.approx(1.5 / 7)
    assert slow["yaw_replans"] == pytest.approx((10 + 20 + 10 + 10 + 20 + 20 + 20) / 7)
    assert slow["mission_s"] == pytest.approx((40.0 + 50.0) / 2)  # every drone arrived, a contact or not
    assert slow["label"] == "s: planner.cruise_speed_mps=0.5"  # as `mpcde report` labels the cell
    assert fast["shares"]["tracking"] == 1.0 and fast["yaw_replans"] == 12.0  # shares over drones that planned


def test_seeds_limits_the_flights_read(tmp_path):
    slow, _ = swarm_modes.cell_lines(_store(tmp_path / "s", _rows()), seeds=30)
    assert (slow["flights"], slow["drone_obstacle"]) == (3, 1)
    assert slow["shares"]["tracking"] == pytest.approx(2 / 5)


def test_a_cell_not_flown_yet_prints_nan(tmp_path, capsys):
    rows = [r for r in _rows() if r["cell"] == 0]
    assert mpcde("paper", "modes", _store(tmp_path / "s", rows)) == 0
    last = capsys.readouterr().out.splitlines()[-1].split()
    assert last[:4] == ["0", "0", "0", "0"] and last[4:9] == ["nan%", "nan%", "nan%", "nan", "nan"]


def test_a_folder_that_is_not_a_store_is_one_line_and_exit_2(tmp_path, capsys):
    assert mpcde("paper", "modes", tmp_path) == 2
    out, err = capsys.readouterr()
    assert out == "" and err.count("\n") == 1 and err.startswith("mpcde: error: store=") and "sweep.json" in err
    assert mpcde("paper", "modes", _store(tmp_path / "s", _rows()), "--seeds", "0") == 2
    assert capsys.readouterr().err == "mpcde: error: --seeds=0: an integer >= 1\n"


@pytest.mark.parametrize(
    ("path", "value"),
    [
        (("drone_drone_collisions",), None),
        (("drone_obstacle_collisions",), -1),
        (("success",), 1),
        (("mission_time_s",), "soon"),
        (("agents",), None),
        (("agents", 0, "yaw_mode_fraction"), {"exploring": 2.0, "observing": 0.0, "tracking": 0.0}),
        (("agents", 1, "yaw_replans"), float("nan")),
    ],
)
def test_a_row_it_cannot_read_is_one_line_naming_the_field_and_exit_2(tmp_path, capsys, path, value):
    rows = _rows()
    target = rows[0]["metrics"]
    for key in path[:-1]:
        target = target[key]
    target[path[-1]] = value
    assert mpcde("paper", "modes", _store(tmp_path / "s", rows)) == 2
    out = capsys.readouterr()
    assert out.out == "" and out.err.count("\n") == 1
    field = "metrics." + ".".join(f"[{k}]" if isinstance(k, int) else k for k in path).replace(".[", "[")
    assert f"line 1: {field}=" in out.err


def test_a_row_outside_the_sweep_is_one_line_and_exit_2(tmp_path, capsys):
    """A seed the sweep does not name, or a cell past its last, as `mpcde paper table3` refuses them (the same check)."""
    for i, (key, value) in enumerate((("seed", 40), ("cell", 2))):
        rows = _rows()
        rows[0][key] = value
        assert mpcde("paper", "modes", _store(tmp_path / f"s{i}", rows)) == 2
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and f"line 1: {key}={value}:" in err


def test_render_prints_one_line_per_cell(tmp_path, capsys):
    assert mpcde("paper", "modes", _store(tmp_path / "s", _rows())) == 0
    out = capsys.readouterr().out.splitlines()
    assert len(out) == 4 and out[3].endswith("s: planner.cruise_speed_mps=2.0")
    assert out[2].split()[:9] == ["4", "1", "1", "2", "21.4%", "21.4%", "57.1%", "15.7", "45.00"]


KEPT_SEEDS = 30  # fig6_modes holds all 30 seeds of its sweep file


def test_the_report_of_the_kept_swarm_stores_stands_verbatim_in_mp_cde_md(tmp_path, unpack_kept_store, capsys):
    """mp-cde.md pastes `mpcde paper modes`' output for MP-CDE's kept Fig. 6 row and the kept swarm ablation, on the
    seeds the ablation flew: printed, not typed (issue 28)."""
    stores = [unpack_kept_store(name, tmp_path / name) for name in ("fig6_denied_portable", "fig6_modes")]
    assert max(r["seed"] for r in map(json.loads, (stores[1] / "results.jsonl").read_text().splitlines())) == KEPT_SEEDS - 1
    assert mpcde("paper", "modes", *stores, "--seeds", KEPT_SEEDS) == 0
    text = capsys.readouterr().out
    assert text == swarm_modes.render([line for s in stores for line in swarm_modes.cell_lines(s, KEPT_SEEDS)]) + "\n"
    doc = (Path(__file__).resolve().parents[4] / "docs" / "results" / "mp-cde.md").read_text()
    assert text in doc, "mp-cde.md lacks `mpcde paper modes`' output for fig6_denied_portable and fig6_modes"
