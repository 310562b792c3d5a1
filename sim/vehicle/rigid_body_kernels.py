"""The world's per-tick arithmetic, compiled (numba): motors -> force and torque, and the state read-back.

:func:`motor_wrench_to_body_loads` fuses, per drone, what
:meth:`sim.vehicle.motors.MotorBank.thrusts_for_wrench` (allocation with yaw
torque yielding first, then clipping to [0, f_max]), :meth:`MotorBank.step`
(first-order motor lag, omega += (omega_cmd - omega)(1 - exp(-dt / tau_m)))
and :meth:`sim.world.World.step` (F = sum_i f_i R e3 - c_d v, tau = R (sum_i r_i x f_i e3
+ sum_i s_i k_m w_i^2 e3)) compute in numpy; those numpy forms stay the tests'
oracle. :func:`rotations_and_body_rates` is R(q) (normalised quaternion) and
Omega_body = R^T omega_world. Together they replace the small-array numpy of
every tick (benchmarks/bench_sim.py,
docs/results/env.md#the-compiled-physics-tick).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

__all__ = ["motor_wrench_to_body_loads", "rotations_and_body_rates"]


@njit(cache=True)
def motor_wrench_to_body_loads(wrench, A_inv, f_max, speed, enabled, thrust_coeff, torque_coeff, motor_dirs, lag_alpha, rotor_pos, R, vel, linear_drag):
    """World force (N, 3) [N] and torque (N, 3) [N m] of the motors tracking ``wrench`` (N, 4); ``speed`` (N, 4) updated in place.

    Args:
        wrench: (N, 4) desired [f, M_x, M_y, M_z]; A_inv: (4, 4) inverse allocation; f_max: per-motor thrust limit [N].
        speed: (N, 4) motor speeds [rad/s]; enabled: (N,) motors on.
        thrust_coeff, torque_coeff: k_f [N s^2], k_m [N m s^2]; motor_dirs: (4,) spin signs.
        lag_alpha: 1 - exp(-dt / tau_m) (1: no lag); rotor_pos: (4, 3) hubs in body [m].
        R: (N, 3, 3) body->world; vel: (N, 3) [m/s]; linear_drag: c_d [N s/m].
    """
    n = wrench.shape[0]
    force = np.empty((n, 3))
    torque = np.empty((n, 3))
    f = np.empty(4)
    f0 = np.empty(4)
    for i in range(n):
        bad = False
        for m in range(4):
            acc = 0.0
            acc0 = 0.0
            for k in range(4):
                acc += A_inv[m, k] * wrench[i, k]
                if k < 3:
                    acc0 += A_inv[m, k] * wrench[i, k]
            f[m], f0[m] = acc, acc0
            if acc < 0.0 or acc > f_max:
                bad = True
        if bad:  # the yaw torque yields first: the largest s in [0, 1] with 0 <= f0 + s dyaw <= f_max
            s = np.inf
            for m in range(4):
                d = f[m] - f0[m]
                if d > 0:
                    s = min(s, (f_max - f0[m]) / d)
                elif d < 0:
                    s = min(s, -f0[m] / d)
            s = min(max(s, 0.0), 1.0)
            for m in range(4):
                f[m] = f0[m] + s * (f[m] - f0[m])
        total = 0.0
        tx = 0.0
        ty = 0.0
        tz = 0.0
        for m in range(4):
            cmd = min(max(f[m], 0.0), f_max)
            w_cmd = math.sqrt(max(cmd, 0.0) / thrust_coeff) if enabled[i] else 0.0
            speed[i, m] += (w_cmd - speed[i, m]) * lag_alpha
            w2 = speed[i, m] * speed[i, m]
            thrust = thrust_coeff * w2
            total += thrust
            tx += thrust * rotor_pos[m, 1]
            ty -= thrust * rotor_pos[m, 0]
            tz += torque_coeff * w2 * motor_dirs[m]
        for r in range(3):
            force[i, r] = total * R[i, r, 2] - linear_drag * vel[i, r]
            torque[i, r] = R[i, r, 0] * tx + R[i, r, 1] * ty + R[i, r, 2] * tz
    return force, torque


@njit(cache=True)
def rotations_and_body_rates(quat, omega_world):
    """Rotations (N, 3, 3) from quaternions (N, 4) xyzw (normalised first) and body rates (N, 3) = R^T omega_world."""
    n = quat.shape[0]
    R = np.empty((n, 3, 3))
    omega_b = np.empty((n, 3))
    for i in range(n):
        norm = math.sqrt(quat[i, 0] ** 2 + quat[i, 1] ** 2 + quat[i, 2] ** 2 + quat[i, 3] ** 2)
        x, y, z, w = quat[i, 0] / norm, quat[i, 1] / norm, quat[i, 2] / norm, quat[i, 3] / norm
        R[i, 0, 0] = 1 - 2 * (y * y + z * z)
        R[i, 0, 1] = 2 * (x * y - z * w)
        R[i, 0, 2] = 2 * (x * z + y * w)
        R[i, 1, 0] = 2 * (x * y + z * w)
        R[i, 1, 1] = 1 - 2 * (x * x + z * z)
        R[i, 1, 2] = 2 * (y * z - x * w)
        R[i, 2, 0] = 2 * (x * z - y * w)
        R[i, 2, 1] = 2 * (y * z + x * w)
        R[i, 2, 2] = 1 - 2 * (x * x + y * y)
        for c in range(3):
            omega_b[i, c] = R[i, 0, c] * omega_world[i, 0] + R[i, 1, c] * omega_world[i, 1] + R[i, 2, c] * omega_world[i, 2]
    return R, omega_b
