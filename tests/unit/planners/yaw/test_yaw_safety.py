"""Safety metric, threshold and replanning trigger of MP-CDE Sec. IV-A (Eq. 1-2, Alg. 1 lines 4 and 13)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.ndimage import distance_transform_edt

from perception.types import OccupancySnapshot
from planners.yaw import TrajectoryView, YawPlannerConfig, needs_replan, safe_regime, safety_margin

VOXEL_M = 0.2
ORIGIN = np.array([-3.0, -3.0, 0.0])


def corridor_snapshot() -> OccupancySnapshot:
    """40 x 30 x 10 voxels: verified free for x < 1.0 m (index < 20), unknown beyond."""
    state = np.zeros((40, 30, 10), np.int8)
    state[20:] = OccupancySnapshot.UNKNOWN
    free = (distance_transform_edt(state == 0) * VOXEL_M).astype(np.float32)
    return OccupancySnapshot(0.0, ORIGIN.copy(), VOXEL_M, state, free.copy(), free)


def line(start: np.ndarray, vel: np.ndarray, t0: float, end: float) -> TrajectoryView:
    """Straight flight from ``start`` at constant ``vel`` from ``t0`` to ``end`` [s]."""
    return TrajectoryView(
        position_at=lambda t: start + (np.asarray(t)[:, None] - t0) * vel,
        velocity_at=lambda t: np.broadcast_to(vel, (np.size(t), 3)).copy(),
        end_time_s=end,
    )


def test_safe_time_is_when_the_trajectory_reaches_the_first_unknown_voxel():
    cfg = YawPlannerConfig(free_distance="voxel", safety_horizon_s=8.0)
    start = np.array([-1.9, 0.1, 1.1])  # a voxel centre, 2.9 m before the unknown boundary at x = 1.0
    traj = line(start, np.array([0.5, 0.0, 0.0]), t0=2.0, end=20.0)
    s = safety_margin(corridor_snapshot(), traj, 2.0, cfg)
    t_reach = 2.9 / 0.5
    assert t_reach - cfg.safety_sample_s - 1e-9 <= s.safe_time_s <= t_reach
    assert not s.horizon_reached
    assert s.safe_point_world[0] < 1.0
    assert s.safe_point_world[0] > 1.0 - 0.5 * cfg.safety_sample_s - 1e-9


def test_safety_margin_matches_a_hand_computation():
    cfg = YawPlannerConfig(free_distance="voxel", safety_horizon_s=8.0, v_max_mps=2.0)
    start = np.array([-1.9, 0.1, 1.1])
    traj = line(start, np.array([0.5, 0.0, 0.0]), t0=0.0, end=20.0)
    s = safety_margin(corridor_snapshot(), traj, 0.0, cfg)
    # d_free along the line is the distance to the first unknown voxel centre, x = 1.1 (exact under trilinear
    # interpolation: the field is linear in x there); S(tau) = min(d_free / v_max, tau_s - tau), Eq. 1
    x = start[0] + 0.5 * s.taus_s
    expected = np.minimum((1.1 - x) / 2.0, s.safe_time_s - s.taus_s)
    np.testing.assert_allclose(s.margins_s, expected, atol=1e-5)
    assert s.margin_now_s == pytest.approx(min(3.0 / 2.0, s.safe_time_s), abs=1e-5)
    assert s.taus_s[-1] == pytest.approx(s.safe_time_s)


def test_the_second_term_of_eq1_is_active_near_the_safe_point():
    cfg = YawPlannerConfig(free_distance="voxel", safety_horizon_s=8.0, v_max_mps=0.1)  # d_free / v_max large: tau_s - tau decides
    traj = line(np.array([-1.9, 0.1, 1.1]), np.array([0.5, 0.0, 0.0]), t0=0.0, end=20.0)
    s = safety_margin(corridor_snapshot(), traj, 0.0, cfg)
    assert s.margin_now_s == pytest.approx(s.safe_time_s)
    assert s.margins_s[-1] == pytest.approx(0.0, abs=1e-9)


def test_a_hover_in_free_space_is_safe_up_to_the_horizon():
    cfg = YawPlannerConfig(free_distance="voxel")
    s = safety_margin(corridor_snapshot(), TrajectoryView.hover(np.array([-1.9, 0.1, 1.1])), 5.0, cfg)
    assert s.horizon_reached
    assert s.safe_time_s == pytest.approx(cfg.safety_horizon_s)
    assert s.margin_now_s == pytest.approx(min(3.0 / cfg.v_max_mps, cfg.safety_horizon_s), abs=1e-5)


def test_a_drone_in_an_unknown_voxel_has_no_margin():
    s = safety_margin(corridor_snapshot(), TrajectoryView.hover(np.array([2.0, 0.1, 1.1])), 0.0, YawPlannerConfig(free_distance="voxel"))
    assert s.safe_time_s == 0.0 and s.margin_now_s == 0.0


def test_switching_threshold_is_eq2():
    cfg = YawPlannerConfig(free_distance="voxel")
    assert cfg.tau_thr_s == pytest.approx(1.2 * math.pi / 2.0)


@pytest.mark.parametrize(
    "previous, margin, expected",
    [
        (False, 1.0, False),
        (True, 1.0, False),  # below tau_thr: tracking whatever came before
        (False, 2.5, True),
        (True, 2.5, True),  # above tau_thr + 0.1: exploring/observing
        (False, 1.95, False),  # inside the band: keep
        (True, 1.95, True),
        (True, 1.885, True),  # at tau_thr exactly: not below it
    ],
)
def test_hysteresis_keeps_the_previous_regime_inside_the_band(previous, margin, expected):
    cfg = YawPlannerConfig(free_distance="voxel")
    assert safe_regime(previous, margin, round(cfg.tau_thr_s, 3), cfg.hysteresis_s) is expected


def test_replan_trigger_is_alg1_line13():
    assert needs_replan(1.0, 1.885, np.inf, 0.7)  # S(0) < tau_thr
    assert needs_replan(3.0, 1.885, 0.5, 0.7)  # a neighbour closer than C_s
    assert not needs_replan(3.0, 1.885, 0.9, 0.7)
    assert not needs_replan(3.0, 1.885, np.inf, 0.7)


def _level_room(ground: bool = True) -> OccupancySnapshot:
    """40 x 30 x 15 voxels of 0.2 m: verified free in a 4 m (x) by 4 m (y) room, x and y in [-2, 2), between
    z = 0.2 and 2.0 m, occupied ground below, unknown above and outside the room."""
    state = np.full((40, 30, 15), OccupancySnapshot.UNKNOWN, np.int8)
    state[5:25, 5:25, 1:10] = OccupancySnapshot.FREE
    if ground:
        state[:, :, 0] = OccupancySnapshot.OCCUPIED
    free = (distance_transform_edt(state == OccupancySnapshot.FREE) * VOXEL_M).astype(np.float32)
    return OccupancySnapshot(0.0, np.array([-3.0, -3.0, 0.0]), VOXEL_M, state, free.copy(), free)


def test_horizontal_free_distance_ignores_the_ground_and_the_unknown_above_and_is_exact_in_the_plane():
    from planners.yaw.safety import horizontal_free_distance

    snap = _level_room()
    p = np.array([[0.1, 0.1, 0.7], [1.5, -0.5, 0.7], [0.1, 0.1, 2.5]])  # centre, near a wall, above the room
    d = horizontal_free_distance(snap, p, 0.3)
    # centre: the nearest not-free cells are the room's walls, 1.9 m away (cell centre to face)
    assert d[0] == pytest.approx(1.9, abs=1e-9)
    assert d[1] == pytest.approx(2.0 - 1.5, abs=1e-9)
    assert d[2] == 0.0  # its slab is not verified free
    # the 3-D field at the same point is capped by the ground 0.7 m below
    assert snap.free_distance(p[:1])[0] <= 0.7


def test_the_default_free_distance_lets_a_level_drone_leave_tracking_where_the_3d_one_cannot():
    snap = _level_room()
    hover = TrajectoryView.hover(np.array([0.1, 0.1, 0.7]))
    cfg_h = YawPlannerConfig(v_max_mps=0.5)
    cfg_v = YawPlannerConfig(v_max_mps=0.5, free_distance="voxel")
    s_h = safety_margin(snap, hover, 0.0, cfg_h).margin_now_s
    s_v = safety_margin(snap, hover, 0.0, cfg_v).margin_now_s
    assert s_h == pytest.approx(1.9 / 0.5, abs=1e-9) and s_h > cfg_h.tau_thr_s + cfg_h.hysteresis_s
    assert s_v < cfg_v.tau_thr_s  # measured in 3-D the ground keeps it in tracking


def test_free_distance_mode_is_validated():
    with pytest.raises(ValueError, match="^free_distance="):
        YawPlannerConfig(free_distance="3d")


def test_free_space_seen_too_long_ago_ends_the_safe_segment_but_not_d_free():
    """free_max_age_s: tau_s stops where the trajectory enters free space last seen before now - age (Eq. 1)."""
    base = corridor_snapshot()
    seen = np.full(base.shape, 10.0, np.float32)  # the map's latest frame is at 10 s; x < 0.2 m seen then
    seen[16:20] = 7.0  # 0.2 <= x < 1.0 m: verified free, but seen 3 s ago
    snap = OccupancySnapshot(10.0, base.origin_world, VOXEL_M, base.state, base.distance_m, base.free_distance_m, seen)
    traj = line(np.array([-1.9, 0.1, 1.1]), np.array([0.5, 0.0, 0.0]), t0=10.0, end=30.0)
    plain = YawPlannerConfig(free_distance="voxel", safety_horizon_s=8.0, free_max_age_s=math.inf)
    aged = YawPlannerConfig(free_distance="voxel", safety_horizon_s=8.0, free_max_age_s=2.0)
    s0, s1 = safety_margin(snap, traj, 10.0, plain), safety_margin(snap, traj, 10.0, aged)
    assert 2.1 / 0.5 - plain.safety_sample_s - 1e-9 <= s1.safe_time_s <= 2.1 / 0.5  # reaches x = 0.2 after 4.2 s
    assert 2.9 / 0.5 - plain.safety_sample_s - 1e-9 <= s0.safe_time_s <= 2.9 / 0.5  # no ageing: x = 1.0, 5.8 s
    x = -1.9 + 0.5 * s1.taus_s
    d_free = 1.1 - x  # to the first unknown voxel centre, as without ageing (not to the stale space)
    np.testing.assert_allclose(s1.margins_s, np.minimum(d_free / aged.v_max_mps, s1.safe_time_s - s1.taus_s), atol=1e-5)
    assert safety_margin(snap, traj, 10.0, YawPlannerConfig(free_distance="voxel", safety_horizon_s=8.0,
                                                             free_max_age_s=3.5)).safe_time_s == s0.safe_time_s


@pytest.mark.parametrize("age", [0.0, -1.0, float("nan"), True])
def test_free_max_age_is_validated(age):
    with pytest.raises(ValueError, match="^free_max_age_s="):
        YawPlannerConfig(free_max_age_s=age)


@pytest.mark.parametrize("free_distance", ["horizontal", "voxel"])
@pytest.mark.parametrize("t0", [0.0, 3.0, 9.0])
def test_s0_alone_equals_the_first_value_of_the_profile(free_distance, t0):
    cfg = YawPlannerConfig(free_distance=free_distance)
    traj = line(np.array([-1.9, 0.1, 1.1]), np.array([0.5, 0.02, 0.01]), t0=0.0, end=20.0)  # climbs: several slabs
    full = safety_margin(corridor_snapshot(), traj, t0, cfg)
    now = safety_margin(corridor_snapshot(), traj, t0, cfg, profile=False)
    assert now.margins_s.shape == (1,) and now.taus_s.shape == (1,)
    assert now.margin_now_s == full.margin_now_s  # bit for bit: the planner's mode does not move
    assert (now.safe_time_s, now.horizon_reached) == (full.safe_time_s, full.horizon_reached)
    np.testing.assert_array_equal(now.safe_point_world, full.safe_point_world)


def test_occupied_only_distance_counts_trunks_not_unknown_space():
    from planners.yaw.safety import horizontal_free_distance

    snap = corridor_snapshot()  # free for index x < 20, unknown beyond: no obstacle at all
    p = np.array([[-1.9, 0.1, 1.1]])  # a voxel centre
    assert horizontal_free_distance(snap, p, 0.3, occupied_only=True)[0] == np.inf
    state = snap.state.copy()
    i, j, _ = snap.world_to_index(p)[0]
    state[i + 8, j, :] = OccupancySnapshot.OCCUPIED  # a trunk 8 voxels away along +x, inside the free part
    trunk = OccupancySnapshot(0.0, snap.origin_world, snap.voxel_m, state, snap.distance_m, snap.free_distance_m)
    d = horizontal_free_distance(trunk, p, 0.3, occupied_only=True)[0]
    assert d == pytest.approx(8 * VOXEL_M - 0.5 * VOXEL_M)  # centre-to-face, as the verified-free reading
    assert horizontal_free_distance(trunk, p, 0.3)[0] < d  # the unknown boundary and the window edge are nearer
