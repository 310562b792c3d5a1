"""``mpcde report A B --out DIR``: stores of one base scenario paired by seed across stores (mpcde/sweep/cross_report.py)."""

from __future__ import annotations

import json

import pytest
from scipy.stats import binomtest

from mpcde.cli import main
from mpcde.errors import ConfigError
from mpcde.sweep.cross_report import build_cross_report, default_pair_on
from mpcde.sweep.report import build_report
from mpcde.sweep.spec import sweep_from_dict
from mpcde.sweep.store import ResultsStore


def _metrics(success: bool, collisions: int) -> dict:
    return {
        "success": success, "collisions": collisions, "drone_drone_collisions": collisions, "drone_obstacle_collisions": 0,
        "min_inter_drone_distance_m": 0.1 if collisions else 0.8, "mission_time_s": 10.0 if success else None,
        "tracking_pos_rmse_m": None,
    }  # fmt: skip


def _store(folder, sweep: dict, outcomes: dict[tuple[int, int], bool]) -> None:
    """A store of ``sweep`` whose flight (cell, seed) succeeded as ``outcomes`` says (a collision where it did not)."""
    spec = sweep_from_dict(sweep, folder)
    store = ResultsStore.for_sweep(folder, spec)
    cells = spec.cells()
    for (cell, seed), ok in outcomes.items():
        store.append({
            "cell": cell, "values": cells[cell].values, "seed": seed, "status": "ok", "error": None,
            "metrics": _metrics(ok, 0 if ok else 1), "wall_s": 1.0, "version": "test", "git_rev": None,
        })  # fmt: skip


METHOD = {"base": "crossing", "seeds": 10, "overrides": {"duration_s": 5}, "axes": {"planner.kind": ["mpcde"], "planner.cruise_speed_mps": [0.5, 1.0]}}
BASELINE = {
    "base": "crossing", "seeds": 6, "overrides": {"duration_s": 5, "radio.view_gated": True},
    "axes": {"planner.kind": ["minco_comm"], "radio.delay_s": [0.0, 0.5], "planner.cruise_speed_mps": [0.5, 1.0]},
}  # fmt: skip


@pytest.fixture
def two_stores(tmp_path):
    """The method: 10 seeds per speed, seeds 3 and 7 fail at 1 m/s. The baseline: 6 seeds per cell, cells
    (delay 0, 0.5 m/s) fail on seeds 0-4, the others fail on seed 1 only; cell (delay 0.5, 1 m/s) has flown
    seeds 0-2 (a store still growing)."""
    method = {(c, s): not (c == 1 and s in (3, 7)) for c in range(2) for s in range(10)}
    baseline = {}
    for c in range(4):
        for s in range(3 if c == 3 else 6):
            baseline[(c, s)] = s > 4 if c == 0 else s != 1
    _store(tmp_path / "method", METHOD, method)
    _store(tmp_path / "baseline", BASELINE, baseline)
    return tmp_path / "method", tmp_path / "baseline"


def test_cells_are_paired_across_stores_on_the_shared_axis_over_the_seeds_both_flew(two_stores):
    method, baseline = two_stores
    report = build_cross_report([method, baseline])
    # planner.kind is set in both but its values never meet: it is what the stores compare
    assert report["pair_keys"] == [{"stores": ["method", "baseline"], "keys": ["duration_s", "planner.cruise_speed_mps"]}]
    assert report["shared_overrides"] == {"duration_s": 5}
    assert len(report["cells"]) == 2 + 4 and len(report["pairs"]) == 4  # each baseline cell meets the method once
    by = {(p["on"]["planner.cruise_speed_mps"], report["cells"][p["b"]]["settings"]["radio.delay_s"]): p for p in report["pairs"]}
    p = by[(0.5, 0.0)]  # seeds 0-5: the method wins all six, the baseline only seed 5
    assert (p["paired_seeds"], p["a_only"], p["b_only"], p["a_success_paired"], p["b_success_paired"]) == (6, 5, 0, 6, 1)
    assert p["success_difference"] == pytest.approx(5 / 6)
    assert p["mcnemar_p"] == pytest.approx(binomtest(0, 5).pvalue)
    p = by[(1.0, 0.0)]  # seeds 0-5: the method fails seed 3, the baseline seed 1
    assert (p["paired_seeds"], p["a_only"], p["b_only"], p["success_difference"]) == (6, 1, 1, 0.0)
    assert p["mcnemar_p"] == 1.0
    p = by[(1.0, 0.5)]  # the growing cell: seeds 0-2 only
    assert (p["paired_seeds"], p["a_only"], p["b_only"]) == (3, 1, 0)


def test_per_cell_figures_are_those_of_each_stores_own_report(two_stores):
    method, baseline = two_stores
    cross = build_cross_report([method, baseline])["cells"]
    own = build_report(method)["cells"] + build_report(baseline)["cells"]
    keys = ("flights", "success_rate", "success_low", "success_high", "collisions_per_flight", "min_distance_m", "mission_time_s")
    assert [[c[k] for k in keys] for c in cross] == [[c[k] for k in keys] for c in own]


def test_the_default_pairs_on_every_field_two_stores_both_set_whose_values_meet():
    def sweep(overrides, axes):
        return {"overrides": overrides, "axes": [[k, v] for k, v in axes.items()]}

    method = sweep({"duration_s": 100}, {"planner.kind": ["mpcde"], "planner.cruise_speed_mps": [0.5, 1.0]})
    fixed = sweep({"duration_s": 100, "planner.cruise_speed_mps": 1}, {"planner.kind": ["dmpc"]})  # speed an override, an int
    delayed = sweep({"radio.delay_s": 0.5}, {"planner.kind": ["minco_comm"], "planner.cruise_speed_mps": [2.0]})
    assert default_pair_on(method, fixed) == ["duration_s", "planner.cruise_speed_mps"]  # 1 meets 1.0
    assert default_pair_on(method, delayed) == []  # 0.5/1.0 never meet 2.0; the delay is the baseline's own
    assert default_pair_on(fixed, delayed) == []


def test_a_speed_fixed_as_an_override_pairs_only_with_that_speed_and_three_stores_pair_two_by_two(tmp_path):
    _store(tmp_path / "method", METHOD, {(c, s): True for c in range(2) for s in range(4)})
    fixed = {"base": "crossing", "seeds": 4, "overrides": {"duration_s": 5, "planner.cruise_speed_mps": 1}, "axes": {"planner.kind": ["dmpc"]}}
    _store(tmp_path / "fixed", fixed, {(0, s): s != 2 for s in range(4)})
    fast = {"base": "crossing", "seeds": 4, "overrides": {"duration_s": 5}, "axes": {"planner.kind": ["auto"], "planner.cruise_speed_mps": [2.0]}}
    _store(tmp_path / "fast", fast, {(0, s): True for s in range(4)})
    report = build_cross_report([tmp_path / "method", tmp_path / "fixed", tmp_path / "fast"])
    labels = [(report["cells"][p["a"]]["label"], report["cells"][p["b"]]["label"]) for p in report["pairs"]]
    # method x fixed: on speed, so only method's 1 m/s cell. x fast: speeds never meet, so speed is what those
    # stores compare (as planner.kind is), and every cell pairs with fast's: method's two, fixed's one
    assert len(report["pairs"]) == 1 + 2 + 1, labels
    assert report["pair_keys"][1:] == [
        {"stores": ["method", "fast"], "keys": ["duration_s"]}, {"stores": ["fixed", "fast"], "keys": ["duration_s"]},
    ]
    speed_pair = next(p for p in report["pairs"] if p["on"])
    assert speed_pair["on"] == {"planner.cruise_speed_mps": 1.0} and (speed_pair["a_only"], speed_pair["b_only"]) == (1, 0)
    assert report["cells"][speed_pair["a"]]["settings"]["planner.cruise_speed_mps"] == 1.0


def test_failed_rows_and_empty_stores_pair_no_seed_and_equal_folder_names_stay_apart(tmp_path):
    method = {(c, s): True for c in range(2) for s in range(4)}
    _store(tmp_path / "a" / "sw", METHOD, method)
    _store(tmp_path / "b" / "sw", BASELINE, {})
    report = build_cross_report([tmp_path / "a" / "sw", tmp_path / "b" / "sw"])
    assert {c["store"] for c in report["cells"]} == {str(tmp_path / "a" / "sw"), str(tmp_path / "b" / "sw")}
    assert len(report["pairs"]) == 4 and all(p["paired_seeds"] == 0 and p["mcnemar_p"] == 1.0 for p in report["pairs"])
    assert all(p["success_difference"] is None for p in report["pairs"])
    store = ResultsStore.read(tmp_path / "b" / "sw")
    store.append({
        "cell": 0, "values": {}, "seed": 0, "status": "failed", "error": "RuntimeError: x", "metrics": None,
        "wall_s": 1.0, "version": "test", "git_rev": None,
    })  # fmt: skip
    report = build_cross_report([tmp_path / "a" / "sw", tmp_path / "b" / "sw"])
    assert all(p["paired_seeds"] == 0 for p in report["pairs"]) and report["cells"][2]["failed"] == 1
    with pytest.raises(ConfigError, match="given twice"):
        build_cross_report([tmp_path / "a" / "sw", tmp_path / "a" / ".." / "a" / "sw"])


def test_the_cli_writes_the_cross_report_and_refuses_bad_requests_in_one_line(two_stores, tmp_path, capsys):
    method, baseline = two_stores
    out = tmp_path / "cross"
    assert main(["report", str(method), str(baseline), "--out", str(out)]) == 0
    assert "method x baseline: duration_s, planner.cruise_speed_mps" in capsys.readouterr().out
    assert len(json.loads((out / "report.json").read_text())["pairs"]) == 4
    assert {p.name for p in out.iterdir()} == {"report.txt", "report.md", "report.json"}

    other = dict(METHOD, base="antipodal")
    _store(tmp_path / "other", other, {(0, 0): True})
    cases = [
        (["report", str(method), str(baseline)], "--out=None"),
        (["report", str(method), str(tmp_path / "other"), "--out", str(tmp_path / "x1")], "another base scenario"),
        (["report", str(method), str(baseline), "--out", str(tmp_path / "x2"), "--pair-on", "radio.delay_s"], "--pair-on='radio.delay_s'"),
        (["report", str(method), str(baseline), "--out", str(method)], "sweep folder"),
        (["report", str(method), str(baseline), "--out", str(method / "inside")], "sweep folder"),
    ]  # fmt: skip
    for argv, words in cases:
        assert main(argv) == 2
        err = capsys.readouterr().err.strip()
        assert len(err.splitlines()) == 1 and err.startswith("mpcde: error: ") and words in err, err
    assert not (tmp_path / "x1").exists() and not (tmp_path / "x2").exists()
    assert {p.name for p in method.iterdir()} == {"results.jsonl", "sweep.json"}
