"""Table III from the stores (mpcde.paper.table3, `mpcde paper table3`; issue 28, deliverable 4), and mp-cde.md
holds its whole output on every kept Table III store verbatim."""

from __future__ import annotations

import contextlib
import io
import math
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from sweep_stores import YAWS, mpcde, table3_store, write_store  # tests/unit/mpcde/paper/sweep_stores.py

from mpcde.paper import table3

DOC = Path(__file__).resolve().parents[4] / "docs" / "results" / "mp-cde.md"


def test_table3_cells_and_margin_come_from_the_store(tmp_path):
    table = table3.cells(table3_store(tmp_path))
    assert [c["method"] for c in table] == ["zhou", "no_exploring", "no_tracking", "ours"]
    ours = table[3]
    assert (ours["flights"], ours["successes"], ours["s_obs_mean_m2"]) == (2, 1, 450.0)
    assert ours["s_obs_sd_m2"] == pytest.approx(math.sqrt(200.0))
    assert ours["paper_s_obs_m2"] == 167.5 and table[2]["paper_s_obs_m2"] is None
    assert table3.margins(table) == [(0, 4.0, 450.0, 510.0)]


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
    table = table3.cells(write_store(tmp_path / "t3", axes, rows))
    [pair] = table3.paired(table, "ours", "zhou")
    assert (pair["seeds"], pair["a_larger"], pair["mean_diff_m2"]) == (5, 5, pytest.approx(4.0))
    assert pair["p"] == pytest.approx(0.0625)
    assert table3.paired(table, "ours", "no_exploring") == []  # not flown
    assert table[3]["modes"]["tracking"] == pytest.approx((0.5 + 1.0 + 4 * 0.5) / 6)
    text = table3.render(table)
    assert "  density 8: ours - Zhou's [26]: mean +4.0 m^2, ours larger on 5 of 5, equal on 0, p = 0.062\n" in text
    assert "  density 8, Zhou's [26]: 1.00 / 0.00 / 0.00\n" in text


def test_table3_reads_the_store_as_mpcde_report_does(tmp_path, capsys):
    """A last line cut short (a sweep still running, or a crash) is left out. Bad input stops the command with one
    line on stderr naming what is wrong, exit status 2 and nothing on stdout: no store, a folder without sweep.json
    or without results.jsonl (a kept store still packed is named as such), a corrupt row, a sweep whose axes are not
    Table III's, a flight without S_obs."""
    store = table3_store(tmp_path)
    whole = table3.cells(store)
    with open(store / "results.jsonl", "a") as f:
        f.write('{"cell": 3, "seed": 9, "metr')  # no newline: a partial row
    assert table3.cells(store) == whole
    assert mpcde("paper", "table3", store) == 0 and capsys.readouterr().out == table3.render(whole)

    def refused(argv: list, *needles: str) -> None:
        assert mpcde("paper", "table3", *argv) == 2
        out, err = capsys.readouterr()
        assert out == "" and err.startswith("mpcde: error: ") and err.count("\n") == 1, err
        assert all(n in err for n in needles), err

    refused([], "STORE_DIR")
    refused([store, tmp_path / "x"], "x", "no sweep.json")
    refused([store, "--no-such-option"], "unrecognized arguments: --no-such-option")
    refused([tmp_path / "nowhere"], "nowhere", "no sweep.json")
    packed = write_store(tmp_path / "packed", [], [])
    (packed / "results.jsonl").rename(packed / "results.jsonl.gz")
    refused([packed], "results.jsonl.gz", "gunzip")
    (packed / "results.jsonl.gz").unlink()
    refused([packed], "no results.jsonl", "at least one flight")
    density = ["world.obstacle_density_per_100m2", [4.0]]
    swapped, extra = [["denied.yaw", YAWS], density], [density, ["denied.yaw", YAWS], ["seed_offset", [0]]]
    for i, axes in enumerate(([["planner.cruise_speed_mps", [1.0]]], swapped, extra)):
        refused([write_store(tmp_path / f"axes{i}", axes, [])], "sweep.axes=", "a Table III sweep")
    no_area = write_store(tmp_path / "no_area", [density, ["denied.yaw", YAWS]], [{"cell": 1, "seed": 4, "metrics": {"success": True}}])
    refused([no_area], "line 1 (cell 1 seed 4): metrics=['observed_area_swarm_m2']")
    text = (store / "results.jsonl").read_text()
    (store / "results.jsonl").write_text(text.replace("\n", "\nnot json\n", 1))
    refused([store], "store line 2", "corrupt")


KEYS = st.sampled_from(["method", "free_distance", "exploring_mode", "tracking_mode", "exploring", "tracking", "zhou", "occupied"]) | st.text(max_size=6)
JSON = st.recursive(st.none() | st.booleans() | st.integers() | st.floats() | st.text(max_size=8) | st.sampled_from(["zhou", "mpcde", "occupied", "voxel"]),
                    lambda inner: st.lists(inner, max_size=3) | st.dictionaries(KEYS, inner, max_size=3), max_leaves=6)
FIELDS = [("cell",), ("seed",), ("metrics",), ("metrics", "observed_area_swarm_m2"), ("metrics", "success"), ("metrics", "agents"),
          ("metrics", "agents", 0), ("metrics", "agents", 0, "yaw_mode_fraction"), ("metrics", "agents", 0, "yaw_mode_fraction", "tracking")]


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(field=st.sampled_from(FIELDS), value=JSON, axis=st.booleans())
def test_table3_answers_any_value_in_a_store_with_a_report_or_one_line(tmp_path_factory, field, value, axis):
    """Property: whatever JSON value stands in one field a Table III report reads (a row's cell, seed or metrics, or
    one axis value of the sweep), the command prints a report (exit 0) or one line on stderr (exit 2): never a
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
        code = mpcde("paper", "table3", store)
    if code == 0:
        assert out.getvalue().startswith("density /100m^2") and err.getvalue() == ""
    else:
        assert code == 2 and out.getvalue() == "", err.getvalue()
        assert err.getvalue().startswith("mpcde: error: ") and err.getvalue().count("\n") == 1, err.getvalue()


def test_methods_under_another_reading_of_d_free_are_paired_within_their_reading(tmp_path, capsys):
    """Ours and Zhou's with Eq. 1's d_free read to the nearest occupied cell, flown in stores of their own, are
    methods of their own (every method's S(0) triggers replans): one table with the first store's cells, ordered by
    density then method; the margin and the paper's orderings are tested within one reading, and ours with the
    reading against ours with the default; the stores and their revisions close the report. Stores of different
    scenarios, a store given twice, two stores flying one cell, a method flown twice in one store and methods
    outside Table III are refused."""
    first = table3_store(tmp_path)  # density 4: Zhou's 500 / 520, w/o exploring 400 / 410, ours 440 / 460
    density = ["world.obstacle_density_per_100m2", [4.0]]
    ours_occ, zhou_occ = {"method": "mpcde", "free_distance": "occupied"}, {"method": "zhou", "free_distance": "occupied"}

    def flights(cell: int, areas: tuple[float, float]) -> list[dict]:
        return [{"cell": cell, "seed": seed, "metrics": {"observed_area_swarm_m2": a, "success": True}} for seed, a in enumerate(areas)]

    second = write_store(tmp_path / "occupied", [density, ["denied.yaw", [ours_occ]]], flights(0, (530.0, 515.0)))
    third = write_store(tmp_path / "zhou_occupied", [density, ["denied.yaw", [zhou_occ]]], flights(0, (490.0, 500.0)))
    table = table3.merged_cells([third, second, first])  # any order: the table's is density, reading, method
    assert [c["method"] for c in table] == ["zhou", "no_exploring", "no_tracking", "ours", "zhou/occupied", "ours/occupied"]
    assert table3.pairs_of(table) == [("ours", "zhou"), ("ours", "no_exploring"), ("ours/occupied", "zhou/occupied"),
                                      ("ours/occupied", "no_exploring/occupied"), ("ours/occupied", "ours")]  # fmt: skip
    assert mpcde("paper", "table3", first, second, third) == 0
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
    assert table3.render(table3.merged_cells([first])) == table3.render(table3.cells(first))

    def refused(argv: list, *needles: str) -> None:
        assert mpcde("paper", "table3", *argv) == 2
        out, err = capsys.readouterr()
        assert out == "" and err.count("\n") == 1 and all(n in err for n in needles), err

    refused([first, tmp_path / "table3" / "."], "arguments=", "each store once")
    again = write_store(tmp_path / "again", [density, ["denied.yaw", [ours_occ]]], flights(0, (1.0, 2.0)))
    refused([second, again], "again: sweep.axes[1][1]='ours, d_free to occupied'", "no earlier store flies (store occupied does)")
    other = write_store(tmp_path / "other_range", [density, ["denied.yaw", [ours_occ]]], flights(0, (1.0, 2.0)), overrides={"camera.depth_max_m": 4.5})
    refused([first, other], "other_range: sweep.overrides=", "stores reported together fly one Table III")
    odd = write_store(tmp_path / "odd", [density, ["denied.yaw", [{"free_distance": "sideways"}]]], [])
    refused([odd], "free_distance=['sideways']", "one of horizontal, occupied, voxel")
    twice = write_store(tmp_path / "twice", [density, ["denied.yaw", [{"method": "zhou"}, {"method": "zhou", "sensing_range_m": 4.5}]]], [])
    refused([twice], "sweep.axes[1][1]=", "each method once per density")
    spin = write_store(tmp_path / "spin", [density, ["denied.yaw", [{"method": "spin"}]]], [])
    refused([spin], "method=['spin']", "mpcde or zhou")
    stray = write_store(tmp_path / "stray", [density, ["denied.yaw", [ours_occ]]], flights(1, (1.0, 2.0)))
    refused([stray], "line 1: cell=1", "< 1")


def test_a_density_past_the_papers_three_has_no_paper_figure(tmp_path):
    density = ["world.obstacle_density_per_100m2", [4.0, 8.0, 12.0, 16.0]]
    rows = [{"cell": c, "seed": 0, "metrics": {"observed_area_swarm_m2": 100.0 + c, "success": True}} for c in (0, 3, 12, 15)]
    write_store(tmp_path / "table3", [density, ["denied.yaw", YAWS]], rows)
    assert "(-)" in table3.render(table3.cells(tmp_path / "table3"))


def test_signed_rank_p_drops_equal_seeds_and_corrects_for_ties_in_closed_form():
    """Zeros are dropped (the five positive differences left give the exact 2 / 2^5); six equal positive differences
    (all tied, ranks 3.5) give the normal approximation with the tie correction: T+ = 21 against a mean of 10.5 and a
    variance of 6 * 7 * 13 / 24 - (6^3 - 6) / 48 = 18.375; under two non-zero differences there is no test."""
    from scipy.stats import norm

    assert table3.signed_rank_p([0.0, 3.0, 1.0, 10.0, 4.0, 2.0]) == pytest.approx(0.0625)
    assert table3.signed_rank_p([1.0] * 6) == pytest.approx(2 * norm.sf(10.5 / math.sqrt(18.375)))
    assert table3.signed_rank_p([0.0, 0.0, 1.0]) is None and table3.signed_rank_p([0.0, 0.0]) is None


HISTORY = DOC.parent / "history" / "mp-cde.md"
# every kept Table III store (or stores of one Table III, reported together) whose whole report a page pastes: the
# record's on the current page, the sweeps beside it (4.5 m, 2 m/s, d_free read literally) in its history
TABLE3_REPORTED = [
    (("table3_portable",), DOC),
    (("table3_fuel",), HISTORY),
    (("table3_fuel_2mps",), HISTORY),
    (("table3_fuel", "table3_fuel_occupied", "table3_fuel_occupied_baselines", "table3_fuel_occupied_no_tracking"), HISTORY),
    (("table3_portable", "table3_occupied"), HISTORY),
]


@pytest.mark.parametrize(("names", "page"), TABLE3_REPORTED, ids=["+".join(names) for names, _ in TABLE3_REPORTED])
def test_the_table3_report_of_each_kept_store_stands_verbatim_in_mp_cde_md(tmp_path, unpack_kept_store, capsys, names, page):
    """mp-cde.md (or its history page) pastes `mpcde paper table3`'s whole output for each kept Table III store, or
    stores reported together (the cell table, the margins, the paired tests and the modes): pasted from the command,
    not typed (issue 28, deliverable 4)."""
    assert mpcde("paper", "table3", *[unpack_kept_store(name, tmp_path / name) for name in names]) == 0
    text = capsys.readouterr().out
    assert text in page.read_text(), f"{page.relative_to(DOC.parent)} lacks `mpcde paper table3`'s output for {' '.join(names)}"
