"""The SE(3) control law of :mod:`sim.vehicle.controller`, compiled (numba): one drone at a time, no temporaries.

The equations are the controller module's (Lee, Leok, McClamroch 2010, with
the clamped conditional integral and the tilt limit); :meth:`SE3Controller.step`
calls :func:`se3_wrenches` at every physics tick, where the numpy form of the
same law (:meth:`SE3Controller.step_numpy`, kept as the test's oracle) spends
most of its time in small-array overhead (benchmarks/bench_sim.py).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

__all__ = ["se3_wrenches"]


@njit(cache=True)
def se3_wrenches(
    pos, vel, R, omega, ref_pos, ref_vel, ref_acc, ref_yaw, ref_yaw_rate, integral, dt,
    mass, gravity, k_x, k_v, k_i, k_R, k_W, J, integral_limit, integral_zone, tan_max_tilt,
):  # fmt: skip
    """Desired wrenches (N, 4) ``[f, M_x, M_y, M_z]`` [N, N m]; updates ``integral`` (N, 3) [m s] in place.

    Args:
        pos, vel: (N, 3) state [m], [m/s]; R: (N, 3, 3) body->world; omega: (N, 3) body rates [rad/s].
        ref_pos, ref_vel, ref_acc: (N, 3) reference; ref_yaw, ref_yaw_rate: (N,) [rad], [rad/s].
        integral: (N, 3) the integral state; dt: the period [s].
        mass [kg], gravity [m/s^2], k_x, k_v, k_i: position gains; k_R, k_W, J: (3,) attitude gains and inertia.
        integral_limit [m s], integral_zone [m], tan_max_tilt: tan of the tilt limit.
    """
    n = pos.shape[0]
    out = np.empty((n, 4))
    F = np.empty(3)
    b1 = np.empty(3)
    b2 = np.empty(3)
    Rd = np.empty((3, 3))
    for i in range(n):
        for k in range(3):
            ex = pos[i, k] - ref_pos[i, k]
            ev = vel[i, k] - ref_vel[i, k]
            if abs(ex) < integral_zone:
                integral[i, k] += ex * dt
            integral[i, k] = min(max(integral[i, k], -integral_limit), integral_limit)
            F[k] = -k_x * ex - k_v * ev - k_i * integral[i, k] + mass * ref_acc[i, k]
        F[2] += mass * gravity
        F[2] = max(F[2], 0.1 * mass * gravity)
        horiz = math.sqrt(F[0] * F[0] + F[1] * F[1])
        max_h = F[2] * tan_max_tilt
        if horiz > max_h:
            s = max_h / max(horiz, 1e-12)
            F[0] *= s
            F[1] *= s
        thrust = F[0] * R[i, 0, 2] + F[1] * R[i, 1, 2] + F[2] * R[i, 2, 2]
        norm = math.sqrt(F[0] * F[0] + F[1] * F[1] + F[2] * F[2])
        b3x, b3y, b3z = F[0] / norm, F[1] / norm, F[2] / norm
        cx, cy = math.cos(ref_yaw[i]), math.sin(ref_yaw[i])
        # b2 = b3 x b1_c / |.|, b1_c = (cos yaw, sin yaw, 0)
        b2[0], b2[1], b2[2] = -b3z * cy, b3z * cx, b3x * cy - b3y * cx
        nb2 = math.sqrt(b2[0] * b2[0] + b2[1] * b2[1] + b2[2] * b2[2])
        b2[0] /= nb2
        b2[1] /= nb2
        b2[2] /= nb2
        # b1 = b2 x b3
        b1[0] = b2[1] * b3z - b2[2] * b3y
        b1[1] = b2[2] * b3x - b2[0] * b3z
        b1[2] = b2[0] * b3y - b2[1] * b3x
        for r in range(3):
            Rd[r, 0], Rd[r, 1] = b1[r], b2[r]
        Rd[0, 2], Rd[1, 2], Rd[2, 2] = b3x, b3y, b3z
        # E = R_d^T R; e_R = 1/2 vee(E - E^T)
        E = np.zeros((3, 3))
        for a in range(3):
            for b in range(3):
                acc = 0.0
                for k in range(3):
                    acc += Rd[k, a] * R[i, k, b]
                E[a, b] = acc
        eR0 = 0.5 * (E[2, 1] - E[1, 2])
        eR1 = 0.5 * (E[0, 2] - E[2, 0])
        eR2 = 0.5 * (E[1, 0] - E[0, 1])
        # e_W = Omega - R^T R_d Omega_d with Omega_d = (0, 0, yaw_rate): R^T R_d e3 * yaw_rate = E^T[:, 2] * yaw_rate
        w = ref_yaw_rate[i]
        eW0 = omega[i, 0] - E[2, 0] * w
        eW1 = omega[i, 1] - E[2, 1] * w
        eW2 = omega[i, 2] - E[2, 2] * w
        o0, o1, o2 = omega[i, 0], omega[i, 1], omega[i, 2]
        j0, j1, j2 = J[0] * o0, J[1] * o1, J[2] * o2
        out[i, 0] = max(thrust, 0.0)
        out[i, 1] = -k_R[0] * eR0 - k_W[0] * eW0 + (o1 * j2 - o2 * j1)
        out[i, 2] = -k_R[1] * eR1 - k_W[1] * eW1 + (o2 * j0 - o0 * j2)
        out[i, 3] = -k_R[2] * eR2 - k_W[2] * eW2 + (o0 * j1 - o1 * j0)
    return out
