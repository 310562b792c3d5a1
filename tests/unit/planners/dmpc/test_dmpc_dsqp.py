"""dSQP (Stomberg et al. Algorithm 3): the minimum-distance rows, their Jacobian, and the outer loop on a swap."""

from __future__ import annotations

import numpy as np
import pytest

from planners.dmpc.admm.config import AdmmFormationConfig
from planners.dmpc.admm.distance import DistanceRows, distance_gradient, distance_residual, owned_partners
from planners.dmpc.admm.formation import AdmmFormationAgent, solve_admm_round
from planners.dmpc.admm.ocp import DroneLayout
from planners.dmpc.sparse_qp.pattern import SparsePattern
from sim.checks import ConfigError

THETA_INV = np.array([1.0, 1.0, 0.5])


@pytest.mark.parametrize("downwash", [1.0, 2.0])
def test_the_gradient_of_the_distance_matches_central_differences(downwash):
    rng = np.random.default_rng(3)
    own, other = rng.normal(size=(20, 3)), rng.normal(size=(20, 3))
    a = distance_gradient(own, other, downwash)
    step = 1e-6
    for axis in range(3):
        e = np.zeros(3)
        e[axis] = step
        # d xi / d p_o = -d (d - xi) / d p_o
        fd = -(distance_residual(own + e, other, 0.4, downwash) - distance_residual(own - e, other, 0.4, downwash)) / (2 * step)
        assert np.allclose(a[:, axis], fd, rtol=1e-6, atol=1e-8)
        fd_other = -(distance_residual(own, other + e, 0.4, downwash) - distance_residual(own, other - e, 0.4, downwash)) / (2 * step)
        assert np.allclose(-a[:, axis], fd_other, rtol=1e-6, atol=1e-8)


def test_coinciding_plans_take_the_fallback_direction():
    p = np.zeros((2, 3))
    assert np.allclose(distance_gradient(p, p, 2.0), [[1.0, 0.0, 0.0]] * 2)
    assert np.allclose(distance_gradient(p, p, 1.0, fallback_world=np.array([0.0, 3.0, 0.0])), [[0.0, 1.0, 0.0]] * 2)


def test_the_linearised_row_is_the_tangent_and_an_inner_approximation():
    """Row a'(p - w) + s >= d at zbar: equal to xi's tangent, and every point meeting it is at least d - s apart."""
    K = 4
    lay = DroneLayout(K, (0, 2))
    rows = DistanceRows(lay, (0,), d_min_m=0.4, downwash=2.0, first_step_free=True)
    pattern = SparsePattern()
    pattern.add(np.array([0]), np.array([0]), np.array([0.0]))  # a row above, as the own rows are
    s = rows.add_to(pattern, first_row=1)
    A, coo_to_csc = pattern.to_csc((1 + rows.count, lay.size))
    rng = np.random.default_rng(7)
    zbar = rng.normal(size=lay.size)
    A.data[coo_to_csc[s]] = rows.values(zbar)
    D = A[1:].toarray()
    lower, upper = rows.bounds()
    assert lower[0] == -1e30 and np.all(lower[1:] == 0.4) and np.all(upper == 1e30)  # k = 1 free (Remark 1)
    pbar, wbar = zbar[lay.pos].reshape(K, 3), zbar[lay.copy(0)].reshape(K, 3)
    assert np.allclose(D @ zbar - zbar[lay.slack], np.linalg.norm((pbar - wbar) * THETA_INV, axis=1))  # tangent at zbar
    for _ in range(200):  # xi convex: xi(p - w) >= a'(p - w) for every z
        z = rng.normal(size=lay.size) * 2.0
        p, w = z[lay.pos].reshape(K, 3), z[lay.copy(0)].reshape(K, 3)
        assert np.all(np.linalg.norm((p - w) * THETA_INV, axis=1) >= D @ z - z[lay.slack] - 1e-12)
    with pytest.raises(ValueError, match="not neighbours"):
        DistanceRows(lay, (5,), 0.4, 2.0, True)


def test_the_higher_id_holds_each_pair_once():
    assert owned_partners(3, [0, 1, 4, 5]) == (0, 1)
    assert owned_partners(0, [1, 2]) == ()
    pairs = {(i, j) for i in range(5) for j in owned_partners(i, [k for k in range(5) if k != i])}
    assert pairs == {(i, j) for i in range(5) for j in range(i)}


@pytest.mark.parametrize(("field", "value"), [("solver", "sqp"), ("sqp_iterations", 0), ("d_min_m", 0.0), ("downwash", 0.5)])
def test_bad_dsqp_settings_are_refused(field, value):
    with pytest.raises(ConfigError, match=f"^{field}="):
        AdmmFormationConfig(**{field: value})


def _swap(cfg: AdmmFormationConfig):
    starts = np.array([[-1.0, 0.05, 1.5], [1.0, -0.05, 1.5]])
    goals = np.array([[1.0, 0.0, 1.5], [-1.0, 0.0, 1.5]])
    agents = [AdmmFormationAgent(0, cfg, {1: goals[0] - goals[1]}), AdmmFormationAgent(1, cfg, {0: goals[1] - goals[0]})]
    for i, a in enumerate(agents):
        a.start_step(np.r_[starts[i], 0.0, 0.0, 0.0], np.tile(goals[i], (cfg.horizon_steps, 1)), 0.0, np.zeros(3))
    res = solve_admm_round(agents)
    distance = np.linalg.norm((res[0].pos_world - res[1].pos_world) * THETA_INV, axis=1)[2:]  # k >= 2: p[1] is data
    return distance, res


def test_the_sqp_outer_loop_on_a_two_robot_swap_meets_the_distance_within_its_slack():
    """Two drones head-on (5 cm apart sideways) swap: ADMM plans them through each other, dSQP keeps d_min."""
    distance, res = _swap(AdmmFormationConfig(solver="dsqp", rho=100.0, l_max=10, sqp_iterations=20, distance_rows="copies"))
    slack = max(r.slack for r in res)
    assert slack < 0.01 and distance.min() >= 0.4 - slack - 2e-3
    assert res[0].iterations == 200 and max(r.primal_residual[-1] for r in res) < 2e-3  # consensus reached
    plain, _ = _swap(AdmmFormationConfig(solver="admm", rho=100.0, l_max=200))
    assert plain.min() < 0.2  # the ADMM without the constraint flies them within 0.2 m


def test_the_nlp_reference_is_the_centralized_qp_where_no_distance_binds():
    """IPOPT on the non-convex OCP = OSQP on the convex one when every pair stays far apart (same assembly)."""
    from planners.dmpc.admm.centralized import centralized_formation_qp
    from planners.dmpc.admm.centralized_nlp import centralized_formation_nlp
    from planners.dmpc.formation_graph import FormationGraph

    cfg = AdmmFormationConfig(solver="dsqp")
    slots = np.array([[0.0, 0.0, 0.0], [2.0, 0.0, 0.0], [0.0, 2.0, 0.0]])
    graph = FormationGraph(slots, ((0, 1), (0, 2), (1, 2)))
    rng = np.random.default_rng(2)
    states = np.c_[slots + rng.uniform(-0.3, 0.3, (3, 3)) + [0.0, 0.0, 1.5], rng.uniform(-0.5, 0.5, (3, 3))]
    refs = np.stack([np.tile(s + [1.0, 0.5, 1.5], (cfg.horizon_steps, 1)) for s in slots])
    u_now = rng.uniform(-1.0, 1.0, (3, 3))
    qp = centralized_formation_qp(cfg, graph, states, refs, u_now)
    nlp = centralized_formation_nlp(cfg, graph, states, refs, u_now)
    assert nlp.success and abs(nlp.cost - qp.cost) <= 1e-6 * qp.cost
    assert np.abs(nlp.acc_world - qp.acc_world).max() < 1e-4


def test_the_nlp_reference_keeps_the_swap_apart_where_the_qp_does_not():
    from planners.dmpc.admm.centralized import centralized_formation_qp
    from planners.dmpc.admm.centralized_nlp import centralized_formation_nlp
    from planners.dmpc.formation_graph import FormationGraph

    cfg = AdmmFormationConfig(solver="dsqp")
    goals = np.array([[1.0, 0.0, 1.5], [-1.0, 0.0, 1.5]])
    states = np.c_[[[-1.0, 0.05, 1.5], [1.0, -0.05, 1.5]], np.zeros((2, 3))]
    refs = np.stack([np.tile(g, (cfg.horizon_steps, 1)) for g in goals])
    graph = FormationGraph(goals - goals.mean(axis=0), ((0, 1),))
    nlp = centralized_formation_nlp(cfg, graph, states, refs, np.zeros((2, 3)))
    qp = centralized_formation_qp(cfg, graph, states, refs, np.zeros((2, 3)))
    gap = lambda pos: np.linalg.norm((pos[0] - pos[1]) * THETA_INV, axis=1)[2:].min()  # noqa: E731
    assert nlp.success and gap(nlp.pos_world) >= cfg.d_min_m - nlp.slack[1] - 1e-6 and nlp.slack[1] < 0.01
    assert gap(qp.pos_world) < 0.2 and nlp.cost > qp.cost  # the constraint costs: the QP's optimum is not feasible


def test_rows_against_the_means_constrain_the_own_plan_only_and_hold_against_the_mean():
    K = 4
    lay = DroneLayout(K, (0,))
    rows = DistanceRows(lay, (0,), d_min_m=0.4, downwash=2.0, first_step_free=False, against_means=True)
    pattern = SparsePattern()
    s = rows.add_to(pattern, first_row=0)
    A, coo_to_csc = pattern.to_csc((rows.count, lay.size))
    rng = np.random.default_rng(11)
    zbar = rng.normal(size=lay.size)
    A.data[coo_to_csc[s]] = rows.values(zbar)
    D = A.toarray()
    lower, _ = rows.bounds()
    assert np.all(D[:, lay.copy(0)] == 0.0)  # the copy is not a decision of the row
    wbar = zbar[lay.copy(0)].reshape(K, 3)
    for _ in range(200):  # a'p + s >= d + a'wbar implies xi(p - wbar) >= d - s
        z = rng.normal(size=lay.size) * 2.0
        margin = D @ z - lower  # >= 0 where the row holds
        p = z[lay.pos].reshape(K, 3)
        xi = np.linalg.norm((p - wbar) * THETA_INV, axis=1)
        assert np.all(xi >= 0.4 + margin - z[lay.slack] - 1e-12)


def test_the_swap_with_rows_against_the_means_at_the_papers_rho_keeps_apart_in_closed_loop():
    """Two kinematic drones swap head-on for 12 s with 5 x 2 iterations a step: apart by d_min at every sample."""
    from planners.dmpc.model import discrete_model

    out = {}
    for rows in ("copies", "means"):
        cfg = AdmmFormationConfig(solver="dsqp", l_max=2, sqp_iterations=5, rho=1.0, distance_rows=rows)
        starts, goals = np.array([[-1.0, 0.05, 1.5], [1.0, -0.05, 1.5]]), np.array([[1.0, 0.0, 1.5], [-1.0, 0.0, 1.5]])
        agents = [AdmmFormationAgent(0, cfg, {1: goals[0] - goals[1]}), AdmmFormationAgent(1, cfg, {0: goals[1] - goals[0]})]
        A, B = discrete_model("double", cfg.step_s)
        x, u_now, closest = np.c_[starts, np.zeros((2, 3))], np.zeros((2, 3)), np.inf
        for step in range(60):
            for i, a in enumerate(agents):
                a.start_step(x[i], np.tile(goals[i], (cfg.horizon_steps, 1)), step * cfg.step_s, u_now[i])
            res = solve_admm_round(agents)
            u_next = np.array([r.acc_world[1] for r in res])
            x = np.array([A @ x[i] + B @ u_now[i] for i in range(2)])
            u_now = u_next
            closest = min(closest, float(np.linalg.norm((x[0, :3] - x[1, :3]) * THETA_INV)))
        out[rows] = (closest, bool(np.abs(x[:, :3] - goals).max() < 0.05))
    assert out["means"][0] >= 0.4 and out["means"][1]  # apart and arrived
    assert out["copies"][0] < 0.2  # the paper's rows at rho = 1: the copies lag, the plans go within contact
