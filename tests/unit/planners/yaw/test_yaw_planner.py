"""The yaw planner's modes (MP-CDE Alg. 1 lines 1-12): switching, exploring, observing, tracking."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest
from scipy.ndimage import distance_transform_edt

from perception.types import NeighborPrediction, OccupancySnapshot
from planners.yaw import TrajectoryView, YawPlan, YawPlanner, YawPlannerConfig, ZhouYawPlanner, make_yaw_planner, mean_bearing

VOXEL_M = 0.2
ORIGIN = np.array([-6.0, -6.0, 0.0])
SHAPE = (60, 60, 10)
DRONE = np.array([0.1, 0.1, 1.1])  # a voxel centre in the middle of the window
CENTRES = ORIGIN + VOXEL_M * (np.indices(SHAPE).transpose(1, 2, 3, 0) + 0.5)  # (nx, ny, nz, 3)
FREE, UNKNOWN, OCCUPIED = OccupancySnapshot.FREE, OccupancySnapshot.UNKNOWN, OccupancySnapshot.OCCUPIED


def paper_config() -> YawPlannerConfig:
    """MP-CDE's planner as in the paper: 3-D d_free, tracking mode straight along travel (no swing)."""
    return YawPlannerConfig(free_distance="voxel", tracking_sweep_deg=0.0)


def make_snapshot(state: np.ndarray) -> OccupancySnapshot:
    """Snapshot of ``state`` with exact EDT layers (free distance: to the nearest not-free voxel centre)."""
    occupied = state == OCCUPIED
    dist = (distance_transform_edt(~occupied) * VOXEL_M).astype(np.float32)
    free = (distance_transform_edt(state == FREE) * VOXEL_M).astype(np.float32)
    return OccupancySnapshot(0.0, ORIGIN.copy(), VOXEL_M, state.astype(np.int8), dist, free)


def uniform_snapshot(free_distance_m: float) -> OccupancySnapshot:
    """All voxels verified free, with d_free set to ``free_distance_m`` everywhere (controls S(0) = d_free / v_max)."""
    state = np.zeros(SHAPE, np.int8)
    field = np.full(SHAPE, free_distance_m, np.float32)
    return OccupancySnapshot(0.0, ORIGIN.copy(), VOXEL_M, state, field, field)


def disc_free(radius_m: float) -> np.ndarray:
    """(nx, ny, nz) bool: voxel centres within ``radius_m`` of the drone in xy."""
    return np.hypot(CENTRES[..., 0] - DRONE[0], CENTRES[..., 1] - DRONE[1]) <= radius_m


def line(vel: np.ndarray, start: np.ndarray = DRONE, t0: float = 0.0, end: float = 10.0) -> TrajectoryView:
    return TrajectoryView(
        position_at=lambda t: start + (np.asarray(t)[:, None] - t0) * vel,
        velocity_at=lambda t: np.broadcast_to(vel, (np.size(t), 3)).copy(),
        end_time_s=end,
    )


def neighbour(pos, stamp_s: float, vel=(0.0, 0.0, 0.0), nid: int = 0, sigma_m: float = 0.1) -> NeighborPrediction:
    cov = np.diag([sigma_m**2] * 3 + [0.01] * 3)
    return NeighborPrediction.constant_velocity(nid, "perception", stamp_s, np.asarray(pos, float), vel, cov)


def assert_rate_limited(plan: YawPlan, yaw0: float, cfg: YawPlannerConfig) -> None:
    assert plan.yaws[0] == yaw0
    assert np.all(np.abs(np.diff(plan.yaws)) <= cfg.max_step_rad + 1e-12)
    assert len(plan.yaws) == cfg.n_steps + 1
    np.testing.assert_allclose(np.diff(plan.times_s), cfg.period_s)


HOVER = TrajectoryView.hover(DRONE)


# --- mode switching --------------------------------------------------------------------------------


def test_small_margin_tracks_and_large_margin_explores():
    cfg = paper_config()
    planner = YawPlanner(cfg)
    assert planner.plan(0.0, 0.0, HOVER, uniform_snapshot(1.0)).mode == "tracking"
    plan = planner.plan(0.1, 0.0, HOVER, uniform_snapshot(2.5))
    assert plan.mode == "exploring"
    assert plan.safety_margin_s == pytest.approx(2.5)
    assert plan.tau_thr_s == pytest.approx(cfg.tau_thr_s)


def test_hysteresis_keeps_the_mode_inside_the_band():
    planner = YawPlanner(paper_config())
    band = uniform_snapshot(1.95)  # tau_thr = 1.885 s < S(0) = 1.95 s < tau_thr + 0.1 s
    assert planner.plan(0.0, 0.0, HOVER, band).mode == "tracking"  # starts in tracking, stays
    assert planner.plan(0.1, 0.0, HOVER, uniform_snapshot(2.5)).mode == "exploring"
    assert planner.plan(0.2, 0.0, HOVER, band).mode == "exploring"  # stays
    assert planner.plan(0.3, 0.0, HOVER, uniform_snapshot(1.8)).mode == "tracking"
    assert planner.plan(0.4, 0.0, HOVER, band).mode == "tracking"  # stays
    planner.reset()
    assert not planner.in_safe_regime


def test_the_paper_ablations_switch_one_mode_off_each():
    """Table III: w/o exploring, the heading follows travel where exploring would run (observing unchanged);
    w/o tracking, a small margin keeps exploring or observing instead of turning to travel."""
    from dataclasses import replace

    fwd = line(np.array([1.0, 0.0, 0.0]))
    seen = neighbour((2.0, 1.0, 1.1), stamp_s=0.9)
    no_explore = YawPlanner(replace(paper_config(), exploring_mode=False))
    plan = no_explore.plan(1.0, 0.5, fwd, uniform_snapshot(3.0))
    assert plan.mode == "tracking" and no_explore.in_safe_regime
    assert plan.yaws[-1] == pytest.approx(0.0, abs=1e-9)  # turned to travel (+x) within the rate limit
    assert no_explore.plan(1.1, 0.0, fwd, uniform_snapshot(3.0), [seen]).mode == "observing"
    no_track = YawPlanner(replace(paper_config(), tracking_mode=False))
    plan = no_track.plan(1.0, 0.0, fwd, uniform_snapshot(1.0))  # S(0) = 1 s < tau_thr: the full planner tracks
    assert plan.mode == "exploring" and not no_track.in_safe_regime
    assert no_track.plan(1.1, 0.0, fwd, uniform_snapshot(1.0), [seen]).mode == "observing"
    assert YawPlanner(paper_config()).plan(1.0, 0.0, fwd, uniform_snapshot(1.0)).mode == "tracking"


def test_zhou_s_method_always_looks_for_the_most_unknown_space():
    """Zhou et al.'s yaw (Table III's comparison): with a small safety margin and a neighbour in view it still
    explores, towards the unknown half of the map (left of +x travel), where MP-CDE tracks."""
    from dataclasses import replace

    state = np.full(SHAPE, FREE, np.int8)
    state[CENTRES[..., 1] > DRONE[1] + 0.5] = UNKNOWN  # everything left of the drone unknown
    snap = make_snapshot(state)
    fwd = line(np.array([1.0, 0.0, 0.0]))
    near = replace(paper_config(), method="zhou")
    assert isinstance(make_yaw_planner(near), ZhouYawPlanner) and type(make_yaw_planner(paper_config())) is YawPlanner
    seen = neighbour((2.0, -1.0, 1.1), stamp_s=0.95)
    plan = ZhouYawPlanner(near).plan(1.0, 0.0, fwd, uniform_snapshot(1.0), [seen])
    assert plan.mode == "exploring" and plan.safety_margin_s == pytest.approx(1.0)  # S(0) still reported (line 13)
    plan = ZhouYawPlanner(near).plan(1.0, 0.0, fwd, snap, [seen])
    assert plan.mode == "exploring" and plan.yaws[-1] > 0.5  # turned left, to the unknown
    assert_rate_limited(plan, 0.0, near)
    assert YawPlanner(paper_config()).plan(1.0, 0.0, fwd, uniform_snapshot(1.0), [seen]).mode == "tracking"
    with pytest.raises(ValueError, match="^method='fuel'"):
        YawPlannerConfig(method="fuel")


def test_observing_needs_every_neighbour_recently_seen():
    planner = YawPlanner(paper_config())
    snap = uniform_snapshot(3.0)
    seen = neighbour((2.0, 1.0, 1.1), stamp_s=0.9, nid=0)
    unseen = neighbour((-2.0, 1.0, 1.1), stamp_s=0.0, nid=1)  # 1.0 s > t_hold = 0.6 s
    assert planner.plan(1.0, 0.0, HOVER, snap, [seen]).mode == "observing"
    plan = planner.plan(1.1, 0.0, HOVER, snap, [seen, unseen])
    assert plan.mode == "exploring" and (plan.n_recent, plan.n_active) == (1, 2)
    assert planner.plan(1.2, 0.0, HOVER, snap, []).mode == "exploring"


# --- exploring -------------------------------------------------------------------------------------


def half_known_state(unknown_side: float) -> np.ndarray:
    """Free within 2.6 m of the drone; beyond it known free on one side, unknown on the other (sign of y)."""
    state = np.full(SHAPE, FREE, np.int8)
    side = np.sign(CENTRES[..., 1] - DRONE[1]) == np.sign(unknown_side)
    state[side & ~disc_free(2.6)] = UNKNOWN
    return state


@pytest.mark.parametrize("unknown_side", [-1.0, 1.0])
def test_exploring_turns_the_camera_towards_the_unknown_side(unknown_side):
    cfg = paper_config()
    plan = YawPlanner(cfg).plan(0.0, 0.0, HOVER, make_snapshot(half_known_state(unknown_side)))
    assert plan.mode == "exploring"
    assert np.sign(plan.yaws[-1]) == np.sign(unknown_side)  # right (y < 0) is negative yaw
    assert abs(plan.yaws[-1]) > 1.0
    assert_rate_limited(plan, 0.0, cfg)


def occlusion_state(wall: bool) -> np.ndarray:
    """Free band -3.5 <= y < 2.2 (and the disc around the drone); left of it a wall (or unknown), then unknown.

    Without the wall the unknown on the left (from y = 2.2) is larger than on the right (from y = -3.5).
    """
    y = CENTRES[..., 1]
    state = np.full(SHAPE, UNKNOWN, np.int8)
    state[(y >= -3.5) & (y < 2.2)] = FREE
    if wall:
        state[(y >= 2.2) & (y < 2.4)] = OCCUPIED
    return state


def test_an_obstacle_occludes_the_unknown_space_behind_it():
    cfg = paper_config()
    open_plan = YawPlanner(cfg).plan(0.0, 0.0, HOVER, make_snapshot(occlusion_state(wall=False)))
    walled = YawPlanner(cfg).plan(0.0, 0.0, HOVER, make_snapshot(occlusion_state(wall=True)))
    assert open_plan.mode == walled.mode == "exploring"
    assert open_plan.yaws[-1] > 0.5  # without the wall: towards the larger unknown region (left)
    assert walled.yaws[-1] < -0.5  # the wall hides everything on the left: turn right


@pytest.mark.parametrize("looked_from", [-1.0, 1.0])
def test_the_coverage_window_turns_the_camera_away_from_what_it_just_saw(looked_from):
    """Unknown all around: the map alone cannot tell left from right; the window W of recent yaws does."""
    cfg = paper_config()
    planner = YawPlanner(cfg)
    snap = make_snapshot(np.where(disc_free(2.6), FREE, UNKNOWN).astype(np.int8))
    for k in range(5):  # 0.5 s looking 0.7 rad to one side of the current yaw
        planner.plan(-0.5 + 0.1 * k, looked_from * 0.7, HOVER, snap)
    plan = planner.plan(0.0, 0.0, HOVER, snap)
    assert plan.mode == "exploring"
    assert plan.yaws[-1] * looked_from < -0.5  # it turns to the other side


def test_a_neighbour_not_seen_for_t_hold_attracts_the_yaw():
    cfg = paper_config()
    snap = uniform_snapshot(3.0)  # nothing unknown: only the visibility term
    for side in (1.0, -1.0):
        lost = neighbour((0.1, 0.1 + 3.0 * side, 1.1), stamp_s=-1.0)
        plan = YawPlanner(cfg).plan(0.0, 0.0, HOVER, snap, [lost])
        assert plan.mode == "exploring"
        assert plan.yaws[-1] * side > 1.0  # towards +-pi/2
        assert abs(plan.yaws[-1] - side * math.pi / 2) < 0.6
        assert_rate_limited(plan, 0.0, cfg)


def test_visibility_counts_only_the_neighbours_not_recently_seen():
    snap = uniform_snapshot(3.0)
    seen = neighbour((0.1, 3.1, 1.1), stamp_s=-0.1, nid=0)  # left, seen 0.1 s ago
    lost = neighbour((0.1, -2.9, 1.1), stamp_s=-1.0, nid=1)  # right, lost
    plan = YawPlanner(paper_config()).plan(0.0, 0.0, HOVER, snap, [seen, lost])
    assert plan.mode == "exploring"
    assert plan.yaws[-1] < -1.0


def test_with_nothing_to_gain_exploring_holds_the_yaw():
    plan = YawPlanner(paper_config()).plan(0.0, 0.7, HOVER, uniform_snapshot(3.0))
    assert plan.mode == "exploring"
    np.testing.assert_allclose(plan.yaws, 0.7)


# --- observing -------------------------------------------------------------------------------------


def test_observing_points_closer_to_the_near_neighbour():
    cfg = paper_config()
    b_near, b_far = math.radians(60), math.radians(-60)
    near = neighbour(DRONE + 1.5 * np.array([math.cos(b_near), math.sin(b_near), 0.0]), stamp_s=0.0, nid=0)
    far = neighbour(DRONE + 6.0 * np.array([math.cos(b_far), math.sin(b_far), 0.0]), stamp_s=0.0, nid=1)
    plan = YawPlanner(cfg).plan(0.0, 0.0, HOVER, uniform_snapshot(3.0), [near, far])
    assert plan.mode == "observing"
    # Eq. 6 by hand: weights 1 / (d + eps), bearings averaged as unit vectors
    w1, w2 = 1 / (1.5 + cfg.distance_eps_m), 1 / (6.0 + cfg.distance_eps_m)
    expected = math.atan2(w1 * math.sin(b_near) + w2 * math.sin(b_far), w1 * math.cos(b_near) + w2 * math.cos(b_far))
    assert expected > 0.3
    assert plan.yaws[-1] == pytest.approx(expected, abs=1e-9)
    assert_rate_limited(plan, 0.0, cfg)


def test_circular_mean_of_bearings_near_pi_does_not_flip_to_zero():
    b = math.radians(170)
    targets = np.array([DRONE + 3 * np.array([math.cos(b), math.sin(b), 0]),
                        DRONE + 3 * np.array([math.cos(-b), math.sin(-b), 0])])
    mean = mean_bearing(DRONE, targets, 0.2)
    assert abs(abs(mean) - math.pi) < 1e-9  # the arithmetic mean of +170 and -170 deg would be 0
    preds = [neighbour(targets[0], 0.0, nid=0), neighbour(targets[1], 0.0, nid=1)]
    plan = YawPlanner(paper_config()).plan(0.0, 3.0, HOVER, uniform_snapshot(3.0), preds)
    assert plan.mode == "observing"
    assert plan.yaws[-1] == pytest.approx(math.pi, abs=1e-9)  # continuous from 3.0, not towards 0
    assert mean_bearing(DRONE, np.array([DRONE + (1, 0, 0), DRONE - (1, 0, 0)]), 0.2) is None


# --- tracking --------------------------------------------------------------------------------------


def test_tracking_follows_the_direction_of_travel_at_the_rate_limit():
    cfg = paper_config()
    plan = YawPlanner(cfg).plan(0.0, 0.0, line(np.array([0.0, 1.0, 0.0])), uniform_snapshot(1.0))
    assert plan.mode == "tracking"
    steps = np.round(plan.yaws[:8] / cfg.max_step_rad, 9)
    np.testing.assert_array_equal(steps, np.arange(8))  # full rate until the heading is reached
    assert plan.yaws[-1] == pytest.approx(math.pi / 2)
    assert_rate_limited(plan, 0.0, cfg)


def test_tracking_turns_the_short_way_across_pi_and_holds_when_still():
    cfg = paper_config()
    heading = -3.0  # = 3.283 rad: 0.283 rad from yaw 3.0 the short way, across +pi
    vel = np.array([math.cos(heading), math.sin(heading), 0.0])
    plan = YawPlanner(cfg).plan(0.0, 3.0, line(vel), uniform_snapshot(1.0))
    assert plan.yaws[-1] == pytest.approx(2 * math.pi + heading)
    assert np.all(np.diff(plan.yaws) >= 0.0)
    still = YawPlanner(cfg).plan(0.0, 3.0, line(np.array([0.05, 0.0, 0.0])), uniform_snapshot(1.0))
    np.testing.assert_allclose(still.yaws, 3.0)


def test_tracking_uses_the_velocity_along_the_future_trajectory():
    """Flying +x until 0.55 s, then +y: the yaw holds 0 while the heading is 0, then turns at the rate limit."""
    def vel(t):
        t = np.asarray(t)[:, None]
        return np.where(t < 0.55, [[1.0, 0.0, 0.0]], [[0.0, 1.0, 0.0]])

    traj = TrajectoryView(lambda t: DRONE + np.zeros((np.size(t), 3)), vel, 10.0)
    plan = YawPlanner(paper_config()).plan(0.0, 0.0, traj, uniform_snapshot(1.0))
    np.testing.assert_allclose(plan.yaws[:6], 0.0)  # layers at 0.1 .. 0.5 s head +x
    np.testing.assert_allclose(plan.yaws[6:], 0.2 * np.arange(1, 8))  # then +y: 0.2 rad per step
    ended = YawPlanner(paper_config()).plan(0.0, 0.0, line(np.array([0.0, 1.0, 0.0]), end=0.35), uniform_snapshot(1.0))
    assert ended.yaws[-1] == pytest.approx(math.pi / 2)  # after the end: the last heading of travel is kept


# --- the plan's outputs ----------------------------------------------------------------------------


def test_yaw_at_is_piecewise_linear_and_holds_after_the_end():
    traj = line(np.array([0.0, 1.0, 0.0]), t0=2.0, end=12.0)
    plan = YawPlanner(paper_config()).plan(2.0, 0.0, traj, uniform_snapshot(1.0))
    yaw, rate = plan.yaw_at(2.05)
    assert yaw == pytest.approx(0.1) and rate == pytest.approx(2.0)
    assert plan.yaw_at(2.0 + 0.1 * 12 + 1.0) == (pytest.approx(plan.yaws[-1]), 0.0)
    assert plan.yaw_at(1.0) == (0.0, 0.0)


def test_plan_reports_the_nearest_neighbour_distance_for_the_replan_trigger():
    preds = [neighbour(DRONE + (0.5, 0, 0), 0.0, nid=0), neighbour(DRONE + (3, 0, 0), 0.0, nid=1)]
    plan = YawPlanner(paper_config()).plan(0.0, 0.0, HOVER, uniform_snapshot(3.0), preds)
    assert plan.min_neighbour_distance_m == pytest.approx(0.5)
    assert YawPlanner(paper_config()).plan(0.0, 0.0, HOVER, uniform_snapshot(3.0)).min_neighbour_distance_m == math.inf


def test_non_finite_inputs_are_refused():
    with pytest.raises(ValueError, match="yaw"):
        YawPlanner(paper_config()).plan(0.0, float("nan"), HOVER, uniform_snapshot(3.0))


def test_sweep_offsets_are_a_triangle_wave():
    from planners.yaw import sweep_offsets

    a, period = math.radians(30.0), 1.2
    t = np.array([0.0, 0.15, 0.3, 0.45, 0.6, 0.9, 1.2, 1.5])
    expected = a * np.array([0.0, 0.5, 1.0, 0.5, 0.0, -1.0, 0.0, 1.0])
    np.testing.assert_allclose(sweep_offsets(t, a, period), expected, atol=1e-12)
    np.testing.assert_array_equal(sweep_offsets(t, 0.0, period), 0.0)


def test_tracking_sweep_swings_about_the_travel_direction_and_keeps_it_in_view():
    from planners.yaw import sweep_offsets

    cfg = YawPlannerConfig(free_distance="voxel", tracking_sweep_deg=35.0, tracking_sweep_period_s=1.4)
    heading = 0.7
    vel = np.array([math.cos(heading), math.sin(heading), 0.0])
    plain = YawPlanner(paper_config()).plan(0.0, heading, line(vel), uniform_snapshot(1.0))
    np.testing.assert_allclose(plain.yaws, heading)  # no sweep: straight along travel
    p = YawPlanner(cfg).plan(0.0, heading, line(vel), uniform_snapshot(1.0))
    assert p.mode == "tracking"
    # the swing turns at 4 * 35 deg / 1.4 s = 100 deg/s < 2 rad/s: the yaws follow it exactly
    np.testing.assert_allclose(p.yaws[1:] - heading, sweep_offsets(p.times_s[1:], math.radians(35.0), 1.4), atol=1e-12)
    assert np.ptp(p.yaws) > math.radians(50.0)
    assert np.all(np.abs(p.yaws - heading) < math.radians(cfg.fov_h_deg / 2))  # the direction of travel stays in view
    assert_rate_limited(p, heading, cfg)


def test_the_default_sweep_reaches_60_deg_within_the_rate_limit_and_leaves_travel_briefly():
    from planners.yaw import sweep_offsets

    cfg = YawPlannerConfig(free_distance="voxel")
    assert (cfg.tracking_sweep_deg, cfg.tracking_sweep_period_s) == (60.0, 2.1)  # the package's default (docs/results/yaw_planner.md#tracking_sweep_deg-60-deg-every-21-s)
    heading = -0.4
    vel = np.array([math.cos(heading), math.sin(heading), 0.0])
    offsets = []
    for t in np.arange(0.0, 2.1, cfg.period_s * cfg.n_steps):  # consecutive plans over one period
        yaw0 = heading + float(sweep_offsets(np.array([t]), math.radians(60.0), 2.1)[0])  # where the last plan left it
        p = YawPlanner(cfg).plan(float(t), yaw0, line(vel), uniform_snapshot(1.0))
        assert p.mode == "tracking"
        # 4 * 60 deg / 2.1 s = 1.99 rad/s < 2 rad/s: the yaws follow the triangle exactly
        np.testing.assert_allclose(p.yaws[1:] - heading, sweep_offsets(p.times_s[1:], math.radians(60.0), 2.1), atol=1e-9)
        assert_rate_limited(p, yaw0, cfg)
        offsets.extend(p.yaws - heading)
    offsets = np.degrees(offsets)
    # sampled every t_y = 0.1 s, the triangle's peaks (at 0.525 s + k 1.05 s) are met at 57.1 deg: a neighbour at
    # 90 deg still enters the 85 deg frame by 9.6 deg on both sides
    assert offsets.max() > 57.0 and offsets.min() < -57.0
    outside = np.mean(np.abs(offsets) > cfg.fov_h_deg / 2)
    assert 0.2 < outside < 0.35  # travel out of view 1 - 42.5 / 60 = 29 % of the time


@pytest.mark.parametrize("value", [-1.0, 90.0, 120.0])
def test_tracking_sweep_is_validated(value):
    with pytest.raises(ValueError, match="^tracking_sweep_deg="):
        YawPlannerConfig(tracking_sweep_deg=value)


def test_a_sweep_faster_than_the_yaw_rate_limit_is_refused():
    YawPlannerConfig(tracking_sweep_deg=60.0, tracking_sweep_period_s=2.1)  # 1.99 rad/s: accepted
    with pytest.raises(ValueError, match=r"^tracking_sweep_deg=60\.0: allowed 4 \* sweep / tracking_sweep_period_s <= yaw_rate_max_radps=2\.0 .*a period >= 2\.09 s"):
        YawPlannerConfig(tracking_sweep_deg=60.0, tracking_sweep_period_s=1.4)


def test_the_agent_factory_gives_each_denied_drone_the_swarm_size():
    """The mission's size (for flight levels), not the neighbours' state."""
    import mpcde
    from mpcde.flight.loop import prepare_run
    from mpcde.stacks.build import make_agent

    for name, mode, size in (("forest_swarm", "denied", 6), ("crossing", "auto", 2)):
        prepared = prepare_run(mpcde.load_scenario(name, mode=mode))
        agent = make_agent(prepared.config, 0, prepared.goals, prepared.obstacles)
        denied = agent if mode == "denied" else agent.denied
        assert denied.swarm_size == size


