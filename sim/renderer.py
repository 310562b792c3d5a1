"""Render the forward cameras of a scene in one PyBullet DIRECT client.

Obstacles and drones are rasterised by PyBullet's TinyRenderer through a
projection matrix that reproduces K exactly; the ground plane z = 0 and the
sky are then drawn analytically into the pixels nothing covered (ray-plane
intersection per pixel). This is exact: every surface lies above z = 0, so it
always occludes the ground behind it. A render client never steps physics; it
only receives poses.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pybullet as pb

from sim.camera import (
    CameraConfig,
    depth_buffer_to_depth_m,
    intrinsics,
    opengl_projection_from_intrinsics,
    opengl_view_from_camera_to_world,
)
from sim.scene import RenderStyle, SceneSpec, build_obstacles, load_drones

__all__ = ["RawRender", "SceneRenderer"]

PARKED_POS = [0.0, 0.0, -100.0]  # where a camera's own drone waits during its render


@dataclass(frozen=True)
class RawRender:
    """Noise-free render of one camera.

    Attributes:
        rgb: (H, W, 3) uint8.
        depth_true_m: (H, W) float32 depth along the optical axis [m]; ``inf``
            where nothing is hit (sky).
        drone_index_mask: (H, W) int16, drone index or -1.
    """

    rgb: np.ndarray
    depth_true_m: np.ndarray
    drone_index_mask: np.ndarray


class SceneRenderer:
    """A render-only PyBullet client holding a copy of the scene."""

    def __init__(self, spec: SceneSpec, camera: CameraConfig) -> None:
        self.spec = spec
        self.camera = camera
        self.client = pb.connect(pb.DIRECT)
        build_obstacles(self.client, spec.obstacles, with_collision=False)
        n = spec.n_drones
        self.drone_ids = load_drones(self.client, spec, np.tile(PARKED_POS, (n, 1)), np.tile([0, 0, 0, 1.0], (n, 1)), fixed=True)
        self.body_to_drone = np.full(max(self.drone_ids, default=0) + 2, -1, np.int16)
        for i, b in enumerate(self.drone_ids):
            self.body_to_drone[b] = i
        self.K = intrinsics(camera)
        W, H = camera.width_px, camera.height_px
        self.projection = opengl_projection_from_intrinsics(self.K, W, H, camera.render_near_m, camera.render_far_m)
        u, v = np.meshgrid(np.arange(W, dtype=np.float64), np.arange(H, dtype=np.float64))
        # ray directions in the camera frame with unit z: K^-1 [u, v, 1]
        self.rays_camera = np.stack([(u - self.K[0, 2]) / self.K[0, 0], (v - self.K[1, 2]) / self.K[1, 1], np.ones_like(u)], axis=-1)

    def close(self) -> None:
        """Disconnect the client."""
        if self.client is not None and pb.isConnected(self.client):
            pb.disconnect(self.client)
        self.client = None

    def set_drone_poses(self, pos_world: np.ndarray, quat_xyzw: np.ndarray) -> None:
        """Place all drones: (N, 3) positions [m], (N, 4) quaternions."""
        for i, b in enumerate(self.drone_ids):
            pb.resetBasePositionAndOrientation(b, pos_world[i].tolist(), quat_xyzw[i].tolist(), physicsClientId=self.client)

    def render(self, transform_camera_to_world: np.ndarray, own_drone: int | None, style: RenderStyle | None = None) -> RawRender:
        """Render one camera at its *true* pose.

        Args:
            transform_camera_to_world: (4, 4) true camera pose.
            own_drone: index of the camera's drone (hidden during the render so
                its own frame does not block the view), or None.
            style: lighting and colours; the scene's by default.
        """
        style = style or self.spec.style
        cam = self.camera
        W, H = cam.width_px, cam.height_px
        own_pose = None
        if own_drone is not None:
            own_pose = pb.getBasePositionAndOrientation(self.drone_ids[own_drone], physicsClientId=self.client)
            pb.resetBasePositionAndOrientation(self.drone_ids[own_drone], PARKED_POS, [0, 0, 0, 1], physicsClientId=self.client)
        light = np.asarray(style.light_direction, float)
        light = light / np.linalg.norm(light)
        _, _, rgba, zbuf, seg = pb.getCameraImage(
            W,
            H,
            viewMatrix=opengl_view_from_camera_to_world(transform_camera_to_world),
            projectionMatrix=self.projection,
            renderer=pb.ER_TINY_RENDERER,
            lightDirection=(light * 100.0).tolist(),
            lightAmbientCoeff=style.ambient,
            lightDiffuseCoeff=style.diffuse,
            lightSpecularCoeff=style.specular,
            shadow=0,
            physicsClientId=self.client,
        )
        if own_pose is not None:
            pb.resetBasePositionAndOrientation(self.drone_ids[own_drone], own_pose[0], own_pose[1], physicsClientId=self.client)
        rgb = np.asarray(rgba, np.uint8).reshape(H, W, 4)[:, :, :3].copy()
        depth = depth_buffer_to_depth_m(np.asarray(zbuf).reshape(H, W), cam.render_near_m, cam.render_far_m)
        seg = np.asarray(seg, np.int64).reshape(H, W)
        background = seg < 0
        mask = np.full((H, W), -1, np.int16)
        obj = np.where(background, 0, seg & ((1 << 24) - 1))
        obj = np.clip(obj, 0, self.body_to_drone.size - 1)
        mask[~background] = self.body_to_drone[obj[~background]]
        depth[background] = np.inf
        self._draw_ground_and_sky(rgb, depth, background, transform_camera_to_world, style, light)
        return RawRender(rgb=rgb, depth_true_m=depth, drone_index_mask=mask)

    def _draw_ground_and_sky(
        self,
        rgb: np.ndarray,
        depth: np.ndarray,
        background: np.ndarray,
        T_cw: np.ndarray,
        style: RenderStyle,
        light: np.ndarray,
    ) -> None:
        """Fill background pixels with the z = 0 ground (ray-plane hit) or the sky.

        For a pixel ray r_c = K^-1 [u, v, 1] (unit optical z), the world ray is
        R_wc r_c from t_wc; it meets z = 0 at lambda = -t_z / (R_wc r_c)_z, and
        lambda is the depth along the optical axis.
        """
        if not np.any(background):
            return
        rays = self.rays_camera[background]  # (n, 3)
        R, t = T_cw[:3, :3], T_cw[:3, 3]
        dz = rays @ R[2]
        with np.errstate(divide="ignore", invalid="ignore"):
            lam = np.where(dz < -1e-9, -t[2] / dz, np.inf)
        hit = np.isfinite(lam) & (lam <= self.camera.render_far_m)
        colours = np.empty((rays.shape[0], 3))
        colours[:] = style.sky_rgb
        if np.any(hit):
            xy = t[:2] + lam[hit, None] * (rays[hit] @ R[:2].T)
            checker = (np.floor(xy[:, 0]).astype(np.int64) + np.floor(xy[:, 1]).astype(np.int64)) & 1
            shade = style.ambient + style.diffuse * max(light[2], 0.0)
            base = np.asarray(style.ground_rgb) * shade
            colours[hit] = base * (1.0 - style.ground_checker_contrast * checker)[:, None]
        rgb[background] = np.clip(colours * 255.0 + 0.5, 0, 255).astype(np.uint8)
        d = depth[background]
        d[hit] = lam[hit]
        d[~hit] = np.inf
        depth[background] = d
