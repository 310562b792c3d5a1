"""The world's compiled per-tick arithmetic equals its numpy form (motors, loads, rotations)."""

from __future__ import annotations

import numpy as np

from sim.rotations import rotation_from_quat_xyzw
from sim.vehicle.motors import MotorBank
from sim.vehicle.params import QuadrotorParams
from sim.vehicle.rigid_body_kernels import motor_wrench_to_body_loads, rotations_and_body_rates


def test_motor_loads_match_the_numpy_motor_bank_with_saturation_and_failed_motors():
    rng = np.random.default_rng(2)
    n, dt = 200, 1 / 240
    p = QuadrotorParams()
    numpy_bank, kernel_bank = MotorBank(p, n), MotorBank(p, n)
    numpy_bank.enabled[:10] = kernel_bank.enabled[:10] = False
    q = rng.normal(size=(n, 4))
    R = rotation_from_quat_xyzw(q)
    vel = rng.normal(size=(n, 3))
    r = p.rotor_pos_body
    alpha = 1.0 - np.exp(-dt / p.motor_time_constant_s)
    saturated = 0
    for _ in range(5):
        wrench = np.column_stack([rng.uniform(0, 4 * p.max_thrust_per_motor_n * 1.2, n), rng.normal(size=(n, 3)) * 0.05])
        cmd = numpy_bank.thrusts_for_wrench(wrench)
        saturated += int(np.sum((cmd == 0) | (cmd == p.max_thrust_per_motor_n)))
        thrusts, drag = numpy_bank.step(cmd, dt)
        tau_body = np.stack([thrusts @ r[:, 1], -(thrusts @ r[:, 0]), drag.sum(axis=1)], axis=1)
        force = thrusts.sum(axis=1)[:, None] * R[:, :, 2] - p.linear_drag_coeff * vel
        torque = np.einsum("nij,nj->ni", R, tau_body)
        f_k, t_k = motor_wrench_to_body_loads(
            wrench, kernel_bank.A_inv, float(kernel_bank.f_max), kernel_bank.speed_radps, kernel_bank.enabled, p.thrust_coeff, p.torque_coeff,
            np.asarray(p.motor_dirs, float), alpha, np.ascontiguousarray(r), R, vel, p.linear_drag_coeff,
        )  # fmt: skip
        np.testing.assert_allclose(kernel_bank.speed_radps, numpy_bank.speed_radps, rtol=1e-8)  # summation order only
        np.testing.assert_allclose(f_k, force, rtol=1e-8, atol=1e-12)
        np.testing.assert_allclose(t_k, torque, rtol=1e-8, atol=1e-9)  # torques cancel to ~1e-2 N m: absolute 1e-9
    assert saturated > 0  # the allocation's saturation branch ran


def test_rotations_and_body_rates_match_numpy():
    rng = np.random.default_rng(3)
    q = rng.normal(size=(50, 4)) * 3  # not unit: normalised first
    w = rng.normal(size=(50, 3))
    R, wb = rotations_and_body_rates(q, w)
    R0 = rotation_from_quat_xyzw(q)
    np.testing.assert_allclose(R, R0, atol=1e-14)
    np.testing.assert_allclose(wb, np.einsum("nji,nj->ni", R0, w), atol=1e-14)
