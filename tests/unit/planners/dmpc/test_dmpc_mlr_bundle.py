"""MLR-DMPC pieces for drones that host the CUs: the per-drone bundle, a CU's start round, a late CU, report sums."""

from __future__ import annotations

import math

import numpy as np
import pytest

from planners.dmpc.mlr.compute_unit import ComputeUnit, CuStepReport, summarize_reports
from planners.dmpc.mlr.config import MlrConfig
from planners.dmpc.mlr.tracker import TrackerUpdate
from planners.dmpc.mlr.trajectory import ReferenceTrajectory, TrajectoryId
from planners.dmpc.mlr.types import CuTrajectoryMessage, MlrBundle, RecoveryReply, UavStateMessage
from planners.dmpc.mlr.uav import INITIAL_ID, initial_trajectory

CFG = MlrConfig(n_uavs=3, n_cus=1, horizon_rounds=5)
STARTS = np.array([[0.0, 0.0, 1.0], [1.5, 0.0, 1.0], [0.0, 1.5, 1.0]])
GOALS = STARTS + np.array([1.0, 0.0, 0.0])


def _state(i: int, k: int, following: TrajectoryId = INITIAL_ID) -> UavStateMessage:
    return UavStateMessage(i, k, STARTS[i], np.zeros(3), GOALS[i], following)


def test_initial_trajectory_hovers_where_it_starts() -> None:
    tr = initial_trajectory(CFG, STARTS[1], 0.4)
    x = tr.states_at(np.array([0.4, 3.0]))
    assert tr.meta == INITIAL_ID and np.allclose(x[:, :3], STARTS[1]) and np.allclose(x[:, 3:], 0.0)


def test_a_bundle_lists_its_messages_and_refuses_parts_of_other_rounds_or_drones() -> None:
    initial = initial_trajectory(CFG, STARTS[0])
    reply = RecoveryReply(0, 1, 4, initial)
    cu = CuTrajectoryMessage(0, 4, np.ones(3, np.uint8))
    b = MlrBundle(_state(0, 4), [reply], cu, initial)
    assert b.sender_id == 0 and b.round_index == 4
    assert [type(m) for m in b.messages()] == [UavStateMessage, RecoveryReply, CuTrajectoryMessage]
    assert b.messages()[0] is b.state and b.messages()[1] is reply and b.messages()[2] is cu
    lone = MlrBundle(_state(0, 4))
    assert len(lone.messages()) == 1 and lone.messages()[0] is lone.state
    with pytest.raises(ValueError, match="replies"):
        MlrBundle(_state(0, 4), (RecoveryReply(1, 1, 4, initial),))
    with pytest.raises(ValueError, match="cu_message.round_index"):
        MlrBundle(_state(0, 4), (), CuTrajectoryMessage(0, 3, np.ones(3, np.uint8)))
    computed = ReferenceTrajectory(TrajectoryId(2, 0), 0.6, initial.x0, initial.inputs, 0.2)
    with pytest.raises(ValueError, match="initial.meta"):
        MlrBundle(_state(0, 4), initial=computed)


def test_the_first_round_of_a_cu_started_late_in_the_run_misses_no_cu_slot() -> None:
    initial = [initial_trajectory(CFG, p) for p in STARTS]
    cu = ComputeUnit(CFG, 0, initial, GOALS, first_round=3)
    _, report = cu.step(3, [_state(i, 2) for i in range(3)])  # no CU message of round 2: nobody ran then
    assert report.deprecated == () and not report.tracker_update.all_deprecated


def test_a_cu_that_joins_late_starts_deprecated_and_is_restored_by_the_metadata() -> None:
    initial = [initial_trajectory(CFG, p) for p in STARTS]
    cu = ComputeUnit(CFG, 0, initial, GOALS, first_round=3, joined_late=True)
    assert cu.trackers.deprecated_ids == (0, 1, 2)
    # round 5: it hears UAVs 0 and 1 still on their initial hover, UAV 2's state message is lost
    msg, report = cu.step(5, [_state(0, 4), _state(1, 4)])
    assert report.tracker_update.restored == (0, 1) and report.deprecated == (2,)
    assert report.mode == "request" and report.uav_id == 2 and msg.uav_id == 2


def _report(k: int, mode: str, deprecated: tuple[int, ...] = ()) -> CuStepReport:
    return CuStepReport(k, mode, None, (0,), (), TrackerUpdate(deprecated, (), False))


def test_report_summary_counts_rounds_and_has_nan_timings_without_a_qp() -> None:
    reports = [_report(1, "idle"), _report(2, "request", (0, 2)), _report(3, "donate"), _report(3, "failed")]
    s = summarize_reports(reports)
    assert (s["rounds_with_mlr"], s["deprecated_trackers"], s["recovery_requests"], s["qp_failures"]) == (2, 2, 1, 1)
    assert s["computations"] == 0 and math.isnan(s["qp_solve_ms_median"]) and math.isnan(s["qp_iterations_median"])
