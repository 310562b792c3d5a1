"""DMPC-Swarm's promise in the comm stack: halting plans, kept as broadcast, and no replanning while a near neighbour is unheard."""

from __future__ import annotations

import numpy as np
from dmpc_crossing_agent import crossing_dmpc_agent  # tests/unit/mpcde/onboard/dmpc_crossing_agent.py

from mpcde.config.scenario import load_scenario
from mpcde.onboard.dmpc import HALT_TOLERANCE_MPS, DmpcAgent
from sim.types import PlanMessage, PoseEstimate, RadioMessage

ROUND = 0.2
START, GOAL = np.array([-4.0, 0.0, 1.5]), np.array([4.0, 0.0, 1.5])


def _agent(**dmpc) -> DmpcAgent:
    return crossing_dmpc_agent(np.stack([GOAL, np.array([0.0, 4.0, 1.5])]), **dmpc)


def _plain(**dmpc) -> DmpcAgent:
    """The on-demand paper's plain DMPC (replanning every round, on-demand rows, no halt), stated in full."""
    return _agent(commit_when_unheard=False, qp=load_scenario("crossing").dmpc.replanning().qp, **dmpc)


def _message(t: float, pos: np.ndarray, sender: int = 1) -> RadioMessage:
    times = t + ROUND * np.arange(16)
    plan = PlanMessage(sender, t, times, np.tile(pos, (16, 1)), np.zeros((16, 3)))
    return RadioMessage(sender_id=sender, send_time_s=t, receive_time_s=t, payload=plan)


def _fly(agent: DmpcAgent, rounds: int, heard, neighbour: np.ndarray, t0: float = 0.0) -> list[PlanMessage]:
    """Radio rounds with a perfectly tracked reference; ``heard(k)`` says whether round k's inbox holds the neighbour's plan."""
    out = []
    for k in range(rounds):
        t = t0 + k * ROUND
        ref = agent.reference(t)
        pos, vel = (START, np.zeros(3)) if agent.plan is None else (ref.pos_world, ref.vel_world)
        agent.on_pose_estimate(PoseEstimate(t, pos, vel, np.array([0.0, 0.0, 0.0, 1.0]), np.zeros(3)))
        agent.on_radio([_message(t - ROUND, neighbour)] if heard(k) else [])
        agent.plan_round(t)
        out.append(agent.outgoing(t))
    return out


def test_every_broadcast_plan_ends_in_a_halt():
    msgs = _fly(_agent(), 10, lambda k: True, np.array([0.0, 5.0, 1.5]))
    assert np.linalg.norm(msgs[-1].vel_world[1]) > 0.5  # it flies toward the goal
    for m in msgs:
        assert np.all(np.abs(m.vel_world[-1]) < HALT_TOLERANCE_MPS)


def test_an_unheard_near_neighbour_freezes_the_plan_until_it_is_heard_again():
    agent = _agent()
    near = np.array([0.0, 3.0, 1.5])
    msgs = _fly(agent, 12, lambda k: k < 5 or k >= 9, near)
    assert agent.stats.commits == 4  # rounds 5-8
    # while unheard, each broadcast is the plan of round 4, resampled: the trajectory the neighbour planned against
    reference = msgs[4]
    for m in msgs[5:9]:
        i = np.searchsorted(reference.times_s, m.times_s[0] - 1e-9)
        np.testing.assert_allclose(m.pos_world[: 16 - i], reference.pos_world[i:], atol=1e-9)
    assert not np.allclose(msgs[10].pos_world[-1], msgs[8].pos_world[-1])  # heard again: it replans


def test_a_far_unheard_neighbour_does_not_freeze_and_the_plain_dmpc_never_does():
    agent = _agent(commit_range_m=2.0)
    _fly(agent, 10, lambda k: k < 3, np.array([0.0, 8.0, 1.5]))
    assert agent.stats.commits == 0
    plain = _plain()
    msgs = _fly(plain, 10, lambda k: k < 3, np.array([0.0, 3.0, 1.5]))
    assert plain.stats.commits == 0 and np.abs(msgs[-1].vel_world[-1]).max() > HALT_TOLERANCE_MPS


def test_a_halted_plan_is_kept_past_the_timeout_and_a_moving_one_is_dropped():
    agent = _agent(plan_timeout_s=0.5)
    _fly(agent, 8, lambda k: k == 0, np.array([0.0, 3.0, 1.5]))
    assert agent.stats.dropped_plans == 0 and agent.stats.commits == 7
    plain = _plain(plan_timeout_s=0.5)
    _fly(plain, 8, lambda k: k == 0, np.array([0.0, 3.0, 1.5]))
    assert plain.stats.dropped_plans > 0
