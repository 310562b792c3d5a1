"""The sweep stores kept in the repository (docs/results/stores/README.md) against the docs that report them.

For every row of that README's table: the store holds the stated number of
flights, every one flown at the stated revision, with the axes and seeds its
sweep file still names (a sweep file is fixed before its first flight), and
the cell table of its ``mpcde report`` stands verbatim in the results file the
row names: the numbers in the docs are the report's, not typed.
"""

from __future__ import annotations

import json
import re
from pathlib import Path

import pytest

from mpcde.sweep.report import build_report, format_report
from mpcde.sweep.spec import load_sweep
from mpcde.sweep.store import ResultsStore, json_safe

ROOT = Path(__file__).resolve().parents[4]
STORES = ROOT / "docs" / "results" / "stores"
ROW = re.compile(r"^\| `(?P<folder>[^`]+)` \| `(?P<sweep>[^`]+)` \| (?P<flights>\d+) \| (?P<rev>[0-9a-f]{7}), (?P<date>[0-9-]+) \| `(?P<doc>[^`]+)`.* \| (?P<numerics>portable|native, bfloat16|native, float32) \|$")


# the README's second table: results kept beside the stores that are not sweeps (`mpcde eval-tracking`'s results.json)
EVAL_ROW = re.compile(r"^\| `(?P<folder>[^`]+)` \| `(?P<command>mpcde eval-tracking[^`]*)` \| (?P<rev>[0-9a-f]{7}), [0-9-]+ \| `(?P<doc>[^`]+)`.* \| (?P<numerics>portable|native) \|$")


PAPER_KIND_SINCE = "2026-12-03"
"""The day the denied stack (``planner.kind: mpcde``) began to look before moving by default and the sweep files of
MP-CDE as published began to name ``mpcde_paper``: a store flown before it flew, as ``mpcde``, exactly what
``mpcde_paper`` flies now (its preset pins the paper's settings), so its sweep file's ``mpcde_paper`` reads as
``mpcde`` there (docs/results/denied_default.md)."""


def _as_flown(value, date: str):
    """``value`` (a sweep spec's axes or overrides) with ``mpcde_paper`` read as ``mpcde`` for a store flown before
    :data:`PAPER_KIND_SINCE`."""
    if date >= PAPER_KIND_SINCE:
        return value
    if isinstance(value, dict):
        return {k: _as_flown(v, date) for k, v in value.items()}
    if isinstance(value, list):
        return [_as_flown(v, date) for v in value]
    return "mpcde" if value == "mpcde_paper" else value


def _readme_rows(pattern: re.Pattern[str]) -> list[dict[str, str]]:
    return [m.groupdict() for line in (STORES / "README.md").read_text().splitlines() if (m := pattern.match(line))]


def _kept() -> list[dict[str, str]]:
    rows = _readme_rows(ROW)
    assert rows, "the README's table lists no store"
    return rows


def _kept_evals() -> list[dict[str, str]]:
    return _readme_rows(EVAL_ROW)


def test_every_kept_folder_is_listed_in_the_readme() -> None:
    listed = [r["folder"] for r in _kept() + _kept_evals()]
    assert sorted(listed) == sorted(p.name for p in STORES.iterdir() if p.is_dir())


@pytest.mark.parametrize("row", _kept_evals(), ids=lambda r: r["folder"])
def test_a_kept_eval_is_at_its_revision_and_profile_and_its_table_stands_in_the_doc(row: dict[str, str]) -> None:
    results = json.loads((STORES / row["folder"] / "results.json").read_text())
    run = results["run"]
    assert run["git_rev"][:7] == row["rev"] and not run["git_rev"].endswith("+dirty")
    assert run["numerics"]["effective"] == row["numerics"]
    from mpcde.evals.tracking import format_table

    table = format_table(results)  # the table `mpcde eval-tracking` prints and writes first in results.txt
    assert (STORES / row["folder"] / "results.txt").read_text().startswith(table)
    doc = (ROOT / "docs" / "results" / row["doc"]).read_text()
    assert table in doc, f"{row['doc']} does not hold the table of {row['folder']}"


@pytest.mark.parametrize("row", _kept(), ids=lambda r: r["folder"])
def test_a_kept_store_is_complete_unchanged_in_its_sweep_and_reported_verbatim(
    row: dict[str, str], tmp_path: Path, unpack_kept_store
) -> None:
    folder = unpack_kept_store(row["folder"], tmp_path / row["folder"])
    store = ResultsStore.read(folder)
    rows = store.rows()
    assert len(rows) == int(row["flights"]) and all(r["status"] == "ok" for r in rows)
    assert {r["git_rev"][:7] for r in rows} == {row["rev"]}
    profile, _, precision = row["numerics"].partition(", ")
    if profile == "portable":  # recorded by every flight since the profile exists (mpcde/numerics.py)
        assert {r["metrics"]["numerics"]["effective"] for r in rows} == {"portable"}
    else:  # flown before it: the CPU's own kernels, the detector's precision as "auto" resolved there
        assert all("numerics" not in r["metrics"] or r["metrics"]["numerics"]["profile"] == "native" for r in rows)
        assert {r["metrics"]["detector_precision"] for r in rows} <= {precision, None}
    spec = _as_flown(load_sweep(ROOT / row["sweep"], check_cells=False).to_dict(), row["date"])  # a record: checked when flown
    kept = json.loads((folder / "sweep.json").read_text())["sweep"]
    assert (kept["axes"], kept["seeds"], kept["overrides"], kept["base_name"]) == (
        json_safe(json.loads(json.dumps(spec["axes"]))), spec["seeds"], json_safe(spec["overrides"]), spec["base_name"])  # fmt: skip  (the store writes inf as null)
    table = format_report(build_report(folder)).split("\n\n")[1]  # the cell table, after the header line
    doc = (ROOT / "docs" / "results" / row["doc"]).read_text()
    assert table in doc, f"{row['doc']} does not hold the report's cell table of {row['folder']}"
