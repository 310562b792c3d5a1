"""The paper summary reads its numbers from the stores (mpcde.paper.summary, `mpcde paper summary`; issue 28,
deliverable 4), and mp-cde.md holds its rows on the kept stores verbatim."""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
from pathlib import Path

from sweep_stores import YAWS, mpcde, table3_store, write_store  # tests/unit/mpcde/paper/sweep_stores.py

from mpcde.paper import summary

ROOT = Path(__file__).resolve().parents[4]
KEPT = ROOT / "docs" / "results" / "stores"


def test_a_corrupt_input_is_one_line_and_a_missing_one_is_named(tmp_path, capsys):
    """A corrupt store stops the summary with one line on stderr and nothing on stdout (exit 2), as does a report
    that is not JSON; a store with no flight yet is left out and said to be; more than one RUNS_DIR is refused."""
    store = table3_store(tmp_path)
    text = (store / "results.jsonl").read_text()
    (store / "results.jsonl").write_text(text.replace("\n", "\nnot json\n", 1))
    assert mpcde("paper", "summary", tmp_path) == 2
    out, err = capsys.readouterr()
    assert out == "" and err.startswith("mpcde: error: store line 2=") and err.count("\n") == 1
    assert mpcde("paper", "summary", tmp_path, "x") == 2 and "unrecognized arguments: x" in capsys.readouterr().err
    (store / "results.jsonl").unlink()  # no flight recorded yet: left out, said
    assert mpcde("paper", "summary", tmp_path) == 0
    out = capsys.readouterr().out
    assert "<!-- table3: " in out and "results.jsonl missing -->" in out and "| Table III" not in out
    (store / "results.jsonl").write_text(text)
    (tmp_path / "fig10").mkdir()
    (tmp_path / "fig10" / "report.json").write_text("{not json")
    assert mpcde("paper", "summary", tmp_path) == 2
    assert capsys.readouterr().err.startswith(f"mpcde: error: {tmp_path / 'fig10' / 'report.json'}=")


def test_a_table3_cell_not_flown_yet_has_no_summary_row(tmp_path):
    density = ["world.obstacle_density_per_100m2", [4.0, 8.0, 12.0, 16.0]]  # a fourth density, beyond the paper's three
    rows = [{"cell": c, "seed": 0, "metrics": {"observed_area_swarm_m2": 100.0 + c, "success": True}} for c in (0, 3, 12, 15)]
    write_store(tmp_path / "table3", [density, ["denied.yaw", YAWS]], rows)
    rows = summary.table3(tmp_path)
    assert [r.split(" | ")[0] for r in rows] == [
        "| Table III, Zhou's [26], density 4", "| Table III, ours, density 4", "| Table III, Zhou's [26], density 16",
        "| Table III, ours, density 16", "| Table III, ours against Zhou's, density 4", "| Table III, ours against Zhou's, density 16"]
    assert rows[-1].startswith("| Table III, ours against Zhou's, density 16 | - | +2.7 % |")  # 115 / 112: no paper figure


def test_the_summary_prints_the_stores_numbers_and_names_what_is_missing(tmp_path):
    table3_store(tmp_path)
    (tmp_path / "akf_pipeline").mkdir()
    rows = [{"speed_mps": 0.5, "filter": "akf", "pos_rmse_m": 0.0477, "vel_rmse_mps": 0.1194}]
    (tmp_path / "akf_pipeline" / "results.json").write_text(json.dumps({"rows": rows}))
    out = subprocess.run([sys.executable, "-m", "mpcde", "paper", "summary", str(tmp_path)], capture_output=True, text=True, check=True).stdout
    lines = out.splitlines()
    assert lines[0].startswith("| paper figure | paper | ours | command | commit | date |")
    assert "| Table III, ours, density 4 | 167.5 m^2 | 450.0 +- 14.1 m^2, success 1 of 2 |" in out
    assert "| Table III, ours against Zhou's, density 4 | +17 % | -11.8 % |" in out  # 450 / 510 - 1
    assert "| AKF vs KF, AKF at 0.5 m/s | 0.06 m, 0.25 m/s | position 0.048 m, velocity 0.119 m/s |" in out
    assert "<!-- fig10:" in out and "<!-- fig6:" in out  # no such reports here: said, not invented
    assert summary.revisions(tmp_path / "table3")[0] == "0000000"


def test_fig6_ranks_only_view_gated_baselines_and_sets_others_beside(tmp_path):
    """The paper's Fig. 6 comparison is MP-CDE against view-gated baselines; a store flown over the scenario's
    own radio (auto) is listed beside MP-CDE, not as a baseline it must beat."""
    stores = []
    base = {"duration_s": 100}
    for name, overrides in (("denied", base), ("gated", {**base, "radio.view_gated": True}), ("auto", base), ("levels", {**base, "denied.flight_level_spacing_m": 0.4})):
        write_store(tmp_path / name, [], [{"cell": 0, "seed": 0, "metrics": {"success": True}}])
        stores.append({"name": name, "folder": str(tmp_path / name), "overrides": overrides})
    cell = {"flights": 30, "success_rate": 0.9, "success_low": 0.74, "success_high": 0.97, "collisions_per_flight": 0.1}
    cells = []
    for store, values in (("denied", {"planner.kind": "mpcde"}), ("gated", {"planner.kind": "dmpc"}), ("auto", {"planner.kind": "auto"}), ("levels", {"planner.kind": "mpcde"})):
        values = {**values, "planner.cruise_speed_mps": 1.0}  # as `mpcde report` writes a cell: settings = store overrides + axis values
        cells.append({**cell, "store": store, "values": values, "settings": {**next(s["overrides"] for s in stores if s["name"] == store), **values}})
    pair = {"a_success_paired": 27, "b_success_paired": 3, "paired_seeds": 30, "mcnemar_p": 1e-6}
    unpaired = {**pair, "a": 0, "b": 1, "paired_seeds": 0, "a_success_paired": 0, "b_success_paired": 0}  # a cell not flown yet
    report = {"stores": stores, "shared_overrides": base, "cells": cells,
              "pairs": [{**pair, "a": 0, "b": 1}, {**pair, "a": 0, "b": 2}, {**pair, "a": 0, "b": 3, "b_success_paired": 1}, unpaired,
                        {**pair, "a": 2, "b": 3},  # auto x the variant: no row (auto is not a baseline)
                        {**pair, "a": 1, "b": 3, "a_success_paired": 3, "b_success_paired": 30}]}  # the view-gated baseline x the variant
    (tmp_path / "fig6").mkdir()
    (tmp_path / "fig6" / "report.json").write_text(json.dumps(report))
    rows = summary.fig6(tmp_path)
    assert len(rows) == 6
    assert rows[0].startswith("| Fig. 6, MP-CDE at 1 m/s | about 95 % | 90 % (74-97 %) of 30, 0.10 collisions per flight |")
    # a variant of the denied stack (a store of planner.kind mpcde set apart by a store-wide override) has MP-CDE's rows too
    assert rows[1].startswith("| Fig. 6, MP-CDE with denied.flight_level_spacing_m=0.4 at 1 m/s | about 95 % | 90 % (74-97 %) of 30, 0.10 collisions per flight | (same) |")
    assert rows[2].startswith("| Fig. 6, baseline at 1 m/s | below MP-CDE | gated (planner.kind=dmpc), view-gated: 3 successes against MP-CDE's 27 on 30")
    assert rows[3].startswith("| Fig. 6, beside at 1 m/s | - | auto (planner.kind=auto), scenario's radio (not view-gated): 3 successes")
    # a store set apart by a store-wide override, not an axis (flight levels), says so in its row
    assert rows[4].startswith("| Fig. 6, beside at 1 m/s | - | levels (denied.flight_level_spacing_m=0.4, planner.kind=mpcde), the denied stack (no radio): 1 success against")
    # a variant of the denied stack is ranked against the view-gated baselines too (not against auto)
    assert rows[5].startswith("| Fig. 6, baseline at 1 m/s | below MP-CDE | gated (planner.kind=dmpc), view-gated: 3 successes against 30 of "
                              "MP-CDE with denied.flight_level_spacing_m=0.4 (levels) on 30 paired seeds, McNemar p = 1e-06 | (same) |")


def test_the_akf_rows_cite_the_revision_eval_tracking_recorded(tmp_path):
    head = subprocess.run(["git", "-C", str(ROOT), "rev-parse", "HEAD"], capture_output=True, text=True, check=True).stdout.strip()
    date = subprocess.run(["git", "-C", str(ROOT), "show", "-s", "--format=%cs", head], capture_output=True, text=True, check=True).stdout.strip()
    (tmp_path / "akf_pipeline").mkdir()
    rows = [{"speed_mps": 2.0, "filter": "kf", "pos_rmse_m": 0.1, "vel_rmse_mps": 0.5}]
    for rev, cited in ((head, f"{head[:7]} | {date}"), (head + "+dirty", f"{head[:7]}+dirty | {date}"), (None, "not recorded | -")):
        results = {"rows": rows, "run": {"seeds": [0], "duration_s": 30.0, "version": "0", "git_rev": rev}}
        (tmp_path / "akf_pipeline" / "results.json").write_text(json.dumps(results))
        assert summary.akf(tmp_path) == [
            f"| AKF vs KF, KF at 2 m/s | - | position 0.100 m, velocity 0.500 m/s | `mpcde eval-tracking --measurements pipeline --seeds 10` | {cited} |"
        ]


def test_a_single_store_report_gives_mp_cde_rows_only_and_skips_unflown_cells(tmp_path):
    """The denied sweep's store reported alone (no baselines kept beside it) still gives MP-CDE's rows."""
    write_store(tmp_path / "fig6", [], [{"cell": 1, "seed": 0, "metrics": {"success": True}}])
    flown = {"flights": 100, "success_rate": 0.94, "success_low": 0.875, "success_high": 0.97, "collisions_per_flight": 0.06}
    empty = {"flights": 0, "success_rate": None, "success_low": None, "success_high": None, "collisions_per_flight": None}
    cells = [{**empty, "values": {"planner.kind": "mpcde", "planner.cruise_speed_mps": 0.5}},
             {**flown, "values": {"planner.kind": "mpcde", "planner.cruise_speed_mps": 1.0}}]  # fmt: skip
    (tmp_path / "fig6" / "report.json").write_text(json.dumps({"cells": cells, "pairs": []}))
    assert summary.fig6(tmp_path) == [
        "| Fig. 6, MP-CDE at 1 m/s | about 95 % | 94 % (88-97 %) of 100, 0.06 collisions per flight "
        "| `mpcde sweep data/sweeps/forest_swarm_denied.yaml` | 0000000 | ? |"
    ]


FIG10_KEPT = "fig10_portable"
# MP-CDE's row first, then what is paired with it; each store's cells (one per speed, two for the MINCO baseline's delays)
FIG6_KEPT = {"fig6_denied_portable": 3, "fig6_auto_portable": 3, "fig6_fresh_portable": 3, "fig6_fresh2_portable": 3, "fig6_dmpc_portable": 3,
             "fig6_minco_portable": 6}
# of those, stores of the denied stack itself (look before moving): MP-CDE's rows of their own, and each is ranked
# against the view-gated baselines too
FIG6_VARIANTS = 2
FIG6_BASELINES = ["fig6_dmpc_portable", "fig6_minco_portable"]  # flown over the view-gated radio
TABLE3_KEPT = "table3_portable"
AKF_KEPT = "akf_pipeline_portable"


def test_the_summary_rows_of_the_kept_stores_stand_verbatim_in_mp_cde_md(tmp_path, monkeypatch, unpack_kept_store, capsys):
    """The summary rows of docs/results/mp-cde.md#the-paper-beside-ours-in-one-table for Fig. 10, Fig. 6 (MP-CDE and
    the stores kept beside it), Table III and AKF vs KF are `mpcde paper summary`'s output on the stores and results kept in the repository, not typed
    (issue 28, deliverable 4). The Fig. 6 report is built as its command in the rows names it, from runs/."""
    from mpcde.sweep.cross_report import build_cross_report
    from mpcde.sweep.report import build_report
    from mpcde.sweep.store import json_safe

    monkeypatch.chdir(tmp_path)  # the cross-store report records its folders as given: runs/NAME, as in the doc
    runs = Path("runs")
    unpack_kept_store(FIG10_KEPT, runs / "fig10")
    (runs / "fig10" / "report.json").write_text(json.dumps(json_safe(build_report(runs / "fig10"))))
    for name in FIG6_KEPT:
        unpack_kept_store(name, runs / name)
    (runs / "fig6").mkdir()
    report = build_cross_report([f"runs/{name}" for name in FIG6_KEPT])  # as `mpcde report runs/A runs/B --out runs/fig6`
    (runs / "fig6" / "report.json").write_text(json.dumps(json_safe(report)))
    unpack_kept_store(TABLE3_KEPT, runs / "table3")
    (runs / "akf_pipeline").mkdir()
    shutil.copy(KEPT / AKF_KEPT / "results.json", runs / "akf_pipeline" / "results.json")
    doc = (ROOT / "docs" / "results" / "mp-cde.md").read_text()
    assert mpcde("paper", "summary") == 0  # RUNS_DIR defaults to runs/
    rows = capsys.readouterr().out.splitlines()[2:]
    assert rows == summary.fig10(runs) + summary.fig6(runs) + summary.table3(runs) + summary.akf(runs)
    paired = sum(FIG6_KEPT.values()) - 3  # every cell of every other store, paired with MP-CDE's
    assert len(rows) == 2 + 3 + 3 * FIG6_VARIANTS + paired + FIG6_VARIANTS * sum(FIG6_KEPT[b] for b in FIG6_BASELINES) + 12 + 3 + 6
    missing = [row for row in rows if row not in doc]
    assert not missing, f"mp-cde.md lacks the kept stores' summary rows: {missing}"
