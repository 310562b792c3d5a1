"""The denied agent's heading: the yaw planner on its schedule, Alg. 1 line 13's trigger, the along-travel ablation."""

import numpy as np
import pytest

from mpcde.onboard.denied.heading import ActiveYaw, trajectory_view
from perception.types import NeighborPrediction, OccupancySnapshot
from planners.minco import minco_s3
from planners.yaw import YawPlannerConfig


def _free_map():
    shape = (60, 60, 24)
    return OccupancySnapshot(
        time_s=0.0, origin_world=np.array([-4.5, -4.5, 0.0]), voxel_m=0.15, state=np.zeros(shape, np.int8),
        distance_m=np.full(shape, 3.0, np.float32), free_distance_m=np.full(shape, 3.0, np.float32),
    )


def _line(t0=0.0):
    start = np.array([[0.0, 0.0, 1.5], [0.0, 0.0, 0.0], [0.0, 0.0, 0.0]])
    goal = np.array([[0.0, 3.0, 1.5], [0.0, 0.0, 0.0], [0.0, 0.0, 0.0]])  # along +y
    return minco_s3(start, goal, np.zeros((0, 3)), np.array([4.0]), t0_s=t0)


def _nb(p, seen_at):
    return NeighborPrediction.constant_velocity(1, "perception", seen_at, np.asarray(p, float), np.zeros(3), np.eye(6) * 1e-4)


def test_trajectory_view_reads_the_minco_trajectory_at_absolute_times_and_holds_its_end():
    traj = _line(t0=2.0)
    view = trajectory_view(traj, np.zeros(3))
    np.testing.assert_allclose(view.positions(np.array([2.0, 4.0, 9.0])), traj.pos(np.array([0.0, 2.0, 4.0])))
    assert view.end_time_s == pytest.approx(6.0)
    np.testing.assert_allclose(trajectory_view(None, np.array([1.0, 2.0, 3.0])).positions(np.array([0.0, 5.0])), [[1, 2, 3]] * 2)


def test_plans_every_period_and_the_reference_follows_the_plan_within_the_rate_limit():
    h = ActiveYaw(YawPlannerConfig(), True, 0.0, 0.7, 2.0)
    traj, snap = _line(), _free_map()
    assert h.due(0.0)
    h.update(0.0, snap, traj, np.zeros(3), [_nb([2.0, 0.0, 1.5], seen_at=0.0)])
    assert not h.due(0.05) and h.due(0.1)
    yaws = [h.reference(t, None)[0] for t in np.arange(0.0, 0.1, 1 / 240)]
    np.testing.assert_allclose(yaws, [h.plan.yaw_at(t)[0] for t in np.arange(0.0, 0.1, 1 / 240)])
    assert np.max(np.abs(np.diff(yaws))) <= 2.0 / 240 + 1e-9
    assert h.metrics()["yaw_plans"] == 1


def test_line_13_triggers_a_replan_for_a_neighbour_within_the_swarm_clearance_only():
    traj, snap = _line(), _free_map()
    near = ActiveYaw(YawPlannerConfig(), True, 0.0, 0.7, 2.0).update(0.0, snap, traj, np.zeros(3), [_nb([0.5, 0.0, 1.5], 0.0)])
    far = ActiveYaw(YawPlannerConfig(), True, 0.0, 0.7, 2.0).update(0.0, snap, traj, np.zeros(3), [_nb([2.5, 0.0, 1.5], 0.0)])
    assert near and not far  # a free map: S(0) is large, so only the distance term can fire


def test_the_ablation_heads_along_travel_rate_limited():
    h = ActiveYaw(YawPlannerConfig(), False, 0.0, 0.7, 2.0)
    assert not h.due(0.0) and h.metrics() == {}
    v = np.array([0.0, 1.0, 0.0])  # travel along +y: the heading turns to +pi/2 at 2 rad/s
    yaws = [h.reference(t, v)[0] for t in np.arange(0.0, 1.0, 1 / 240)]
    assert yaws[-1] == pytest.approx(np.pi / 2, abs=1e-9)
    assert np.max(np.diff(yaws)) <= 2.0 / 240 + 1e-9
