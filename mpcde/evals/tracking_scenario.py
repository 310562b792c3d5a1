"""The tracking evaluation's world: manoeuvring targets in front of a hovering observer's camera.

:func:`make_scenario` gives the ground truth of one run
(:class:`TrackingScenario`: the observer's pose, the targets' positions and
velocities at the 25 Hz frame times); :func:`camera_pose` and
:func:`in_camera_view` say where the observer's forward camera is and what it
can see; :func:`hover_truth` is the observer's true state for its pose
estimator. Both measurement sources of ``mpcde eval-tracking``
(:class:`mpcde.evals.tracking.SyntheticMeasurements`,
:class:`mpcde.evals.tracking_pipeline.PipelineMeasurements`) build on these.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from sim.camera import CameraConfig
from sim.ground_truth import TrueState
from sim.rendering.camera_rig import CameraRig
from sim.rotations import quat_xyzw_from_yaw, rotation_from_quat_xyzw

__all__ = [
    "RATE_HZ",
    "VIEW_AZIMUTH_DEG",
    "VIEW_RANGE_M",
    "TrackingScenario",
    "camera_pose",
    "hover_truth",
    "in_camera_view",
    "make_scenario",
]

RATE_HZ = 25.0
"""Perception rate (MP-CDE: 25 Hz)."""

VIEW_RANGE_M = (2.0, 7.0)
"""Horizontal range [m] from the observer within which the targets fly (they steer back when outside)."""

VIEW_AZIMUTH_DEG = 30.0
"""Largest azimuth [deg] off the observer's optical axis within which the targets fly."""


@dataclass(frozen=True)
class TrackingScenario:
    """Ground truth of one tracking run (never seen by the tracker).

    Attributes:
        times_s: (T,) frame times [s].
        observer_pos_world: (3,) the observer's (hovering) position [m].
        target_pos_world: (T, n, 3) target positions [m].
        target_vel_world: (T, n, 3) target velocities [m/s].
        observer_yaw_rad: the observer's (fixed) yaw [rad]; its forward camera
            (body +x, :class:`sim.camera.CameraConfig`) looks along world
            ``(cos yaw, sin yaw, 0)``.
    """

    times_s: np.ndarray
    observer_pos_world: np.ndarray
    target_pos_world: np.ndarray
    target_vel_world: np.ndarray
    observer_yaw_rad: float = 0.0

    @property
    def n_targets(self) -> int:
        """Number of target drones."""
        return self.target_pos_world.shape[1]


def _wrap_rad(angle_rad: float) -> float:
    """``angle_rad`` wrapped into [-pi, pi)."""
    return (angle_rad + np.pi) % (2 * np.pi) - np.pi


def make_scenario(
    speed_mps: float, n_targets: int, duration_s: float, seed: int, rate_hz: float = RATE_HZ
) -> TrackingScenario:
    """Manoeuvring target paths in front of a hovering observer at ``(0, 0, 1.5)`` m, yaw 0.

    The observer's one forward camera looks along world +x, so the targets fly
    in its view: the region ``VIEW_RANGE_M`` (2-7 m horizontal range) x
    ``|azimuth| <= VIEW_AZIMUTH_DEG`` (30 deg) x height within about
    ``+-0.8 m`` of the observer. Each target starts inside it (range 3-6 m,
    ``|az| <= 20 deg``) and flies segments of 1-3 s; at each segment start it
    picks a new speed in ``[0.6, 1.3] * speed_mps`` (reached at 0.5 m/s^2)
    and, with probability 0.6, a turn rate of 0.2-1.0 rad/s capped so the
    lateral acceleration stays under 2 m/s^2 (turn rate changed at 1 rad/s^2).
    Steering back: when the point ``0.3 + 0.5 speed_mps`` seconds of straight
    flight ahead lies outside the region shrunk by a margin (range
    2.3-6.44 m, ``|az| <= 25.5 deg``), the target turns towards the region's
    centre (4.5 m straight ahead) at up to 3 m/s^2 of lateral acceleration
    (turn rate changed at 3 rad/s^2) and eases off to ``0.8 speed_mps``; once
    its course stays inside it flies straight at a new speed in
    ``[1.0, 1.3] * speed_mps``. At 2 m/s it still overshoots the region now
    and then, and it turns back often (time inside and mean speed measured:
    docs/results/tracking_eval.md#make_scenario-how-the-target-paths-stay-in-view). Height follows a gentle climb and descent,
    ``z = z_obs + c + A sin(0.5 t + phase)`` with ``|c| <= 0.2`` m and
    ``A = min(0.4 speed_mps, 0.55)`` m. Integrated at 10
    sub-steps per frame.
    """
    rng = np.random.default_rng([seed, int(round(speed_mps * 1000)), 17])
    n_frames = int(round(duration_s * rate_hz))
    dt = 1.0 / rate_hz
    sub = 10
    h = dt / sub
    observer = np.array([0.0, 0.0, 1.5])
    yaw = 0.0
    r_min, r_max = VIEW_RANGE_M
    az_max = np.radians(VIEW_AZIMUTH_DEG)
    centre_xy = observer[:2] + 0.5 * (r_min + r_max) * np.array([np.cos(yaw), np.sin(yaw)])
    pos = np.zeros((n_frames, n_targets, 3))
    vel = np.zeros((n_frames, n_targets, 3))
    turn_max = min(1.0, 2.0 / (1.3 * speed_mps))  # lateral acceleration <= 2 m/s^2
    steer_max = min(1.5, 3.0 / (1.3 * speed_mps))  # <= 3 m/s^2 when turning back
    climb_amp_m = min(0.4 * speed_mps, 0.55)
    look_s = 0.3 + 0.5 * speed_mps  # about the time a turn back takes (turn-rate ramp plus half a turn)
    for j in range(n_targets):
        rng_xy = rng.uniform(3.0, 6.0)
        az = yaw + np.radians(rng.uniform(-20.0, 20.0))
        offset_z, phase = rng.uniform(-0.2, 0.2), rng.uniform(0, 2 * np.pi)
        p = observer + np.array([rng_xy * np.cos(az), rng_xy * np.sin(az), offset_z + climb_amp_m * np.sin(phase)])
        heading = rng.uniform(0, 2 * np.pi)
        speed, turn, speed_goal, turn_goal, seg_left = speed_mps, 0.0, speed_mps, 0.0, 0.0
        t, steering = 0.0, False
        for k in range(n_frames):
            for _ in range(sub):
                seg_left -= h
                if seg_left <= 0:
                    seg_left = rng.uniform(1.0, 3.0)
                    speed_goal = speed_mps * rng.uniform(0.6, 1.3)
                    turn_goal = rng.choice([-1.0, 1.0]) * rng.uniform(0.2, 1.0) * turn_max * (rng.random() < 0.6)
                # where the target would be after look_s of straight flight: outside the region -> turn back now
                ahead = p[:2] - observer[:2] + look_s * speed * np.array([np.cos(heading), np.sin(heading)])
                r_xy = np.hypot(*ahead)
                az_rel = _wrap_rad(np.arctan2(ahead[1], ahead[0]) - yaw)
                if r_xy > 0.92 * r_max or r_xy < 1.15 * r_min or abs(az_rel) > 0.85 * az_max:  # a margin inside the region
                    to_centre = np.arctan2(centre_xy[1] - p[1], centre_xy[0] - p[0])
                    off = _wrap_rad(to_centre - heading)
                    turn_goal = np.clip(3.0 * off, -steer_max, steer_max)  # turn towards the centre
                    speed_goal = min(speed_goal, 0.8 * speed_mps)  # and eases off to turn tighter
                    seg_left, steering = max(seg_left, 0.5), True
                elif steering:  # back on a course that stays inside: straight, speeding up again
                    turn_goal, speed_goal, steering = 0.0, speed_mps * rng.uniform(1.0, 1.3), False
                ramp = 3.0 if steering else 1.0  # turn-rate change [rad/s^2]: quicker when turning back
                turn += np.clip(turn_goal - turn, -ramp * h, ramp * h)
                speed += np.clip(speed_goal - speed, -0.5 * h, 0.5 * h)
                heading += turn * h
                t += h
                v_z = 0.5 * climb_amp_m * np.cos(0.5 * t + phase)  # d/dt of A sin(0.5 t + phase)
                v = np.array([speed * np.cos(heading), speed * np.sin(heading), v_z])
                p = p + v * h
            pos[k, j], vel[k, j] = p, v
    times = np.arange(1, n_frames + 1) * dt
    return TrackingScenario(times, observer, pos, vel, yaw)


def camera_pose(scenario: TrackingScenario, camera: CameraConfig) -> tuple[np.ndarray, np.ndarray]:
    """The observer's forward camera: ``(pos_world (3,) [m], rotation_camera_to_world (3, 3))``.

    Body frame = world rotated by ``scenario.observer_yaw_rad`` about z (a
    hovering drone, level); the camera sits at ``camera.mount_offset_body_m``
    with the optical frame of :func:`sim.camera.rotation_camera_to_body`.
    """
    rotation_body_to_world = rotation_from_quat_xyzw(quat_xyzw_from_yaw(scenario.observer_yaw_rad))
    T = CameraRig(camera, seed=0).transform_camera_to_world(np.asarray(scenario.observer_pos_world, float), rotation_body_to_world)
    return T[:3, 3], T[:3, :3]


def in_camera_view(
    points_world: np.ndarray,
    camera_pos_world: np.ndarray,
    rotation_camera_to_world: np.ndarray,
    camera: CameraConfig,
    margin_m: float,
) -> np.ndarray:
    """(n,) bool: which of ``points_world`` (n, 3) [m] a drone centred there is inside the camera's view.

    Inside means: depth along the optical axis in ``[camera.depth_min_m,
    camera.depth_max_m]`` and the point at least ``margin_m`` inside each of
    the four side planes of the frustum (``hfov_deg`` x ``vfov_deg``), i.e. a
    drone of radius ``margin_m`` is entirely in the image. ``camera_pos_world``
    (3,) [m]; ``rotation_camera_to_world`` (3, 3).
    """
    p_cam = (np.asarray(points_world, float).reshape(-1, 3) - camera_pos_world) @ rotation_camera_to_world
    x, y, z = p_cam[:, 0], p_cam[:, 1], p_cam[:, 2]
    half_h, half_v = np.radians(camera.hfov_deg) / 2, np.radians(camera.vfov_deg) / 2
    # signed distance inside a side plane through the optical centre at half-angle a: z sin a - |x| cos a
    inside_h = z * np.sin(half_h) - np.abs(x) * np.cos(half_h) >= margin_m
    inside_v = z * np.sin(half_v) - np.abs(y) * np.cos(half_v) >= margin_m
    return inside_h & inside_v & (z >= camera.depth_min_m) & (z <= camera.depth_max_m)


def hover_truth(time_s: float, pos_world: np.ndarray, yaw_rad: float) -> TrueState:
    """The true state of one level drone hovering at ``pos_world`` (3,) [m] with heading ``yaw_rad`` (for its pose estimator)."""
    quat = quat_xyzw_from_yaw(yaw_rad)
    return TrueState(
        time_s=float(time_s), pos_world=np.asarray(pos_world, float)[None], vel_world=np.zeros((1, 3)), quat_xyzw=quat[None],
        rotation_body_to_world=rotation_from_quat_xyzw(quat)[None], ang_vel_body=np.zeros((1, 3)),
        obstacle_contact=np.zeros(1, bool), failed=np.zeros(1, bool),
    )  # fmt: skip
