"""The DMPC QP: KKT conditions of OSQP's solutions, constraint geometry, fixed sparsity, errors, config validation."""

from __future__ import annotations

import dataclasses
from typing import ClassVar

import numpy as np
import pytest

from planners.dmpc.collision import ellipsoidal_distance, on_demand_constraints
from planners.dmpc.config import DmpcConfig
from planners.dmpc.model import rollout
from planners.dmpc.qp import DmpcProblem, DmpcSolveError, QpSnapshot
from planners.dmpc.types import DmpcPlan
from qp_kkt import assert_kkt  # tests/unit/planners/dmpc/qp_kkt.py



@dataclasses.dataclass(frozen=True)
class TightDmpcConfig(DmpcConfig):
    """DmpcConfig solved to 1e-8 and polished (its OSQP settings are class constants): the KKT checks need it."""

    osqp_eps_abs: ClassVar[float] = 1e-8
    osqp_eps_rel: ClassVar[float] = 1e-8
    osqp_polish: ClassVar[bool] = True
    osqp_max_iter: ClassVar[int] = 100000


def _x0(cfg: DmpcConfig, pos=(0.0, 0.0, 1.5), vel=(1.5, 0.0, 0.0)) -> np.ndarray:
    x0 = np.zeros(cfg.state_dim)
    x0[:3], x0[3:6] = pos, vel
    return x0


def _hover_neighbour(pos, neighbor_id: int = 1, cfg: DmpcConfig | None = None):
    cfg = cfg or DmpcConfig()
    return DmpcPlan.hover(0.0, cfg.step_s, cfg.horizon_steps, pos).as_neighbor_prediction(neighbor_id, 0.0)


CASES = {
    "on_demand_double": dict(collision_mode="on_demand", model="double"),
    "on_demand_triple": dict(collision_mode="on_demand", model="triple"),
    "bvc_double": dict(collision_mode="bvc", model="double"),
    "bvc_triple_halt": dict(collision_mode="bvc", model="triple", terminal_halt=True),
    "on_demand_formation_obstacles": dict(
        collision_mode="on_demand", max_obstacle_planes=2, terminal_halt=True, obstacle_avoidance="every_step"
    ),
}


@pytest.mark.parametrize("case", sorted(CASES))
def test_solution_satisfies_its_constraints_and_the_kkt_conditions(case: str) -> None:
    cfg = TightDmpcConfig(max_neighbours=3, **CASES[case])
    problem = DmpcProblem(cfg)
    x0 = _x0(cfg)
    neighbours = [_hover_neighbour([2.0, 0.05, 1.5], 1), _hover_neighbour([1.0, 3.0, 1.5], 2)]
    kwargs = {}
    if "formation" in case:
        kwargs = dict(formation_offsets={2: np.array([0.0, 2.0, 0.0])}, obstacles=[(np.array([0.0, 1.0, 0.0]), -0.3)])
    # BVC needs collision-free previous plans (hover here); on demand, the constant-velocity
    # guess (no previous plan) runs into neighbour 1, so a plane is built.
    previous = DmpcPlan.hover(0.0, cfg.step_s, cfg.horizon_steps, x0[:3]) if cfg.collision_mode == "bvc" else None
    result = problem.solve(x0, [4.0, 0.0, 1.5], neighbours, previous, t_now_s=0.0, **kwargs)
    assert result.status == "solved"
    assert result.n_collision_constraints >= 1
    assert_kkt(problem.snapshot())
    # The returned trajectory is the model's response to the returned inputs.
    states = rollout(cfg.model, cfg.step_s, x0, result.inputs)
    np.testing.assert_allclose(result.pos_world, states[1:, :3], atol=1e-9)
    np.testing.assert_allclose(result.vel_world, states[1:, 3:6], atol=1e-9)
    # Box limits.
    tol = 1e-6
    assert np.all(np.abs(result.vel_world) <= cfg.limits.v_max_mps + tol)
    assert np.all(np.abs(result.acc_world) <= cfg.limits.a_max_mps2 + tol)
    assert np.all(result.pos_world >= np.asarray(cfg.pos_min_world) - tol)
    if cfg.model == "triple":
        assert np.all(np.abs(result.inputs) <= cfg.limits.j_max_mps3 + tol)
    if cfg.terminal_halt:
        np.testing.assert_allclose(result.vel_world[-1], 0.0, atol=1e-6)
    if "obstacles" in kwargs:
        assert np.all(result.pos_world[:, 1] >= -0.3 - tol)
    if cfg.collision_mode == "bvc":
        # Previous plans 2 m apart: the midway plane keeps every sample >= (r_min_m + 2) / 2 away.
        d = ellipsoidal_distance(result.pos_world - np.array([2.0, 0.05, 1.5]), cfg.downwash)
        assert d.min() >= (cfg.r_min_m + 2.0) / 2 - 1e-6
    else:
        # Re-derive the on-demand plane independently and check the plan meets it (with its slack).
        S, K, h = cfg.conflict_substeps, cfg.horizon_steps, cfg.step_s
        t_fine = (h / S) * np.arange(1, K * S + 1)
        own_guess = x0[:3] + x0[3:6] * t_fine[:, None]
        nb = np.stack([n.position(t_fine) for n in neighbours])
        cons = on_demand_constraints(own_guess, nb, cfg.r_min_m, cfg.downwash, cfg.conflict_margin_m, 3.0,
                                     linearise_at=cfg.on_demand_time)  # fmt: skip
        assert cons.count == result.n_collision_constraints
        p = result.plan.position(t_fine[cons.time_index])
        lhs = np.einsum("nd,nd->n", cons.normal, p) + result.slack
        assert np.all(lhs >= cons.offset - 1e-6)
        assert result.conflict_time_s == pytest.approx(t_fine[cons.step_index])


def test_without_neighbours_the_plan_reaches_the_goal_and_stops() -> None:
    cfg = TightDmpcConfig(terminal_halt=True)
    problem = DmpcProblem(cfg)
    x0 = _x0(cfg, vel=(0.0, 0.0, 0.0))
    result = problem.solve(x0, [1.0, -0.5, 2.0], [], None, t_now_s=3.0)
    assert result.n_collision_constraints == 0 and np.isnan(result.conflict_time_s)
    np.testing.assert_allclose(result.pos_world[-1], [1.0, -0.5, 2.0], atol=3e-2)  # goal vs smoothness trade-off
    assert result.plan.t0_s == 3.0
    np.testing.assert_allclose(result.plan.pos_world[0], x0[:3])
    assert_kkt(problem.snapshot())


def test_formation_term_pulls_towards_the_desired_offset() -> None:
    cfg = TightDmpcConfig(weight_formation=1000.0)
    problem = DmpcProblem(cfg)
    neighbour = _hover_neighbour([5.0, 5.0, 1.5], neighbor_id=7)
    x0 = _x0(cfg, vel=(0.0, 0.0, 0.0))
    free = problem.solve(x0, [0.0, 0.0, 1.5], [neighbour], None, t_now_s=0.0)
    held = problem.solve(x0, [0.0, 0.0, 1.5], [neighbour], None, {7: np.array([3.0, 3.0, 0.0])}, t_now_s=0.0)
    target = np.array([2.0, 2.0, 1.5])  # p_j - d_ij
    assert np.linalg.norm(held.pos_world[-1] - target) < 0.5 * np.linalg.norm(free.pos_world[-1] - target)
    assert_kkt(problem.snapshot())


@pytest.mark.parametrize("model", ["double", "triple"])
def test_qp_objective_equals_the_cost_rolled_out_step_by_step(model: str) -> None:
    """1/2 U^T P U + q^T U is J(U) up to a constant, J evaluated on a step-by-step rollout.

    Guards the sparse P: its pattern keeps only the structural nonzeros (no
    cross-axis entries), so a cost term that coupled the axes, or an entry
    dropped from the pattern, would show here. Random U have cross-axis terms.
    """
    cfg = DmpcConfig(model=model, weight_formation=7.0, weight_smoothness=3.0)
    problem = DmpcProblem(cfg)
    x0 = _x0(cfg, vel=(0.4, -0.2, 0.1))
    goal = np.array([3.0, -1.0, 2.0])
    hover = {4: np.array([2.0, 2.0, 1.5]), 5: np.array([-2.0, 1.0, 1.0])}  # neighbour id -> position [m]
    neighbours = [_hover_neighbour(pos, j, cfg) for j, pos in hover.items()]
    offsets = {4: np.array([2.0, 1.0, 0.0]), 5: np.array([-1.0, 1.5, -0.5])}
    problem.solve(x0, goal, neighbours, None, offsets, t_now_s=0.0)
    snap = problem.snapshot()
    n_u, K = 3 * cfg.horizon_steps, cfg.horizon_steps
    P = snap.P.toarray()
    P = np.triu(P) + np.triu(P, 1).T  # OSQP holds the upper triangle
    targets = [hover[j] - offsets[j] for j in hover]  # p_j - d_ij

    def J(U: np.ndarray) -> float:
        u = U.reshape(K, 3)
        p = rollout(model, cfg.step_s, x0, u)[1:, :3]
        cost = cfg.weight_goal * np.sum((p[K - cfg.goal_steps :] - goal) ** 2)
        cost += cfg.weight_formation * sum(np.sum((p - t) ** 2) for t in targets)
        du = np.diff(np.vstack([np.zeros(3), u]), axis=0)  # u[-1] = 0 without a previous plan
        return float(cost + cfg.weight_smoothness * np.sum(du**2))

    def f(U: np.ndarray) -> float:
        return float(0.5 * U @ P[:n_u, :n_u] @ U + snap.q[:n_u] @ U)

    rng = np.random.default_rng(3)
    for _ in range(5):
        U = rng.normal(0.0, 2.0, n_u)
        np.testing.assert_allclose(f(U) - f(np.zeros(n_u)), J(U) - J(np.zeros(n_u)), rtol=1e-9, atol=1e-6)
    assert snap.P[:n_u, :n_u].nnz == 3 * K * (K + 1) // 2  # three dense axis blocks, no cross-axis entries


def test_sparsity_pattern_is_fixed_across_rounds() -> None:
    for mode in ("on_demand", "bvc"):
        cfg = DmpcConfig(collision_mode=mode, max_neighbours=3)
        problem = DmpcProblem(cfg)
        x0 = _x0(cfg, vel=(0.0, 0.0, 0.0))
        problem.solve(x0, [4.0, 0, 1.5], [], None, t_now_s=0.0)
        a0 = problem.snapshot().A
        result = problem.solve(x0, [4.0, 0, 1.5], [_hover_neighbour([0.3, 0.0, 1.5])], None, t_now_s=0.0)
        assert result.n_collision_constraints >= 1
        a1 = problem.snapshot().A
        assert a0.nnz == a1.nnz
        np.testing.assert_array_equal(a0.indices, a1.indices)
        np.testing.assert_array_equal(a0.indptr, a1.indptr)


def test_a_round_reports_whether_it_refactorised() -> None:
    # on demand: no conflict twice leaves A as sent, no refactorisation; a new conflict plane changes A
    problem = DmpcProblem(DmpcConfig(collision_mode="on_demand", max_neighbours=3))
    x0 = _x0(problem.config, vel=(0.0, 0.0, 0.0))
    problem.solve(x0, [4.0, 0, 1.5], [], None, t_now_s=0.0)
    assert not problem.solve(x0, [4.0, 0, 1.5], [], None, t_now_s=0.0).refactorised
    assert problem.solve(x0, [4.0, 0, 1.5], [_hover_neighbour([0.3, 0.0, 1.5])], None, t_now_s=0.0).refactorised
    # BVC: a plane per neighbour and step, which moves with the previous plans
    bvc = DmpcProblem(DmpcConfig(collision_mode="bvc", max_neighbours=3))
    previous = DmpcPlan.hover(0.0, 0.2, 15, x0[:3])
    bvc.solve(x0, [4.0, 0, 1.5], [_hover_neighbour([2.0, 0.0, 1.5])], previous, t_now_s=0.0)
    assert bvc.solve(x0, [4.0, 0, 1.5], [_hover_neighbour([1.5, 0.5, 1.5])], previous, t_now_s=0.0).refactorised


def test_infeasible_problem_raises_with_the_problem_attached() -> None:
    cfg = DmpcConfig()
    problem = DmpcProblem(cfg)
    x0 = _x0(cfg, pos=(0.0, 0.0, -5.0), vel=(0.0, 0.0, 0.0))  # far below the box, cannot climb in time
    with pytest.raises(DmpcSolveError) as info:
        problem.solve(x0, [0.0, 0.0, 1.0], [], None, t_now_s=0.0)
    assert "infeasible" in info.value.status
    assert isinstance(info.value.snapshot, QpSnapshot) and info.value.snapshot.A.shape[1] == 45 + cfg.max_neighbours
    # The caller falls back and the problem keeps working.
    ok = problem.solve(_x0(cfg), [1.0, 0.0, 1.5], [], None, t_now_s=0.0)
    assert ok.status == "solved"


def test_bad_inputs_are_rejected() -> None:
    cfg = DmpcConfig()
    problem = DmpcProblem(cfg)
    with pytest.raises(ValueError, match="x0"):
        problem.solve(np.zeros(9), [0, 0, 1], [], None, t_now_s=0.0)
    with pytest.raises(ValueError, match="max_obstacle_planes=0"):
        problem.solve(_x0(cfg), [0, 0, 1], [], None, t_now_s=0.0, obstacles=[(np.array([1.0, 0, 0]), 0.0)])
    limited = DmpcProblem(DmpcConfig(max_obstacle_planes=1))
    plane = (np.array([1.0, 0, 0]), 0.0)
    with pytest.raises(ValueError, match="max_obstacle_planes=1"):
        limited.solve(_x0(cfg), [0, 0, 1], [], None, t_now_s=0.0, obstacles=[plane, plane])


INVALID = [
    ("horizon_steps", 1),
    ("step_s", 0.0),
    ("step_s", float("nan")),
    ("model", "quadruple"),
    ("goal_steps", 0),
    ("goal_steps", 16),
    ("horizon_steps", 2),  # fewer steps than goal_steps = 3
    ("weight_goal", -1.0),
    ("weight_smoothness", -0.1),
    ("weight_slack_quadratic", 0.0),
    ("pos_min_world", (0.0, 0.0)),
    ("pos_max_world", (-30.0, 0.0, 1.0)),
    ("limits", 2.0),
    ("r_min_m", 0.0),
    ("downwash", 0.5),
    ("collision_mode", "voronoi"),
    ("neighbourhood_factor", 0.5),
    ("on_demand_time", "last"),
    ("conflict_substeps", 0),
    ("max_neighbours", 0),
    ("max_obstacle_planes", -1),
    ("terminal_halt", "yes"),
    ("vertical_obstacle_planes", 1),
    ("obstacle_culling", "no"),
    ("osqp_scaling", -1),
    ("osqp_max_iter", 0),
]


@pytest.mark.parametrize(("field", "value"), INVALID)
def test_invalid_parameters_are_rejected_with_a_one_line_message(field: str, value: object) -> None:
    with pytest.raises(ValueError) as info:
        if field in {f.name for f in dataclasses.fields(DmpcConfig)}:
            DmpcConfig(**{field: value})
        else:  # a class constant: a subclass overrides it
            type("Overridden", (DmpcConfig,), {field: value})()
    message = str(info.value)
    assert "\n" not in message and field in message and ":" in message


def test_defaults_follow_the_paper() -> None:
    cfg = DmpcConfig()
    assert (cfg.horizon_steps, cfg.step_s, cfg.limits.a_max_mps2, cfg.neighbourhood_factor) == (15, 0.2, 4.0, 3.0)
    assert dataclasses.is_dataclass(cfg) and cfg.state_dim == 6 and cfg.horizon_s == pytest.approx(3.0)
    with pytest.raises(dataclasses.FrozenInstanceError):
        cfg.r_min_m = 1.0  # type: ignore[misc]


def test_more_neighbours_than_slots_keeps_the_nearest() -> None:
    for mode in ("on_demand", "bvc"):
        cfg = DmpcConfig(collision_mode=mode, max_neighbours=1)
        problem = DmpcProblem(cfg)
        x0 = _x0(cfg, vel=(0.0, 0.0, 0.0))
        near, far = _hover_neighbour([0.3, 0.0, 1.5], 1), _hover_neighbour([-0.35, 0.0, 1.5], 2)
        previous = DmpcPlan.hover(0.0, cfg.step_s, cfg.horizon_steps, x0[:3])
        result = problem.solve(x0, [0.0, 0.0, 1.5], [far, near], previous, t_now_s=0.0)
        assert result.n_collision_constraints == (1 if mode == "on_demand" else cfg.horizon_steps)
        # The kept plane is the one against the nearer neighbour: the drone backs away from it (towards -x).
        assert result.pos_world[0, 0] < -0.04  # BVC: at most -0.05, the plane below (met to OSQP's tolerance)
        if mode == "bvc":  # midway plane between 0 and 0.3 m, buffered: x <= 0.3 - (0.4 + 0.3) / 2 = -0.05
            assert np.all(result.pos_world[:, 0] <= -0.05 + 1e-3)


def _obstacle_planes(cfg: DmpcConfig) -> list[tuple[np.ndarray, np.ndarray]]:
    """A near wall the plan must respect (y >= -0.25) and two far walls no feasible plan reaches early."""
    K = cfg.horizon_steps
    near = (np.tile([0.0, 1.0, 0.0], (K, 1)), np.full(K, -0.25))  # y >= -0.25: active from the first steps
    far_x = (np.array([-1.0, 0.0, 0.0]), -6.0)  # x <= 6: reachable only late in the horizon
    far_diag = (np.tile(np.array([0.6, -0.8, 0.0]), (K, 1)), np.full(K, -5.0))  # 0.6 x - 0.8 y >= -5
    return [near, far_x, far_diag]


def test_culled_obstacle_rows_change_nothing_and_hold_anyway() -> None:
    # Culling leaves out rows the velocity/input limits imply; the QP (and so its solution) is the same.
    results = {}
    for culling in (True, False):
        kind = TightDmpcConfig if culling else type("Unculled", (TightDmpcConfig,), {"obstacle_culling": False})  # a class constant
        cfg = kind(max_obstacle_planes=3, obstacle_avoidance="every_step")
        problem = DmpcProblem(cfg)
        x0 = _x0(cfg, vel=(1.5, -1.0, 0.0))  # heading for the near wall
        planes = _obstacle_planes(cfg)
        results[culling] = problem.solve(x0, [8.0, -2.0, 1.5], [], None, t_now_s=0.0, obstacles=planes)
        assert_kkt(problem.snapshot())
    K = DmpcConfig().horizon_steps
    kept, full = results[True], results[False]
    assert full.n_obstacle_rows == 3 * K
    assert 0 < kept.n_obstacle_rows < full.n_obstacle_rows  # something was culled, not everything
    np.testing.assert_allclose(kept.inputs, full.inputs, atol=1e-6)
    # Every plane, culled or not, holds at every step of the culled problem's solution.
    for normal, offset in planes:
        lhs = np.einsum("kd,kd->k", np.broadcast_to(normal, (K, 3)), kept.pos_world)
        assert np.all(lhs >= np.broadcast_to(offset, (K,)) - 1e-6)


def test_culling_keeps_a_plane_that_a_fast_plan_can_reach() -> None:
    # A plane 1 m ahead at 2 m/s is reachable from step 2 on, so it must stay and be met.
    cfg = TightDmpcConfig(max_obstacle_planes=1, obstacle_avoidance="every_step")
    problem = DmpcProblem(cfg)
    x0 = _x0(cfg, vel=(2.0, 0.0, 0.0))
    result = problem.solve(x0, [10.0, 0.0, 1.5], [], None, t_now_s=0.0, obstacles=[(np.array([-1.0, 0, 0]), -1.0)])
    assert result.n_obstacle_rows >= cfg.horizon_steps - 2
    assert np.all(result.pos_world[:, 0] <= 1.0 + 1e-6)


def test_unused_on_demand_slots_have_zero_slack_and_warm_start_does_not_change_the_answer() -> None:
    cfg = TightDmpcConfig(max_neighbours=3)
    x0 = _x0(cfg)
    neighbours = [_hover_neighbour([2.0, 0.05, 1.5], 1), _hover_neighbour([1.0, 3.0, 1.5], 2)]
    warm = DmpcProblem(cfg)
    first = warm.solve(x0, [4.0, 0.0, 1.5], neighbours, None, t_now_s=0.0)
    assert first.n_collision_constraints == 1
    assert np.all(warm.snapshot().x[45 + 1 :] == 0.0)  # unused slacks pinned at 0
    # Second round from the first plan's next state: warm-started (shifted x and y) vs a fresh problem.
    x1 = np.r_[first.pos_world[0], first.vel_world[0]]
    again = warm.solve(x1, [4.0, 0.0, 1.5], neighbours, first.plan, t_now_s=0.2)
    cold = DmpcProblem(cfg).solve(x1, [4.0, 0.0, 1.5], neighbours, first.plan, t_now_s=0.2)
    np.testing.assert_allclose(again.inputs, cold.inputs, atol=1e-4)  # [m/s^2]; both solved to 1e-8
    assert_kkt(warm.snapshot())


def test_vertical_obstacle_pattern_gives_the_same_plan_and_rejects_tilted_planes() -> None:
    plans = {}
    for vertical in (False, True):
        cfg = TightDmpcConfig(max_obstacle_planes=3, vertical_obstacle_planes=vertical)
        problem = DmpcProblem(cfg)
        x0 = _x0(cfg, vel=(1.5, -1.0, 0.0))
        plans[vertical] = problem.solve(x0, [8.0, -2.0, 1.5], [], None, t_now_s=0.0, obstacles=_obstacle_planes(cfg))
        assert_kkt(problem.snapshot())
    np.testing.assert_allclose(plans[True].inputs, plans[False].inputs, atol=1e-6)
    tilted = DmpcProblem(DmpcConfig(max_obstacle_planes=1, vertical_obstacle_planes=True))
    with pytest.raises(ValueError, match="vertical_obstacle_planes"):
        tilted.solve(_x0(DmpcConfig()), [1.0, 0, 1.5], [], None, t_now_s=0.0, obstacles=[(np.array([0.0, 0.6, 0.8]), 0.0)])
