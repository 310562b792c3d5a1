"""DMPC's start state under a drifted pose estimate: the plan, not a ratchet (``dmpc.state_tolerance_m``).

The SE(3) controller tracks the plan with the true state, so a drone whose
estimate has drifted by b sits b away from its own well-tracked plan in its
own eyes. Past ``state_tolerance_m`` each round restarts from the estimate, the
controller moves the drone by b to follow, and the estimate moves with it: the
drone walks off by b per round (traced on the forest: docs/results/history/mp-cde.md#auto-at-the-current-code-seventeenth-sitting).
Here the controller is ideal (the truth is the reference) and the estimate is
the truth plus a constant drift of 0.15 m down, the size traced there.
"""

from __future__ import annotations

import numpy as np
from dmpc_crossing_agent import crossing_dmpc_agent  # tests/unit/mpcde/onboard/dmpc_crossing_agent.py

from mpcde.onboard.dmpc import DmpcAgent
from sim.types import PoseEstimate

ROUND = 0.2
START, GOAL = np.array([-2.0, 0.0, 1.5]), np.array([2.0, 0.0, 1.5])
DRIFT = np.array([0.0, 0.0, -0.15])


def _agent(**dmpc) -> DmpcAgent:
    return crossing_dmpc_agent(np.stack([GOAL, np.array([0.0, 40.0, 1.5])]), **dmpc)


def _fly(agent: DmpcAgent, rounds: int) -> np.ndarray:
    """Radio rounds alone (no neighbour heard), an ideal controller; returns the true positions, (rounds, 3) [m]."""
    truth = []
    for k in range(rounds):
        t = k * ROUND
        ref = agent.reference(t)
        pos, vel = (START, np.zeros(3)) if agent.plan is None else (ref.pos_world, ref.vel_world)
        truth.append(np.array(pos, float))
        agent.on_pose_estimate(PoseEstimate(t, pos + DRIFT, vel, np.array([0.0, 0.0, 0.0, 1.0]), np.zeros(3)))
        agent.on_radio([])
        agent.plan_round(t)
        agent.outgoing(t)
    return np.array(truth)


def test_the_default_tolerance_flies_a_drifted_drone_to_its_goal():
    agent = _agent()
    assert agent.config.state_tolerance_m > np.linalg.norm(DRIFT)
    truth = _fly(agent, 60)
    assert np.linalg.norm(truth[-1] - GOAL) < 0.05
    assert truth[:, 2].min() > GOAL[2] - np.linalg.norm(DRIFT) - 0.01  # the drift taken once, by the first plan, never again
    assert agent.stats.state_resets == 1  # the first round only (no plan yet)


def test_a_tolerance_below_the_drift_ratchets_the_drone_off_its_goal():
    agent = _agent(state_tolerance_m=0.1)
    truth = _fly(agent, 60)
    assert agent.stats.state_resets == 60  # every round restarts from the estimate
    assert truth[-1, 2] < GOAL[2] - 0.5  # the drift taken again every round
