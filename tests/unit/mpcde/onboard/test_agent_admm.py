"""The ADMM formation agent's sub-rounds without physics: drones exchange their bundles by hand; the admm: config.

The harness flies every drone exactly on its reference (its pose estimate is
the reference's state at the sub-round), delivers each sub-round's bundles in
the next one, and drops the ones a test says are lost.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import replace

import numpy as np
import pytest

from mpcde.config.admm import AdmmAgentConfig
from mpcde.config.scenario import load_scenario
from mpcde.errors import ConfigError
from mpcde.flight.metrics import formation_metrics
from mpcde.onboard.admm import AdmmAgent
from mpcde.stacks.build import make_agent
from planners.dmpc.admm.formation import AdmmFormationAgent, solve_admm_round
from planners.dmpc.admm.local_qp import AdmmLocalQpError
from planners.dmpc.admm.types import AdmmBundle
from sim.rotations import quat_xyzw_from_yaw
from sim.types import PoseEstimate, RadioMessage

CONFIG = AdmmAgentConfig(graph="ring")
ARENA_M = (24.0, 12.0)
ROUND_S = CONFIG.sub_round_s  # 0.02 s
R = CONFIG.rounds_per_step  # 10 sub-rounds per 0.2 s step
STARTS = np.array([[-5.8, 0.8, 1.5], [-5.8, -0.8, 1.5], [-4.2, -0.8, 1.5], [-4.2, 0.8, 1.5]])  # a square, in order
GOALS = STARTS + [10.0, 0.0, 0.0]
START_YAW = 0.3
Drop = Callable[[int, int, int], bool]  # (sub-round, sender, receiver) -> lost
Silent = Callable[[int, int], bool]  # (sub-round, drone) -> its outgoing is not called (as for a failed drone)


def _round(agent, t: float):
    """One radio round of ``agent`` at ``t``: plan, then what it broadcasts (what the loop does)."""
    agent.plan_round(t)
    return agent.outgoing(t)


def _estimate(t: float, pos: np.ndarray, vel: np.ndarray) -> PoseEstimate:
    return PoseEstimate(t, np.asarray(pos, float), np.asarray(vel, float), quat_xyzw_from_yaw(START_YAW), np.zeros(3))


def _swarm(config: AdmmAgentConfig = CONFIG, start_delay_s: float = 0.0) -> list[AdmmAgent]:
    agents = [AdmmAgent(i, GOALS, config, ARENA_M, start_delay_s, 1.0) for i in range(len(GOALS))]
    for a, p in zip(agents, STARTS):
        a.on_pose_estimate(_estimate(0.0, p, np.zeros(3)))
    return agents


class _Radio:
    """Delivers each sub-round's bundles in the next, except those ``drop`` says are lost."""

    def __init__(self, agents: list[AdmmAgent], drift: np.ndarray = np.zeros(3)) -> None:
        self.agents = agents
        self.drift = drift  # the pose estimate's error [m]: each drone flies its reference, its estimate is off by this
        self.inbox: list[list[RadioMessage]] = [[] for _ in agents]

    def fly(self, rounds: range, drop: Drop = lambda n, s, r: False, silent: Silent = lambda n, i: False) -> list:
        """Run the sub-rounds ``rounds``; returns each sub-round's [(sender, bundle)]."""
        log = []
        for n in rounds:
            t = n * ROUND_S
            for a in self.agents:
                pos, vel, _ = a.reference_state(t)
                a.on_pose_estimate(_estimate(t, pos + self.drift, vel))
                a.on_radio(self.inbox[a.drone_id])
            sent = [(a.drone_id, None if silent(n, a.drone_id) else _round(a, t)) for a in self.agents]
            log.append(sent)
            self.inbox = [
                [RadioMessage(s, t, t, b) for s, b in sent if b is not None and s != r and not drop(n, s, r)]
                for r in range(len(self.agents))
            ]
        return log


def _group_sums(agents: list[AdmmAgent]) -> np.ndarray:
    """(N,) max |sum of gamma entries on p_j| over j's own block and every copy of it (paper Eq. (5))."""
    out = []
    for j, owner in enumerate(agents):
        total = owner.admm.gamma[owner.admm.layout.pos].copy()
        for a in agents:
            if j in a.neighbour_ids:
                total += a.admm.gamma[a.admm.layout.copy(j)]
        out.append(np.abs(total).max())
    return np.array(out)


# ---------------------------------------------------------------------- the ideal exchange


def test_over_an_ideal_radio_the_sub_rounds_reproduce_solve_admm_round_step_by_step() -> None:
    agents = _swarm()
    offsets = [a.formation.offsets_of(a.drone_id) for a in agents]
    assert sorted(offsets[0]) == [1, 3]  # ring neighbours, d_ij = goal_i - goal_j = desired p_i - p_j
    np.testing.assert_allclose(offsets[0][1], GOALS[0] - GOALS[1])
    ref = [AdmmFormationAgent(i, agents[i].planner_config, offsets[i]) for i in range(4)]
    radio = _Radio(agents)
    states = np.c_[STARTS, np.zeros((4, 3))]
    for s in range(5):
        radio.fly(range(s * R, (s + 1) * R + 1) if s == 0 else range(s * R + 1, (s + 1) * R + 1))
        for i, a in enumerate(ref):
            a.start_step(states[i], agents[i].own_reference(s * CONFIG.step_s), s * CONFIG.step_s)
        expected = solve_admm_round(ref)
        for a, e in zip(agents, expected):
            assert a.plan.t0_s == pytest.approx(s * CONFIG.step_s) and a.plan.iterations == CONFIG.l_max
            np.testing.assert_allclose(a.plan.pos_world, e.pos_world, atol=1e-9)
            np.testing.assert_allclose(a.plan.acc_world, e.acc_world, atol=1e-9)
            np.testing.assert_allclose(a.plan.primal_residual, e.primal_residual, atol=1e-9)
        states = np.array([np.r_[e.pos_world[1], e.vel_world[1]] for e in expected])  # the next step's x0
    m = agents[0].extra_metrics()
    assert m["steps"] == 5 and m["iterations"] == 25 and m["copies_missing"] == m["means_missing"] == 0
    assert m["copies_received"] == m["means_received"] == 2 * 25 and m["late_messages"] == 0
    assert np.max(_group_sums(agents)) < 1e-9


def test_each_sub_round_sends_one_bundle_of_copies_or_means_and_the_plan_is_flown_one_step_later() -> None:
    agents = _swarm(start_delay_s=0.5)
    log = _Radio(agents).fly(range(2 * R + 1))
    kinds = [b.kind for _, b in (sent[0] for sent in log)]
    assert kinds[:R] == ["copies", "means"] * CONFIG.l_max and kinds[R] == "copies"
    first = log[0][0][1]
    assert isinstance(first, AdmmBundle) and sorted(m.receiver for m in first.copies) == [1, 3]  # ring neighbours
    ref = agents[2].reference(0.1)  # before the first plan (ready at h): hover at the start
    assert np.allclose(ref.pos_world, STARTS[2]) and np.allclose(ref.vel_world, 0.0)
    assert ref.yaw == pytest.approx(START_YAW) and ref.yaw_rate == 0.0
    assert agents[2].plan.t0_s == pytest.approx(CONFIG.step_s)  # step 1's plan, flown from 2 h
    # departure at the first step at or after 0.5 s: before it the own reference is the start
    assert agents[2].departure_s == pytest.approx(0.6)
    assert np.allclose(agents[2].own_reference(0.4), STARTS[2])
    line = agents[2].own_reference(0.6)
    assert np.allclose(line[:, 1:], STARTS[2, 1:]) and np.allclose(np.diff(line[:, 0]), 0.2)  # 1 m/s along +x


def test_the_formation_flies_to_its_goals_on_a_continuous_reference() -> None:
    agents = _swarm()
    _Radio(agents).fly(range(75 * R))  # 15 s
    pos = np.array([a.reference_state(75 * R * ROUND_S)[0] for a in agents])
    assert np.linalg.norm(pos - GOALS, axis=1).max() < 0.05
    assert formation_metrics(pos[None], GOALS)["formation_error_final_m"] < 1e-3
    # every step started on the plan: the reference jumps only by OSQP's tolerance on the dynamics rows
    assert all(a.stats.max_reference_jump_m < 1e-3 for a in agents)
    assert all(a.stats.state_resets == 0 and a.stats.qp_failures == 0 for a in agents)


# ---------------------------------------------------------------------- lost, late and missed


def test_a_lost_copy_is_left_out_of_the_average_and_its_holder_skips_that_multiplier_update() -> None:
    agents = _swarm()
    radio = _Radio(agents)
    radio.fly(range(0, 2), lambda n, s, r: n == 0 and s == 1 and r == 0)  # drone 1's copy for drone 0, iteration 1
    before = agents[1].admm.gamma[agents[1].admm.layout.copy(0)]
    radio.fly(range(2, 3))
    assert agents[0].stats.copies_missing == 1 and agents[0].stats.copies_received == 1
    assert agents[1].stats.not_averaged == 1  # drone 0's mean said so
    np.testing.assert_array_equal(agents[1].admm.gamma[agents[1].admm.layout.copy(0)], before)
    assert np.max(_group_sums(agents)) < 1e-9


def test_a_missed_mean_is_repaired_from_the_owners_next_bundle_and_eq_5_holds_again() -> None:
    agents = _swarm()
    radio = _Radio(agents)
    radio.fly(range(0, 3), lambda n, s, r: n == 1 and s == 0 and r == 1)  # drone 0's mean of iteration 1 to drone 1
    assert agents[1].stats.means_missing == 1 and agents[1].stats.resolved_means == 0
    assert np.max(_group_sums(agents)) > 1e-6  # drone 1 skipped its Step 8 term on its copy of p_0
    radio.fly(range(3, 5))  # drone 0's mean of iteration 2 (sent in sub-round 3) repeats the first
    assert agents[1].stats.resolved_means == 1 and np.max(_group_sums(agents)) < 1e-9


@pytest.mark.parametrize("seed", [1, 7])
def test_under_random_loss_missed_means_are_repaired_and_the_formation_still_arrives(seed: int) -> None:
    agents = _swarm()
    radio = _Radio(agents)
    lost = np.random.default_rng(seed).uniform(size=(60 * R, 4, 4)) < 0.3
    radio.fly(range(60 * R), lambda n, s, r: bool(lost[n, s, r]))
    radio.fly(range(60 * R, 75 * R))
    st = [a.stats for a in agents]
    missing, repaired = sum(s.means_missing for s in st), sum(s.resolved_means for s in st)
    unresolved = sum(s.unresolved_means for s in st)
    assert sum(s.copies_missing for s in st) > 500 and missing > 500 and sum(s.aborted_steps for s in st) == 0
    # a mean lost to its holder in all l_max bundles that repeat it (0.3^5 each) stays unresolved
    assert repaired + unresolved == missing and unresolved <= 0.01 * missing
    if unresolved == 0:  # seed 1: Eq. (5) holds exactly again
        assert np.max(_group_sums(agents)) < 1e-9
    else:  # seed 7: 4 terms rho (w_ji - xbar_j) left off, each of the size of the consensus residual
        assert np.max(_group_sums(agents)) < 0.01
    pos = np.array([a.reference_state(75 * R * ROUND_S)[0] for a in agents])
    assert np.linalg.norm(pos - GOALS, axis=1).max() < 0.05


def test_a_late_bundle_is_counted_and_not_used() -> None:
    agents = _swarm()
    log = _Radio(agents).fly(range(2))
    old = log[0][1][1]  # drone 1's copies of sub-round 0 arriving in sub-round 2 (drone 0 expects means)
    agents[0].on_radio([RadioMessage(1, 0.0, 2 * ROUND_S, old)])
    _round(agents[0], 2 * ROUND_S)
    assert agents[0].stats.late_messages == 1 and agents[0].stats.means_missing == 2


def test_a_skipped_sub_round_aborts_the_step_and_the_drone_rejoins_at_the_next() -> None:
    agents = _swarm()
    radio = _Radio(agents)
    radio.fly(range(0, 4 * R), silent=lambda n, i: n == 3 and i == 2)  # sub-round 3 never ran on drone 2
    assert agents[2].stats.skipped_rounds == 1
    assert agents[2].stats.aborted_steps == 1 and agents[2].stats.steps == 2  # steps 1 and 2 completed
    assert all(a.stats.steps == 3 for a in agents if a.drone_id != 2)
    assert sum(a.stats.unresolved_means for a in agents) == 0


def test_a_failed_local_qp_ends_the_step_and_the_drone_keeps_its_plan(monkeypatch: pytest.MonkeyPatch) -> None:
    agents = _swarm()
    radio = _Radio(agents)
    radio.fly(range(0, R + 1))
    plan = agents[3].plan

    def fail() -> list:
        raise AdmmLocalQpError(3, "primal infeasible", np.zeros(1), np.zeros(1), np.zeros(1))

    monkeypatch.setattr(agents[3].admm, "local_step", fail)
    radio.fly(range(R + 1, R + 3))
    monkeypatch.undo()
    radio.fly(range(R + 3, 4 * R + 1))
    assert agents[3].stats.qp_failures == 1 and agents[3].stats.aborted_steps == 1
    assert agents[3].stats.steps == 3 and agents[3].plan is not plan
    assert all(a.stats.steps == 4 for a in agents[:3])


# ---------------------------------------------------------------------- config and scenario


@pytest.mark.parametrize(
    ("field", "value"),
    [("horizon_steps", 1), ("l_max", 0), ("step_s", 0.0), ("rho", -1.0), ("weight_input", 0.0),
     ("weight_formation", -1.0), ("limits", 2.0), ("altitude_range_m", (2.0, 1.0)), ("graph", "star"),
     ("warm_start", 1), ("max_start_offset_m", 0.0)],
)  # fmt: skip
def test_invalid_admm_settings_name_their_field(field: str, value: object) -> None:
    with pytest.raises(ConfigError) as e:
        AdmmAgentConfig(**{field: value})
    assert e.value.field == field


def test_the_radio_runs_at_the_admm_exchange_rate_derived_from_the_files_values() -> None:
    assert load_scenario("formation_open").radio.rate_hz == pytest.approx(50.0)  # 2 x 5 / 0.2 s
    assert load_scenario("formation_open", planner_kind="dmpc").radio.rate_hz == pytest.approx(5.0)  # the file's
    cfg = load_scenario("formation_open", {"admm": {"l_max": 4}})
    assert cfg.radio.rate_hz == pytest.approx(40.0)
    assert load_scenario("formation_open", {"radio": {"rate_hz": 50.0}, "admm": {"radio_rate_from_step": False}})
    with pytest.raises(ConfigError) as e:
        load_scenario("formation_open", {"admm": {"radio_rate_from_step": False}})
    assert e.value.field == "radio.rate_hz" and "50 Hz" in e.value.allowed


@pytest.mark.parametrize(
    ("overrides", "field"),
    [({"world": {"obstacle_density_per_100m2": 1.0}}, "world.obstacle_density_per_100m2"),
     ({"world": {"obstacles": [{"kind": "tree", "center_xy": [0.0, 4.0]}]}}, "world.obstacles"),
     ({"radio": {"delay_s": 0.02}}, "radio.delay_s"),
     ({"planner": {"kind": "admm", "cruise_speed_mps": 3.0}}, "planner.cruise_speed_mps"),
     ({"admm": {"altitude_range_m": [2.0, 3.0]}}, "drones.starts[0]"),
     ({"physics": {"physics_hz": 48.0}}, "physics.physics_hz")],
)  # fmt: skip
def test_scenarios_the_admm_planner_cannot_fly_are_refused_naming_the_field(overrides: dict, field: str) -> None:
    with pytest.raises(ConfigError) as e:
        load_scenario("formation_open", overrides)
    assert e.value.field == field


def test_starts_off_the_goals_formation_are_refused_for_want_of_collision_avoidance() -> None:
    with pytest.raises(ConfigError, match=r"^drones\.starts\[\d\]=.*no collision avoidance"):
        load_scenario("antipodal", planner_kind="admm")
    moved = {"drones": {"starts": (STARTS + [0.0, 0.0, 0.3]).tolist(), "goals": GOALS.tolist()}}
    assert load_scenario("formation_open", moved).planner.kind == "admm"  # a translated formation is fine


def test_make_agent_builds_the_admm_agent_with_the_goals_as_its_formation() -> None:
    cfg = load_scenario("formation_open")
    goals = np.asarray(cfg.drones.goals)
    agent = make_agent(cfg, 2, goals, ())
    assert isinstance(agent, AdmmAgent) and agent.neighbour_ids == (0, 1, 3)  # complete graph
    np.testing.assert_allclose(agent.formation.offset(2, 0), goals[2] - goals[0])
    assert agent.config.radio_rate_hz == pytest.approx(cfg.radio.rate_hz)
    assert replace(cfg.admm, graph="ring").formation(goals).neighbours(2) == (1, 3)


def test_formation_metrics_are_zero_for_the_goals_shape_anywhere_and_match_a_hand_value() -> None:
    pos = np.stack([GOALS + [1.0, -2.0, 0.5], GOALS])
    assert formation_metrics(pos, GOALS)["formation_error_max_m"] == pytest.approx(0.0, abs=1e-12)
    bent = GOALS.copy()
    bent[0] += [0.3, 0.0, 0.0]  # 3 of the 6 pairs off by 0.3 m
    m = formation_metrics(bent[None], GOALS)
    assert m["formation_error_final_m"] == pytest.approx(np.sqrt(3 * 0.09 / 6))
    assert formation_metrics(np.zeros((0, 4, 3)), GOALS)["formation_error_mean_m"] is None


# ---------------------------------------------------------------------- a drifted pose estimate

DRIFT = np.array([0.0, 0.0, -0.15])  # the drift traced on the forest for DMPC (docs/results/history/mp-cde.md#auto-at-the-current-code-seventeenth-sitting)


def test_a_drifted_estimate_starts_every_step_on_the_plan_at_the_default_tolerance() -> None:
    agents = _swarm()
    assert CONFIG.state_tolerance_m > np.linalg.norm(DRIFT)
    _Radio(agents, DRIFT).fly(range(75 * R))
    pos = np.array([a.reference_state(75 * R * ROUND_S)[0] for a in agents])
    assert np.linalg.norm(pos - GOALS, axis=1).max() < 0.01  # the drones fly their plans to the goals
    assert all(a.stats.state_resets == 0 for a in agents)


def test_a_tolerance_below_the_drift_ratchets_the_formation_below_its_goals() -> None:
    agents = _swarm(replace(CONFIG, state_tolerance_m=0.1))
    _Radio(agents, DRIFT).fly(range(75 * R))
    pos = np.array([a.reference_state(75 * R * ROUND_S)[0] for a in agents])
    assert np.all(pos[:, 2] < GOALS[:, 2] - 0.2)  # more than the drift itself: taken again step after step
    assert all(a.stats.state_resets > 30 for a in agents)
