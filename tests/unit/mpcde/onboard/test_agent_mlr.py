"""The MLR-DMPC agent's rounds without physics: drones exchange their bundles by hand; the mlr: config and its checks.

The harness flies every drone exactly on its reference (its pose estimate is
the reference's state at the round), delivers each round's bundles at the
next round, and drops the ones a test says are lost.
"""

from __future__ import annotations

import dataclasses

from collections.abc import Callable
from dataclasses import replace

import numpy as np
import pytest

from mpcde.config.mlr import MlrAgentConfig
from mpcde.config.scenario import load_scenario
from mpcde.errors import ConfigError
from mpcde.stacks.build import make_agent
from mpcde.onboard.mlr import MlrAgent
from planners.dmpc.collision import ellipsoidal_distance
from planners.dmpc.mlr.types import MlrBundle
from planners.limits import KinematicLimits
from sim.rotations import quat_xyzw_from_yaw
from sim.types import PoseEstimate, RadioMessage

ROUND_S = 0.2
ANGLES = 2 * np.pi * np.arange(3) / 3
STARTS = np.c_[1.5 * np.cos(ANGLES), 1.5 * np.sin(ANGLES), np.full(3, 1.5)]
GOALS = STARTS * np.array([-1.0, -1.0, 1.0])  # a three-drone swap through the centre
START_YAW = 0.7
Drop = Callable[[int, int, int], bool]  # (round, sender, receiver) -> lost


def _round(agent, t: float):
    """One radio round of ``agent`` at ``t``: plan, then what it broadcasts (what the loop does)."""
    agent.plan_round(t)
    return agent.outgoing(t)


def _estimate(t: float, pos: np.ndarray, vel: np.ndarray | None = None) -> PoseEstimate:
    vel = np.zeros(3) if vel is None else vel
    return PoseEstimate(t, np.asarray(pos, float), np.asarray(vel, float), quat_xyzw_from_yaw(START_YAW), np.zeros(3))


def _swarm(n_cus: int = 1, start_delay_s: float = 0.4, keep_ambiguous: bool = True) -> list[MlrAgent]:
    cfg = MlrAgentConfig(num_compute_units=n_cus).planner_config(3, (12.0, 12.0))
    cfg = dataclasses.replace(cfg, keep_ambiguous=keep_ambiguous)
    agents = [MlrAgent(i, GOALS, cfg, start_delay_s) for i in range(3)]
    for a, p in zip(agents, STARTS):
        a.on_pose_estimate(_estimate(0.0, p))
    return agents


class _Radio:
    """Delivers each round's bundles at the next round, except those ``drop`` says are lost."""

    def __init__(self, agents: list[MlrAgent]) -> None:
        self.agents = agents
        self.inbox: list[list[RadioMessage]] = [[] for _ in agents]

    def fly(self, rounds: range, drop: Drop = lambda k, s, r: False) -> tuple[list, float]:
        """Run ``rounds``; returns (every round's bundles, smallest reference distance at the round times [m])."""
        agents, n = self.agents, len(self.agents)
        log, d_min = [], np.inf
        iu = np.triu_indices(n, 1)
        for k in rounds:
            t = k * ROUND_S
            for a in agents:
                pos, vel, _ = a.reference_state(t)
                a.on_pose_estimate(_estimate(t, pos, vel))
                a.on_radio(self.inbox[a.drone_id])
            sent = [(a.drone_id, _round(a, t)) for a in agents]
            log.append(sent)
            self.inbox = [[RadioMessage(s, t, t, b) for s, b in sent if s != r and not drop(k, s, r)] for r in range(n)]
            refs = np.array([a.reference_state(t)[0] for a in agents])
            d = ellipsoidal_distance(refs[iu[0]] - refs[iu[1]], agents[0].config.downwash)
            d_min = min(d_min, float(d.min()))
        return log, d_min


def _fly(agents: list[MlrAgent], rounds: range, drop: Drop = lambda k, s, r: False) -> tuple[list, float]:
    return _Radio(agents).fly(rounds, drop)


def test_before_the_compute_units_start_every_drone_hovers_and_sends_its_initial_trajectory() -> None:
    agents = _swarm(start_delay_s=0.5)
    assert agents[0].start_round == 3  # the first round at or after the start delay
    log, _ = _fly(agents, range(3))
    for sent in log:
        for i, b in sent:
            assert isinstance(b, MlrBundle) and b.cu_message is None and b.initial is not None
            assert np.allclose(b.initial.x0[:3], STARTS[i])
    ref = agents[1].reference(0.55)
    assert np.allclose(ref.pos_world, STARTS[1]) and np.allclose(ref.vel_world, 0.0)
    assert ref.yaw == pytest.approx(START_YAW)


def test_exchanged_bundles_fly_every_drone_to_its_goal_on_continuous_references_kept_apart() -> None:
    agents = _swarm(n_cus=2)
    log, d_min = _fly(agents, range(60))
    assert [a.stats.cu_start_round for a in agents] == [2, 2, None]
    for a in agents:
        assert a.stats.switches > 0 and a.stats.max_reference_jump_m < 1e-9
        assert np.linalg.norm(a.reference_state(60 * ROUND_S)[0] - GOALS[a.drone_id]) < 0.1
    assert d_min >= agents[0].config.d_hat_min_m - 0.01  # Eq. 15 at the check times (T_c = T)
    metrics = [a.extra_metrics() for a in agents]
    assert metrics[0]["computations"] > 0 and metrics[1]["computations"] > 0 and metrics[2]["computations"] == 0
    assert metrics[2]["qp_solve_ms_median"] is None
    # no recovery: each host's CU hears its own drone's state messages onboard (a drone never hears itself)
    assert sum(m["recovery_requests"] + m["deprecated_trackers"] for m in metrics) == 0
    assert all(b.initial is None for _, b in log[-1])  # nobody follows its initial hover any more


@pytest.mark.parametrize("keep_ambiguous", [False, True])
def test_lost_bundles_are_recovered_by_request_and_reply_and_the_references_stay_apart(keep_ambiguous: bool) -> None:
    agents = _swarm(n_cus=1, keep_ambiguous=keep_ambiguous)
    rng = np.random.default_rng(3)
    lost = rng.uniform(size=(40, 3, 3)) < 0.3
    radio = _Radio(agents)
    _, d_lossy = radio.fly(range(40), lambda k, s, r: bool(lost[k, s, r]))
    _, d_after = radio.fly(range(40, 70))
    m = [a.extra_metrics() for a in agents]
    if keep_ambiguous:  # one CU: only lost state messages of a just-recomputed drone deprecate, and step 2b keeps them
        assert m[0]["deprecated_trackers"] == 0 and m[0]["computations"] > 0
    else:  # Alg. 2 Line 13 as in the paper
        assert m[0]["recovery_requests"] > 0 and m[0]["deprecated_trackers"] > 0 and m[0]["rounds_with_mlr"] > 0
        assert sum(x["recovery_replies"] for x in m) > 0
    assert not agents[0].cu.trackers.any_deprecated  # recovered once the radio works again
    assert all(a.stats.max_reference_jump_m < 1e-9 for a in agents)
    assert min(d_lossy, d_after) >= agents[0].config.d_hat_min_m - 0.01


def test_a_cu_that_missed_an_initial_trajectory_joins_late_and_still_flies_the_swarm() -> None:
    agents = _swarm(n_cus=1)  # k0 = 2
    _fly(agents, range(70), lambda k, s, r: k <= 2 and s == 2 and r == 0)  # drone 2 unheard by the host until round 3
    assert agents[0].stats.cu_start_round == 4  # round 3's bundles are read in round 4
    assert agents[0].extra_metrics()["recovery_requests"] == 0  # the metadata restored every tracker at once
    assert all(np.linalg.norm(a.reference_state(70 * ROUND_S)[0] - GOALS[a.drone_id]) < 0.1 for a in agents)
    # the host flew trajectories its own CU computed: they reach its UAV onboard
    assert agents[0].uav.switches and all(traj.meta.cu_id == 0 for _, traj in agents[0].uav.switches)


def test_a_bundle_of_an_earlier_round_is_dropped_and_counted() -> None:
    agents = _swarm(n_cus=1)
    log, _ = _fly(agents, range(2))
    stale = RadioMessage(1, 0.0, 0.0, log[0][1][1])  # drone 1's round-0 bundle arriving in round 2
    agents[0].on_radio([stale])
    _round(agents[0], 2 * ROUND_S)
    assert agents[0].stats.late_bundles == 1 and 1 not in {b.sender_id for b in agents[0]._received}


# ---------------------------------------------------------------------- config


@pytest.mark.parametrize(
    ("field", "value"),
    [("num_compute_units", 0), ("horizon_rounds", 1), ("trigger", "fifo"), ("limits", 1.0), ("d_hat_min_m", 0.0),
     ("downwash", 0.5), ("altitude_range_m", (2.0, 1.0)), ("arena_margin_m", float("nan"))],
)  # fmt: skip
def test_invalid_mlr_settings_name_their_field(field: str, value: object) -> None:
    with pytest.raises(ConfigError) as e:
        MlrAgentConfig(**{field: value})
    assert e.value.field == field and "\n" not in str(e.value)


def test_planner_config_takes_n_from_the_scenario_and_the_box_from_the_arena() -> None:
    cfg = MlrAgentConfig(num_compute_units=3, trigger="db", limits=KinematicLimits(1.5, 3.0, 10.0)).planner_config(7, (12.0, 10.0))
    assert (cfg.n_uavs, cfg.n_cus, cfg.trigger, cfg.limits.v_max_mps) == (7, 3, "db", 1.5)
    assert cfg.pos_min_world == (-5.7, -4.7, 0.3) and cfg.pos_max_world == (5.7, 4.7, 3.0)


def _mlr_scenario(**overrides: object):
    base = {"planner": {"kind": "mlr"}, "drones": {"layout": "antipodal", "count": 4, "radius_m": 3.0}}
    return load_scenario("antipodal", {**base, **overrides})


@pytest.mark.parametrize(
    ("overrides", "field"),
    [({"mlr": {"num_compute_units": 4}}, "mlr.num_compute_units"),
     ({"world": {"arena_size_m": [12.0, 12.0], "obstacles": [{"kind": "tree", "center_xy": [0.0, 0.0]}]}},
      "world.obstacles"),
     ({"world": {"arena_size_m": [12.0, 12.0], "obstacle_density_per_100m2": 2.0}}, "world.obstacle_density_per_100m2"),
     ({"radio": {"rate_hz": 10.0}}, "mlr.round_s"),
     ({"radio": {"delay_s": 0.2}}, "radio.delay_s"),
     ({"drones": {"layout": "antipodal", "count": 4, "radius_m": 3.0, "altitude_m": 3.5}}, "drones.starts[0]"),
     ({"mlr": {"trigger": "fifo"}}, "mlr.trigger")],
)  # fmt: skip
def test_a_scenario_mlr_cannot_fly_is_refused_naming_the_field(overrides: dict, field: str) -> None:
    with pytest.raises(ConfigError) as e:
        _mlr_scenario(**overrides)
    assert e.value.field == field and "\n" not in str(e.value)


def test_switching_an_obstacle_scenario_to_mlr_is_refused() -> None:
    cfg = load_scenario("forest_sparse")
    with pytest.raises(ConfigError, match="no obstacle constraints") as e:
        replace(cfg, planner=replace(cfg.planner, kind="mlr"))
    assert e.value.field == "world.obstacle_density_per_100m2"


def test_make_agent_builds_an_mlr_agent_per_drone_with_cus_on_the_first_drones() -> None:
    cfg = _mlr_scenario(mlr={"num_compute_units": 2, "trigger": "rr"})
    goals = np.asarray(GOALS.tolist() + [[0.0, -1.5, 1.5]])
    agents = [make_agent(cfg, i, goals, ()) for i in range(4)]
    assert all(isinstance(a, MlrAgent) for a in agents)
    assert [a.cu_index for a in agents] == [0, 1, None, None]
    assert agents[0].config.n_uavs == 4 and agents[0].config.trigger == "rr"
    assert getattr(agents[0], "detector_request", None) is None  # it does not perceive


def test_mlr_is_a_mode_of_fly_and_compare() -> None:
    from mpcde.cli import build_parser
    from mpcde.evals.compare import check_modes
    from mpcde.stacks import get_stack

    assert get_stack("mlr").kind == "mlr" and check_modes(["comm", "mlr"]) == ("comm", "mlr")
    args = build_parser().parse_args(["fly", "antipodal", "--mode", "mlr", "--out", "x"])
    assert get_stack(args.mode).kind == "mlr"
