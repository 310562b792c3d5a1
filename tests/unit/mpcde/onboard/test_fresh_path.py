"""Look before moving (mpcde.onboard.denied.look): which point of the corridor ahead is stale."""

import numpy as np
import pytest

from mpcde.config.denied import DeniedAgentConfig
from mpcde.onboard.denied.look import FreshPathWatch, first_stale_point
from perception.types import OccupancySnapshot
from planners.minco import minco_s3

VOXEL = 0.1
ORIGIN = np.array([-2.0, -2.0, 0.0])
SHAPE = (60, 40, 30)  # x -2..4, y -2..2, z 0..3


def _snapshot(seen_s: np.ndarray, state: np.ndarray | None = None, time_s: float = 10.0) -> OccupancySnapshot:
    state = np.zeros(SHAPE, np.int8) if state is None else state
    return OccupancySnapshot(time_s, ORIGIN.copy(), VOXEL, state, np.full(SHAPE, 3.0), np.full(SHAPE, 3.0), seen_s)


def _along_x(length=3.0, duration=6.0):
    start = np.array([[0.0, 0.0, 1.5], [0.0, 0.0, 0.0], [0.0, 0.0, 0.0]])
    goal = np.array([[length, 0.0, 1.5], [0.0, 0.0, 0.0], [0.0, 0.0, 0.0]])
    return minco_s3(start, goal, np.zeros((0, 3)), np.array([duration]), t0_s=0.0)


def _index(p):
    return tuple(np.floor((np.asarray(p) - ORIGIN) / VOXEL).astype(int))


KW = dict(max_age_s=1.0, half_width_m=0.25, near_m=0.3, far_m=1.3)


def test_a_corridor_seen_within_the_age_has_no_stale_point():
    assert first_stale_point(_snapshot(np.full(SHAPE, 9.5, np.float32)), _along_x(), 0.0, **KW) is None


def test_the_first_stale_point_in_path_order_is_returned_and_points_outside_the_corridor_do_not_count():
    seen = np.full(SHAPE, 9.5, np.float32)
    seen[_index([1.0, 0.25, 1.5])] = 8.0  # beside the path, 1 m ahead, seen 2 s ago
    seen[_index([0.8, 0.0, 1.5])] = 8.5  # on the path, nearer, seen 1.5 s ago
    seen[_index([0.5, 0.8, 1.5])] = 0.0  # 0.8 m aside: outside the corridor
    point = first_stale_point(_snapshot(seen), _along_x(), 0.0, **KW)
    assert point is not None and _index(point) == _index([0.8, 0.0, 1.5])
    seen[_index([0.8, 0.0, 1.5])] = 9.5
    point = first_stale_point(_snapshot(seen), _along_x(), 0.0, **KW)
    assert point is not None and _index(point) == _index([1.0, 0.25, 1.5])


@pytest.mark.parametrize("x", [0.1, 1.8])
def test_space_nearer_than_near_or_beyond_far_is_not_checked(x):
    seen = np.full(SHAPE, 9.5, np.float32)
    seen[_index([x, 0.0, 1.5])] = 0.0
    assert first_stale_point(_snapshot(seen), _along_x(), 0.0, **KW) is None


@pytest.mark.parametrize("state_value", [OccupancySnapshot.UNKNOWN, OccupancySnapshot.OCCUPIED])
def test_only_free_space_ages_unknown_and_occupied_voxels_are_not_stale(state_value):
    seen = np.full(SHAPE, 9.5, np.float32)
    state = np.zeros(SHAPE, np.int8)
    seen[_index([1.0, 0.0, 1.5])] = 0.0
    state[_index([1.0, 0.0, 1.5])] = state_value
    assert first_stale_point(_snapshot(seen, state), _along_x(), 0.0, **KW) is None
    state[_index([1.0, 0.0, 1.5])] = OccupancySnapshot.FREE
    assert first_stale_point(_snapshot(seen, state), _along_x(), 0.0, **KW) is not None


def test_the_corridor_follows_the_path_from_now_and_its_held_end_adds_nothing():
    seen = np.full(SHAPE, 9.5, np.float32)
    seen[_index([0.8, 0.0, 1.5])] = 0.0
    traj = _along_x()
    t_past = float(np.interp(1.2, traj.pos(np.linspace(0, 6, 601))[:, 0], np.linspace(0, 6, 601)))  # the drone is at x = 1.2
    assert first_stale_point(_snapshot(seen), traj, t_past, **KW) is None  # behind the drone now
    at_goal = _along_x(length=0.2, duration=1.0)  # the path ends 0.2 m ahead: nothing in [near, far] moves
    assert first_stale_point(_snapshot(np.zeros(SHAPE, np.float32)), at_goal, 0.0, **KW) is None


def test_without_seen_times_nothing_is_stale():
    assert first_stale_point(_snapshot(None), _along_x(), 0.0, **KW) is None


def _watch(**fields) -> FreshPathWatch:
    return FreshPathWatch(DeniedAgentConfig(fresh_path_age_s=1.0, **fields), period_s=0.1, same_point_m=2 * VOXEL)


def test_the_watch_checks_every_period_and_is_off_with_an_infinite_age():
    watch = _watch()
    assert watch.enabled and watch.due(0.0) and not watch.due(0.05) and watch.due(0.1) and not watch.due(0.15)
    assert not FreshPathWatch(DeniedAgentConfig(), 0.1, 0.2).enabled
    assert FreshPathWatch(DeniedAgentConfig(), 0.1, 0.2).metrics() == {}


def test_a_stale_point_begins_a_hold_an_ageing_one_a_glance_and_neither_while_glancing_begins_a_glance():
    watch = _watch()
    seen = np.full(SHAPE, 9.5, np.float32)
    seen[_index([0.8, 0.0, 1.5])] = 8.0  # stale (2 s), within stopping distance 0 + 1 m
    look = watch.check(_snapshot(seen), _along_x(), 0.0, 0.0, glancing=False)
    assert look is not None and look.stop and _index(look.point_world) == _index([0.8, 0.0, 1.5])
    assert watch.looking and watch.stops and watch.holds == 1 and watch.glances == 0
    watch.end()
    seen = np.full(SHAPE, 9.5, np.float32)
    seen[_index([1.8, 0.0, 1.5])] = 9.2  # 0.8 s old: ageing, beyond the hold's 1 m but within the glances' 2 m
    assert watch.check(_snapshot(seen), _along_x(), 0.0, 0.0, glancing=True) is None
    look = watch.check(_snapshot(seen), _along_x(), 0.0, 0.0, glancing=False)
    assert look is not None and not look.stop and watch.glances == 1 and not watch.stops
    assert _watch(fresh_path_glance_age_s=float("inf")).check(_snapshot(seen), _along_x(), 0.0, 0.0, glancing=False) is None


def test_a_point_not_refreshed_by_the_look_at_it_rests_the_check_for_the_rest_time():
    watch = _watch()  # fresh_path_rest_s: 2 s
    point = np.array([1.0, 0.0, 1.5])
    assert watch.begin(0.0, point, stop=True) is not None
    watch.end()
    assert watch.begin(0.5, point + 0.1, stop=True) is None  # within two voxels of the last look's point
    assert watch.unrefreshed == 1 and watch.holds == 1 and not watch.looking
    assert not watch.due(2.4) and watch.due(2.5)
    assert watch.begin(2.5, point, stop=True) is not None  # the memory of the last point was cleared by the rest
    assert watch.metrics() == {"fresh_path_holds": 2, "fresh_path_glances": 0, "fresh_path_unrefreshed": 1, "fresh_path_unsafe_stops": 0}


def test_a_hold_whose_stop_is_refused_begins_as_a_glance_and_can_stop_is_asked_only_for_a_hold():
    watch = _watch()
    asked = []
    look = watch.begin(0.0, np.array([1.0, 0.0, 1.5]), stop=True, can_stop=lambda: asked.append(1) or False)
    assert look is not None and not look.stop and not watch.stops and watch.looking
    assert (watch.holds, watch.glances, watch.unsafe_stops) == (0, 1, 1) and asked == [1]
    watch.end()
    assert watch.begin(0.5, np.array([2.0, 0.0, 1.5]), stop=False, can_stop=lambda: asked.append(1) or False).stop is False
    assert asked == [1]  # a glance does not ask
    assert watch.begin(1.0, np.array([3.0, 0.0, 1.5]), stop=True, can_stop=lambda: True).stop and watch.holds == 1
