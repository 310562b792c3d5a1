"""MINCO trajectory optimiser: gradient of the whole cost, clearances and limits after solving, errors."""

from __future__ import annotations

import numpy as np
import pytest

from perception.types import NeighborPrediction, OccupancySnapshot
from planners.limits import KinematicLimits
from planners.trajectory_optimizer import (
    TrajectoryOptimizationError,
    TrajectoryOptimizerConfig,
    build_trajectory_problem,
    solve,
)
from planners.trajectory_variables import _dtime_dtau, _tau_to_time, _time_to_tau


class CylinderField:
    """Signed distance to the nearest of vertical cylinders (centres (n, 2) [m], radii (n,) [m])."""

    def __init__(self, centers_xy, radii_m):
        self.centers_xy = np.asarray(centers_xy, float)
        self.radii_m = np.asarray(radii_m, float)

    def distance_and_gradient(self, points_world):
        diff = points_world[:, None, :2] - self.centers_xy[None]
        rho = np.linalg.norm(diff, axis=2)
        d_all = rho - self.radii_m[None]
        k = np.argmin(d_all, axis=1)
        rows = np.arange(points_world.shape[0])
        grad = np.zeros_like(points_world)
        grad[:, :2] = diff[rows, k] / rho[rows, k][:, None]
        return d_all[rows, k], grad


class NanField:
    def distance_and_gradient(self, points_world):
        return np.full(points_world.shape[0], np.nan), np.zeros_like(points_world)


START = np.array([[0.0, 0.0, 1.0], [0.0, 0.0, 0.0], [0.0, 0.0, 0.0]])
GOAL = np.array([[10.0, 0.0, 1.0], [0.0, 0.0, 0.0], [0.0, 0.0, 0.0]])
STRAIGHT = np.array([START[0], GOAL[0]])


def _dense(traj, n=4000):
    t = np.linspace(0.0, traj.total_duration, n)
    return t, traj.pos(t), traj.vel(t), traj.acc(t)


def _crossing_neighbor(t0):
    """A neighbour that flies across the straight line at x = 5 m."""
    return NeighborPrediction.constant_velocity(4, "radio", t0, [5.0, -3.0, 1.0], [0.0, 1.0, 0.0], np.zeros((6, 6)))


def test_time_map_round_trips_and_its_derivative_matches_finite_differences():
    T = np.array([0.05, 0.5, 1.0, 1.7, 6.0])
    tau = _time_to_tau(T)
    np.testing.assert_allclose(_tau_to_time(tau), T, rtol=1e-12)
    h = 1e-7
    fd = (_tau_to_time(tau + h) - _tau_to_time(tau - h)) / (2 * h)
    np.testing.assert_allclose(_dtime_dtau(tau), fd, rtol=1e-6)


def test_total_cost_gradient_matches_finite_differences():
    field = CylinderField([[3.0, 0.3], [7.0, -0.2]], [0.4, 0.3])
    cfg = TrajectoryOptimizerConfig(limits=KinematicLimits(1.0, 0.3), samples_per_piece=8, initial_speed_fraction=1.0)
    nb = NeighborPrediction.constant_velocity(
        1, "perception", 0.0, [5.0, -0.5, 1.2], [0.0, 0.1, 0.0], np.diag([0.01] * 3 + [0.02] * 3)
    )
    problem = build_trajectory_problem(START, GOAL, STRAIGHT, field, [nb], 0.0, cfg)
    rng = np.random.default_rng(5)
    x = problem.x0 + rng.normal(scale=0.05, size=problem.x0.size)
    f, g = problem.cost_and_gradient(x)
    terms = problem.last_terms
    assert all(terms[k] > 0 for k in range(4)), terms[:4]
    h = 1e-6
    for k in range(x.size):
        xp, xm = x.copy(), x.copy()
        xp[k] += h
        xm[k] -= h
        fd = (problem.cost_and_gradient(xp)[0] - problem.cost_and_gradient(xm)[0]) / (2 * h)
        assert g[k] == pytest.approx(fd, rel=1e-5, abs=1e-6 * (1 + abs(f)))


def test_long_segments_are_split_and_the_waypoints_become_inner_points():
    cfg = TrajectoryOptimizerConfig(max_piece_length_m=2.0)
    wp = np.array([[0.1, 0.0, 1.0], [4.0, 0.0, 1.0], [4.0, 1.0, 1.0], [10.2, 0.0, 1.0]])
    problem = build_trajectory_problem(START, GOAL, wp, None, [], 0.0, cfg)
    q, T = problem.unpack(problem.x0)
    assert problem.num_pieces == 2 + 1 + 4
    np.testing.assert_allclose(q[1], [4.0, 0.0, 1.0])
    np.testing.assert_allclose(q[2], [4.0, 1.0, 1.0])
    np.testing.assert_allclose(T.sum(), problem.initial_durations.sum(), rtol=1e-12)


def test_trajectory_past_cylinders_keeps_its_clearance_on_the_true_field():
    field = CylinderField([[3.0, 0.3], [5.5, -0.35], [8.0, 0.25]], [0.35, 0.3, 0.4])
    cfg = TrajectoryOptimizerConfig(obstacle_clearance_m=0.4)
    result = solve(build_trajectory_problem(START, GOAL, STRAIGHT, field, [], 0.0, cfg))
    _, pos, _, _ = _dense(result.trajectory)
    d, _ = field.distance_and_gradient(pos)
    assert d.min() >= cfg.obstacle_clearance_m
    assert result.feasible and result.status == "converged"
    np.testing.assert_allclose(pos[-1], GOAL[0], atol=1e-9)
    assert field.distance_and_gradient(np.linspace(START[0], GOAL[0], 100))[0].min() < 0.1  # the line was blocked


def test_speed_and_acceleration_limits_hold_after_optimisation():
    cfg = TrajectoryOptimizerConfig(limits=KinematicLimits(1.5, 1.5))
    result = solve(build_trajectory_problem(START, GOAL, STRAIGHT, None, [], 0.0, cfg))
    _, _, vel, acc = _dense(result.trajectory)
    speed = np.linalg.norm(vel, axis=1).max()
    accel = np.linalg.norm(acc, axis=1).max()
    # soft constraints: within 1 % of the limits, and the limits are active (the time weight pushes into them)
    assert speed <= 1.01 * cfg.limits.v_max_mps and accel <= 1.01 * cfg.limits.a_max_mps2
    assert speed >= 0.95 * cfg.limits.v_max_mps
    unconstrained = solve(
        build_trajectory_problem(START, GOAL, STRAIGHT, None, [], 0.0, TrajectoryOptimizerConfig(limits=KinematicLimits(50.0, 50.0)))
    )
    assert np.linalg.norm(_dense(unconstrained.trajectory)[2], axis=1).max() > 1.5 * cfg.limits.v_max_mps


@pytest.mark.parametrize("solver", ["lbfgs", "scipy"])
def test_crossing_neighbor_is_avoided_by_the_swarm_clearance_under_the_ellipsoid_metric(solver):
    t0 = 100.0
    cfg = TrajectoryOptimizerConfig(solver=solver)
    plain = solve(build_trajectory_problem(START, GOAL, STRAIGHT, None, [], t0, cfg))
    # a neighbour flying across the line at 1 m/s that would meet the drone at x = 5 m
    t, pos, _, _ = _dense(plain.trajectory)
    t_meet = t[np.argmin(np.abs(pos[:, 0] - 5.0))]
    meet = plain.trajectory.pos(t_meet)
    nb = NeighborPrediction.constant_velocity(4, "radio", t0, meet - [0.0, t_meet, 0.0], [0.0, 1.0, 0.0], np.zeros((6, 6)))
    result = solve(build_trajectory_problem(START, GOAL, STRAIGHT, None, [nb], t0, cfg))
    scale = np.array([1.0, 1.0, 1.0 / np.sqrt(cfg.swarm_z_scale)])  # E^{1/2}

    def ellipsoid_distance(res):
        t, pos, _, _ = _dense(res.trajectory)
        return np.linalg.norm((pos - nb.position(t0 + t)) * scale, axis=1).min()

    assert ellipsoid_distance(plain) < 0.05  # without the neighbour term they would collide
    assert ellipsoid_distance(result) >= cfg.swarm_clearance_m
    assert result.min_swarm_margin_m >= cfg.swarm_clearance_m and result.feasible


def test_uncertain_neighbor_is_avoided_by_clearance_plus_its_uncertainty_radius():
    t0 = 3.0
    cov = np.diag([0.02, 0.02, 0.02, 0.01, 0.01, 0.01])
    nb = NeighborPrediction.constant_velocity(4, "perception", t0 - 0.3, [5.0, -3.3, 1.0], [0.0, 1.0, 0.0], cov)
    cfg = TrajectoryOptimizerConfig()
    result = solve(build_trajectory_problem(START, GOAL, STRAIGHT, None, [nb], t0, cfg))
    t, pos, _, _ = _dense(result.trajectory)
    scale = np.array([1.0, 1.0, 1.0 / np.sqrt(cfg.swarm_z_scale)])
    dist = np.linalg.norm((pos - nb.position(t0 + t)) * scale, axis=1)
    radius = np.minimum(nb.uncertainty_radius(t0 + t), cfg.max_uncertainty_inflation_m)
    assert radius.min() > 0.2
    assert np.min(dist - radius) >= cfg.swarm_clearance_m


def test_own_lbfgs_and_scipy_reach_the_same_cost():
    field = CylinderField([[3.0, 0.3], [7.0, -0.3]], [0.35, 0.3])
    costs = []
    for solver in ("lbfgs", "scipy"):
        cfg = TrajectoryOptimizerConfig(solver=solver, relative_cost_tolerance=1e-9, gradient_tolerance=1e-7)
        costs.append(solve(build_trajectory_problem(START, GOAL, STRAIGHT, field, [], 0.0, cfg)).cost)
    assert costs[0] == pytest.approx(costs[1], rel=1e-3)


def test_non_finite_field_raises_the_optimizer_error_carrying_the_problem():
    problem = build_trajectory_problem(START, GOAL, STRAIGHT, NanField(), [], 0.0, TrajectoryOptimizerConfig())
    with pytest.raises(TrajectoryOptimizationError) as info:
        solve(problem)
    assert info.value.problem is problem


@pytest.mark.parametrize(
    "field, value",
    [
        ("weight_time", -1.0),
        ("limits", 2.0),
        ("swarm_z_scale", 0.9),
        ("max_iterations", 0),
        ("solver", "newton"),
        ("initial_speed_fraction", 1.5),
        ("samples_per_piece", 1),
    ],
)
def test_invalid_config_raises_one_line_value_error(field, value):
    with pytest.raises(ValueError, match=f"^{field}=") as info:
        TrajectoryOptimizerConfig(**{field: value})
    assert "\n" not in str(info.value)


def test_bad_waypoints_raise_value_error():
    with pytest.raises(ValueError, match="waypoints_world"):
        build_trajectory_problem(START, GOAL, np.zeros((1, 3)), None, [], 0.0)


class _PlainField:
    """Hides an OccupancySnapshot behind the bare protocol, forcing the Python L-BFGS driver."""

    def __init__(self, snapshot):
        self.snapshot = snapshot

    def distance_and_gradient(self, points_world):
        return self.snapshot.distance_and_gradient(points_world)


def _cylinder_snapshot():
    voxel = 0.2
    origin = np.array([-1.0, -3.0, 0.0])
    shape = (60, 30, 12)
    centres = origin + voxel * (np.indices(shape).reshape(3, -1).T + 0.5)
    occupied = np.zeros(shape[0] * shape[1] * shape[2], bool)
    for c, r in (([3.0, 0.3], 0.35), ([6.5, -0.3], 0.4)):
        occupied |= np.linalg.norm(centres[:, :2] - np.array(c), axis=1) <= r
    occupied = occupied.reshape(shape)
    from scipy.ndimage import distance_transform_edt

    dist = (distance_transform_edt(~occupied) - distance_transform_edt(occupied)) * voxel
    return OccupancySnapshot(0.0, origin, voxel, np.where(occupied, 1, 0).astype(np.int8), dist.astype(np.float32), dist.astype(np.float32))


def test_compiled_and_python_lbfgs_drivers_agree():
    snapshot = _cylinder_snapshot()
    nb = _crossing_neighbor(0.0)
    results = []
    for field in (snapshot, _PlainField(snapshot)):
        results.append(solve(build_trajectory_problem(START, GOAL, STRAIGHT, field, [nb], 0.0, TrajectoryOptimizerConfig())))
    compiled, python = results
    assert compiled.cost == pytest.approx(python.cost, rel=1e-6)
    assert abs(compiled.iterations - python.iterations) <= 2
    t = np.linspace(0.0, compiled.trajectory.total_duration, 200)
    np.testing.assert_allclose(compiled.trajectory.pos(t), python.trajectory.pos(t), atol=1e-4)


def test_a_short_hop_gets_min_pieces_and_can_dodge_a_neighbor():
    start = np.array([[0.0, 0.0, 1.2], [0.5, 0.0, 0.0], [0.0, 0.0, 0.0]])
    goal = np.array([[2.0, 0.3, 1.2], [0.0, 0.0, 0.0], [0.0, 0.0, 0.0]])
    ts = np.array([0.0, 1.0, 2.0])
    plan = NeighborPrediction(
        1, "radio", 0.0, ts, np.array([[1.0, -1.0, 1.2], [1.0, 0.0, 1.2], [1.0, 1.0, 1.2]]), np.tile([0.0, 1.0, 0.0], (3, 1)),
        np.zeros((6, 6)),
    )  # fmt: skip
    cfg = TrajectoryOptimizerConfig(min_pieces=3)
    problem = build_trajectory_problem(start, goal, np.array([start[0], goal[0]]), None, [plan], 0.0, cfg)
    assert problem.num_pieces == 3
    result = solve(problem)
    t, pos, _, _ = _dense(result.trajectory)
    scale = np.array([1.0, 1.0, 1.0 / np.sqrt(cfg.swarm_z_scale)])
    assert np.linalg.norm((pos - plan.position(t)) * scale, axis=1).min() >= cfg.swarm_clearance_m


def test_altitude_band_turns_a_pass_over_a_neighbour_into_a_pass_beside_it():
    """A neighbour hovers on the line, the front end's waypoint a little above it: free, the optimiser
    climbs 0.9 m over it (out of a level camera's vertical view); with the band [0.8, 1.2] m it stays in the
    layer (the cubic penalty's settling depth, 2 mm here) and clears the neighbour sideways instead."""
    wp = np.array([START[0], [5.0, 0.01, 1.1], GOAL[0]])
    nb = NeighborPrediction.constant_velocity(4, "radio", 0.0, [5.0, 0.0, 1.0], [0.0, 0.0, 0.0], np.zeros((6, 6)))
    out = {}
    for band in [(-np.inf, np.inf), (0.8, 1.2)]:
        cfg = TrajectoryOptimizerConfig(altitude_band_m=band)
        result = solve(build_trajectory_problem(START, GOAL, wp, None, [nb], 0.0, cfg))
        _, pos, _, _ = _dense(result.trajectory)
        assert result.feasible and result.min_swarm_margin_m >= cfg.swarm_clearance_m
        out[band] = (pos[:, 2].max(), np.abs(pos[:, 1]).max())
    (z_free, y_free), (z_band, y_band) = out.values()
    assert z_free > 1.5  # over it
    assert z_band <= 1.2 + 0.01 and y_band > y_free + 0.2  # beside it
