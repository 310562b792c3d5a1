"""Sampled penalties: values against brute force, gradients against finite differences."""

from __future__ import annotations

import numpy as np
import pytest

from perception.types import NeighborPrediction, OccupancySnapshot
from planners.limits import KinematicLimits
from planners.minco import MincoS3
from planners.trajectory_cost import NeighborTable, PenaltyParameters, TrajectoryCost
from planners.trajectory_penalty import _neighbor_state


class CylinderField:
    """Signed distance to the nearest of vertical cylinders (centres (n, 2) [m], radii (n,) [m])."""

    def __init__(self, centers_xy: np.ndarray, radii_m: np.ndarray):
        self.centers_xy = np.asarray(centers_xy, float)
        self.radii_m = np.asarray(radii_m, float)

    def distance_and_gradient(self, points_world: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        diff = points_world[:, None, :2] - self.centers_xy[None]
        rho = np.linalg.norm(diff, axis=2)
        d_all = rho - self.radii_m[None]
        k = np.argmin(d_all, axis=1)
        rows = np.arange(points_world.shape[0])
        grad = np.zeros_like(points_world)
        grad[:, :2] = diff[rows, k] / rho[rows, k][:, None]
        return d_all[rows, k], grad


def _problem(seed: int = 3, m: int = 4):
    rng = np.random.default_rng(seed)
    head = np.array([[0.0, 0.0, 1.0], [1.0, 0.2, 0.0], [0.0, 0.0, 0.0]])
    tail = np.array([[8.0, 0.5, 1.2], [0.0, 0.0, 0.0], [0.0, 0.0, 0.0]])
    q = np.linspace(head[0], tail[0], m + 1)[1:-1] + rng.normal(scale=0.3, size=(m - 1, 3))
    T = rng.uniform(0.6, 1.0, m)
    return head, tail, q, T


def _neighbors(t0: float):
    cov = np.diag([0.01, 0.02, 0.01, 0.04, 0.03, 0.02])
    track = NeighborPrediction.constant_velocity(7, "perception", t0 - 0.2, [4.0, -2.0, 1.1], [0.0, 1.2, 0.0], cov)
    ts = t0 + np.array([0.0, 0.8, 1.6, 2.4, 3.5])
    pos = np.array([[6.0, 2.0, 1.0], [5.0, 1.0, 1.1], [4.0, 0.4, 1.2], [3.0, 0.0, 1.2], [2.0, -0.5, 1.0]])
    vel = np.gradient(pos, ts, axis=0)
    plan = NeighborPrediction(2, "radio", t0 - 0.1, ts, pos, vel, np.zeros((6, 6)))
    return [track, plan]


def _total_cost(cost: TrajectoryCost, head, tail, q, T):
    minco = MincoS3()
    minco.set_conditions(head, tail, T.size)
    minco.set_parameters(q, T)
    terms = cost.evaluate(minco.coefficients, T)
    gq, gt = minco.propagate_grad(terms.grad_by_coeffs, terms.grad_by_times)
    return terms, gq, gt


def _assert_gradients_match_finite_differences(cost, head, tail, q, T, gq, gt, h: float = 1e-6) -> None:
    """Central differences of the total penalty by every inner point coordinate and duration."""
    for i in range(q.shape[0]):
        for d in range(3):
            qp, qm = q.copy(), q.copy()
            qp[i, d] += h
            qm[i, d] -= h
            fd = (_total_cost(cost, head, tail, qp, T)[0].total - _total_cost(cost, head, tail, qm, T)[0].total) / (2 * h)
            assert gq[i, d] == pytest.approx(fd, rel=1e-5, abs=1e-6 * (1 + abs(fd)))
    for i in range(T.size):
        Tp, Tm = T.copy(), T.copy()
        Tp[i] += h
        Tm[i] -= h
        fd = (_total_cost(cost, head, tail, q, Tp)[0].total - _total_cost(cost, head, tail, q, Tm)[0].total) / (2 * h)
        assert gt[i] == pytest.approx(fd, rel=1e-5, abs=1e-6 * (1 + abs(fd)))


@pytest.fixture
def cost():
    params = PenaltyParameters(limits=KinematicLimits(1.5, 2.0), samples_per_piece=8, max_uncertainty_inflation_m=5.0)
    field = CylinderField([[3.0, 0.6], [5.5, 0.0]], [0.5, 0.4])
    return TrajectoryCost(params, 10.0, field, _neighbors(10.0))


def test_neighbor_kernel_matches_neighbor_prediction():
    nbs = _neighbors(10.0)
    table = NeighborTable(nbs)
    for n, nb in enumerate(nbs):
        for t in (9.0, 10.0, 10.3, 11.1, 12.0, 13.5, 15.0):
            state = _neighbor_state(table.times_s, table.pos_world, table.vel_world, table.offsets[n], table.offsets[n + 1], t)
            p, v = np.array(state[:3]), np.array(state[3:])
            np.testing.assert_allclose(p, nb.position(t), atol=1e-12)
            h = 1e-6
            np.testing.assert_allclose(v, (nb.position(t + h) - nb.position(t - h)) / (2 * h), atol=1e-5)
        t = np.array([12.0])
        dt = t - table.t_last_s[n]
        a, b, c = table.radius_terms[n, :3]
        np.testing.assert_allclose(np.sqrt(a + b * dt + c * dt**2), nb.uncertainty_radius(t), rtol=1e-12)


def test_every_penalty_is_active_in_the_test_problem(cost):
    terms, _, _ = _total_cost(cost, *_problem())
    assert terms.vel > 0 and terms.acc > 0 and terms.obstacle > 0 and terms.swarm > 0


@pytest.mark.parametrize("term", ["vel", "acc", "obstacle", "swarm"])
def test_each_penalty_gradient_matches_finite_differences(term):
    weights = {k: 0.0 for k in ("weight_vel", "weight_acc", "weight_obstacle", "weight_swarm")}
    weights[f"weight_{term}"] = 1.0
    params = PenaltyParameters(limits=KinematicLimits(1.5, 2.0), samples_per_piece=8, max_uncertainty_inflation_m=5.0, **weights)
    field = CylinderField([[3.0, 0.6], [5.5, 0.0]], [0.5, 0.4])
    cost = TrajectoryCost(params, 10.0, field, _neighbors(10.0))
    head, tail, q, T = _problem()
    terms, gq, gt = _total_cost(cost, head, tail, q, T)
    assert getattr(terms, term) > 1e-6
    _assert_gradients_match_finite_differences(cost, head, tail, q, T, gq, gt)


def test_penalty_values_match_a_brute_force_trapezoid(cost):
    head, tail, q, T = _problem()
    terms, _, _ = _total_cost(cost, head, tail, q, T)
    minco = MincoS3()
    minco.set_conditions(head, tail, T.size)
    minco.set_parameters(q, T)
    traj = minco.trajectory(cost.t0_s)
    p = cost.params
    K = p.samples_per_piece
    start = np.concatenate([[0.0], np.cumsum(T)[:-1]])
    vel = acc = obs = sw = 0.0
    for i in range(T.size):
        t_loc = start[i] + np.linspace(0.0, T[i], K + 1)
        w = np.full(K + 1, T[i] / K)
        w[[0, -1]] *= 0.5
        v, a, x = traj.vel(t_loc), traj.acc(t_loc), traj.pos(t_loc)  # C^4 joints: either piece at a joint
        vel += np.sum(w * np.maximum((v**2).sum(1) - p.limits.v_max_mps**2, 0) ** 3) * p.weight_vel
        acc += np.sum(w * np.maximum((a**2).sum(1) - p.limits.a_max_mps2**2, 0) ** 3) * p.weight_acc
        d, _ = cost.distance_field.distance_and_gradient(x)
        obs += np.sum(w * np.maximum(p.obstacle_clearance_m + p.clearance_margin_m - d, 0) ** 3) * p.weight_obstacle
        for nb in _neighbors(cost.t0_s):
            t_abs = cost.t0_s + t_loc
            e = x - nb.position(t_abs)
            ell2 = e[:, 0] ** 2 + e[:, 1] ** 2 + e[:, 2] ** 2 / p.swarm_z_scale
            r = np.minimum(nb.uncertainty_radius(t_abs, p.uncertainty_sigma), p.max_uncertainty_inflation_m)
            sw += np.sum(w * np.maximum((p.swarm_clearance_m + p.clearance_margin_m + r) ** 2 - ell2, 0) ** 3) * p.weight_swarm
    assert terms.vel == pytest.approx(vel, rel=1e-9)
    assert terms.acc == pytest.approx(acc, rel=1e-9)
    assert terms.obstacle == pytest.approx(obs, rel=1e-9)
    assert terms.swarm == pytest.approx(sw, rel=1e-9)


def test_penalties_vanish_inside_the_limits():
    params = PenaltyParameters(limits=KinematicLimits(50.0, 50.0))
    cost = TrajectoryCost(params, 0.0, None, [])
    head, tail, q, T = _problem()
    terms, gq, gt = _total_cost(cost, head, tail, q, T)
    assert terms.total == 0.0 and not gq.any() and not gt.any()
    assert np.isinf(terms.min_obstacle_distance_m) and np.isinf(terms.min_swarm_margin_m)


@pytest.mark.parametrize(
    "field, value", [("limits", 2.0), ("swarm_z_scale", 0.5), ("samples_per_piece", 1), ("weight_swarm", -1.0), ("swarm_recovery_mps", 0.0)]
)
def test_invalid_parameters_raise_one_line_value_error(field, value):
    with pytest.raises(ValueError, match=field):
        PenaltyParameters(**{field: value})


def test_compiled_snapshot_interpolation_equals_occupancy_snapshot():
    rng = np.random.default_rng(11)
    shape = (9, 7, 5)
    dist = rng.normal(size=shape).astype(np.float32)
    state = np.zeros(shape, np.int8)
    snap = OccupancySnapshot(0.0, np.array([-1.0, 2.0, 0.0]), 0.2, state, dist, np.abs(dist))
    cost = TrajectoryCost(PenaltyParameters(), 0.0, snap, [])
    pts = np.array([-1.0, 2.0, 0.0]) + rng.uniform(-0.3, 2.2, size=(400, 3))  # inside and outside the window
    d_ref, g_ref = snap.distance_and_gradient(pts)
    d, g = cost.distance_and_gradient(pts)
    np.testing.assert_allclose(d, d_ref, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(g, g_ref, rtol=1e-12, atol=1e-12)


def test_skipping_far_neighbors_changes_neither_penalties_nor_gradients():
    """The bounding-box pruning (active without statistics) must be exact."""
    rng = np.random.default_rng(8)
    t0 = 10.0
    nbs = [
        NeighborPrediction.constant_velocity(k, "perception", t0, p, v, np.eye(6) * 0.01)
        for k, (p, v) in enumerate(zip(rng.uniform([0, -4, 0.5], [8, 4, 1.5], (8, 3)), rng.normal(scale=0.8, size=(8, 3))))
    ] + _neighbors(t0)
    cost = TrajectoryCost(PenaltyParameters(samples_per_piece=8), t0, None, nbs)
    head, tail, q, T = _problem()
    minco = MincoS3()
    minco.set_conditions(head, tail, T.size)
    minco.set_parameters(q, T)
    outs = []
    for stats in (True, False):
        gdc, gdt = np.zeros((6 * T.size, 3)), np.zeros(T.size)
        outs.append((cost.accumulate(minco.coefficients, T, gdc, gdt, stats=stats), gdc, gdt))
    (o1, c1, t1), (o2, c2, t2) = outs
    assert o1[3] > 0
    np.testing.assert_array_equal(o1[:7], o2[:7])
    np.testing.assert_array_equal(c1, c2)
    np.testing.assert_array_equal(t1, t2)


def _close_neighbour(t0: float) -> list[NeighborPrediction]:
    """A track 0.3 m beside the start of :func:`_problem`, flying the same way (the start is inside C_s)."""
    cov = np.diag([0.01, 0.01, 0.01, 0.02, 0.02, 0.02])
    return [NeighborPrediction.constant_velocity(4, "perception", t0 - 0.1, [0.2, 0.25, 1.0], [1.0, 0.1, 0.0], cov)]


def _relaxed_cost(rho: float, start: bool = True) -> TrajectoryCost:
    params = PenaltyParameters(
        limits=KinematicLimits(50.0, 50.0), weight_vel=0.0, weight_acc=0.0, weight_obstacle=0.0,
        samples_per_piece=8, max_uncertainty_inflation_m=5.0, swarm_recovery_mps=rho,
    )  # fmt: skip
    head = _problem()[0]
    return TrajectoryCost(params, 10.0, None, _close_neighbour(10.0), head[0] if start else None)


def test_start_inside_the_clearance_starts_at_the_current_distance_and_grows_back():
    """clr(t) = C_s + margin + r(t) - max(0, s0 - rho (t - t0)): zero penalty at t0, brute force elsewhere."""
    rho = 0.4
    cost = _relaxed_cost(rho)
    head, tail, q, T = _problem()
    p = cost.params
    nb = _close_neighbour(10.0)[0]
    t0 = cost.t0_s
    e0 = head[0] - nb.position(t0)
    ell0 = np.sqrt(e0[0] ** 2 + e0[1] ** 2 + e0[2] ** 2 / p.swarm_z_scale)
    r0 = min(float(nb.uncertainty_radius(np.array([t0]), p.uncertainty_sigma)[0]), p.max_uncertainty_inflation_m)
    s0 = p.swarm_clearance_m + p.clearance_margin_m + r0 - ell0
    assert s0 > 0.3  # deep inside
    assert cost.neighbors.radius_terms[0, 3] == pytest.approx(s0, rel=1e-12)
    terms, _, _ = _total_cost(cost, head, tail, q, T)
    minco = MincoS3()
    minco.set_conditions(head, tail, T.size)
    minco.set_parameters(q, T)
    traj = minco.trajectory(t0)
    K = p.samples_per_piece
    start = np.concatenate([[0.0], np.cumsum(T)[:-1]])
    sw = 0.0
    for i in range(T.size):
        t_loc = start[i] + np.linspace(0.0, T[i], K + 1)
        w = np.full(K + 1, T[i] / K)
        w[[0, -1]] *= 0.5
        x, t_abs = traj.pos(t_loc), t0 + t_loc
        e = x - nb.position(t_abs)
        ell2 = e[:, 0] ** 2 + e[:, 1] ** 2 + e[:, 2] ** 2 / p.swarm_z_scale
        r = np.minimum(nb.uncertainty_radius(t_abs, p.uncertainty_sigma), p.max_uncertainty_inflation_m)
        clr = p.swarm_clearance_m + p.clearance_margin_m + r - np.maximum(0.0, s0 - rho * (t_abs - t0))
        viol = np.maximum(clr**2 - ell2, 0)
        if i == 0:
            assert viol[0] == pytest.approx(0.0, abs=1e-12)  # the start itself is not penalised
        sw += np.sum(w * viol**3) * p.weight_swarm
    assert terms.swarm > 0
    assert terms.swarm == pytest.approx(sw, rel=1e-9)
    full, _, _ = _total_cost(_relaxed_cost(rho, start=False), head, tail, q, T)
    assert full.swarm > 10 * terms.swarm  # the paper's form asks for the jump at once


def test_relaxed_clearance_gradient_matches_finite_differences():
    cost = _relaxed_cost(0.4)
    head, tail, q, T = _problem()
    terms, gq, gt = _total_cost(cost, head, tail, q, T)
    assert terms.swarm > 1e-6
    _assert_gradients_match_finite_differences(cost, head, tail, q, T, gq, gt)


def test_infinite_recovery_rate_is_the_full_clearance():
    head, tail, q, T = _problem()
    off, _, _ = _total_cost(_relaxed_cost(np.inf), head, tail, q, T)
    full, _, _ = _total_cost(_relaxed_cost(0.4, start=False), head, tail, q, T)
    assert not _relaxed_cost(np.inf).neighbors.radius_terms[:, 3].any()
    assert off.swarm == full.swarm > 0


def test_altitude_band_gradient_matches_finite_differences_and_its_value_a_brute_force_trapezoid():
    """The band penalty alone (every other weight 0): both sides violated, against central differences and
    against the trapezoid of w_z max(z - z_hi, z_lo - z, 0)^3 over the samples."""
    weights = {k: 0.0 for k in ("weight_vel", "weight_acc", "weight_obstacle", "weight_swarm")}
    params = PenaltyParameters(samples_per_piece=8, altitude_band_m=(0.9, 1.1), weight_altitude=10.0, **weights)
    cost = TrajectoryCost(params, 10.0, None, [])
    head, tail, q, T = _problem()
    terms, gq, gt = _total_cost(cost, head, tail, q, T)
    _assert_gradients_match_finite_differences(cost, head, tail, q, T, gq, gt)
    minco = MincoS3()
    minco.set_conditions(head, tail, T.size)
    minco.set_parameters(q, T)
    traj = minco.trajectory(cost.t0_s)
    start = np.concatenate([[0.0], np.cumsum(T)[:-1]])
    expected, above, below = 0.0, False, False
    for i in range(T.size):
        t_loc = start[i] + np.linspace(0.0, T[i], 9)
        z = traj.pos(t_loc)[:, 2]
        above, below = above or bool(np.any(z > 1.1)), below or bool(np.any(z < 0.9))
        pen = 10.0 * np.maximum(np.maximum(z - 1.1, 0.9 - z), 0.0) ** 3
        w = np.full(9, T[i] / 8)
        w[[0, -1]] *= 0.5
        expected += float(np.sum(w * pen))
    assert above and below  # both sides of the band are exercised
    assert terms.obstacle == pytest.approx(expected, rel=1e-10)
    assert terms.vel == terms.acc == terms.swarm == 0.0


@pytest.mark.parametrize("band", [(1.0, 1.0), (2.0, 1.0), (float("nan"), 1.0)])
def test_altitude_band_must_be_ordered(band):
    with pytest.raises(Exception, match="altitude_band_m"):
        PenaltyParameters(altitude_band_m=band)
