"""DMPC prediction model and plan type: stacked matrices vs step-by-step simulation, exact interpolation."""

from __future__ import annotations

import numpy as np
import pytest

from perception.types import NeighborPrediction
from planners.dmpc.model import discrete_model, fine_position_matrices, prediction_matrices, rollout
from planners.dmpc.types import DmpcPlan

H_S, K = 0.2, 15


@pytest.mark.parametrize("model", ["double", "triple"])
def test_prediction_matrices_match_step_by_step_simulation(model: str, rng: np.random.Generator) -> None:
    pm = prediction_matrices(model, H_S, K)
    n = pm.A.shape[0]
    for _ in range(5):
        x0 = rng.normal(size=n)
        inputs = rng.normal(size=(K, 3))
        states = rollout(model, H_S, x0, inputs)
        U = inputs.ravel()
        np.testing.assert_allclose(pm.A0_pos @ x0 + pm.Lambda_pos @ U, states[1:, :3].ravel(), atol=1e-12)
        np.testing.assert_allclose(pm.A0_vel @ x0 + pm.Lambda_vel @ U, states[1:, 3:6].ravel(), atol=1e-12)
        acc = inputs.ravel() if model == "double" else states[1:, 6:9].ravel()
        np.testing.assert_allclose(pm.A0_acc @ x0 + pm.Lambda_acc @ U, acc, atol=1e-12)


@pytest.mark.parametrize("model", ["double", "triple"])
def test_discrete_model_is_the_exact_zero_order_hold(model: str) -> None:
    # Two half steps equal one full step with the same held input.
    A, B = discrete_model(model, H_S)
    A2, B2 = discrete_model(model, H_S / 2)
    np.testing.assert_allclose(A2 @ A2, A, atol=1e-15)
    np.testing.assert_allclose(A2 @ B2 + B2, B, atol=1e-15)


@pytest.mark.parametrize("model", ["double", "triple"])
def test_fine_position_matrices_match_a_finer_simulation(model: str, rng: np.random.Generator) -> None:
    S = 4
    A0_f, L_f = fine_position_matrices(model, H_S, K, S)
    pm = prediction_matrices(model, H_S, K)
    A0_1, L_1 = fine_position_matrices(model, H_S, K, 1)
    np.testing.assert_allclose(A0_1, pm.A0_pos, atol=1e-15)
    np.testing.assert_allclose(L_1, pm.Lambda_pos, atol=1e-15)
    x0 = rng.normal(size=pm.A.shape[0])
    inputs = rng.normal(size=(K, 3))
    fine_states = rollout(model, H_S / S, x0, np.repeat(inputs, S, axis=0))  # input held over each step
    np.testing.assert_allclose(A0_f @ x0 + L_f @ inputs.ravel(), fine_states[1:, :3].ravel(), atol=1e-12)


def test_unknown_model_is_rejected() -> None:
    with pytest.raises(ValueError, match="model='quad'"):
        discrete_model("quad", H_S)


def _double_integrator_plan(rng: np.random.Generator) -> tuple[DmpcPlan, np.ndarray, np.ndarray]:
    x0 = np.r_[rng.normal(size=3), rng.normal(size=3)]
    inputs = rng.normal(size=(K, 3))
    states = rollout("double", H_S, x0, inputs)
    acc = np.vstack([inputs, np.zeros((1, 3))])
    return DmpcPlan(1.0, H_S, states[:, :3], states[:, 3:6], acc), x0, inputs


def test_plan_interpolation_is_exact_between_samples(rng: np.random.Generator) -> None:
    plan, x0, inputs = _double_integrator_plan(rng)
    S = 8
    fine = rollout("double", H_S / S, x0, np.repeat(inputs, S, axis=0))
    t = plan.t0_s + (H_S / S) * np.arange(K * S)
    np.testing.assert_allclose(plan.position(t), fine[:-1, :3], atol=1e-12)
    np.testing.assert_allclose(plan.velocity(t), fine[:-1, 3:6], atol=1e-12)
    np.testing.assert_allclose(plan.acceleration(t), np.repeat(inputs, S, axis=0), atol=1e-10)


def test_shifted_plan_keeps_the_trajectory_and_extends_the_tail_at_constant_velocity(rng: np.random.Generator) -> None:
    plan, _, _ = _double_integrator_plan(rng)
    shifted = plan.shifted(plan.t0_s + 2 * H_S)
    assert shifted.horizon_steps == plan.horizon_steps
    np.testing.assert_allclose(shifted.pos_world[: K - 1], plan.pos_world[2:], atol=1e-12)
    np.testing.assert_allclose(shifted.acc_world[: K - 2], plan.acc_world[2:K], atol=1e-10)
    # tail: p_K + v_K (t - t_K), zero acceleration
    np.testing.assert_allclose(shifted.pos_world[-1], plan.pos_world[-1] + 2 * H_S * plan.vel_world[-1], atol=1e-12)
    np.testing.assert_allclose(shifted.vel_world[-2:], np.tile(plan.vel_world[-1], (2, 1)), atol=1e-12)
    np.testing.assert_allclose(shifted.acc_world[-2:], 0.0)


def test_plan_as_neighbor_prediction_gives_the_same_positions(rng: np.random.Generator) -> None:
    plan, _, _ = _double_integrator_plan(rng)
    pred = plan.as_neighbor_prediction(neighbor_id=3, stamp_s=0.9)
    assert isinstance(pred, NeighborPrediction)
    assert pred.source == "radio" and pred.neighbor_id == 3 and pred.age_s(1.2) == pytest.approx(0.3)
    np.testing.assert_allclose(pred.cov_world, 0.0)
    t = np.linspace(plan.t0_s - 0.3, plan.t_end_s + 0.5, 97)
    np.testing.assert_allclose(pred.position(t), plan.position(t), atol=1e-12)
    np.testing.assert_allclose(pred.uncertainty_radius(t), 0.0)


def test_hover_plan_and_bad_shapes() -> None:
    plan = DmpcPlan.hover(0.0, H_S, K, [1.0, 2.0, 3.0])
    np.testing.assert_allclose(plan.position([0.0, 1.0, 10.0]), np.tile([1.0, 2.0, 3.0], (3, 1)))
    with pytest.raises(ValueError, match="DmpcPlan"):
        DmpcPlan(0.0, H_S, np.zeros((4, 3)), np.zeros((3, 3)), np.zeros((4, 3)))
    with pytest.raises(ValueError, match="h_s"):
        DmpcPlan(0.0, 0.0, np.zeros((4, 3)), np.zeros((4, 3)), np.zeros((4, 3)))
