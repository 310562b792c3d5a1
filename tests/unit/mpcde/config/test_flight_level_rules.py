"""Flight levels (denied.flight_level_spacing_m): refused at load when they would not be distinct or would leave the altitudes."""

import pytest

from mpcde.cli import main
from mpcde.config.scenario import load_scenario
from mpcde.errors import ConfigError


MPCDE = {"planner": {"kind": "mpcde"}}


def test_levels_that_fit_load_and_the_largest_spacing_is_named_when_they_do_not():
    cfg = load_scenario("forest_swarm", {**MPCDE, "denied": {"flight_level_spacing_m": 0.4}})  # 6 drones about 1.5 m: 0.5 to 2.5 m
    assert cfg.denied.flight_level_spacing_m == 0.4
    with pytest.raises(ConfigError, match=r"^denied\.flight_level_spacing_m=0\.5: <= 0\.4 m for 6 drones about 1\.5 m") as e:
        load_scenario("forest_swarm", {**MPCDE, "denied": {"flight_level_spacing_m": 0.5}})
    assert "\n" not in str(e.value)
    # the rule is the levels' stacks': another planner does not fly them
    assert load_scenario("forest_swarm", {"planner": {"kind": "dmpc"}, "denied": {"flight_level_spacing_m": 0.5}})


def test_the_lowest_level_keeps_the_front_ends_clearance_from_the_ground():
    # 6 drones 0.4 m apart about 1.5 m: the lowest level is 0.5 m = 0.45 m clearance + 0.4 / 8, allowed to rounding;
    # 7 put one at 0.3 m, where every front-end search fails against the ground the camera maps (the held-out ring)
    ring = lambda n: {"drones": {"layout": "antipodal", "count": n, "radius_m": 5.0, "altitude_m": 1.5}}  # noqa: E731
    assert load_scenario("antipodal", {**MPCDE, **ring(6), "denied": {"flight_level_spacing_m": 0.4}}).denied.flight_level_spacing_m == 0.4
    with pytest.raises(ConfigError, match=r"^denied\.flight_level_spacing_m=0\.4: <= 0\.336 m for 7 drones .*front_end_clearance_m \+ s / 8 = 0\.5 m"):
        load_scenario("antipodal", {**MPCDE, **ring(7), "denied": {"flight_level_spacing_m": 0.4}})
    assert load_scenario("antipodal", {**MPCDE, **ring(7), "denied": {"flight_level_spacing_m": 0.336}})


def test_levels_need_one_mission_altitude():
    two_altitudes = {
        "drones": {"layout": "explicit", "starts": [[-4.0, 0.0, 1.5], [0.0, -4.0, 2.0]], "goals": [[4.0, 0.0, 1.5], [0.0, 4.0, 2.0]]},
        "planner": {"kind": "mpcde"},
    }
    with pytest.raises(ConfigError, match=r"^denied\.flight_level_spacing_m=0\.4: inf \(no levels\) unless .* drone 1's is 2 m, drone 0's 1\.5 m"):
        load_scenario("crossing", {**two_altitudes, "denied": {"flight_level_spacing_m": 0.4}})
    assert load_scenario("crossing", two_altitudes)  # without levels the layout flies


def test_the_cli_refuses_levels_in_one_line_with_exit_2_and_writes_nothing(tmp_path, capsys):
    from mpcde.config.scenario import SCENARIO_DIR

    path = tmp_path / "levels.yaml"
    path.write_text((SCENARIO_DIR / "forest_swarm.yaml").read_text() + "denied:\n  flight_level_spacing_m: 1.0\n")
    out = tmp_path / "run"
    code = main(["fly", str(path), "--out", str(out), "--quiet", "--mode", "denied"])
    err = capsys.readouterr().err
    assert code == 2 and len(err.strip().splitlines()) == 1 and "denied.flight_level_spacing_m=1.0" in err, err
    assert not out.exists()


@pytest.mark.parametrize("kind", ["mpcde", "mpcde_paper", "auto", "minco_comm"])
def test_a_denied_planners_start_or_goal_nearer_the_ground_than_its_clearance_is_refused(kind):
    low_goal = {
        "drones": {"layout": "explicit", "starts": [[-4.0, 0.0, 1.5], [0.0, -4.0, 1.5]], "goals": [[4.0, 0.0, 1.5], [0.0, 4.0, 0.3]]},
        "planner": {"kind": kind},
    }
    with pytest.raises(ConfigError, match=r"^drones\.goals\[1\]=\[0\.0, 4\.0, 0\.3\]: an altitude >= denied\.front_end_clearance_m = 0\.45 m") as e:
        load_scenario("crossing", low_goal)
    assert "\n" not in str(e.value)
    # at the clearance it loads, and a smaller clearance admits the lower goal
    assert load_scenario("crossing", {**low_goal, "drones": {**low_goal["drones"], "goals": [[4.0, 0.0, 1.5], [0.0, 4.0, 0.45]]}})
    assert load_scenario("crossing", {**low_goal, "denied": {"front_end_clearance_m": 0.25}})


def test_stacks_without_the_denied_planner_may_fly_low():
    low = {"drones": {"layout": "explicit", "starts": [[-4.0, 0.0, 0.3], [0.0, -4.0, 1.5]], "goals": [[4.0, 0.0, 0.3], [0.0, 4.0, 1.5]]}}
    assert load_scenario("crossing", {**low, "planner": {"kind": "dmpc"}})
