"""The ``orca`` section of a scenario file: what the ORCA stack flies with."""

from __future__ import annotations

from dataclasses import dataclass

from sim.checks import require_non_negative, require_positive

__all__ = ["OrcaConfig"]


@dataclass(frozen=True)
class OrcaConfig:
    """Settings of the ORCA stack (a scenario's top-level ``orca:`` section).

    Attributes:
        horizon_s: ORCA's time horizon tau [s]: velocities that would collide
            within it are forbidden (van den Berg et al., Eq. 5).
        max_speed_mps: horizontal speed limit [m/s]; ``planner.cruise_speed_mps``
            replaces it when the scenario sets one.
        vertical_gain_per_s: climb rate per metre of altitude error [1/s].
        max_climb_mps: vertical speed limit [m/s].
        radius_margin_m: added to the two drones' radii in the combined radius r [m].
        sigma_scale: the combined radius grows by this many standard deviations
            of the track's horizontal position (a neighbour seen long ago is kept
            further away).
        arrive_s: within ``max_speed_mps * arrive_s`` of the goal the preferred
            speed falls linearly to zero [s].
        max_accel_mps2: the reference's acceleration limit [m/s^2].
        yaw_rate_max_radps: heading rate limit [rad/s]; the camera turns toward
            the direction of travel.
    """

    horizon_s: float = 2.0
    max_speed_mps: float = 1.0
    vertical_gain_per_s: float = 1.0
    max_climb_mps: float = 0.5
    radius_margin_m: float = 0.3
    sigma_scale: float = 1.0
    arrive_s: float = 1.5
    max_accel_mps2: float = 3.0
    yaw_rate_max_radps: float = 1.5

    def __post_init__(self) -> None:  # each refusal a one-line mpcde.ConfigError naming the field
        for name in ("horizon_s", "max_speed_mps", "vertical_gain_per_s", "max_climb_mps", "arrive_s", "max_accel_mps2", "yaw_rate_max_radps"):
            require_positive(name, getattr(self, name))
        for name in ("radius_margin_m", "sigma_scale"):
            require_non_negative(name, getattr(self, name))
