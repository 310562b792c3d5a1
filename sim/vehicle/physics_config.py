"""Physics and low-level control settings (the ``physics:`` section of a scenario)."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import ClassVar

from sim.checks import ConfigError
from sim.vehicle.controller import ControllerGains
from sim.vehicle.params import QuadrotorParams

__all__ = ["PhysicsConfig"]


@dataclass(frozen=True)
class PhysicsConfig:
    """Physics and low-level control.

    Class constant (:data:`typing.ClassVar`, not a field: no scenario, sweep or
    preset sets it, so a scenario file that names ``physics.gains`` is refused
    as an unknown key; docs/design.md section 7): ``gains``. Code that flies
    other gains builds :class:`sim.vehicle.controller.SE3Controller` with its
    own :class:`~sim.vehicle.controller.ControllerGains`, or subclasses this.

    Attributes:
        physics_hz: physics and controller rate [Hz] (PyBullet default 240).
        quadrotor: airframe, rotors and motors.
        gains: SE(3) controller gains.
        crash_tilt_rad: a drone tilted beyond this [rad] while touching
            something is declared failed (motors off) and falls.
    """

    physics_hz: float = 240.0
    quadrotor: QuadrotorParams = field(default_factory=QuadrotorParams)
    gains: ClassVar[ControllerGains] = ControllerGains()
    crash_tilt_rad: float = 1.2

    def __post_init__(self) -> None:
        if not 50.0 <= self.physics_hz <= 2000.0:
            raise ConfigError("physics_hz", self.physics_hz, "in [50, 2000] Hz")

