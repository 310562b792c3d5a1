"""Camera poses of the drones and the assembly of sensor frames.

Joins the renderer's noise-free output with the drone's own pose estimate and
the depth sensor model into the :class:`sim.types.RgbdFrame` that onboard code
receives, and the :class:`sim.types.GroundTruthSegmentation` it never does.
"""

from __future__ import annotations

import numpy as np

from sim.camera import CameraConfig, apply_depth_sensor_model, intrinsics, rotation_camera_to_body
from sim.rendering.tiny import RawRender
from sim.rotations import rotation_from_quat_xyzw
from sim.types import GroundTruthSegmentation, PoseEstimate, RgbdFrame

__all__ = ["CameraRig", "sensor_depth"]


def sensor_depth(depth_true_m: np.ndarray, camera: CameraConfig, seed: int, drone: int, frame_index: int) -> np.ndarray:
    """The depth sensor's output (H, W) [m] for one capture, seeded by (run seed, drone, frame index).

    The same inputs give the same noise wherever it is computed (a render
    worker or the main process).
    """
    rng = np.random.default_rng([seed, 0xCA3, drone, frame_index])
    return apply_depth_sensor_model(depth_true_m, rng, camera)


class CameraRig:
    """The forward camera mounted on each drone (same mount on all)."""

    def __init__(self, camera: CameraConfig, seed: int) -> None:
        self.camera = camera
        self.K = intrinsics(camera)
        self.K.setflags(write=False)
        self.rotation_camera_to_body = rotation_camera_to_body(camera.mount_pitch_deg)
        self.offset_body_m = np.asarray(camera.mount_offset_body_m, float)
        self.seed = seed

    def transform_camera_to_world(self, pos_world: np.ndarray, rotation_body_to_world: np.ndarray) -> np.ndarray:
        """(4, 4) camera pose from a body pose: (3,) position [m], (3, 3) attitude."""
        T = np.eye(4)
        T[:3, :3] = rotation_body_to_world @ self.rotation_camera_to_body
        T[:3, 3] = pos_world + rotation_body_to_world @ self.offset_body_m
        return T

    def frame(self, drone: int, frame_index: int, time_s: float, raw: RawRender, estimate: PoseEstimate) -> RgbdFrame:
        """Onboard frame: sensor-model depth, pose from the drone's own *estimate*.

        The noise generator is seeded by (run seed, drone, frame index), so
        frames do not depend on how renders were distributed over workers;
        a render pool asked for sensor depth has already applied it.
        """
        depth_m = raw.depth_sensor_m if raw.depth_sensor_m is not None else sensor_depth(raw.depth_true_m, self.camera, self.seed, drone, frame_index)
        T_est = self.transform_camera_to_world(estimate.pos_world, rotation_from_quat_xyzw(estimate.quat_xyzw))
        return RgbdFrame(drone_id=drone, time_s=time_s, rgb=raw.rgb, depth_m=depth_m, K=self.K, transform_camera_to_world=T_est)

    @staticmethod
    def segmentation(drone: int, time_s: float, raw: RawRender, transform_camera_to_world_true: np.ndarray) -> GroundTruthSegmentation:
        """Ground-truth labels of the same capture (metrics and datasets only)."""
        return GroundTruthSegmentation(
            drone_id=drone, time_s=time_s, drone_index_mask=raw.drone_index_mask, transform_camera_to_world_true=transform_camera_to_world_true
        )
