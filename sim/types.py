"""Sensor-message types that leave sim/ (frozen dataclasses).

Frames (DESIGN.md section 2): ``world`` is inertial, z up; ``body`` is x
forward, y left, z up; ``camera`` is the OpenCV optical frame (x right, y down,
z forward). Quaternions are ``quat_xyzw``. SI units throughout.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from sim.checks import ConfigError

__all__ = [
    "ObstacleSpec",
    "FlatOutputReference",
    "GroundTruthSegmentation",
    "PlanMessage",
    "PoseEstimate",
    "RadioMessage",
    "RgbdFrame",
]


@dataclass(frozen=True)
class RgbdFrame:
    """One forward-camera capture, as onboard code receives it (no segmentation).

    Attributes:
        drone_id: index of the drone that carries the camera.
        time_s: capture time in [s] of simulated time.
        rgb: colour image, uint8, shape (H, W, 3).
        depth_m: metric depth along the optical axis in [m], float32, shape
            (H, W); pixels outside the valid range are ``NaN``.
        K: pinhole intrinsics (3, 3) in pixels (OpenCV convention).
        transform_camera_to_world: (4, 4) homogeneous transform from the camera
            optical frame to world, built from the drone's own pose *estimate*
            at capture time (not ground truth).
    """

    drone_id: int
    time_s: float
    rgb: np.ndarray
    depth_m: np.ndarray
    K: np.ndarray
    transform_camera_to_world: np.ndarray

    @property
    def shape_px(self) -> tuple[int, int]:
        """(H, W) of the images in pixels."""
        return self.depth_m.shape[0], self.depth_m.shape[1]


@dataclass(frozen=True)
class GroundTruthSegmentation:
    """Ground-truth segmentation of one capture; never handed to onboard code.

    Attributes:
        drone_id: the camera's drone.
        time_s: capture time in [s].
        drone_index_mask: int16 (H, W); ``k >= 0`` where drone ``k`` is the
            visible surface, ``-1`` elsewhere (obstacles, ground, sky).
        transform_camera_to_world_true: (4, 4) true camera pose at capture.
    """

    drone_id: int
    time_s: float
    drone_index_mask: np.ndarray
    transform_camera_to_world_true: np.ndarray


@dataclass(frozen=True)
class PoseEstimate:
    """A drone's estimate of its own state (VIO stand-in: truth + noise + drift).

    Attributes:
        time_s: time of the estimate in [s].
        pos_world: position (3,) in [m].
        vel_world: velocity (3,) in [m/s].
        quat_xyzw: attitude body->world, (4,), PyBullet order.
        ang_vel_body: body rates (3,) in [rad/s].
    """

    time_s: float
    pos_world: np.ndarray
    vel_world: np.ndarray
    quat_xyzw: np.ndarray
    ang_vel_body: np.ndarray

    def extrapolated(self, time_s: float) -> tuple[np.ndarray, np.ndarray]:
        """(position (3,) [m], velocity (3,) [m/s]) at ``time_s`` [s], at constant velocity from this estimate.

        p(t) = p + v (t - t_est), v(t) = v: what a planner that starts its round
        at ``time_s`` takes for its own state when it trusts the estimate. Used by
        the DMPC, ADMM and MLR agents; ``time_s`` before the estimate extrapolates
        backwards.
        """
        vel = np.asarray(self.vel_world, float)
        return np.asarray(self.pos_world, float) + vel * (time_s - self.time_s), vel.copy()


@dataclass(frozen=True)
class FlatOutputReference:
    """Reference for the geometric SE(3) tracking controller (differential flatness).

    Attributes:
        pos_world: desired position (3,) in [m].
        vel_world: desired velocity (3,) in [m/s].
        acc_world: desired acceleration (3,) in [m/s^2] (feed-forward).
        yaw: desired heading in [rad] (body x axis about world z).
        yaw_rate: desired heading rate in [rad/s].
    """

    pos_world: np.ndarray
    vel_world: np.ndarray = field(default_factory=lambda: np.zeros(3))
    acc_world: np.ndarray = field(default_factory=lambda: np.zeros(3))
    yaw: float = 0.0
    yaw_rate: float = 0.0

    @staticmethod
    def hover(pos_world: np.ndarray, yaw: float = 0.0) -> "FlatOutputReference":
        """Hold ``pos_world`` (3,) [m] at heading ``yaw`` [rad]."""
        return FlatOutputReference(pos_world=np.asarray(pos_world, float).copy(), yaw=float(yaw))


@dataclass(frozen=True)
class RadioMessage:
    """One broadcast message as a receiver gets it.

    Attributes:
        sender_id: the broadcasting drone's index.
        send_time_s: when it was sent, in [s] (receivers compute the age).
        receive_time_s: when it was delivered, in [s] (send time + delay).
        payload: what the sender broadcast (e.g. a plan); the radio never looks inside.
    """

    sender_id: int
    send_time_s: float
    receive_time_s: float
    payload: Any


@dataclass(frozen=True)
class PlanMessage:
    """A drone's broadcast of its own planned trajectory (the radio payload).

    Attributes:
        sender_id: the broadcasting drone.
        time_s: when the plan was sent [s].
        times_s: (K,) absolute sample times [s].
        pos_world: (K, 3) planned positions [m].
        vel_world: (K, 3) planned velocities [m/s].
    """

    sender_id: int
    time_s: float
    times_s: np.ndarray
    pos_world: np.ndarray
    vel_world: np.ndarray


@dataclass(frozen=True)
class ObstacleSpec:
    """One static obstacle.

    Attributes:
        kind: ``"tree"`` (vertical cylinder) or ``"box"``.
        center_xy: (2,) ground position of its axis/centre in world [m].
        height_m: height [m] (from z = 0).
        radius_m: cylinder radius [m] (trees).
        half_extents_xy: (2,) half sizes along the box's own x, y [m] (boxes).
        yaw: box heading about world z [rad].
        rgba: colour (4,) in [0, 1].
    """

    kind: str
    center_xy: tuple[float, float]
    height_m: float
    radius_m: float = 0.0
    half_extents_xy: tuple[float, float] = (0.0, 0.0)
    yaw: float = 0.0
    rgba: tuple[float, float, float, float] = (0.45, 0.32, 0.2, 1.0)

    def __post_init__(self) -> None:
        if self.kind not in ("tree", "box"):
            raise ConfigError("kind", self.kind, "allowed 'tree' or 'box'")
        if self.height_m <= 0:
            raise ConfigError("height_m", self.height_m, "must be > 0")
        if self.kind == "tree" and self.radius_m <= 0:
            raise ConfigError("radius_m", self.radius_m, "a tree needs a radius > 0")
        if self.kind == "box" and min(self.half_extents_xy) <= 0:
            raise ConfigError("half_extents_xy", self.half_extents_xy, "a box needs positive half sizes")

    @property
    def footprint_radius_m(self) -> float:
        """Radius [m] of the smallest vertical cylinder containing the obstacle."""
        return self.radius_m if self.kind == "tree" else float(np.hypot(*self.half_extents_xy))

