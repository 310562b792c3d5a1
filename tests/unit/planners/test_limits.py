"""KinematicLimits: one dataclass for every stack's limits, checked once, and refused where a planner cannot keep them."""

import math

import pytest

from mpcde.config.scenario import load_scenario
from mpcde.errors import ConfigError
from planners.dmpc import DmpcConfig
from planners.dmpc.admm.config import AdmmFormationConfig
from planners.dmpc.mlr.config import MlrConfig
from planners.limits import KinematicLimits
from planners.trajectory_optimizer import TrajectoryOptimizerConfig


@pytest.mark.parametrize(
    ("field", "value", "message"),
    [
        ("v_max_mps", 0.0, "v_max_mps=0.0: a finite number > 0 [m/s]"),
        ("a_max_mps2", float("nan"), "a_max_mps2=nan: a finite number > 0 [m/s^2]"),
        ("v_max_mps", math.inf, "v_max_mps=inf: a finite number > 0 [m/s]"),
        ("j_max_mps3", -1.0, "j_max_mps3=-1.0: a finite number > 0 [m/s^3] (or inf: no jerk limit)"),
        ("a_max_mps2", True, "a_max_mps2=True: a finite number > 0 [m/s^2]"),
    ],
)
def test_bad_limits_are_refused_in_one_line(field, value, message):
    with pytest.raises(ConfigError) as e:
        KinematicLimits(**{field: value})
    assert str(e.value) == message


def test_every_planner_holds_the_same_dataclass_with_its_papers_defaults():
    assert DmpcConfig().limits == KinematicLimits(2.0, 4.0, 20.0)  # on-demand DMPC, per axis
    assert MlrConfig().limits == KinematicLimits(1.0, 3.0, 10.0)  # DMPC-Swarm, per axis, jerk input
    assert AdmmFormationConfig().limits == KinematicLimits(2.0, 4.0)  # acceleration input: no jerk limit
    assert TrajectoryOptimizerConfig().limits == KinematicLimits(2.0, 4.0)  # MINCO's norm penalties
    cfg = load_scenario("crossing")
    sections = (cfg.denied.limits, cfg.dmpc.qp.limits, cfg.mlr.limits, cfg.admm.limits)
    assert all(type(s) is KinematicLimits for s in sections)


@pytest.mark.parametrize(
    ("override", "path"),
    [
        ({"denied": {"limits": {"j_max_mps3": 5.0}}}, "denied.limits.j_max_mps3=5.0: .inf: MINCO's penalties"),
        ({"admm": {"limits": {"j_max_mps3": 5.0}}}, "admm.limits.j_max_mps3=5.0: .inf: the double integrator's input"),
        ({"mlr": {"limits": {"j_max_mps3": ".inf"}}}, "mlr.limits.j_max_mps3=inf: a finite number > 0 [m/s^3]: the jerk is the input"),
        ({"dmpc": {"qp": {"limits": {"v_max_mps": -1.0}}}}, "dmpc.qp.limits.v_max_mps=-1.0: "),
    ],
)
def test_a_section_refuses_the_limit_its_planner_cannot_keep_naming_the_whole_path(override, path):
    with pytest.raises(ConfigError) as e:
        load_scenario("crossing", override)
    assert str(e.value).startswith(path) and "\n" not in str(e.value)


def test_a_limit_set_in_a_file_reaches_the_planner():
    cfg = load_scenario("crossing", {"planner": {"kind": "mpcde"}, "denied": {"limits": {"v_max_mps": 1.5, "a_max_mps2": 2.0}}})
    assert cfg.denied.limits == KinematicLimits(1.5, 2.0)
    assert cfg.denied.yaw.v_max_mps == 1.5  # derived in resolve: Eq. 1 predicts with the optimiser's speed limit
    mlr = load_scenario("crossing", {"mlr": {"limits": {"j_max_mps3": 7.0}}}).mlr.planner_config(4, (10.0, 10.0))
    assert mlr.limits.j_max_mps3 == 7.0
