"""Physical parameters of the simulated quadrotor (a Q250-class X frame).

Defaults follow MP-CDE's platform (Sec. V-A): 0.80 kg, 180 x 180 x 75 mm,
thrust-to-weight 4.2. Inertia and motor constants are typical of that class
(not given in the paper; chosen here and stated). The visual/collision model is
``data/quadrotor.urdf``; its mass and inertia must match these (a test holds it).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from sim.checks import ConfigError

__all__ = ["GRAVITY_MPS2", "QuadrotorParams"]

GRAVITY_MPS2 = 9.81


@dataclass(frozen=True)
class QuadrotorParams:
    """Rigid body, rotors and motors.

    Attributes:
        mass_kg: total mass [kg].
        inertia_kgm2: principal moments (Ixx, Iyy, Izz) in the body frame [kg m^2].
        arm_length_m: centre-to-motor distance [m]; motors on the diagonals.
        thrust_coeff: k_f in f = k_f * omega^2 [N s^2/rad^2].
        torque_coeff: k_m in tau = k_m * omega^2 [N m s^2/rad^2] (rotor drag torque).
        motor_speed_max_radps: motor speed limit [rad/s]; sets thrust-to-weight.
        motor_time_constant_s: first-order lag of the motor speed [s].
        linear_drag_coeff: body drag force = -c * v_world [N s/m].
        robot_radius_m: radius of the envelope used by metrics (180 mm frame) [m].
        motor_dirs: sign of each rotor's drag (reaction) torque on the body about
            body z, in the order of ``motor_angles_rad``; diagonal pairs share a sign.
        motor_angles_rad: azimuth of each motor in the body frame [rad]
            (front-left, rear-left, rear-right, front-right).
    """

    mass_kg: float = 0.80
    inertia_kgm2: tuple[float, float, float] = (0.0023, 0.0023, 0.0040)
    arm_length_m: float = 0.08
    thrust_coeff: float = 1.051e-6
    torque_coeff: float = 1.68e-8
    motor_speed_max_radps: float = 2800.0
    motor_time_constant_s: float = 0.02
    linear_drag_coeff: float = 0.03
    robot_radius_m: float = 0.10
    motor_dirs: tuple[float, float, float, float] = (-1.0, 1.0, -1.0, 1.0)
    motor_angles_rad: tuple[float, float, float, float] = field(
        default=(np.pi / 4, 3 * np.pi / 4, 5 * np.pi / 4, 7 * np.pi / 4)
    )

    def __post_init__(self) -> None:
        for name in ("mass_kg", "arm_length_m", "thrust_coeff", "torque_coeff", "motor_speed_max_radps"):
            if not getattr(self, name) > 0:
                raise ConfigError(name, getattr(self, name), "must be > 0")
        if len(self.inertia_kgm2) != 3 or min(self.inertia_kgm2) <= 0:
            raise ConfigError("inertia_kgm2", self.inertia_kgm2, "three positive moments")
        if self.motor_time_constant_s < 0:
            raise ConfigError("motor_time_constant_s", self.motor_time_constant_s, "must be >= 0")

    @property
    def max_thrust_per_motor_n(self) -> float:
        """Thrust of one motor at full speed [N]."""
        return self.thrust_coeff * self.motor_speed_max_radps**2

    @property
    def thrust_to_weight(self) -> float:
        """Four motors at full speed over weight (MP-CDE platform: 4.2)."""
        return 4 * self.max_thrust_per_motor_n / (self.mass_kg * GRAVITY_MPS2)

    @property
    def inertia_matrix(self) -> np.ndarray:
        """(3, 3) body-frame inertia [kg m^2]."""
        return np.diag(self.inertia_kgm2)

    @property
    def rotor_pos_body(self) -> np.ndarray:
        """(4, 3) rotor hub positions in the body frame [m]."""
        a = np.asarray(self.motor_angles_rad)
        return np.stack([self.arm_length_m * np.cos(a), self.arm_length_m * np.sin(a), np.zeros(4)], axis=1)
