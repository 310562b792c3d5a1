"""The start-state rule DMPC and ADMM share (:mod:`planners.dmpc.start_state`): closed-form cases."""

from __future__ import annotations

import numpy as np
import pytest

from mpcde.config.admm import AdmmAgentConfig
from mpcde.config.dmpc import DmpcAgentConfig
from planners.dmpc.start_state import TOLERANCE_M, TOLERANCE_MPS, plan_start_state

PLAN_POS, PLAN_VEL = np.array([1.0, 2.0, 1.5]), np.array([0.5, 0.0, 0.0])


@pytest.mark.parametrize(
    ("dp", "dv", "from_plan"),
    [
        (np.zeros(3), np.zeros(3), True),
        (np.array([0.0, 0.0, 0.2999]), np.zeros(3), True),  # just inside the position bound
        (np.array([0.0, 0.0, 0.3001]), np.zeros(3), False),
        (np.array([0.2, 0.2, 0.09]), np.zeros(3), True),  # norm 0.297: the bound is on the distance, not per axis
        (np.array([0.2, 0.2, 0.11]), np.zeros(3), False),
        (np.zeros(3), np.array([0.0, 0.3001, 0.0]), False),  # the velocity alone
    ],
)
def test_the_plan_state_is_kept_exactly_while_the_estimate_is_within_both_tolerances(dp, dv, from_plan) -> None:
    pos, vel, used_plan = plan_start_state(PLAN_POS + dp, PLAN_VEL + dv, PLAN_POS, PLAN_VEL, 0.3, 0.3)
    assert used_plan is from_plan
    np.testing.assert_array_equal(pos, PLAN_POS if from_plan else PLAN_POS + dp)
    np.testing.assert_array_equal(vel, PLAN_VEL if from_plan else PLAN_VEL + dv)


def test_zero_tolerances_start_from_the_estimate_whenever_it_differs() -> None:
    pos, vel, used_plan = plan_start_state(PLAN_POS + 1e-9, PLAN_VEL, PLAN_POS, PLAN_VEL, 0.0, 0.0)
    assert not used_plan and np.array_equal(pos, PLAN_POS + 1e-9)


def test_both_agents_default_to_the_shared_tolerances() -> None:
    for cfg in (DmpcAgentConfig(), AdmmAgentConfig()):
        assert (cfg.state_tolerance_m, cfg.state_tolerance_mps) == (TOLERANCE_M, TOLERANCE_MPS) == (0.3, 0.3)
