"""Control allocation and motor dynamics of the X-frame quadrotor (batched over drones).

The wrench ``w = [F, tau_x, tau_y, tau_z]`` (collective thrust [N] along body z
and body torques [N m]) relates to the four rotor thrusts ``f`` [N] by
``w = A f`` with rows ``[1, 1, 1, 1]``, ``y_i``, ``-x_i``, ``s_i k_m / k_f``
(rotor position ``(x_i, y_i)`` in the body frame, drag-torque sign ``s_i``).
Motor speeds follow a first-order lag; thrust ``k_f omega^2`` and drag torque
``k_m omega^2`` come from the *actual* speeds, so saturation and lag are real.
"""

from __future__ import annotations

import numpy as np

from sim.vehicle.params import QuadrotorParams

__all__ = ["MotorBank", "allocation_matrix"]


def allocation_matrix(params: QuadrotorParams) -> np.ndarray:
    """(4, 4) matrix A with wrench = A @ rotor_thrusts (see module docstring)."""
    r = params.rotor_pos_body
    c = params.torque_coeff / params.thrust_coeff
    return np.stack([np.ones(4), r[:, 1], -r[:, 0], c * np.asarray(params.motor_dirs)])


class MotorBank:
    """Motor speeds of N quadrotors and their allocation.

    Attributes:
        speed_radps: (N, 4) current motor speeds [rad/s].
    """

    def __init__(self, params: QuadrotorParams, n_drones: int) -> None:
        self.params = params
        self.A = allocation_matrix(params)
        self.A_inv = np.linalg.inv(self.A)
        self.f_max = params.max_thrust_per_motor_n
        hover = np.sqrt(params.mass_kg * 9.81 / 4 / params.thrust_coeff)
        self.speed_radps = np.full((n_drones, 4), hover)
        self.enabled = np.ones(n_drones, bool)

    def thrusts_for_wrench(self, wrench: np.ndarray) -> np.ndarray:
        """Rotor thrust commands (N, 4) [N] for desired wrenches (N, 4).

        Collective thrust and roll/pitch torques have priority: where the
        command would leave [0, f_max], the yaw torque is scaled down first,
        then the thrusts are clipped.
        """
        f = wrench @ self.A_inv.T
        bad = (f.min(axis=1) < 0) | (f.max(axis=1) > self.f_max)
        if np.any(bad):
            no_yaw = wrench[bad].copy()
            no_yaw[:, 3] = 0.0
            f0 = no_yaw @ self.A_inv.T
            dyaw = f[bad] - f0  # per-motor contribution of the yaw torque
            # largest s in [0, 1] with 0 <= f0 + s * dyaw <= f_max, per drone
            with np.errstate(divide="ignore", invalid="ignore"):
                up = np.where(dyaw > 0, (self.f_max - f0) / dyaw, np.inf)
                dn = np.where(dyaw < 0, -f0 / dyaw, np.inf)
            s = np.clip(np.minimum(up.min(axis=1), dn.min(axis=1)), 0.0, 1.0)
            f[bad] = f0 + s[:, None] * dyaw
        return np.clip(f, 0.0, self.f_max)

    def step(self, thrust_cmd: np.ndarray, dt_s: float) -> tuple[np.ndarray, np.ndarray]:
        """Advance the motor lag by ``dt_s`` [s] toward thrust commands (N, 4) [N].

        Returns:
            thrusts (N, 4) [N] and drag torques about body z (N, 4) [N m]
            (signed by ``motor_dirs``) produced by the actual motor speeds.
        """
        p = self.params
        speed_cmd = np.sqrt(np.maximum(thrust_cmd, 0.0) / p.thrust_coeff)
        speed_cmd[~self.enabled] = 0.0
        if p.motor_time_constant_s > 0:
            # omega += (omega_cmd - omega) (1 - exp(-dt / tau_m))
            self.speed_radps += (speed_cmd - self.speed_radps) * (1.0 - np.exp(-dt_s / p.motor_time_constant_s))
        else:
            self.speed_radps = speed_cmd
        w2 = self.speed_radps**2
        return p.thrust_coeff * w2, p.torque_coeff * w2 * np.asarray(p.motor_dirs)
