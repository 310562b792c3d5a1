"""`mpcde paper ...` and `mpcde explain`: what they print from stores, and bad input as one line with exit status 2.

The reports' contents are tested in tests/unit/mpcde/paper/ (each against mp-cde.md on the kept stores) and
explain's bookkeeping in tests/unit/mpcde/evals/test_explain.py; here, the commands as a user types them."""

from __future__ import annotations

import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from mpcde.cli import main

ROOT = Path(__file__).resolve().parents[4]


def _mpcde(argv: list, capsys) -> tuple[int, str, str]:  # noqa: ANN001
    try:
        code = main([str(a) for a in argv])
    except SystemExit as e:  # argparse's refusals
        code = int(e.code)
    out, err = capsys.readouterr()
    return code, out, err


# the causes of the kept store outage_speeds, as its kept collision_causes.jsonl gives them (no flight to fly again)
OUTAGE_CAUSES = """
cell                                                 flights with coll.  causes (events)
planner.kind="mpcde_paper", planner.cruise_speed_mps=0.5      20          0  -
planner.kind="mpcde_paper", planner.cruise_speed_mps=1.0      20          0  -
planner.kind="mpcde_paper", planner.cruise_speed_mps=2.0      20          0  -
planner.kind="dmpc", planner.cruise_speed_mps=0.5         20          0  -
planner.kind="dmpc", planner.cruise_speed_mps=1.0         20          0  -
planner.kind="dmpc", planner.cruise_speed_mps=2.0         20          0  -
planner.kind="auto", planner.cruise_speed_mps=0.5         20          0  -
planner.kind="auto", planner.cruise_speed_mps=1.0         20          1  late detection 1
planner.kind="auto", planner.cruise_speed_mps=2.0         20          3  control overshoot 1, never in view 2
"""


def test_explain_tabulates_a_kept_stores_causes_without_flying_what_is_explained(tmp_path, unpack_kept_store, capsys):
    store = unpack_kept_store("outage_speeds", tmp_path / "outage_speeds")
    shutil.copy(ROOT / "docs" / "results" / "stores" / "outage_speeds" / "collision_causes.jsonl", store)
    before = (store / "collision_causes.jsonl").read_text()
    code, out, err = _mpcde(["explain", ROOT / "data" / "sweeps" / "radio_outage_speeds.yaml", store], capsys)
    assert (code, err) == (0, "") and out == OUTAGE_CAUSES
    assert (store / "collision_causes.jsonl").read_text() == before


@pytest.mark.parametrize(
    ("argv", "needle"),
    [
        (["explain", "nowhere.yaml", "store"], "sweep='nowhere.yaml'"),
        (["explain", ROOT / "data" / "sweeps" / "radio_outage_speeds.yaml", "nowhere"], "store='nowhere': no sweep.json"),
        (["explain", ROOT / "data" / "sweeps" / "radio_outage_speeds.yaml", "nowhere", "--limit", "-1"], "--limit=-1: an integer >= 0"),
        (["explain", "only-one"], "the following arguments are required"),
        (["paper"], "the following arguments are required: REPORT"),
        (["paper", "table4"], "invalid choice: 'table4'"),
        (["paper", "table3"], "the following arguments are required: STORE_DIR"),
        (["paper", "table3", "nowhere"], "store='nowhere': no sweep.json there (nowhere/sweep.json)"),
        (["paper", "modes", "nowhere"], "store='nowhere': no sweep.json there"),
        (["paper", "modes", "nowhere", "--seeds", "x"], "argument --seeds: invalid int value: 'x'"),
        (["paper", "summary", "a", "b"], "unrecognized arguments: b"),
        (["paper", "goals", "a", "b"], "unrecognized arguments: b"),
        (["paper", "ceiling", "nowhere.yaml", "--flights", "0:0"], "sweep='nowhere.yaml'"),
        (["paper", "ceiling", ROOT / "data" / "sweeps" / "table3_active_perception.yaml", "--flights", "0:0", "12:0"], "--flights='12:0'"),
        (["paper", "ceiling", ROOT / "data" / "sweeps" / "table3_active_perception.yaml"], "the following arguments are required: --flights"),
    ],
)
def test_bad_input_is_one_line_and_exit_2(argv, needle, capsys):
    code, out, err = _mpcde(argv, capsys)
    assert code == 2 and out == "" and err.startswith("mpcde: error: ") and err.count("\n") == 1, err
    assert needle in err, err


def test_the_reports_of_an_empty_runs_folder_name_every_missing_input(tmp_path, capsys):
    for report, parts in (("summary", ["fig10", "fig6", "table3", "akf"]), ("goals", ["table3", "fig6", "swarm_modes", "fig10", "akf"])):
        code, out, err = _mpcde(["paper", report, tmp_path], capsys)
        assert (code, err) == (0, "")
        assert [line.split(":")[0] for line in out.splitlines()[2:]] == [f"<!-- {p}" for p in parts]


def test_paper_runs_as_the_console_command_does():
    done = subprocess.run([sys.executable, "-m", "mpcde", "paper", "--help"], capture_output=True, text=True, timeout=120)
    assert done.returncode == 0
    assert all(name in done.stdout for name in ("table3", "summary", "goals", "modes", "ceiling"))
