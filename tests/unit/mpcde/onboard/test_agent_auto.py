"""The auto agent's mode switch, hand-overs and per-neighbour fallback (synthetic frames and radio, no flight)."""

from dataclasses import replace

import numpy as np
import pytest
from test_agent_denied_tracks import GOAL, NEIGHBOUR, START, _frame

from mpcde.config.scenario import load_scenario
from mpcde.errors import ConfigError
from mpcde.onboard.auto import AutoAgent
from mpcde.stacks.build import make_agent
from sim.types import PlanMessage, PoseEstimate, RadioMessage

ROUND = 0.2  # radio period [s] (5 Hz)


def _agent(**auto) -> AutoAgent:
    cfg = load_scenario("crossing", {"auto": auto} if auto else None)
    cfg = replace(cfg, planner=replace(cfg.planner, kind="auto"))
    cfg.__post_init__()
    agent = make_agent(cfg, 0, np.stack([GOAL, NEIGHBOUR]), ())
    assert isinstance(agent, AutoAgent)
    return agent


BEHIND = START + np.array([-1.5, 0.0, 0.0])  # a hovering drone the camera (looking along +x) cannot see


def _plan_message(t: float, sender: int = 1, pos_world: np.ndarray = NEIGHBOUR) -> RadioMessage:
    """Drone ``sender`` hovering at ``pos_world`` says so."""
    times = t + ROUND * np.arange(16)
    plan = PlanMessage(sender, t, times, np.tile(pos_world, (16, 1)), np.zeros((16, 3)))
    return RadioMessage(sender_id=sender, send_time_s=t, receive_time_s=t, payload=plan)


def _run(agent: AutoAgent, t_from: float, t_to: float, radio_on, behind=False) -> list[tuple[float, str]]:
    """Frames at 25 Hz and radio rounds at 5 Hz over [t_from, t_to); ``radio_on(t)`` says if drone 1 is heard
    (and drone 2 hovering at BEHIND when ``behind``).

    The drone tracks its reference perfectly: each pose estimate is the reference at that time.
    Returns the mode after each round.
    """
    modes = []
    for k in range(round(t_from / 0.04), round(t_to / 0.04)):
        t = 0.04 * k
        ref = agent.reference(t)
        pos, vel = (START, np.zeros(3)) if agent.comm.latest_estimate is None else (ref.pos_world, ref.vel_world)
        agent.on_pose_estimate(PoseEstimate(t, pos, vel, np.array([0.0, 0.0, 0.0, 1.0]), np.zeros(3)))
        agent.on_frame(*_frame(t))
        if k % 5 == 0:
            # the inbox holds what was sent in the previous round
            heard = t > 0 and radio_on(t - ROUND)
            inbox = [_plan_message(t - ROUND)] + ([_plan_message(t - ROUND, 2, BEHIND)] if behind else [])
            agent.on_radio(inbox if heard else [])
            agent.plan_round(t)
            agent.outgoing(t)
            modes.append((round(t, 2), agent.mode))
    return modes


def test_with_the_radio_it_flies_dmpc_and_still_tracks_and_maps_without_planning_the_denied_half():
    agent = _agent()
    modes = _run(agent, 0.0, 2.0, lambda t: True)
    assert {m for _, m in modes} == {"comm"}
    assert agent.denied.stats.replans == 0 and agent.denied.trajectory is None  # the denied half only observes
    assert len(agent.denied.stats.map_ms) == 50  # every frame mapped: warm when an outage starts
    assert len(agent.perception.predictions(2.0)) == 1  # the neighbour is tracked
    s = agent.comm.stats
    assert len(s.qp_solve_s) >= 5
    assert s.substituted_plans == 0 and s.unknown_tracks == 0  # the track is that fresh plan's drone


def test_a_neighbour_whose_plan_goes_stale_is_planned_against_by_its_track():
    agent = _agent()
    # drone 1 heard until 1.0 s, then silent for 0.8 s: stale after 0.5 s, radio not yet out (1.0 s)
    modes = _run(agent, 0.0, 1.8, lambda t: t < 1.0)
    assert {m for _, m in modes} == {"comm"}
    assert agent.comm.stats.substituted_plans >= 1


def test_silence_switches_to_the_denied_stack_and_a_message_switches_back_with_a_continuous_reference():
    agent = _agent(handover="continue")
    silence = agent.config.radio_silence_s
    t_switch = 0.4 + silence + ROUND  # last message sent at 0.4 s; the first round whose silence exceeds the limit
    modes = _run(agent, 0.0, t_switch, lambda t: t < 0.6)
    assert modes[-1][1] == "comm"
    before = agent.comm.reference_state(t_switch)  # what the DMPC plan commands at the switch
    modes += _run(agent, t_switch, t_switch + 0.04, lambda t: False)
    assert modes[-1] == (round(t_switch, 2), "denied")
    after = agent.reference(t_switch)
    np.testing.assert_allclose(after.pos_world, before[0], atol=1e-9)
    np.testing.assert_allclose(after.vel_world, before[1], atol=1e-9)
    assert agent.switches == [(pytest.approx(t_switch), "denied")]

    modes += _run(agent, t_switch + 0.04, 3.0, lambda t: False)
    assert agent.denied.stats.replans >= 1  # the denied half plans now
    t_back = 3.0
    before = agent.denied.reference(t_back)
    modes += _run(agent, 3.0, 3.04, lambda t: True)  # a message arrives at the round at 3.0 s
    assert modes[-1] == (3.0, "comm") and agent.switches[-1] == (pytest.approx(t_back), "comm")
    # the DMPC half starts from the denied reference: its first plan begins where that reference was
    np.testing.assert_allclose(agent.comm.plan.position(t_back), before.pos_world, atol=1e-6)
    np.testing.assert_allclose(agent.comm.yaw, before.yaw)


def test_in_denied_mode_an_untracked_neighbour_is_remembered_from_the_radio_for_plan_memory_s():
    agent = _agent(handover="continue")  # the memory is counted from the send time (a halt lengthens it)
    memory = agent.config.plan_memory_s
    _run(agent, 0.0, 2.0, lambda t: t < 0.6, behind=True)  # last messages sent at 0.4 s; denied from 1.6 s
    assert agent.mode == "denied"
    t = 2.0
    by_id = {p.neighbor_id: p for p in agent.denied.neighbours(t)}
    # drone 1 is in view: its remembered plan gives way to its track, keeping the drone's id
    assert by_id[1].source == "perception"
    # drone 2 was never seen: the planner and the yaw planner know it only from its last plan
    assert by_id[2].source == "radio"
    np.testing.assert_allclose(by_id[2].position(t), BEHIND)
    assert agent.memory.remembered_plans >= 2
    later = agent.denied.neighbours(0.4 + memory + 0.01)  # the plans are forgotten: the tracks alone
    assert [p.source for p in later] == ["perception"]
    # no memory: only what the camera tracks (the pure MP-CDE neighbour set)
    agent.config = agent.memory.config = replace(agent.config, plan_memory_s=0.0)  # the memory reads its own copy
    assert [p.source for p in agent.denied.neighbours(t)] == ["perception"]


def test_invalid_auto_settings_name_the_field():
    with pytest.raises(ConfigError, match=r"^auto\.radio_silence_s="):
        load_scenario("crossing", {"auto": {"radio_silence_s": 0}})
    with pytest.raises(ConfigError, match=r"^auto\.fusion\.gate_m="):
        load_scenario("crossing", {"auto": {"fusion": {"gate_m": -1}}})
    with pytest.raises(ConfigError, match=r"^auto\.plan_memory_s=-1(\.0)?: a finite number >= 0"):
        load_scenario("crossing", {"auto": {"plan_memory_s": -1}})
    with pytest.raises(ConfigError, match=r"^auto\.handover='stop': one of 'continue', 'halt'"):
        load_scenario("crossing", {"auto": {"handover": "stop"}})


def test_a_halting_hand_over_flies_the_last_plan_to_its_halt_turns_once_round_and_only_then_plans():
    agent = _agent()  # handover: halt is the default
    t_switch = 0.4 + agent.config.radio_silence_s + ROUND
    _run(agent, 0.0, t_switch + 0.04, lambda t: t < 0.6, behind=True)  # last messages sent at 0.4 s
    assert agent.mode == "denied"
    plan = agent.comm.plan
    assert np.all(np.abs(plan.vel_world[-1]) < 1e-3)  # commit_when_unheard: the plan flown ends in a halt
    (halt_s, turn_end_s), = agent.handovers
    rate = agent.denied.config.yaw_rate_max_radps
    assert t_switch < halt_s <= plan.t_end_s and turn_end_s == pytest.approx(halt_s + 2.0 * np.pi / rate)
    halt_pos = plan.position(np.array([plan.t_end_s]))[0]
    # until the halt the reference is the DMPC plan its neighbours remember; the denied half does not plan
    for t in np.arange(t_switch + 0.04, halt_s - 0.01, 0.2):
        np.testing.assert_allclose(agent.reference(t).pos_world, agent.comm.reference_state(t)[0], atol=1e-12)
    _run(agent, t_switch + 0.04, turn_end_s - 0.04, lambda t: False, behind=True)
    assert agent.denied.stats.replans == 0 and agent.denied.stats.failures == 0
    # at the halt: hovering there, turning at the yaw-rate limit
    ref = agent.reference(halt_s + 1.0)
    np.testing.assert_allclose(ref.pos_world, halt_pos, atol=1e-6)
    np.testing.assert_allclose(ref.vel_world, 0.0, atol=1e-9)
    assert ref.yaw_rate == pytest.approx(rate)
    assert agent.reference(halt_s + 2.0).yaw - ref.yaw == pytest.approx(rate)
    # drone 2 (never seen) is still remembered from its last plan when the turn ends, though sent long before
    by_id = {p.neighbor_id: p for p in agent.denied.neighbours(turn_end_s, count=False)}
    assert by_id[2].source == "radio" and turn_end_s - 0.4 > agent.config.plan_memory_s
    _run(agent, turn_end_s - 0.04, turn_end_s + 0.4, lambda t: False, behind=True)
    assert agent.denied.stats.replans >= 1  # it plans once the turn is over
    m = agent.extra_metrics()["halting_handovers"]
    assert m == [{"halt_s": round(halt_s, 3), "turn_end_s": round(turn_end_s, 3)}]


def test_the_continuing_hand_over_replans_at_once_and_records_no_halt():
    agent = _agent(handover="continue")
    _run(agent, 0.0, 2.2, lambda t: t < 0.6)
    assert agent.mode == "denied" and agent.denied.stats.replans >= 1 and agent.handovers == []
