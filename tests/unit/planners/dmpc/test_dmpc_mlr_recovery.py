"""Lazy recovery (MlrConfig.lazy_recovery): which deprecated UAV a CU in MLR asks for, and when it waits instead."""

from __future__ import annotations

import numpy as np
import pytest

from planners.dmpc.mlr.compute_unit import ComputeUnit, summarize_reports
from planners.dmpc.mlr.config import MlrConfig
from planners.dmpc.mlr.trajectory import ReferenceTrajectory, TrajectoryId
from planners.dmpc.mlr.types import CuTrajectoryMessage, RecoveryReply, RecoveryRequest, UavStateMessage
from planners.dmpc.mlr.uav import INITIAL_ID, initial_trajectory

STARTS = np.array([[0.0, 0.0, 1.0], [1.5, 0.0, 1.0], [0.0, 1.5, 1.0]])
GOALS = STARTS + np.array([1.0, 0.0, 0.0])
UNKNOWN = TrajectoryId(0, 1)  # a trajectory CU 1 computed in round 0, which CU 0 never received


def _cfg(lazy: bool = True) -> MlrConfig:
    return MlrConfig(n_uavs=3, n_cus=2, horizon_rounds=5, lazy_recovery=lazy)


def _cu(lazy: bool = True) -> ComputeUnit:
    cfg = _cfg(lazy)
    return ComputeUnit(cfg, 0, [initial_trajectory(cfg, p) for p in STARTS], GOALS)


def _state(i: int, k: int, following: TrajectoryId = INITIAL_ID) -> UavStateMessage:
    return UavStateMessage(i, k, STARTS[i], np.zeros(3), GOALS[i], following)


def _prio() -> np.ndarray:
    return np.full(3, 5, np.uint8)


def test_a_lost_cu_message_makes_a_lazy_cu_wait_a_round_and_the_metadata_restores_it() -> None:
    cu = _cu()
    cu.step(0, [])
    # round 1: CU 1's message of round 0 is lost -> every tracker deprecated (Alg. 2 Line 18)
    msg, rep = cu.step(1, [_state(i, 0) for i in range(3)])
    assert rep.tracker_update.all_deprecated and rep.deprecated == (0, 1, 2)
    assert rep.mode == "wait" and isinstance(msg, CuTrajectoryMessage) and msg.trajectory is None
    # round 2: the state messages name trajectories the trackers hold: restored, no request, no donated slot
    msg, rep = cu.step(2, [_state(i, 1) for i in range(3)] + [CuTrajectoryMessage(1, 1, _prio())])
    assert rep.deprecated == () and rep.tracker_update.restored == (0, 1, 2)
    assert rep.mode in ("compute", "idle") and msg is not None


def test_the_eager_cu_asks_at_once_and_donates_its_next_slot() -> None:
    cu = _cu(lazy=False)
    cu.step(0, [])
    msg, rep = cu.step(1, [_state(i, 0) for i in range(3)])
    assert rep.mode == "request" and isinstance(msg, RecoveryRequest)
    msg, rep = cu.step(2, [_state(i, 1) for i in range(3)] + [CuTrajectoryMessage(1, 1, _prio())])
    assert rep.mode == "donate" and msg is None


def test_a_uav_that_names_an_unknown_trajectory_is_asked_for_first() -> None:
    cu = _cu()
    cu.step(0, [])
    # UAV 2 follows a trajectory of CU 1's lost message: only a reply can restore its tracker
    msg, rep = cu.step(1, [_state(0, 0), _state(1, 0), _state(2, 0, UNKNOWN)])
    assert cu.trackers[2].missing and not cu.trackers[0].missing
    assert rep.mode == "request" and rep.uav_id == 2 and isinstance(msg, RecoveryRequest) and msg.uav_id == 2
    # round 2 (donated): the metadata restores 0 and 1; round 3: UAV 2's reply restores it
    inbox = [_state(0, 1), _state(1, 1), _state(2, 1, UNKNOWN), CuTrajectoryMessage(1, 1, _prio())]
    msg, rep = cu.step(2, inbox)
    assert rep.mode == "donate" and msg is None and rep.deprecated == (2,)
    followed = ReferenceTrajectory.hover(UNKNOWN, 0.2, STARTS[2], _cfg().n_inputs, _cfg().input_step_s)
    _, rep = cu.step(3, [_state(i, 2) for i in range(2)] + [_state(2, 2, UNKNOWN), RecoveryReply(2, 0, 2, followed),
                                                            CuTrajectoryMessage(1, 2, _prio())])
    assert rep.deprecated == () and cu.trackers[2].metas == (UNKNOWN,) and not cu.trackers[2].missing


def test_a_uav_another_cu_asked_for_is_not_asked_for_again_its_reply_restores_both() -> None:
    cu = _cu()
    cu.step(0, [])
    inbox = [_state(0, 0), _state(1, 0), _state(2, 0, UNKNOWN), RecoveryRequest(1, 0, _prio(), 2)]
    msg, rep = cu.step(1, inbox)  # CU 1 asked UAV 2 in round 0; UAV 2 replies in round 1
    assert rep.deprecated == (2,) and not rep.tracker_update.all_deprecated  # CU 1's slot: its request
    assert rep.mode == "wait" and isinstance(msg, CuTrajectoryMessage) and msg.trajectory is None
    followed = ReferenceTrajectory.hover(UNKNOWN, 0.2, STARTS[2], _cfg().n_inputs, _cfg().input_step_s)
    _, rep = cu.step(2, [_state(i, 1) for i in range(2)] + [_state(2, 1, UNKNOWN), RecoveryReply(2, 1, 1, followed)])
    assert rep.deprecated == () and cu.trackers[2].metas == (UNKNOWN,)


def test_a_lazy_cu_waits_at_most_one_round_for_metadata_then_asks() -> None:
    cu = _cu()
    cu.step(0, [])
    _, rep = cu.step(1, [_state(i, 0) for i in range(3)])
    assert rep.mode == "wait"
    # round 2: UAV 1's state message is lost again: its tracker stays deprecated, and is now asked for
    msg, rep = cu.step(2, [_state(0, 1), _state(2, 1), CuTrajectoryMessage(1, 1, _prio())])
    assert rep.deprecated == (1,) and rep.mode == "request" and isinstance(msg, RecoveryRequest) and msg.uav_id == 1


@pytest.mark.parametrize("lazy", [True, False])
def test_a_cu_in_mlr_never_sends_a_trajectory(lazy: bool) -> None:
    """Whatever it chooses, a CU with a deprecated tracker computes nothing (the collision guarantee's premise)."""
    cu = _cu(lazy)
    cu.step(0, [])
    rng = np.random.default_rng(7)
    for k in range(1, 30):
        inbox = [_state(i, k - 1, cu.trackers[i].metas[-1]) for i in range(3) if rng.uniform() > 0.3]
        if rng.uniform() > 0.3:
            inbox.append(CuTrajectoryMessage(1, k - 1, _prio()))
        msg, rep = cu.step(k, inbox)
        if rep.deprecated:
            assert rep.mode in ("request", "donate", "wait")
            assert msg is None or isinstance(msg, RecoveryRequest) or msg.trajectory is None


def test_the_reports_say_why_trackers_went_and_whether_a_request_was_answered() -> None:
    cu = _cu(lazy=False)
    cu.step(0, [])
    _, rep = cu.step(1, [_state(i, 0) for i in range(3)])  # CU 1's message lost: a slot unaccounted for
    assert rep.tracker_update.causes == (("slot", 0), ("slot", 1), ("slot", 2)) and rep.answered is None
    assert rep.mode == "request"
    asked = rep.uav_id
    _, rep = cu.step(2, [_state(i, 1) for i in range(3) if i != asked] + [CuTrajectoryMessage(1, 1, _prio())])
    assert rep.mode == "donate" and rep.answered is None  # the reply is sent in this round's donated slot
    reply = RecoveryReply(asked, 0, 2, initial_trajectory(_cfg(), STARTS[asked]))
    _, rep = cu.step(3, [reply, CuTrajectoryMessage(1, 2, _prio())])
    assert rep.answered is True
    # a state message naming a trajectory the tracker lacks
    _, rep = cu.step(4, [_state(0, 3, UNKNOWN), _state(1, 3), _state(2, 3), CuTrajectoryMessage(1, 3, _prio())])
    assert ("unnamed", 0) in rep.tracker_update.causes


def test_the_summary_counts_where_the_cu_rounds_went() -> None:
    cu = _cu(lazy=False)
    reports = [cu.step(0, [])[1], cu.step(1, [_state(i, 0) for i in range(3)])[1]]
    reports.append(cu.step(2, [CuTrajectoryMessage(1, 1, _prio())])[1])
    s = summarize_reports(reports)
    assert s["cu_rounds"] == 3 and sum(s["cu_modes"].values()) == 3
    assert s["cu_modes"]["request"] == 1 and s["cu_modes"]["donate"] == 1
    assert s["deprecations_by_cause"]["slot"] == 3 and s["rounds_all_deprecated"] == 1
    assert s["recovery_answered"] == 0
