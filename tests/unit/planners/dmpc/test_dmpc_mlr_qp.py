"""MLR-DMPC QP (DMPC-Swarm Eq. 13-15): constraints, KKT conditions, plane geometry, Theorem 1's warm start."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from planners.dmpc.mlr.config import MlrConfig
from planners.dmpc.mlr.qp import MlrProblem, time_varying_bvc
from planners.dmpc.mlr.trajectory import ReferenceTrajectory, TrajectoryId
from qp_kkt import assert_kkt  # tests/unit/planners/dmpc/qp_kkt.py

TIGHT = dict(osqp_eps_abs=1e-6, osqp_eps_rel=1e-6, osqp_polish=True, osqp_max_iter=200000)
THETA_INV = np.array([1.0, 1.0, 1.0 / 1.5])


def _hover(cfg: MlrConfig, pos, meta=TrajectoryId(-1, -1), t0: float = 0.0) -> ReferenceTrajectory:
    return ReferenceTrajectory.hover(meta, t0, np.asarray(pos, float), cfg.n_inputs, cfg.input_step_s)


def _scene(cfg: MlrConfig, rng: np.random.Generator, n_others: int = 6):
    """Own hover at the origin, others on a ring 1-2 m away, some with two candidates."""
    own = _hover(cfg, [0.0, 0.0, 1.2])
    pos, mid = [], []
    for j in range(n_others):
        ang = 2 * np.pi * j / n_others + rng.uniform(-0.2, 0.2)
        r = rng.uniform(0.9, 2.0)
        p = np.array([r * np.cos(ang), r * np.sin(ang), 1.2 + rng.uniform(-0.3, 0.3)])
        for _ in range(1 + (j % 2)):
            p = p + rng.uniform(-0.1, 0.1, 3)
            pos.append(_hover(cfg, p).positions_at(MlrProblem(cfg).check_times(cfg.round_s)))
            mid.append(bool(j % 3 == 0))
    return own, np.array(pos), np.array(mid)


def test_solution_meets_every_constraint_and_the_kkt_conditions(rng: np.random.Generator) -> None:
    cfg = MlrConfig(n_uavs=8, n_cus=2, bvc_margin_m=0.0, soft_rotation=False, **TIGHT)  # Eq. 13 alone
    problem = MlrProblem(cfg)
    own, others, mid = _scene(cfg, rng)
    t0 = cfg.round_s
    res = problem.solve(own, t0, np.array([2.5, 0.3, 1.5]), others, mid, TrajectoryId(0, 1))
    assert res.status == "solved"
    assert_kkt(problem.snapshot())
    traj = res.trajectory
    assert traj.meta == TrajectoryId(0, 1) and traj.t_start_s == t0
    np.testing.assert_allclose(traj.x0, own.states_at(np.array([t0]))[0])  # 13b: starts on the current trajectory
    assert np.all(np.abs(traj.inputs) <= cfg.limits.j_max_mps3 + 1e-6)  # 13c
    knots = traj.knots[1:]
    assert np.all(knots[:, :3] >= np.array(cfg.pos_min_world) - 1e-6)  # 13d
    assert np.all(knots[:, :3] <= np.array(cfg.pos_max_world) + 1e-6)
    assert np.all(np.abs(knots[:, 3:6]) <= cfg.limits.v_max_mps + 1e-6) and np.all(np.abs(knots[:, 6:9]) <= cfg.limits.a_max_mps2 + 1e-6)
    np.testing.assert_allclose(traj.knots[-1, 3:9], 0.0, atol=1e-10)  # 13e, exact
    after = traj.states_at(traj.t_end_s + np.array([0.5, 5.0]))
    np.testing.assert_allclose(after[:, :3], traj.knots[-1, :3][None].repeat(2, 0), atol=1e-9)  # halted
    # 13f: every BVC row, on the rolled-out trajectory at every check time (to the solver tolerance
    # plus the minimum-norm terminal fix, both ~1e-5 here).
    times = problem.check_times(t0)
    rows = time_varying_bvc(own.positions_at(times), others, mid, cfg.d_hat_min_m, cfg.downwash)
    p_new = traj.positions_at(times)
    assert np.all(np.einsum("rhd,hd->rh", rows.normal, p_new) >= rows.offset - 5e-5)
    assert problem.snapshot().A.shape[0] == problem.bvc_row_start + problem.max_bvc_rows  # sized for the maximum


def test_a_neighbour_dead_ahead_yields_a_separating_plane() -> None:
    cfg = MlrConfig(n_uavs=4, n_cus=1, bvc_margin_m=0.0, **TIGHT)
    problem = MlrProblem(cfg)
    own = _hover(cfg, [0.0, 0.0, 1.2])
    times = problem.check_times(cfg.round_s)
    blocker = _hover(cfg, [1.0, 0.0, 1.2]).positions_at(times)
    goal = np.array([2.5, 0.0, 1.2])
    res = problem.solve(own, cfg.round_s, goal, blocker[None], np.array([False]), TrajectoryId(0, 0))
    p = res.trajectory.positions_at(times)
    # Relaxed plane (j keeps its trajectory): x <= 1 - d̂, and the UAV presses against it.
    assert np.all(p[:, 0] <= 1.0 - cfg.d_hat_min_m + 5e-5)
    assert p[-1, 0] == pytest.approx(1.0 - cfg.d_hat_min_m, abs=1e-3)
    rows = time_varying_bvc(own.positions_at(times), blocker[None], np.array([False]), cfg.d_hat_min_m, cfg.downwash)
    np.testing.assert_allclose(rows.normal[0], np.tile([-1.0, 0.0, 0.0], (cfg.n_checks, 1)), atol=1e-12)
    # Without the neighbour it flies through x = 1 - d̂.
    free = problem.solve(own, cfg.round_s, np.array([2.5, 0.0, 1.2]), np.zeros((0, cfg.n_checks, 3)),
                         np.zeros(0, bool), TrajectoryId(0, 0))
    assert free.trajectory.positions_at(times)[-1, 0] > 1.0 - cfg.d_hat_min_m + 0.5


def test_relaxed_plane_is_at_d_hat_from_j_and_midway_plane_at_half_of_d_hat_plus_norm(rng) -> None:
    d_hat, c = 0.45, 1.5
    own = rng.uniform(-1, 1, (5, 3))
    other = own + rng.normal(size=(5, 3))
    other = own + (other - own) * (1.2 / np.linalg.norm((other - own) * THETA_INV, axis=1))[:, None]  # ||n|| = 1.2
    for midway, expected in ((False, d_hat), (True, 0.5 * (d_hat + 1.2))):
        rows = time_varying_bvc(own, other[None], np.array([midway]), d_hat, c)
        np.testing.assert_allclose(rows.plane_distance_m, expected)
        # The plane a^T p = b lies at scaled distance `expected` from p_j along n0 (Eq. 15).
        n0 = (other - own) * THETA_INV / 1.2
        on_plane = other - (n0 * expected) / THETA_INV  # p with n0^T Theta^-1 (p_j - p) = expected
        np.testing.assert_allclose(np.einsum("hd,hd->h", rows.normal[0], on_plane), rows.offset[0], atol=1e-12)
        assert np.all(np.einsum("hd,hd->h", rows.normal[0], own) >= rows.offset[0] - 1e-12)  # own side


def test_planes_are_clipped_at_the_current_distance_so_the_current_trajectory_stays_feasible() -> None:
    own = np.zeros((1, 3))
    other = np.array([[[0.40, 0.0, 0.0]]])  # closer than d̂ = 0.45 (by solver tolerance, say)
    for midway in (False, True):
        rows = time_varying_bvc(own, other, np.array([midway]), 0.45, 1.5, margin_m=0.005)
        assert rows.plane_distance_m[0, 0] == pytest.approx(0.40)
        assert rows.normal[0, 0] @ own[0] >= rows.offset[0, 0] - 1e-12


def test_the_shifted_trajectory_is_a_feasible_point_of_the_next_round(rng) -> None:
    """Theorem 1: the previous solution, shifted by T, meets every constraint of the next QP."""
    cfg = MlrConfig(n_uavs=8, n_cus=2, **TIGHT)
    problem = MlrProblem(cfg)
    own, others, mid = _scene(cfg, rng)
    first = problem.solve(own, cfg.round_s, np.array([2.0, 1.0, 1.5]), others, mid, TrajectoryId(0, 0)).trajectory
    t1 = 2 * cfg.round_s
    times = problem.check_times(t1)
    hover_others = np.array([o[:1].repeat(cfg.n_checks, 0) for o in others])  # hovering others
    problem.solve(first, t1, np.array([2.0, 1.0, 1.5]), hover_others, mid, TrajectoryId(1, 0))
    snap = problem.snapshot()
    x_ws = problem._warm_start(first, t1)
    Ax = snap.A @ x_ws
    assert np.all(Ax >= snap.l - 1e-6) and np.all(Ax <= snap.u + 1e-6)
    assert times.shape == (cfg.n_checks,)


def test_more_candidates_than_reserved_rows_are_refused() -> None:
    cfg = MlrConfig(n_uavs=3, n_cus=1)
    problem = MlrProblem(cfg)
    own = _hover(cfg, [0.0, 0.0, 1.0])
    too_many = np.zeros((2 * 2 + 1, cfg.n_checks, 3)) + 3.0
    with pytest.raises(ValueError, match="others_pos_world"):
        problem.solve(own, cfg.round_s, np.zeros(3), too_many, np.zeros(5, bool), TrajectoryId(0, 0))


def test_sub_round_check_times_use_interior_rows(rng) -> None:
    cfg = MlrConfig(n_uavs=6, n_cus=2, collision_checks_per_round=2, bvc_margin_m=0.0, **TIGHT)
    problem = MlrProblem(cfg)
    own, others, mid = _scene(cfg, rng, n_others=3)
    res = problem.solve(own, cfg.round_s, np.array([2.0, 0.0, 1.2]), others, mid, TrajectoryId(0, 0))
    assert_kkt(problem.snapshot())
    times = problem.check_times(cfg.round_s)
    rows = time_varying_bvc(own.positions_at(times), others, mid, cfg.d_hat_min_m, cfg.downwash)
    assert np.all(np.einsum("rhd,hd->rh", rows.normal, res.trajectory.positions_at(times)) >= rows.offset - 5e-5)
    assert dataclasses.replace(cfg).n_checks == 2 * cfg.horizon_rounds


def test_soft_rotation_meets_eq_15_and_the_kkt_conditions_and_keeps_more_room_to_the_right(rng) -> None:
    """Appendix B4: the slack only tightens Eq. 15, and a UAV to the right earns the larger reward."""
    cfg = MlrConfig(n_uavs=8, n_cus=2, bvc_margin_m=0.0, soft_rotation=True, **TIGHT)
    problem = MlrProblem(cfg)
    own, others, mid = _scene(cfg, rng)
    t0 = cfg.round_s
    res = problem.solve(own, t0, np.array([2.5, 0.3, 1.5]), others, mid, TrajectoryId(0, 1))
    assert res.status == "solved"
    snap = problem.snapshot()
    assert_kkt(snap)
    times = problem.check_times(t0)
    rows = time_varying_bvc(own.positions_at(times), others, mid, cfg.d_hat_min_m, cfg.downwash)
    assert np.all(np.einsum("rhd,hd->rh", rows.normal, res.trajectory.positions_at(times)) >= rows.offset - 5e-5)
    eps = snap.x[-problem._n_eps:]
    assert np.all(eps >= -1e-6) and np.all(eps <= cfg.soft_max_m + 1e-6)
    assert np.all(eps[len(others):] == pytest.approx(0.0, abs=1e-9))  # unused slots stay 0
    # Two UAVs ahead, one on the left (+y) and one on the right, 1.17 m away; the goal 0.3 m ahead
    # leaves 0.46 m of slack to each, more than soft_max_m: only the right one is rewarded.
    problem = MlrProblem(dataclasses.replace(cfg, soft_weight=0.0, soft_weight_right=5.0))
    two = np.stack([_hover(cfg, [1.0, 0.6, 1.2]).positions_at(times), _hover(cfg, [1.0, -0.6, 1.2]).positions_at(times)])
    problem.solve(own, t0, np.array([0.3, 0.0, 1.2]), two, np.array([False, False]), TrajectoryId(0, 1))
    eps = problem.snapshot().x[-problem._n_eps:]
    assert eps[1] == pytest.approx(cfg.soft_max_m, abs=1e-4) and eps[0] == pytest.approx(0.0, abs=1e-4)
