"""scripts/table3_report.py and scripts/paper_summary.py read their numbers from the stores (issue 28, deliverable 4)."""

from __future__ import annotations

import contextlib
import io
import json
import math
import shutil
import subprocess
import sys
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

SCRIPTS = Path(__file__).resolve().parents[3] / "scripts"
sys.path.insert(0, str(SCRIPTS))
import paper_summary  # noqa: E402
import table3_report  # noqa: E402
from sweep_stores import write_store  # noqa: E402  (tests/unit/scripts/sweep_stores.py)

YAWS = [{"method": "zhou"}, {"exploring_mode": False}, {"tracking_mode": False}, {}]
AREAS = {0: [500.0, 520.0], 1: [400.0, 410.0], 2: [505.0, 515.0], 3: [440.0, 460.0]}  # per cell (method), two seeds


def _table3_store(root: Path) -> Path:
    axes = [["world.obstacle_density_per_100m2", [4.0]], ["denied.yaw", YAWS]]
    rows = []
    for cell, areas in AREAS.items():
        for seed, area in enumerate(areas):
            ok = not (cell == 3 and seed == 1)  # one failure, in "ours"
            rows.append({"cell": cell, "seed": seed, "metrics": {"observed_area_swarm_m2": area, "success": ok}})
    rows.append({"cell": 0, "seed": 2, "metrics": None})  # a failed flight is left out
    return write_store(root / "table3", axes, rows)


def test_table3_cells_and_margin_come_from_the_store(tmp_path):
    table = table3_report.cells(_table3_store(tmp_path))
    assert [c["method"] for c in table] == ["zhou", "no_exploring", "no_tracking", "ours"]
    ours = table[3]
    assert (ours["flights"], ours["successes"], ours["s_obs_mean_m2"]) == (2, 1, 450.0)
    assert ours["s_obs_sd_m2"] == pytest.approx(math.sqrt(200.0))
    assert ours["paper_s_obs_m2"] == 167.5 and table[2]["paper_s_obs_m2"] is None
    assert table3_report.margins(table) == [(0, 4.0, 450.0, 510.0)]


def test_table3_pairs_seeds_and_tests_them_against_the_exact_wilcoxon_distribution(tmp_path):
    """Ours against Zhou's over five paired seeds, ours larger on every one: the exact two-sided signed-rank p is
    2 / 2^5 = 0.0625; a seed flown by one method only is left out of the pair; modes are averaged over flights."""
    axes = [["world.obstacle_density_per_100m2", [8.0]], ["denied.yaw", YAWS]]
    half = {"exploring": 0.5, "observing": 0.0, "tracking": 0.5}

    def row(cell, seed, area, mode):  # noqa: ANN001, ANN202
        return {"cell": cell, "seed": seed, "metrics": {"observed_area_swarm_m2": float(area), "success": True, "agents": [{"yaw_mode_fraction": mode}]}}

    # ours flew seed 0, which Zhou's did not: pairing by position instead of by seed would shift every pair
    rows = [row(3, 0, 1.0, half)]
    for seed, (zhou, ours) in enumerate([(100, 103), (100, 101), (100, 110), (100, 104), (100, 102)], start=1):
        rows.append(row(0, seed, zhou, {"exploring": 1.0, "observing": 0.0, "tracking": 0.0}))
        rows.append(row(3, seed, ours, {"exploring": 0.0, "observing": 0.0, "tracking": 1.0} if seed == 1 else half))
    rows.append(row(3, 6, 1.0, None))  # a flight that made no yaw plan records no shares: left out of the mean
    table = table3_report.cells(write_store(tmp_path / "t3", axes, rows))
    [pair] = table3_report.paired(table, "ours", "zhou")
    assert (pair["seeds"], pair["a_larger"], pair["mean_diff_m2"]) == (5, 5, pytest.approx(4.0))
    assert pair["p"] == pytest.approx(0.0625)
    assert table3_report.paired(table, "ours", "no_exploring") == []  # not flown
    assert table[3]["modes"]["tracking"] == pytest.approx((0.5 + 1.0 + 4 * 0.5) / 6)
    text = table3_report.render(table)
    assert "  density 8: ours - Zhou's [26]: mean +4.0 m^2, ours larger on 5 of 5, equal on 0, p = 0.062\n" in text
    assert "  density 8, Zhou's [26]: 1.00 / 0.00 / 0.00\n" in text


def test_table3_report_reads_the_store_as_mpcde_report_does(tmp_path, capsys):
    """A last line cut short (a sweep still running, or a crash) is left out. Bad input stops the script with one
    line on stderr naming what is wrong, exit status 2 and nothing on stdout: wrong arguments, a folder without
    sweep.json or without results.jsonl (a kept store still packed is named as such), a corrupt row, a sweep whose
    axes are not Table III's, a flight without S_obs. paper_summary refuses a corrupt store the same way, leaves out
    a store with no flight yet, and gives no row to a cell not flown."""
    store = _table3_store(tmp_path)
    whole = table3_report.cells(store)
    with open(store / "results.jsonl", "a") as f:
        f.write('{"cell": 3, "seed": 9, "metr')  # no newline: a partial row
    assert table3_report.cells(store) == whole
    assert table3_report.main([str(store)]) == 0 and capsys.readouterr().out == table3_report.render(whole)

    def refused(argv: list[str], *needles: str) -> None:
        assert table3_report.main(argv) == 2
        out, err = capsys.readouterr()
        assert out == "" and err.startswith("table3_report: error: ") and err.count("\n") == 1, err
        assert all(n in err for n in needles), err

    refused([], "arguments=[]", "one or more STORE_DIR")
    refused([str(store), str(tmp_path / "x")], "x", "no sweep.json")
    refused(["-h"], "arguments=['-h']")
    refused([str(tmp_path / "nowhere")], "nowhere", "no sweep.json")
    packed = write_store(tmp_path / "packed", [], [])
    (packed / "results.jsonl").rename(packed / "results.jsonl.gz")
    refused([str(packed)], "results.jsonl.gz", "gunzip")
    (packed / "results.jsonl.gz").unlink()
    refused([str(packed)], "no results.jsonl", "at least one flight")
    density = ["world.obstacle_density_per_100m2", [4.0]]
    swapped, extra = [["denied.yaw", YAWS], density], [density, ["denied.yaw", YAWS], ["seed_offset", [0]]]
    for i, axes in enumerate(([["planner.cruise_speed_mps", [1.0]]], swapped, extra)):
        refused([str(write_store(tmp_path / f"axes{i}", axes, []))], "sweep.axes=", "a Table III sweep")
    no_area = write_store(tmp_path / "no_area", [density, ["denied.yaw", YAWS]], [{"cell": 1, "seed": 4, "metrics": {"success": True}}])
    refused([str(no_area)], "line 1 (cell 1 seed 4): metrics=['observed_area_swarm_m2']")
    text = (store / "results.jsonl").read_text()
    (store / "results.jsonl").write_text(text.replace("\n", "\nnot json\n", 1))
    refused([str(store)], "store line 2", "corrupt")
    assert paper_summary.main([str(tmp_path)]) == 2
    out, err = capsys.readouterr()
    assert out == "" and err.startswith("paper_summary: error: store line 2=") and err.count("\n") == 1
    assert paper_summary.main([str(tmp_path), "x"]) == 2 and "at most one RUNS_DIR" in capsys.readouterr().err
    (store / "results.jsonl").unlink()  # no flight recorded yet: left out, said
    assert paper_summary.main([str(tmp_path)]) == 0
    out = capsys.readouterr().out
    assert "<!-- table3: " in out and "results.jsonl missing -->" in out and "| Table III" not in out
    (store / "results.jsonl").write_text(text)
    (tmp_path / "fig10").mkdir()
    (tmp_path / "fig10" / "report.json").write_text("{not json")
    assert paper_summary.main([str(tmp_path)]) == 2
    assert capsys.readouterr().err.startswith(f"paper_summary: error: {tmp_path / 'fig10' / 'report.json'}=")


KEYS = st.sampled_from(["method", "free_distance", "exploring_mode", "tracking_mode", "exploring", "tracking", "zhou", "occupied"]) | st.text(max_size=6)
JSON = st.recursive(st.none() | st.booleans() | st.integers() | st.floats() | st.text(max_size=8) | st.sampled_from(["zhou", "mpcde", "occupied", "voxel"]),
                    lambda inner: st.lists(inner, max_size=3) | st.dictionaries(KEYS, inner, max_size=3), max_leaves=6)
FIELDS = [("cell",), ("seed",), ("metrics",), ("metrics", "observed_area_swarm_m2"), ("metrics", "success"), ("metrics", "agents"),
          ("metrics", "agents", 0), ("metrics", "agents", 0, "yaw_mode_fraction"), ("metrics", "agents", 0, "yaw_mode_fraction", "tracking")]


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(field=st.sampled_from(FIELDS), value=JSON, axis=st.booleans())
def test_table3_report_answers_any_value_in_a_store_with_a_report_or_one_line(tmp_path_factory, field, value, axis):
    """Property: whatever JSON value stands in one field a Table III report reads (a row's cell, seed or metrics, or
    one axis value of the sweep), the script prints a report (exit 0) or one line on stderr (exit 2): never a
    traceback, never both."""
    root = tmp_path_factory.mktemp("prop")
    axes = [["world.obstacle_density_per_100m2", [4.0, 8.0]], ["denied.yaw", list(YAWS)]]
    share = {"exploring": 0.25, "observing": 0.0, "tracking": 0.75}
    rows = [{"cell": c, "seed": 0, "metrics": {"observed_area_swarm_m2": 100.0 + c, "success": True, "agents": [{"yaw_mode_fraction": dict(share)}]}}
            for c in range(8)]  # fmt: skip
    if axis:
        axes[len(field) % 2][1][0] = value
    else:
        target = rows[3]
        for key in field[:-1]:
            target = target[key]
        target[field[-1]] = value
    store = write_store(root / "t3", axes, rows)
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        code = table3_report.main([str(store)])
    if code == 0:
        assert out.getvalue().startswith("density /100m^2") and err.getvalue() == ""
    else:
        assert code == 2 and out.getvalue() == "", err.getvalue()
        assert err.getvalue().startswith("table3_report: error: ") and err.getvalue().count("\n") == 1, err.getvalue()


def test_methods_under_another_reading_of_d_free_are_paired_within_their_reading(tmp_path, capsys):
    """Ours and Zhou's with Eq. 1's d_free read to the nearest occupied cell, flown in stores of their own, are
    methods of their own (every method's S(0) triggers replans): one table with the first store's cells, ordered by
    density then method; the margin and the paper's orderings are tested within one reading, and ours with the
    reading against ours with the default; the stores and their revisions close the report. Stores of different
    scenarios, a store given twice, two stores flying one cell, a method flown twice in one store and methods
    outside Table III are refused."""
    first = _table3_store(tmp_path)  # density 4: Zhou's 500 / 520, w/o exploring 400 / 410, ours 440 / 460
    density = ["world.obstacle_density_per_100m2", [4.0]]
    ours_occ, zhou_occ = {"method": "mpcde", "free_distance": "occupied"}, {"method": "zhou", "free_distance": "occupied"}

    def flights(cell: int, areas: tuple[float, float]) -> list[dict]:
        return [{"cell": cell, "seed": seed, "metrics": {"observed_area_swarm_m2": a, "success": True}} for seed, a in enumerate(areas)]

    second = write_store(tmp_path / "occupied", [density, ["denied.yaw", [ours_occ]]], flights(0, (530.0, 515.0)))
    third = write_store(tmp_path / "zhou_occupied", [density, ["denied.yaw", [zhou_occ]]], flights(0, (490.0, 500.0)))
    table = table3_report.merged_cells([third, second, first])  # any order: the table's is density, reading, method
    assert [c["method"] for c in table] == ["zhou", "no_exploring", "no_tracking", "ours", "zhou/occupied", "ours/occupied"]
    assert table3_report.pairs_of(table) == [("ours", "zhou"), ("ours", "no_exploring"), ("ours/occupied", "zhou/occupied"),
                                             ("ours/occupied", "no_exploring/occupied"), ("ours/occupied", "ours")]  # fmt: skip
    assert table3_report.main([str(first), str(second), str(third)]) == 0
    out = capsys.readouterr().out
    printed = out.split("\n\n")[0].splitlines()
    w = len("Zhou's [26], d_free to occupied")  # the method column widens to the longest name
    assert printed[4].startswith(f"{4:>15}  {'ours':<{w}} {2:>7}  {450.0:>12.1f} +- {14.1:>5.1f}      50%")
    assert printed[5].startswith(f"{4:>15}  {'Zhou' + chr(39) + 's [26], d_free to occupied':<{w}} {2:>7}  {495.0:>12.1f} +- {7.1:>5.1f}     100%")
    assert printed[6].startswith(f"{4:>15}  {'ours, d_free to occupied':<{w}} {2:>7}  {522.5:>12.1f} +- {10.6:>5.1f}     100%")
    assert "  density 4, both d_free to occupied: +5.6 % (+17 %)\n" in out  # 522.5 / 495
    assert "  density 4: ours, d_free to occupied - Zhou's [26], d_free to occupied: mean +27.5 m^2," in out
    assert "  density 4: ours, d_free to occupied - ours: mean +72.5 m^2" in out
    assert "ours, d_free to occupied - Zhou's [26]:" not in out  # no pair across readings but ours against ours
    assert out.endswith("\nstores (the revisions their flights recorded): table3 (0000000), zhou_occupied (0000000), occupied (0000000)\n")
    assert table3_report.render(table3_report.merged_cells([first])) == table3_report.render(table3_report.cells(first))

    def refused(argv: list[str], *needles: str) -> None:
        assert table3_report.main(argv) == 2
        out, err = capsys.readouterr()
        assert out == "" and err.count("\n") == 1 and all(n in err for n in needles), err

    refused([str(first), str(tmp_path / "table3" / ".")], "arguments=", "each store once")
    again = write_store(tmp_path / "again", [density, ["denied.yaw", [ours_occ]]], flights(0, (1.0, 2.0)))
    refused([str(second), str(again)], "again: sweep.axes[1][1]='ours, d_free to occupied'", "no earlier store flies (store occupied does)")
    other = write_store(tmp_path / "other_range", [density, ["denied.yaw", [ours_occ]]], flights(0, (1.0, 2.0)), overrides={"camera.depth_max_m": 4.5})
    refused([str(first), str(other)], "other_range: sweep.overrides=", "stores reported together fly one Table III")
    odd = write_store(tmp_path / "odd", [density, ["denied.yaw", [{"free_distance": "sideways"}]]], [])
    refused([str(odd)], "free_distance=['sideways']", "one of horizontal, occupied, voxel")
    twice = write_store(tmp_path / "twice", [density, ["denied.yaw", [{"method": "zhou"}, {"method": "zhou", "sensing_range_m": 4.5}]]], [])
    refused([str(twice)], "sweep.axes[1][1]=", "each method once per density")
    spin = write_store(tmp_path / "spin", [density, ["denied.yaw", [{"method": "spin"}]]], [])
    refused([str(spin)], "method=['spin']", "mpcde or zhou")
    stray = write_store(tmp_path / "stray", [density, ["denied.yaw", [ours_occ]]], flights(1, (1.0, 2.0)))
    refused([str(stray)], "line 1: cell=1", "< 1")


def test_a_table3_cell_not_flown_yet_has_no_summary_row(tmp_path):
    density = ["world.obstacle_density_per_100m2", [4.0, 8.0, 12.0, 16.0]]  # a fourth density, beyond the paper's three
    rows = [{"cell": c, "seed": 0, "metrics": {"observed_area_swarm_m2": 100.0 + c, "success": True}} for c in (0, 3, 12, 15)]
    write_store(tmp_path / "table3", [density, ["denied.yaw", YAWS]], rows)
    summary = paper_summary.table3(tmp_path)
    assert [r.split(" | ")[0] for r in summary] == [
        "| Table III, Zhou's [26], density 4", "| Table III, ours, density 4", "| Table III, Zhou's [26], density 16",
        "| Table III, ours, density 16", "| Table III, ours against Zhou's, density 4", "| Table III, ours against Zhou's, density 16"]
    assert summary[-1].startswith("| Table III, ours against Zhou's, density 16 | - | +2.7 % |")  # 115 / 112: no paper figure
    assert "(-)" in table3_report.render(table3_report.cells(tmp_path / "table3"))


def test_signed_rank_p_drops_equal_seeds_and_corrects_for_ties_in_closed_form():
    """Zeros are dropped (the five positive differences left give the exact 2 / 2^5); six equal positive differences
    (all tied, ranks 3.5) give the normal approximation with the tie correction: T+ = 21 against a mean of 10.5 and a
    variance of 6 * 7 * 13 / 24 - (6^3 - 6) / 48 = 18.375; under two non-zero differences there is no test."""
    from scipy.stats import norm

    assert table3_report.signed_rank_p([0.0, 3.0, 1.0, 10.0, 4.0, 2.0]) == pytest.approx(0.0625)
    assert table3_report.signed_rank_p([1.0] * 6) == pytest.approx(2 * norm.sf(10.5 / math.sqrt(18.375)))
    assert table3_report.signed_rank_p([0.0, 0.0, 1.0]) is None and table3_report.signed_rank_p([0.0, 0.0]) is None


def test_the_summary_prints_the_stores_numbers_and_names_what_is_missing(tmp_path):
    _table3_store(tmp_path)
    (tmp_path / "akf_pipeline").mkdir()
    rows = [{"speed_mps": 0.5, "filter": "akf", "pos_rmse_m": 0.0477, "vel_rmse_mps": 0.1194}]
    (tmp_path / "akf_pipeline" / "results.json").write_text(json.dumps({"rows": rows}))
    out = subprocess.run([sys.executable, str(SCRIPTS / "paper_summary.py"), str(tmp_path)], capture_output=True, text=True, check=True).stdout
    lines = out.splitlines()
    assert lines[0].startswith("| paper figure | paper | ours | command | commit | date |")
    assert "| Table III, ours, density 4 | 167.5 m^2 | 450.0 +- 14.1 m^2, success 1 of 2 |" in out
    assert "| Table III, ours against Zhou's, density 4 | +17 % | -11.8 % |" in out  # 450 / 510 - 1
    assert "| AKF vs KF, AKF at 0.5 m/s | 0.06 m, 0.25 m/s | position 0.048 m, velocity 0.119 m/s |" in out
    assert "<!-- fig10:" in out and "<!-- fig6:" in out  # no such reports here: said, not invented
    assert paper_summary.revisions(tmp_path / "table3")[0] == "0000000"


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
    rows = paper_summary.fig6(tmp_path)
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
    head = subprocess.run(["git", "-C", str(SCRIPTS), "rev-parse", "HEAD"], capture_output=True, text=True, check=True).stdout.strip()
    date = subprocess.run(["git", "-C", str(SCRIPTS), "show", "-s", "--format=%cs", head], capture_output=True, text=True, check=True).stdout.strip()
    (tmp_path / "akf_pipeline").mkdir()
    rows = [{"speed_mps": 2.0, "filter": "kf", "pos_rmse_m": 0.1, "vel_rmse_mps": 0.5}]
    for rev, cited in ((head, f"{head[:7]} | {date}"), (head + "+dirty", f"{head[:7]}+dirty | {date}"), (None, "not recorded | -")):
        results = {"rows": rows, "run": {"seeds": [0], "duration_s": 30.0, "version": "0", "git_rev": rev}}
        (tmp_path / "akf_pipeline" / "results.json").write_text(json.dumps(results))
        assert paper_summary.akf(tmp_path) == [
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
    assert paper_summary.fig6(tmp_path) == [
        "| Fig. 6, MP-CDE at 1 m/s | about 95 % | 94 % (88-97 %) of 100, 0.06 collisions per flight "
        "| `mpcde sweep data/sweeps/forest_swarm_denied.yaml` | 0000000 | ? |"
    ]


KEPT = SCRIPTS.parent / "docs" / "results" / "stores"
FIG10_KEPT = "fig10_portable"
# MP-CDE's row first, then what is paired with it; each store's cells (one per speed, two for the MINCO baseline's delays)
FIG6_KEPT = {"fig6_denied_portable": 3, "fig6_auto_portable": 3, "fig6_fresh_portable": 3, "fig6_fresh2_portable": 3, "fig6_dmpc_portable": 3,
             "fig6_minco_portable": 6}
# of those, stores of the denied stack itself (look before moving, at 4b48cfa and bd495e1): MP-CDE's rows of their own,
# and each is ranked against the view-gated baselines too
FIG6_VARIANTS = 2
FIG6_BASELINES = ["fig6_dmpc_portable", "fig6_minco_portable"]  # flown over the view-gated radio
TABLE3_KEPT = "table3_portable"
# every kept Table III store (or stores of one Table III, reported together) whose whole report mp-cde.md pastes
TABLE3_REPORTED = [
    ("table3_portable",),
    ("table3_fuel",),
    ("table3_fuel_2mps",),
    ("table3_fuel", "table3_fuel_occupied", "table3_fuel_occupied_baselines", "table3_fuel_occupied_no_tracking"),
    ("table3_portable", "table3_occupied"),
]
AKF_KEPT = "akf_pipeline_portable"


def test_the_summary_rows_of_the_kept_stores_stand_verbatim_in_mp_cde_md(tmp_path, monkeypatch, unpack_kept_store):
    """docs/results/mp-cde.md's summary rows for Fig. 10, Fig. 6 (MP-CDE and the stores kept beside it), Table III
    and AKF vs KF are this script's output on the stores and results kept in the repository, not typed (issue 28,
    deliverable 4). The Fig. 6 report is built as its command in the rows names it, from runs/."""
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
    doc = (SCRIPTS.parent / "docs" / "results" / "mp-cde.md").read_text()
    rows = paper_summary.fig10(runs) + paper_summary.fig6(runs) + paper_summary.table3(runs) + paper_summary.akf(runs)
    paired = sum(FIG6_KEPT.values()) - 3  # every cell of every other store, paired with MP-CDE's
    assert len(rows) == 2 + 3 + 3 * FIG6_VARIANTS + paired + FIG6_VARIANTS * sum(FIG6_KEPT[b] for b in FIG6_BASELINES) + 12 + 3 + 6
    missing = [row for row in rows if row not in doc]
    assert not missing, f"mp-cde.md lacks the kept stores' summary rows: {missing}"


@pytest.mark.parametrize("names", TABLE3_REPORTED, ids="+".join)
def test_the_table3_report_of_each_kept_store_stands_verbatim_in_mp_cde_md(tmp_path, unpack_kept_store, names):
    """mp-cde.md pastes scripts/table3_report.py's whole output for each kept Table III store, or stores reported
    together (the cell table, the margins, the paired tests and the modes): pasted from the script, not typed
    (issue 28, deliverable 4)."""
    text = table3_report.render(table3_report.merged_cells([unpack_kept_store(name, tmp_path / name) for name in names]))
    doc = (SCRIPTS.parent / "docs" / "results" / "mp-cde.md").read_text()
    assert text in doc, f"mp-cde.md lacks table3_report.py's output for {' '.join(names)}"
