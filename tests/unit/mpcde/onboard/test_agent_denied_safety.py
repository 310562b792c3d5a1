"""The denied agent's fallback stop: committed until a replan succeeds, not restarted at every frame (no flight)."""

import numpy as np
import pytest

from mpcde.config.denied import DeniedAgentConfig
from mpcde.onboard.denied import DeniedAgent
from planners.minco import minco_s3

GOAL = np.array([6.0, 0.0, 1.5])


def _line(start: np.ndarray, velocity: np.ndarray, duration_s: float = 1.0, t0_s: float = 0.0):
    """A single MINCO piece at constant ``velocity`` [m/s] from ``start`` [m]."""
    head = np.stack([start, velocity, np.zeros(3)])
    tail = np.stack([start + velocity * duration_s, velocity, np.zeros(3)])
    return minco_s3(head, tail, np.zeros((0, 3)), np.array([duration_s]), t0_s=t0_s)


def test_a_stop_under_way_is_kept_not_restarted_at_every_failed_replan():
    agent = DeniedAgent(0, GOAL, DeniedAgentConfig())
    agent.trajectory = _line(np.array([0.0, 0.0, 1.5]), np.array([2.0, 0.0, 0.0]), 3.0)
    agent.brake(0.0)
    committed = agent.trajectory
    for k in range(1, 13):  # a failed replan at every 25 Hz frame for half a second
        agent.brake(0.04 * k)
    assert agent.trajectory is committed and agent.stats.brakes == 1
    v_kept = np.linalg.norm(agent.state_at(0.5)[1])

    restarted = DeniedAgent(0, GOAL, DeniedAgentConfig())  # what restarting at every frame would give
    restarted.trajectory = _line(np.array([0.0, 0.0, 1.5]), np.array([2.0, 0.0, 0.0]), 3.0)
    for k in range(13):
        restarted.trajectory = restarted._stopping_piece(0.04 * k, restarted.state_at(0.04 * k))
    v_restarted = np.linalg.norm(restarted.state_at(0.5)[1])
    start = np.stack([[0.0, 0.0, 1.5], [2.0, 0.0, 0.0], np.zeros(3)])
    once = DeniedAgent(0, GOAL, DeniedAgentConfig())._stopping_piece(0.0, start)
    np.testing.assert_allclose(agent.state_at(0.5), np.stack([once.pos(0.5), once.vel(0.5), once.acc(0.5)]), atol=1e-12)
    assert v_restarted > v_kept + 0.2  # restarted: 1.62 m/s after 0.5 s against 1.37 committed


def test_a_successful_replan_ends_the_stop_and_the_next_brake_starts_a_new_one():
    agent = DeniedAgent(0, GOAL, DeniedAgentConfig())
    agent.trajectory = _line(np.array([0.0, 0.0, 1.5]), np.array([2.0, 0.0, 0.0]), 3.0)
    agent.brake(0.0)
    agent.trajectory, agent.braking = _line(np.array([1.0, 0.0, 1.5]), np.array([1.0, 0.0, 0.0]), 3.0, 1.0), False
    agent.brake(1.2)
    assert agent.stats.brakes == 2 and agent.trajectory.t0_s == 1.2


def test_without_flight_levels_the_first_pose_estimate_sets_no_layer():
    from sim.types import PoseEstimate

    free = DeniedAgent(0, np.array([6.0, 0.0, 2.0]), DeniedAgentConfig())
    for z in (1.5, 1.8):
        free.on_pose_estimate(PoseEstimate(0.0, np.array([0.0, 0.0, z]), np.zeros(3), np.array([0.0, 0.0, 0.0, 1.0]), np.zeros(3)))
    assert free.optimizer.altitude_band_m == (-np.inf, np.inf) and free.search.max_altitude_m == np.inf
    assert free.levels is None


def test_a_drone_handed_over_inside_the_obstacle_band_may_leave_it_no_closer_than_it_was():
    agent = DeniedAgent(0, np.array([6.0, 0.0, 1.5]), DeniedAgentConfig())
    band, half_voxel = 0.75 * agent.config.clearance_m, 0.5 * agent.config.map.voxel_m
    at = lambda d: (lambda p: np.full(len(p), d))  # noqa: E731  a map whose every point is d [m] from obstacles
    here = np.zeros(3)
    assert agent.escape.floor(at(0.2), here, band) is None  # a drone that entered the band in flight: the band holds
    agent.look_around_at(1.0, np.array([0.0, 0.0, 1.5]), 0.0)
    assert agent.escape.floor(at(0.2), here, band) == pytest.approx(0.2 - half_voxel)
    assert agent.escape.floor(at(0.15), here, band) == pytest.approx(0.2 - half_voxel)  # fixed: no ratchet inwards
    assert agent.escape.floor(at(band), here, band) is None  # out of the band: the rule ends for good
    assert agent.escape.floor(at(0.2), here, band) is None


def test_a_stop_that_ends_inside_the_obstacle_band_begins_an_escape_no_closer_than_where_it_rests(monkeypatch):
    agent = DeniedAgent(0, GOAL, DeniedAgentConfig())
    band, half_voxel = 0.75 * agent.config.clearance_m, 0.5 * agent.config.map.voxel_m
    clearance = {"d": 0.2}
    monkeypatch.setattr(agent.map, "clearance", lambda p: np.full(len(p), clearance["d"]))
    agent.trajectory = _line(np.array([0.0, 0.0, 1.5]), np.array([1.0, 0.0, 0.0]), 3.0)
    assert not agent.escape.resting_in_band(agent, 5.0)  # a plan, not a stop: whatever its end, no escape
    agent.brake(0.0)
    stop = agent.trajectory
    end = stop.t0_s + stop.total_duration
    assert not agent.escape.resting_in_band(agent, end - 0.04)  # still stopping
    assert agent.escape.resting_in_band(agent, end)
    clearance["d"] = band
    assert not agent.escape.resting_in_band(agent, end)  # at rest outside the band: the band holds
    clearance["d"] = 0.2
    # the first frame at rest: the camera turns once round where the drone rests (nothing planned), then the escape
    from mpcde.onboard.denied.heading import ActiveYaw

    agent.heading = ActiveYaw(agent.yaw_config, True, 0.3, agent.config.swarm_clearance_m, agent.config.swarm_z_scale)
    assert agent.escape.holds(agent, end) and agent.stats.rest_escapes == 1
    turn = 2.0 * np.pi / agent.config.yaw_rate_max_radps
    assert agent.escape.turn == pytest.approx((end, 0.3, end + turn))
    np.testing.assert_allclose(agent.hover_world, stop.pos(np.array([stop.total_duration]))[0])
    assert agent.escape.holds(agent, end + turn - 0.04) and not agent.escape.holds(agent, end + turn)
    assert agent.trajectory is None and not agent.escape.resting_in_band(agent, end + turn + 1.0)  # one escape at a time
    assert not agent.escape.holds(agent, end + turn + 1.0) and agent.stats.rest_escapes == 1
    floor = agent.escape.floor(agent.map.clearance, agent.state_at(end + turn)[0], band)
    assert floor == pytest.approx(0.2 - half_voxel)
    assert agent._safe(stop, agent.map.clearance, end, floor)  # hovering where it rests is no longer refused
    assert not agent._safe(stop, agent.map.clearance, end)  # (it was, at every frame, before)
    closer = lambda p: np.full(len(p), 0.2 - 2 * half_voxel)  # noqa: E731  a plan that goes further in
    away = _line(stop.pos(np.array([stop.total_duration]))[0], np.array([0.0, 1.0, 0.0]), 1.0, end)
    assert not agent._safe(away, closer, end, floor)
    assert agent._safe(away, agent.map.clearance, end, floor)


def test_front_end_refusals_are_counted_by_status_and_fallbacks_counted(monkeypatch):
    from types import SimpleNamespace

    import mpcde.onboard.denied.agent as denied
    from planners.path_search import PathSearchResult

    agent = DeniedAgent(0, GOAL, DeniedAgentConfig())
    agent.trajectory = _line(np.array([0.0, 0.0, 1.5]), np.array([1.0, 0.0, 0.0]), 3.0)
    snap = SimpleNamespace(distance_m=None)
    outcome = {"r": PathSearchResult("goal_blocked", None, None, 0, np.inf, np.zeros(3), True)}
    monkeypatch.setattr(denied, "with_neighbour_capsules", lambda s, *a, **k: s)
    allowed = []
    monkeypatch.setattr(denied, "search_path", lambda *a, goal_fallback: allowed.append(goal_fallback) or outcome["r"])
    assert not agent._replan(snap, [], 0.0) and not agent._replan(snap, [], 0.04)
    assert allowed == [False, False]  # flying a plan: its window moves, so no fallback point
    agent.brake(0.04)
    outcome["r"] = PathSearchResult("no_path", None, None, 10, np.inf, np.zeros(3), False)
    assert not agent._replan(snap, [], 0.08)
    path = np.array([[0.0, 0.0, 1.5], [4.9, 0.0, 1.5]])
    outcome["r"] = PathSearchResult("found", path, path, 10, 4.9, path[-1], True, goal_fallback=True)

    def refuse(*a):
        raise ValueError("optimiser refused")

    monkeypatch.setattr(denied, "build_trajectory_problem", refuse)
    assert not agent._replan(snap, [], 0.12)  # the fallback path was found (counted); the optimiser then failed
    assert allowed[2:] == [True, True]  # stopping: the fallback is allowed
    m = agent.extra_metrics()
    assert m["front_end_failures"] == {"goal_blocked": 2, "no_path": 1}
    assert m["goal_fallbacks"] == 1 and m["plan_failures"] == 4


def test_a_drone_at_rest_at_its_plans_end_may_fall_back(monkeypatch):
    """At rest where its plan ends (the climb to its flight level ends in a hover) the window no longer moves, so
    the front end's fallback point is allowed, as for a drone stopping (2 m/s seed 41: 562 refusals over 23 s)."""
    from types import SimpleNamespace

    import mpcde.onboard.denied.agent as denied
    from planners.path_search import PathSearchResult

    agent = DeniedAgent(0, GOAL, DeniedAgentConfig())
    agent.trajectory = _line(np.array([0.0, 0.0, 1.5]), np.array([0.0, 0.0, 0.2]), 1.0, t0_s=2.0)
    monkeypatch.setattr(denied, "with_neighbour_capsules", lambda s, *a, **k: s)
    allowed = []
    refused = PathSearchResult("no_path", None, None, 10, np.inf, np.zeros(3), True)
    monkeypatch.setattr(denied, "search_path", lambda *a, goal_fallback: allowed.append(goal_fallback) or refused)
    for t in (2.0, 2.96, 3.0, 4.5):
        assert not agent._replan(SimpleNamespace(distance_m=None), [], t)
    assert allowed == [False, False, True, True]
    assert agent.extra_metrics()["front_end_failures"] == {"no_path": 4}


def _first_estimate(agent: DeniedAgent, pos: np.ndarray) -> None:
    from sim.types import PoseEstimate

    agent.on_pose_estimate(PoseEstimate(0.0, np.asarray(pos, float), np.zeros(3), np.array([0.0, 0.0, 0.0, 1.0]), np.zeros(3)))


def test_flight_levels_are_spaced_by_id_about_the_mission_altitude_and_distinct():
    goal = np.array([9.0, 0.0, 1.5])
    config = DeniedAgentConfig(flight_level_spacing_m=0.4)
    levels = []
    for k in range(6):
        agent = DeniedAgent(k, goal, config, swarm_size=6)
        _first_estimate(agent, [-9.0, 0.0, 1.5])
        levels.append(agent.levels.level_m)
    np.testing.assert_allclose(levels, 1.5 + 0.4 * (np.arange(6) - 2.5))
    free = DeniedAgent(0, goal, DeniedAgentConfig(), swarm_size=6)
    _first_estimate(free, [-9.0, 0.0, 1.5])
    assert free.levels is None
    np.testing.assert_array_equal(free._level_goal(np.array([0.0, 0.0, 1.5])), goal)  # no levels: the goal, no layer
    assert free.optimizer.altitude_band_m == (-np.inf, np.inf)


def test_a_drone_climbs_to_its_level_in_place_is_held_there_and_released_near_its_goal():
    goal = np.array([9.0, 0.0, 1.5])
    agent = DeniedAgent(5, goal, DeniedAgentConfig(flight_level_spacing_m=0.4), swarm_size=6)
    _first_estimate(agent, [-9.0, 0.0, 1.5])
    level, b, pad = 2.5, 0.05, agent.config.map.voxel_m
    assert agent.levels.level_m == pytest.approx(level)
    # climbing: in place, the layer spans the current altitude and the level
    np.testing.assert_allclose(agent._level_goal(np.array([-9.0, 0.1, 1.5])), [-9.0, 0.1, level])
    assert agent.optimizer.altitude_band_m == pytest.approx((1.5 - b, level + b))
    assert (agent.search.min_altitude_m, agent.search.max_altitude_m) == pytest.approx((1.5 - b - pad, level + b + pad))
    np.testing.assert_allclose(agent._level_goal(np.array([-9.0, 0.1, 2.2])), [-9.0, 0.1, level])  # still climbing
    assert agent.optimizer.altitude_band_m == pytest.approx((2.2 - b, level + b))
    # reached (within s / 8): to the goal carried to the level, held to the level from then on
    np.testing.assert_allclose(agent._level_goal(np.array([-9.0, 0.0, level - 0.04])), [9.0, 0.0, level])
    agent._level_goal(np.array([-6.0, 0.0, level - 0.3]))
    assert agent.optimizer.altitude_band_m == pytest.approx((level - b, level + b))
    # within flight_level_release_m (1 m) of the goal horizontally: the goal itself, the layer down to it
    np.testing.assert_allclose(agent._level_goal(np.array([8.2, 0.3, level])), goal)
    assert agent.optimizer.altitude_band_m == pytest.approx((1.5 - b, level + b))
    # released for good: pushed back out of the radius, it does not climb back
    np.testing.assert_allclose(agent._level_goal(np.array([7.0, 0.0, 2.0])), goal)


def test_reaching_the_level_on_a_climb_triggers_the_replan_to_the_goal():
    agent = DeniedAgent(0, np.array([9.0, 0.0, 1.5]), DeniedAgentConfig(flight_level_spacing_m=0.4), swarm_size=2)
    _first_estimate(agent, [-9.0, 0.0, 1.5])  # level 1.3 m
    assert not agent._climbed(0.0)  # no plan in hand
    agent.trajectory = _line(np.array([-9.0, 0.0, 1.5]), np.array([0.0, 0.0, -0.2]))
    assert not agent._climbed(0.5) and agent._climbed(0.9)  # 1.4 m, then 1.32 m: within s / 8 of 1.3 m
    agent.levels.reached = True
    assert not agent._climbed(0.9)  # once reached, the replan period rules again


@pytest.mark.parametrize("fields", [{"flight_level_spacing_m": 0.0}, {"flight_level_spacing_m": -1.0}, {"flight_level_release_m": -0.1}])
def test_flight_level_settings_are_checked(fields):
    from sim.checks import ConfigError

    with pytest.raises(ConfigError):
        DeniedAgentConfig(**fields)


def test_look_before_moving_stops_turns_the_camera_to_the_stale_point_then_replans_and_rests_if_it_stays_stale(monkeypatch):
    """denied.fresh_path_age_s: a stale point in the corridor ahead holds the drone, the camera turns to it at the rate
    limit, two t_y after it is on the point the drone replans; a point still stale after that look rests the check."""
    from perception.types import OccupancySnapshot

    cfg = DeniedAgentConfig(fresh_path_age_s=1.0, start_delay_s=0.0)
    agent = DeniedAgent(0, np.array([0.0, 6.0, 1.5]), cfg)
    _first_estimate(agent, np.array([0.0, 0.0, 1.5]))  # yaw 0: facing +x
    agent.trajectory = _line(np.array([0.0, 0.0, 1.5]), np.array([0.0, 0.5, 0.0]), 6.0)  # along +y at 0.5 m/s
    shape, origin, voxel = (40, 60, 30), np.array([-2.0, -1.0, 0.0]), 0.1
    seen = np.full(shape, 0.95, np.float32)
    stale = tuple(np.floor((np.array([0.0, 0.8, 1.5]) - origin) / voxel).astype(int))
    seen[stale] = -1.0  # 0.8 m ahead, seen 2 s before the frame at 1.0 s
    snap = lambda: OccupancySnapshot(1.0, origin, voxel, np.zeros(shape, np.int8), np.full(shape, 3.0), np.full(shape, 3.0), seen)  # noqa: E731
    monkeypatch.setattr(agent.map, "snapshot", snap)
    monkeypatch.setattr(agent.map, "clearance", lambda p: np.full(len(np.reshape(p, (-1, 3))), 3.0))  # no obstacles
    replans = []
    monkeypatch.setattr(agent, "_replan", lambda s, n, t: replans.append(t) or False)

    agent.plan_step(0.2)
    assert agent.look.watch.holds == 1 and agent.braking
    turn_s = (np.pi / 2) / cfg.yaw_rate_max_radps  # from yaw 0 to +y
    yaw, rate = agent.reference(0.2 + 0.5 * turn_s).yaw, agent.reference(0.2 + 0.5 * turn_s).yaw_rate
    assert yaw == pytest.approx(np.pi / 4, abs=1e-6) and rate == pytest.approx(cfg.yaw_rate_max_radps)
    n_before = len(replans)
    agent.plan_step(0.2 + turn_s + 0.1)  # on the point for one t_y: still held, no replan
    assert len(replans) == n_before and agent.look.watch.looking
    agent.plan_step(0.2 + turn_s + 0.2 + 1e-6)  # two t_y: released, replans at once
    assert not agent.look.watch.looking and replans[-1] == pytest.approx(0.2 + turn_s + 0.2 + 1e-6)
    assert agent.reference(0.2 + turn_s + 0.3).yaw == pytest.approx(np.pi / 2, abs=0.25)

    agent.trajectory, agent.braking = _line(np.array([0.0, 0.0, 1.5]), np.array([0.0, 0.5, 0.0]), 6.0, t0_s=1.3), False
    agent.plan_step(1.4)  # the same point still stale after the look: the check rests instead of holding again
    assert agent.look.watch.holds == 1 and agent.look.watch.unrefreshed == 1 and not agent.braking
    agent.plan_step(1.5)
    assert agent.look.watch.holds == 1  # resting for fresh_path_rest_s
    m = agent.extra_metrics()
    assert m["fresh_path_holds"] == 1 and m["fresh_path_unrefreshed"] == 1
    assert "fresh_path_holds" not in DeniedAgent(0, GOAL, DeniedAgentConfig()).extra_metrics()


def test_an_ageing_point_ahead_turns_the_camera_to_it_while_the_drone_flies_on(monkeypatch):
    """denied.fresh_path_glance_age_s: space older than the glance age (not yet stale) is glanced at without a stop;
    the yaw plan is suspended until the camera has been on it for two t_y; replanning goes on meanwhile."""
    from perception.types import OccupancySnapshot

    cfg = DeniedAgentConfig(fresh_path_age_s=1.0, start_delay_s=0.0)
    agent = DeniedAgent(0, np.array([0.0, 6.0, 1.5]), cfg)
    _first_estimate(agent, np.array([0.0, 0.0, 1.5]))
    agent.trajectory = _line(np.array([0.0, 0.0, 1.5]), np.array([0.0, 0.5, 0.0]), 6.0)  # along +y
    shape, origin, voxel = (40, 60, 30), np.array([-2.0, -1.0, 0.0]), 0.1
    seen = np.full(shape, 0.95, np.float32)
    seen[tuple(np.floor((np.array([0.0, 1.8, 1.5]) - origin) / voxel).astype(int))] = 0.3  # 0.7 s old, 1.8 m ahead
    snap = lambda: OccupancySnapshot(1.0, origin, voxel, np.zeros(shape, np.int8), np.full(shape, 3.0), np.full(shape, 3.0), seen)  # noqa: E731
    monkeypatch.setattr(agent.map, "snapshot", snap)
    monkeypatch.setattr(agent.map, "clearance", lambda p: np.full(len(np.reshape(p, (-1, 3))), 3.0))
    replans = []
    monkeypatch.setattr(agent, "_replan", lambda s, n, t: replans.append(t) or False)
    yaw_plans = []
    monkeypatch.setattr(agent.heading, "update", lambda *a: yaw_plans.append(a[0]) or False)

    agent.plan_step(0.2)
    assert agent.look.watch.glances == 1 and agent.look.watch.holds == 0 and not agent.braking
    assert agent.reference(0.2 + np.pi / 4).yaw == pytest.approx(np.pi / 2)  # on +y after a quarter turn at 2 rad/s
    n_yaw = len(yaw_plans)
    agent.plan_step(0.8)  # glancing: no yaw plan, but the periodic replan still runs (due every 0.5 s)
    assert len(yaw_plans) == n_yaw and replans and replans[-1] == 0.8
    agent.plan_step(0.2 + np.pi / 4 + 0.2 + 1e-6)  # two t_y on the point: the yaw plan resumes
    assert len(yaw_plans) == n_yaw + 1 and not agent.look.watch.looking
    off = DeniedAgent(0, np.array([0.0, 6.0, 1.5]), DeniedAgentConfig(fresh_path_age_s=1.0, start_delay_s=0.0, fresh_path_glance_age_s=float("inf")))
    _first_estimate(off, np.array([0.0, 0.0, 1.5]))
    off.trajectory = agent.trajectory
    monkeypatch.setattr(off.map, "snapshot", snap)
    monkeypatch.setattr(off.map, "clearance", lambda p: np.full(len(np.reshape(p, (-1, 3))), 3.0))
    monkeypatch.setattr(off, "_replan", lambda s, n, t: False)
    off.plan_step(0.2)  # without glances an ageing point does nothing until it is stale
    assert off.look.watch.glances == 0 and off.look.watch.holds == 0 and not off.look.watch.looking


def test_a_hold_ends_when_another_turn_has_replaced_its_look():
    """A hold's stop that ends inside the obstacle band begins the turn once round, which restarts the heading; the hold
    then ends rather than wait on a look that no longer exists (2 m/s seed 76 of the look-before-moving sweep)."""
    cfg = DeniedAgentConfig(fresh_path_age_s=1.0, start_delay_s=0.0)
    agent = DeniedAgent(0, np.array([0.0, 6.0, 1.5]), cfg)
    _first_estimate(agent, np.array([0.0, 0.0, 1.5]))
    agent.trajectory = _line(np.array([0.0, 0.0, 1.5]), np.array([0.0, 0.5, 0.0]), 6.0)
    agent.look.watch.begin(0.2, np.array([0.0, 1.0, 1.5]), stop=True)
    agent.brake(0.2)
    agent.heading.look_toward(0.2, np.pi / 2)
    assert agent.look.gate(agent, 0.3).hold  # still turning to the point
    agent.heading.restart(0.0, 0.4)  # what the end of the turn once round does
    assert agent.look.gate(agent, 0.5).released and not agent.look.watch.looking


def test_a_glances_own_point_found_stale_rests_the_check_and_does_not_skip_the_frames_replan(monkeypatch):
    """While a glance is under way, a stale point that is the glance's own (not refreshed yet) rests the check and
    begins no hold, so the frame goes on to its safety check and due replan (returning as if a hold had begun
    would skip both)."""
    from perception.types import OccupancySnapshot

    cfg = DeniedAgentConfig(fresh_path_age_s=1.0, start_delay_s=0.0)
    agent = DeniedAgent(0, np.array([0.0, 6.0, 1.5]), cfg)
    _first_estimate(agent, np.array([0.0, 0.0, 1.5]))
    agent.trajectory = _line(np.array([0.0, 0.0, 1.5]), np.array([0.0, 0.5, 0.0]), 6.0)
    shape, origin, voxel = (40, 60, 30), np.array([-2.0, -1.0, 0.0]), 0.1
    seen = np.full(shape, 0.95, np.float32)
    point = np.array([0.0, 0.8, 1.5])
    seen[tuple(np.floor((point - origin) / voxel).astype(int))] = -1.0  # stale: seen 2 s before the frame at 1.0 s
    snap = lambda: OccupancySnapshot(1.0, origin, voxel, np.zeros(shape, np.int8), np.full(shape, 3.0), np.full(shape, 3.0), seen)  # noqa: E731
    monkeypatch.setattr(agent.map, "snapshot", snap)
    monkeypatch.setattr(agent.map, "clearance", lambda p: np.full(len(np.reshape(p, (-1, 3))), 3.0))
    replans = []
    monkeypatch.setattr(agent, "_replan", lambda s, n, t: replans.append(t) or False)
    agent.look.watch.begin(0.1, point, stop=False)  # a glance at the point, under way
    agent.heading.look_toward(0.1, np.pi / 2)
    agent.last_plan_time_s = -1.0  # a replan is due
    agent.plan_step(0.15)  # still glancing; the check finds the same point stale
    assert agent.look.watch.unrefreshed == 1 and agent.look.watch.holds == 0 and not agent.braking
    assert agent.look.watch.looking and replans == [0.15]


def _fast_agent(clearance):
    """A drone at the origin flying +y at 2 m/s, its map's clearance given by ``clearance`` (n, 3) -> (n,)."""
    agent = DeniedAgent(0, np.array([0.0, 30.0, 1.5]), DeniedAgentConfig(fresh_path_age_s=1.0, start_delay_s=0.0))
    _first_estimate(agent, np.array([0.0, 0.0, 1.5]))
    agent.trajectory = _line(np.array([0.0, 0.0, 1.5]), np.array([0.0, 2.0, 0.0]), 6.0)
    agent.map.clearance = clearance
    return agent


def test_a_hold_may_stop_only_where_the_straight_stop_keeps_out_of_the_obstacle_band():
    """can_stop: the stopping piece (straight along the velocity, about v^2 / a_max long) is checked against the map;
    a drone already inside the band may stop if the stop brings it no closer."""
    far = _fast_agent(lambda p: np.full(len(np.reshape(p, (-1, 3))), 3.0))
    assert far.can_stop(0.0)
    trunk = _fast_agent(lambda p: np.where(np.reshape(p, (-1, 3))[:, 1] > 0.5, 0.05, 3.0))  # a trunk 0.5 m ahead
    assert not trunk.can_stop(0.0)
    beside = _fast_agent(lambda p: np.full(len(np.reshape(p, (-1, 3))), 0.1))  # inside the band, the stop no closer
    assert beside.band_m > 0.1 and beside.can_stop(0.0)


def test_look_before_moving_glances_instead_of_stopping_when_the_stop_is_unsafe(monkeypatch):
    """A stale point ahead whose hold's stop would cut into the band begins a glance: no brake, the plan flown on."""
    from perception.types import OccupancySnapshot

    agent = _fast_agent(lambda p: np.full(len(np.reshape(p, (-1, 3))), 3.0))
    shape, origin, voxel = (40, 80, 30), np.array([-2.0, -1.0, 0.0]), 0.1
    seen = np.full(shape, 0.95, np.float32)
    seen[tuple(np.floor((np.array([0.0, 0.8, 1.5]) - origin) / voxel).astype(int))] = -1.0
    snap = lambda: OccupancySnapshot(1.0, origin, voxel, np.zeros(shape, np.int8), np.full(shape, 3.0), np.full(shape, 3.0), seen)  # noqa: E731
    monkeypatch.setattr(agent.map, "snapshot", snap)
    monkeypatch.setattr(agent, "_replan", lambda s, n, t: False)
    monkeypatch.setattr(agent, "can_stop", lambda t: False)
    plan = agent.trajectory
    agent.plan_step(0.0)
    assert agent.look.watch.unsafe_stops == 1 and agent.look.watch.glances == 1 and agent.look.watch.holds == 0
    assert not agent.braking and agent.trajectory is plan and agent.look.watch.looking and not agent.look.watch.stops
    assert agent.extra_metrics()["fresh_path_unsafe_stops"] == 1
