"""The settings of the learning environments (:class:`mpcde.env.SwarmParallelEnv`, :class:`mpcde.env.SingleDroneEnv`).

Every field is checked when the options are built: a bad value raises
:class:`mpcde.errors.ConfigError` naming ``env.<field>``, the value and what
is allowed (one line), before any world is built.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from sim.checks import ConfigError, require_in

__all__ = ["ACTION_MODES", "OBSERVATIONS", "EnvOptions"]

ACTION_MODES = ("velocity", "reference")
OBSERVATIONS = ("pose", "goal", "camera", "detections", "tracks", "radio")
INVALID_ACTIONS = ("raise", "clip")


@dataclass(frozen=True)
class EnvOptions:
    """How the world is exposed to a learner.

    Attributes:
        control_hz: control steps per simulated second [Hz] (default: the
            camera rate of 25 Hz); physics runs at ``physics.physics_hz``
            (240 Hz) underneath, the action held between control steps.
        action: ``"velocity"``: (4,) world-frame velocity [m/s] and yaw rate
            [rad/s]; ``"reference"``: (11,) flat-output reference: position [m],
            velocity [m/s], acceleration [m/s^2], yaw [rad], yaw rate [rad/s].
            The SE(3) controller tracks either (:mod:`mpcde.env.actions`).
        observe: the observation's entries, a subset of :data:`OBSERVATIONS`
            (:mod:`mpcde.env.observations`); ``camera``, ``detections`` and
            ``tracks`` need cameras. None (the default) follows ``cameras``:
            ``pose``, ``goal``, ``camera``, ``tracks`` with cameras, ``pose``,
            ``goal`` without.
        cameras: render the drones' RGB-D frames (False: the no-camera world
            for fast training; then only ``pose``, ``goal`` and ``radio``).
        track_slots: neighbour-track slots in the ``tracks`` entry.
        detection_slots: box slots in the ``detections`` entry.
        plan_slots: neighbour-plan slots in the ``radio`` entry.
        plan_samples: samples per plan in the ``radio`` entry (and in the plan
            an env-driven drone broadcasts).
        plan_horizon_s: horizon [s] of the plan an env-driven drone broadcasts.
        broadcast: an env-driven drone broadcasts its held action as a plan at
            every radio round (so that radio-using neighbours avoid it); False:
            it is silent, as the ``denied`` stack is.
        copy_images: every observation gets its own copy of the camera's RGB
            and depth arrays (Gymnasium's checker requires observations that
            share no memory); False: the observations of one frame share one
            read-only RGB and one read-only depth array, copied once per frame
            instead of once per step (for control rates above the camera's).
        max_speed_mps: the velocity bound of both action modes [m/s].
        max_accel_mps2: the acceleration bound of the reference action [m/s^2].
        max_yaw_rate_rps: the yaw-rate bound of both action modes [rad/s].
        invalid_action: ``"raise"``: a NaN or out-of-bounds action raises
            ValueError naming the agent, the element, the value and its bounds;
            ``"clip"``: it is clipped into the box (NaN: hover where the drone
            estimates it is) and ``infos[agent]["action_clipped"]`` says so.
        terminate_on_collision: a drone terminates at its first collision.
        terminate_on_arrival: a drone terminates when within the goal tolerance.
        progress_weight: reward per metre of progress toward the goal.
        collision_penalty: reward subtracted at a collision.
        arrival_bonus: reward added at arrival.
    """

    control_hz: float = 25.0
    action: str = "velocity"
    observe: tuple[str, ...] | None = None
    cameras: bool = True
    track_slots: int = 8
    detection_slots: int = 8
    plan_slots: int = 8
    plan_samples: int = 16
    plan_horizon_s: float = 3.0
    broadcast: bool = True
    copy_images: bool = True
    max_speed_mps: float = 3.0
    max_accel_mps2: float = 10.0
    max_yaw_rate_rps: float = math.pi
    invalid_action: str = "raise"
    terminate_on_collision: bool = True
    terminate_on_arrival: bool = True
    progress_weight: float = 1.0
    collision_penalty: float = 10.0
    arrival_bonus: float = 10.0

    def __post_init__(self) -> None:
        if self.observe is None and isinstance(self.cameras, bool):  # the default follows the cameras
            object.__setattr__(self, "observe", ("pose", "goal", "camera", "tracks") if self.cameras else ("pose", "goal"))
        object.__setattr__(self, "observe", tuple(self.observe) if isinstance(self.observe, (list, tuple)) else self.observe)
        require_in("env.control_hz", self.control_hz, 1.0, 1000.0)
        if self.action not in ACTION_MODES:
            raise ConfigError("env.action", self.action, f"one of {', '.join(ACTION_MODES)}")
        if not isinstance(self.observe, tuple) or not self.observe or any(k not in OBSERVATIONS for k in self.observe):
            raise ConfigError("env.observe", self.observe, f"a non-empty list of {', '.join(OBSERVATIONS)}")
        if len(set(self.observe)) != len(self.observe):
            raise ConfigError("env.observe", self.observe, "each entry once")
        for name in ("cameras", "broadcast", "copy_images", "terminate_on_collision", "terminate_on_arrival"):
            if not isinstance(getattr(self, name), bool):
                raise ConfigError(f"env.{name}", getattr(self, name), "true or false")
        needs = [k for k in self.observe if k in ("camera", "detections", "tracks")]
        if needs and not self.cameras:
            raise ConfigError("env.observe", self.observe, f"{', '.join(needs)} only with cameras (env.cameras: true)")
        for name in ("track_slots", "detection_slots", "plan_slots"):
            _integer(name, getattr(self, name), 1, 64)
        _integer("plan_samples", self.plan_samples, 2, 64)
        require_in("env.plan_horizon_s", self.plan_horizon_s, 0.1, 30.0)
        require_in("env.max_speed_mps", self.max_speed_mps, 0.1, 20.0)
        require_in("env.max_accel_mps2", self.max_accel_mps2, 0.1, 50.0)
        require_in("env.max_yaw_rate_rps", self.max_yaw_rate_rps, 0.1, 20.0)
        if self.invalid_action not in INVALID_ACTIONS:
            raise ConfigError("env.invalid_action", self.invalid_action, f"one of {', '.join(INVALID_ACTIONS)}")
        for name in ("progress_weight", "collision_penalty", "arrival_bonus"):
            require_in(f"env.{name}", getattr(self, name), 0.0, 1e6)


def _integer(name: str, value: object, low: int, high: int) -> None:
    if isinstance(value, bool) or not isinstance(value, int) or not (low <= value <= high):
        raise ConfigError(f"env.{name}", value, f"an integer in [{low}, {high}]")
