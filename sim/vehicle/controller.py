"""Geometric SE(3) tracking controller (Lee, Leok, McClamroch, CDC 2010), batched.

For N drones with position x, velocity v, attitude R (body -> world) and body
rates Omega, tracking a flat-output reference (x_d, v_d, a_d, yaw_d, yaw_rate_d)::

    e_x = x - x_d,  e_v = v - v_d
    F_d = -k_x e_x - k_v e_v - k_i int(e_x) + m g e_3 + m a_d       (world)
    f   = F_d . R e_3                                                 (collective thrust)
    b3_d = F_d / |F_d|,  b1_c = [cos yaw_d, sin yaw_d, 0]
    b2_d = b3_d x b1_c / |.|,  R_d = [b2_d x b3_d, b2_d, b3_d]
    e_R = 1/2 vee(R_d^T R - R^T R_d),  e_W = Omega - R^T R_d Omega_d
    M   = -k_R e_R - k_W e_W + Omega x J Omega

with Omega_d = [0, 0, yaw_rate_d] (the feed-forward of body rates from the
reference's jerk is neglected: a stated simplification; the tracking test
bounds its effect). A small integral term (clamped, integrating only near the reference) removes the steady bias of
unmodelled body drag. The tilt of F_d is limited to ``max_tilt_rad``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from sim.rotations import cross_rows, rotation_from_thrust_axis_and_yaw, vee
from sim.vehicle.controller_kernel import se3_wrenches
from sim.vehicle.params import GRAVITY_MPS2, QuadrotorParams

__all__ = ["ControllerGains", "SE3Controller"]


@dataclass(frozen=True)
class ControllerGains:
    """Gains, given as natural frequencies so they scale with mass and inertia.

    Attributes:
        pos_natural_freq_radps: position loop omega_n [rad/s]; k_x = m omega_n^2.
        pos_damping: position loop damping ratio; k_v = 2 zeta m omega_n.
        pos_integral_gain: k_i / m [1/s^3].
        integral_limit_m_s: clamp on each component of int(e_x) [m s].
        integral_zone_m: a component of e_x integrates only while below this [m].
        att_natural_freq_radps: attitude loop omega_n [rad/s]; k_R = J omega_n^2.
        att_damping: attitude damping ratio; k_W = 2 zeta J omega_n.
        max_tilt_rad: limit on the angle between F_d and world z [rad].
    """

    pos_natural_freq_radps: float = 4.0
    pos_damping: float = 0.9
    pos_integral_gain: float = 2.0
    integral_limit_m_s: float = 0.1
    integral_zone_m: float = 0.2
    att_natural_freq_radps: float = 22.0
    att_damping: float = 0.8
    max_tilt_rad: float = 0.7


class SE3Controller:
    """Batched geometric controller; one verb, :meth:`step`."""

    def __init__(self, params: QuadrotorParams, n_drones: int, gains: ControllerGains | None = None) -> None:
        self.params = params
        self.gains = gains or ControllerGains()
        g = self.gains
        m = params.mass_kg
        J = np.asarray(params.inertia_kgm2)
        self.k_x = m * g.pos_natural_freq_radps**2
        self.k_v = 2 * g.pos_damping * m * g.pos_natural_freq_radps
        self.k_i = m * g.pos_integral_gain
        self.k_R = J * g.att_natural_freq_radps**2
        self.k_W = 2 * g.att_damping * J * g.att_natural_freq_radps
        self.J = J
        self.integral = np.zeros((n_drones, 3))

    def step(
        self,
        pos_world: np.ndarray,
        vel_world: np.ndarray,
        rotation_body_to_world: np.ndarray,
        ang_vel_body: np.ndarray,
        ref_pos_world: np.ndarray,
        ref_vel_world: np.ndarray,
        ref_acc_world: np.ndarray,
        ref_yaw: np.ndarray,
        ref_yaw_rate: np.ndarray,
        dt_s: float,
    ) -> np.ndarray:
        """Desired wrenches for N drones (the compiled law, :func:`sim.vehicle.controller_kernel.se3_wrenches`).

        Args:
            pos_world, vel_world: (N, 3) state [m], [m/s].
            rotation_body_to_world: (N, 3, 3).
            ang_vel_body: (N, 3) body rates [rad/s].
            ref_pos_world, ref_vel_world, ref_acc_world: (N, 3) reference.
            ref_yaw, ref_yaw_rate: (N,) [rad], [rad/s].
            dt_s: controller period [s] (for the integral).

        Returns:
            (N, 4) wrench ``[F, tau_x, tau_y, tau_z]`` in [N] and body [N m].
        """
        g = self.gains
        f64 = np.ascontiguousarray
        return se3_wrenches(
            f64(pos_world, float), f64(vel_world, float), f64(rotation_body_to_world, float), f64(ang_vel_body, float),
            f64(ref_pos_world, float), f64(ref_vel_world, float), f64(ref_acc_world, float), f64(ref_yaw, float), f64(ref_yaw_rate, float),
            self.integral, float(dt_s), float(self.params.mass_kg), GRAVITY_MPS2, float(self.k_x), float(self.k_v), float(self.k_i),
            f64(self.k_R, float), f64(self.k_W, float), f64(self.J, float), float(g.integral_limit_m_s), float(g.integral_zone_m), float(np.tan(g.max_tilt_rad)),
        )  # fmt: skip

    def step_numpy(
        self,
        pos_world: np.ndarray,
        vel_world: np.ndarray,
        rotation_body_to_world: np.ndarray,
        ang_vel_body: np.ndarray,
        ref_pos_world: np.ndarray,
        ref_vel_world: np.ndarray,
        ref_acc_world: np.ndarray,
        ref_yaw: np.ndarray,
        ref_yaw_rate: np.ndarray,
        dt_s: float,
    ) -> np.ndarray:
        """The same law as :meth:`step` in numpy (the tests' oracle for the compiled kernel).

        Args:
            pos_world, vel_world: (N, 3) state [m], [m/s].
            rotation_body_to_world: (N, 3, 3).
            ang_vel_body: (N, 3) body rates [rad/s].
            ref_pos_world, ref_vel_world, ref_acc_world: (N, 3) reference.
            ref_yaw, ref_yaw_rate: (N,) [rad], [rad/s].
            dt_s: controller period [s] (for the integral).

        Returns:
            (N, 4) wrench ``[F, tau_x, tau_y, tau_z]`` in [N] and body [N m].
        """
        m = self.params.mass_kg
        R = rotation_body_to_world
        e_x = pos_world - ref_pos_world
        e_v = vel_world - ref_vel_world
        lim = self.gains.integral_limit_m_s
        # conditional integration (anti-windup): only near the reference
        near = (np.abs(e_x) < self.gains.integral_zone_m).astype(float)
        self.integral = np.clip(self.integral + near * e_x * dt_s, -lim, lim)
        e3 = np.array([0.0, 0.0, 1.0])
        # F_d = -k_x e_x - k_v e_v - k_i int e_x + m g e3 + m a_d
        F_d = -self.k_x * e_x - self.k_v * e_v - self.k_i * self.integral + m * GRAVITY_MPS2 * e3 + m * ref_acc_world
        F_d[:, 2] = np.maximum(F_d[:, 2], 0.1 * m * GRAVITY_MPS2)
        # tilt limit: scale the horizontal part so that angle(F_d, e3) <= max_tilt
        horiz = np.linalg.norm(F_d[:, :2], axis=1)
        max_h = F_d[:, 2] * np.tan(self.gains.max_tilt_rad)
        scale = np.where(horiz > max_h, max_h / np.maximum(horiz, 1e-12), 1.0)
        F_d[:, :2] *= scale[:, None]
        b3 = R[:, :, 2]
        thrust = np.einsum("ni,ni->n", F_d, b3)  # f = F_d . R e3
        b3_d = F_d / np.linalg.norm(F_d, axis=1, keepdims=True)
        R_d = rotation_from_thrust_axis_and_yaw(b3_d, ref_yaw)
        RdT_R = np.einsum("nji,njk->nik", R_d, R)
        e_R = 0.5 * vee(RdT_R - np.transpose(RdT_R, (0, 2, 1)))  # e_R = 1/2 vee(R_d^T R - R^T R_d)
        omega_d = np.zeros_like(ang_vel_body)
        omega_d[:, 2] = ref_yaw_rate
        e_W = ang_vel_body - np.einsum("nji,njk,nk->ni", R, R_d, omega_d)  # Omega - R^T R_d Omega_d
        J_omega = self.J * ang_vel_body
        M = -self.k_R * e_R - self.k_W * e_W + cross_rows(ang_vel_body, J_omega)
        return np.concatenate([np.maximum(thrust, 0.0)[:, None], M], axis=1)

    def reset(self, index: int | None = None) -> None:
        """Zero the integral state (all drones, or one)."""
        if index is None:
            self.integral[:] = 0.0
        else:
            self.integral[index] = 0.0
