"""Scenario files: the built-ins load; bad files exit 2 with one line and write nothing."""

import subprocess
import sys

import pytest

from mpcde.cli import main
from mpcde.config.scenario import SCENARIO_DIR, load_scenario
from mpcde.errors import ConfigError
from mpcde.flight.loop import prepare_run

BUILTINS = sorted(p.stem for p in SCENARIO_DIR.glob("*.yaml"))


def test_the_issue_s_built_in_scenarios_exist():
    assert {"crossing", "antipodal", "forest_sparse", "forest_medium", "forest_dense", "forest_swarm"} <= set(BUILTINS)


@pytest.mark.parametrize("name", BUILTINS)
def test_built_in_scenarios_load_and_validate(name):
    cfg = load_scenario(name)
    prepared = prepare_run(cfg)
    assert prepared.starts.shape == prepared.goals.shape


def test_forest_densities_increase():
    counts = [len(prepare_run(load_scenario(f"forest_{d}")).obstacles) for d in ("sparse", "medium", "dense")]
    assert counts[0] < counts[1] < counts[2]


BAD = {
    "unknown_key": ("name: x\nwrold: {}\n", "wrold"),
    "wrong_type": ("camera:\n  rate_hz: fast\n", "camera.rate_hz"),
    "negative_rate": ("camera:\n  rate_hz: -5\n", "camera.rate_hz"),
    "negative_radio_rate": ("radio:\n  rate_hz: -1\n", "radio.rate_hz"),
    "bad_choice": ("radio:\n  loss_model: sometimes\n", "radio.loss_model"),
    "start_inside_obstacle": (
        "world:\n  obstacles: [{kind: tree, center_xy: [-4.0, 0.0], radius_m: 0.5}]\ndrones:\n  starts: [[-4.0, 0.0, 1.5], [0.0, -4.0, 1.5]]\n  goals: [[4.0, 0.0, 1.5], [0.0, 4.0, 1.5]]\n",
        "drones.starts[0]",
    ),
    "goals_too_close": ("drones:\n  starts: [[-4.0, 0.0, 1.5], [0.0, -4.0, 1.5]]\n  goals: [[1.0, 0.0, 1.5], [1.1, 0.0, 1.5]]\n", "drones.goals[1]"),
    "not_yaml": ("name: [unclosed\n", "scenario"),
    "denied_without_cameras": ("planner:\n  kind: mpcde\n", "run.cameras"),  # the test flies with --no-cameras
    "goals_count": ("drones:\n  starts: [[0.0, 0.0, 1.5]]\n  goals: []\n", "drones.goals"),
}


@pytest.mark.parametrize("case", sorted(BAD))
def test_bad_scenario_is_one_line_exit_2_and_nothing_written(case, tmp_path, capsys):
    text, field = BAD[case]
    path = tmp_path / f"{case}.yaml"
    path.write_text(text)
    out = tmp_path / "run"
    code = main(["fly", str(path), "--out", str(out), "--quiet", "--no-cameras"])
    err = capsys.readouterr().err
    assert code == 2
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("mpcde: error: ") and field in lines[0], err
    assert not out.exists()
    assert not any(p.name.startswith(".run.partial") for p in tmp_path.iterdir())


def test_the_console_script_exits_2_on_a_bad_option(tmp_path):
    r = subprocess.run([sys.executable, "-m", "mpcde", "fly", "crossing", "--out", str(tmp_path / "o"), "--seed", "-3"], capture_output=True, text=True)
    assert r.returncode == 2
    assert len(r.stderr.strip().splitlines()) == 1 and "--seed" in r.stderr


def test_config_error_names_field_value_and_allowed():
    with pytest.raises(ConfigError) as e:
        load_scenario(SCENARIO_DIR / "crossing.yaml", {"duration_s": -1.0})
    assert str(e.value) == "duration_s=-1.0: in (0, 3600] s"


def test_a_planner_kind_set_in_code_is_checked_too():
    """The YAML path checks the Literal; dataclasses.replace (how compare switches stacks) must not slip past it."""
    from dataclasses import replace

    cfg = load_scenario("crossing")
    allowed = r"allowed: 'min_jerk_line', 'mpcde', 'mpcde_paper', 'dmpc', 'auto', 'mlr', 'admm', 'minco_comm'$"
    with pytest.raises(ConfigError, match=r"^kind='denied': " + allowed):
        replace(cfg.planner, kind="denied")
    with pytest.raises(ConfigError, match=r"^planner\.kind='denied': allowed:"):
        load_scenario("crossing", {"planner": {"kind": "denied"}})


def test_a_non_empty_out_folder_is_refused_without_overwrite(tmp_path, capsys):
    out = tmp_path / "run"
    out.mkdir()
    (out / "keep.txt").write_text("mine")
    assert main(["fly", "crossing", "--out", str(out), "--quiet"]) == 2
    assert "--out" in capsys.readouterr().err
    assert (out / "keep.txt").read_text() == "mine"
