"""mpcde.paper.goals (`mpcde paper goals`) decides each of issue 28's goals from the stores, and mp-cde.md holds its
output on the kept stores verbatim."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest
from sweep_stores import YAWS, mpcde, write_store  # tests/unit/mpcde/paper/sweep_stores.py

from mpcde.paper import goals as paper_goals

ROOT = Path(__file__).resolve().parents[4]
ZHOU, NO_EXPLORING, NO_TRACKING, OURS = range(4)


def _table3(runs: Path) -> None:
    """Four densities, 20 seeds. Ours minus ours w/o exploring, per seed: 1..20 at density 4 (met); +100 on one seed
    and -1 on nineteen at density 8 (ours' mean is higher, +4.05, but the ranks say reversed: W+ 20, W- 190); +1, -2,
    +3, -4, ... at density 12 (not significant); -100 on one seed and +1 on nineteen at density 16 (ours ranks higher,
    p < 0.05, but its mean is lower). Zhou's sees 100; ours 120 at density 4 (+20 %, above the paper's +17.4 %), else
    100.5 (the paper has no fourth density: no margin row). Ours w/o tracking fails one flight at density 4 only."""
    diffs = {0: [float(s + 1) for s in range(20)], 1: [100.0] + [-1.0] * 19, 2: [(s + 1.0) * (-1) ** s for s in range(20)], 3: [-100.0] + [1.0] * 19}
    ours_base = {0: 120.0, 1: 100.0, 2: 100.0, 3: 100.0}
    rows = []
    for di in range(4):
        for seed in range(20):
            ours = ours_base[di] + (0.5 if di else 0.0)
            areas = {ZHOU: 100.0, NO_EXPLORING: ours - diffs[di][seed], NO_TRACKING: 100.0, OURS: ours}
            for method, area in areas.items():
                ok = not (di == 0 and method == NO_TRACKING and seed == 3)
                rows.append({"cell": 4 * di + method, "seed": seed, "metrics": {"observed_area_swarm_m2": area, "success": ok}})
    write_store(runs / "table3", [["world.obstacle_density_per_100m2", [4.0, 8.0, 12.0, 16.0]], ["denied.yaw", YAWS]], rows, seeds=20)


def _cell(store: str, overrides: dict, values: dict, rate: float, flights: int = 100, failed: int = 0) -> dict:
    values = {"planner.cruise_speed_mps": 0.5, **values}
    return {"store": store, "values": values, "settings": {**overrides, **values}, "flights": flights, "failed": failed, "success_rate": rate,
            "success_low": rate - 0.05, "success_high": min(rate + 0.02, 1.0), "label": store}  # fmt: skip


def _fig6(runs: Path) -> None:
    """At 0.5 m/s: MP-CDE at 93 % (missed by 5 points); a variant at exactly 98 % (met); one view-gated baseline
    that beats MP-CDE on the paired seeds (missed) and loses to the variant (met; the pair lists the variant second);
    auto over the scenario's radio, which beats both and is no baseline (beside, not ranked). At 1 m/s: MP-CDE at
    95 % of 99 recorded flights with one crashed (94 / 100: missed by 1 point), the variant at 94.96 % of 10,000
    (missed by less than 0.1 points), no baseline paired (not shown)."""
    base = {"duration_s": 100}
    gated = {**base, "radio.view_gated": True}
    stores = [{"name": "denied", "overrides": base}, {"name": "baseline", "overrides": gated},
              {"name": "fresh", "overrides": {**base, "denied.fresh_path_age_s": 1.0}}, {"name": "auto", "overrides": base}]  # fmt: skip
    fast = {"planner.cruise_speed_mps": 1.0}
    cells = [_cell("denied", base, {"planner.kind": "mpcde"}, 0.93), _cell("baseline", gated, {"planner.kind": "dmpc"}, 0.5, 30),
             _cell("fresh", stores[2]["overrides"], {"planner.kind": "mpcde"}, 0.98), _cell("auto", base, {"planner.kind": "auto"}, 1.0, 30),
             _cell("denied", base, {"planner.kind": "mpcde", **fast}, 94 / 99, 99, failed=1),
             _cell("fresh", stores[2]["overrides"], {"planner.kind": "mpcde", **fast}, 0.9496, 10000)]  # fmt: skip
    pairs = [{"a": 0, "b": 1, "paired_seeds": 30, "a_success_paired": 12, "b_success_paired": 15, "mcnemar_p": 0.5},
             {"a": 1, "b": 2, "paired_seeds": 30, "a_success_paired": 15, "b_success_paired": 30, "mcnemar_p": 6e-5},
             {"a": 0, "b": 3, "paired_seeds": 30, "a_success_paired": 12, "b_success_paired": 30, "mcnemar_p": 1e-5},
             {"a": 2, "b": 3, "paired_seeds": 30, "a_success_paired": 29, "b_success_paired": 30, "mcnemar_p": 1.0}]  # fmt: skip
    (runs / "fig6").mkdir()
    (runs / "fig6" / "report.json").write_text(json.dumps({"stores": stores, "shared_overrides": base, "cells": cells, "pairs": pairs}))
    modes = [_cell("denied", base, {"planner.kind": "mpcde"}, 0.93), _cell("modes", base, {"denied.yaw": {"tracking_mode": False}}, 0.8, 30)]
    (runs / "fig6_modes_vs").mkdir()
    modes_pairs = [{"a": 0, "b": 1, "paired_seeds": 30, "a_success_paired": 28, "b_success_paired": 24, "mcnemar_p": 0.22}]
    (runs / "fig6_modes_vs" / "report.json").write_text(
        json.dumps({"stores": stores[:1] + [{"name": "modes", "overrides": base}], "shared_overrides": base, "cells": modes, "pairs": modes_pairs}))


def _fig10_akf(runs: Path) -> None:
    (runs / "fig10").mkdir()
    cells = [{"values": {"denied.active_yaw": True}, "flights": 50, "collisions_per_flight": 0.02, "min_distance_m": 0.1},
             {"values": {"denied.active_yaw": False}, "flights": 50, "collisions_per_flight": 0.1, "min_distance_m": 0.05}]  # fmt: skip
    (runs / "fig10" / "report.json").write_text(json.dumps({"cells": cells, "pairs": []}))
    (runs / "akf_pipeline").mkdir()
    rows = [{"speed_mps": 0.5, "filter": "akf", "pos_rmse_m": 0.05, "vel_rmse_mps": 0.2}, {"speed_mps": 0.5, "filter": "kf", "pos_rmse_m": 0.06, "vel_rmse_mps": 0.3},
            {"speed_mps": 1.0, "filter": "akf", "pos_rmse_m": 0.05, "vel_rmse_mps": 0.3}, {"speed_mps": 1.0, "filter": "kf", "pos_rmse_m": 0.06, "vel_rmse_mps": 0.2},
            {"speed_mps": 2.0, "filter": "akf", "pos_rmse_m": 0.24, "vel_rmse_mps": 0.3}, {"speed_mps": 2.0, "filter": "kf", "pos_rmse_m": 0.3, "vel_rmse_mps": 0.4}]  # fmt: skip
    rows = [{**r, "measurements": "pipeline"} for r in rows]
    rows.append({"speed_mps": 2.0, "filter": "akf", "measurements": "synthetic", "pos_rmse_m": 0.01, "vel_rmse_mps": 0.01})  # not the goal's
    (runs / "akf_pipeline" / "results.json").write_text(json.dumps({"rows": rows}))


def _verdicts(rows: list[str]) -> list[tuple[str, str]]:
    """(goal, verdict) of each markdown row."""
    return [(cols[1].strip(), cols[4].strip()) for cols in (row.split("|") for row in rows)]


def test_rank_sums_in_closed_form():
    assert paper_goals.rank_sums([1.0, -2.0, 3.0]) == (4.0, 2.0)
    assert paper_goals.rank_sums([1.0, -1.0, 2.0, 0.0]) == (4.5, 1.5)  # a tie shares its mean rank; a zero is dropped
    assert paper_goals.rank_sums([0.0]) == (0.0, 0.0)


def test_each_goal_is_met_or_missed_from_the_numbers(tmp_path):
    _table3(tmp_path)
    _fig6(tmp_path)
    _fig10_akf(tmp_path)
    assert _verdicts(paper_goals.table3(tmp_path)) == [
        ("Table III, density 4: ours' S_obs above Zhou's by the paper's margin", "met"),
        ("Table III, density 8: ours' S_obs above Zhou's by the paper's margin", "missed by 9.7 points"),  # 10.2 - 0.5
        ("Table III, density 12: ours' S_obs above Zhou's by the paper's margin", "missed by 16.3 points"),  # 16.8 - 0.5
        ("Table III, density 4: ours w/o exploring below ours", "met"),
        ("Table III, density 8: ours w/o exploring below ours", "missed: reversed, ours w/o exploring sees more on most seeds"),
        ("Table III, density 12: ours w/o exploring below ours", "missed: not significant"),
        ("Table III, density 16: ours w/o exploring below ours", "missed: ours ranks higher but its mean is lower"),
        ("Table III, density 4: ours w/o tracking less successful than ours", "met"),
        ("Table III, density 8: ours w/o tracking less successful than ours", "missed"),
        ("Table III, density 12: ours w/o tracking less successful than ours", "missed"),
        ("Table III, density 16: ours w/o tracking less successful than ours", "missed"),
    ]
    assert "rank sums W+ 20 / W- 190" in paper_goals.table3(tmp_path)[4]
    fig6 = paper_goals.fig6(tmp_path)
    assert _verdicts(fig6) == [
        ("Fig. 6, 0.5 m/s: MP-CDE (denied)'s success", "missed by 5.0 points"),
        ("Fig. 6, 1 m/s: MP-CDE (denied)'s success", "missed by 1.0 points"),
        ("Fig. 6, 0.5 m/s: MP-CDE (denied) at least as successful as every view-gated baseline", "missed"),  # auto's 30 is not ranked
        ("Fig. 6, 1 m/s: MP-CDE (denied) at least as successful as every view-gated baseline", "not shown"),
        ("Fig. 6, 0.5 m/s: MP-CDE with denied.fresh_path_age_s=1.0 (fresh)'s success", "met"),
        ("Fig. 6, 1 m/s: MP-CDE with denied.fresh_path_age_s=1.0 (fresh)'s success", "missed by less than 0.1 points"),
        ("Fig. 6, 0.5 m/s: MP-CDE with denied.fresh_path_age_s=1.0 (fresh) at least as successful as every view-gated baseline", "met"),
        ("Fig. 6, 1 m/s: MP-CDE with denied.fresh_path_age_s=1.0 (fresh) at least as successful as every view-gated baseline", "not shown"),
    ]
    assert "of 99, 1 crashed (counted as failures)" in fig6[1]
    assert "12 of 30 paired seeds against the closest baseline's 15 (baseline, planner.kind=dmpc); 1 baseline cells" in fig6[2]
    assert "30 of 30 paired seeds against the closest baseline's 15 (baseline, planner.kind=dmpc)" in fig6[6]
    assert _verdicts(paper_goals.swarm_modes(tmp_path)) == [
        ("beside the goals: Fig. 6's swarm at 0.5 m/s, ours w/o tracking less successful than ours", "not shown")]  # fewer, but p = 0.22
    assert _verdicts(paper_goals.fig10(tmp_path)) == [
        ("Fig. 10: yaw planning on, the crossing pair never collides", "missed (1 collisions, 50 seeds)"),
        ("Fig. 10: yaw planning off, the pair collides as the paper describes, or why not", "reproduced"),
    ]
    assert _verdicts(paper_goals.akf(tmp_path)) == [
        ("AKF vs KF, 0.5 m/s: AKF at most the paper's RMSE", "met"),
        ("AKF vs KF, 2 m/s: AKF at most the paper's RMSE", "missed"),  # 0.24 m > 0.23 m
        ("AKF vs KF, 0.5 m/s: AKF below KF", "met"),
        ("AKF vs KF, 1 m/s: AKF below KF", "missed"),  # velocity above KF's
        ("AKF vs KF, 2 m/s: AKF below KF", "met"),
    ]


@pytest.mark.parametrize(
    ("flights", "failed", "per_flight", "verdict"),
    [(50, 0, 0.0, "met"), (49, 0, 0.0, "missed (0 collisions, 49 seeds)"), (49, 1, 0.0, "missed (0 collisions, 50 seeds, 1 crashed)"),
     (0, 0, None, None)],  # a cell not flown yet has no row
)
def test_fig10_on_needs_fifty_clean_flights(tmp_path, flights, failed, per_flight, verdict):
    (tmp_path / "fig10").mkdir()
    cell = {"values": {"denied.active_yaw": True}, "flights": flights, "failed": failed, "collisions_per_flight": per_flight, "min_distance_m": 0.9}
    (tmp_path / "fig10" / "report.json").write_text(json.dumps({"cells": [cell], "pairs": []}))
    assert [v for _, v in _verdicts(paper_goals.fig10(tmp_path))] == ([verdict] if verdict else [])


def test_missing_inputs_are_named_and_bad_ones_refused_in_one_line(tmp_path, capsys):
    assert mpcde("paper", "goals", tmp_path) == 0
    out = capsys.readouterr().out
    assert out.count("<!-- ") == 5 and "| Table III" not in out  # nothing flown here: said, not invented
    _fig10_akf(tmp_path)
    report = tmp_path / "fig10" / "report.json"
    for text in ("{not json", json.dumps({"cells": [{"values": {}}]})):
        report.write_text(text)
        assert mpcde("paper", "goals", tmp_path) == 2
        out, err = capsys.readouterr()
        assert out == "" and err.startswith("mpcde: error: ") and err.count("\n") == 1, err
    report.write_text(json.dumps({"cells": [], "pairs": []}))
    fig6 = tmp_path / "fig6" / "report.json"
    fig6.parent.mkdir()
    for text in (json.dumps({"stores": [], "cells": [], "pairs": [], "shared_overrides": {}}),  # no store: IndexError
                 json.dumps({"stores": [{"name": "a"}], "cells": [{"store": "b", "flights": 1, "settings": []}], "pairs": [], "shared_overrides": {}})):
        fig6.write_text(text)
        assert mpcde("paper", "goals", tmp_path) == 2
        out, err = capsys.readouterr()
        assert out == "" and err.startswith("mpcde: error: fig6: ") and err.count("\n") == 1, err
    fig6.unlink()
    fig6.mkdir()  # a folder where the report should be
    assert mpcde("paper", "goals", tmp_path) == 2
    assert capsys.readouterr().err.startswith("mpcde: error: fig6: IsADirectoryError=")


KEPT = ROOT / "docs" / "results" / "stores"
FIG6_KEPT = ["fig6_denied_portable", "fig6_auto_portable", "fig6_fresh_portable", "fig6_fresh2_portable", "fig6_dmpc_portable", "fig6_minco_portable"]


def test_the_goals_of_the_kept_stores_stand_verbatim_in_mp_cde_md(tmp_path, monkeypatch, unpack_kept_store, capsys):
    """mp-cde.md's goals table is `mpcde paper goals`' output on the stores kept in the repository, built as the doc's
    commands build them (the same inputs as the summary's kept rows, and the swarm ablation's pair report)."""
    from mpcde.sweep.cross_report import build_cross_report
    from mpcde.sweep.report import build_report
    from mpcde.sweep.store import json_safe

    monkeypatch.chdir(tmp_path)
    runs = Path("runs")
    unpack_kept_store("fig10_portable", runs / "fig10")
    (runs / "fig10" / "report.json").write_text(json.dumps(json_safe(build_report(runs / "fig10"))))
    for name in [*FIG6_KEPT, "fig6_modes"]:
        unpack_kept_store(name, runs / name)
    for out, names in (("fig6", FIG6_KEPT), ("fig6_modes_vs", ["fig6_denied_portable", "fig6_modes"])):
        (runs / out).mkdir()
        (runs / out / "report.json").write_text(json.dumps(json_safe(build_cross_report([f"runs/{n}" for n in names]))))
    unpack_kept_store("table3_portable", runs / "table3")
    (runs / "akf_pipeline").mkdir()
    shutil.copy(KEPT / "akf_pipeline_portable" / "results.json", runs / "akf_pipeline" / "results.json")
    rows = paper_goals.table3(runs) + paper_goals.fig6(runs) + paper_goals.swarm_modes(runs) + paper_goals.fig10(runs) + paper_goals.akf(runs)
    assert mpcde("paper", "goals", runs) == 0
    assert capsys.readouterr().out == "\n".join(paper_goals.HEAD + rows) + "\n"
    assert len(rows) == 9 + 3 * 2 * 3 + 3 + 2 + 5  # Table III, MP-CDE and two variants (success, paired), the swarm, Fig. 10, AKF
    doc = (ROOT / "docs" / "results" / "mp-cde.md").read_text()
    missing = [row for row in rows if row not in doc]
    assert not missing, f"mp-cde.md lacks the kept stores' goal rows: {missing}"


@pytest.mark.parametrize("argv", [["a", "b"], ["--runs", "x"]])
def test_arguments_are_one_runs_folder(argv, capsys):
    assert mpcde("paper", "goals", *argv) == 2
    out, err = capsys.readouterr()
    assert out == "" and err.startswith("mpcde: error: unrecognized arguments: ") and err.count("\n") == 1
