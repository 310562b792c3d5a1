"""Render the forward cameras of a scene in one PyBullet DIRECT client.

Obstacles and drones are rasterised by PyBullet's TinyRenderer through a
projection matrix that reproduces K exactly; the ground plane z = 0 and the
sky are then drawn analytically into the pixels nothing covered (ray-plane
intersection per pixel). This is exact: every surface lies above z = 0, so it
always occludes the ground behind it. A render client never steps physics; it
only receives poses.

A render depends only on its inputs, never on what the client rendered before,
so a flight does not depend on how cameras are spread over render workers
(``run.render_workers``). Two PyBullet behaviours had to be worked around:

- TinyRenderer's output depends on the parity of the number of
  ``getCameraImage`` calls the client has made: one colour channel of about one
  pixel in a thousand renders comes out 1 lower or higher on odd calls, enough
  to change a perceiving flight with the number of render workers. Each render
  is therefore followed by a 1x1 call (a small fraction of a 320 x 240
  render's time), so every real render is an even call.
- ``getBasePositionAndOrientation`` does not round-trip exactly through
  ``resetBasePositionAndOrientation`` (the base pose passes through the
  centre-of-mass frame; ~1e-16 m), so the drone hidden during its own camera's
  render is put back from the pose it was given, not from the one read back.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numba import njit

from sim.bullet import pb
from sim.bullet.scene import RenderStyle, SceneSpec, build_obstacles, load_drones
from sim.camera import (
    CameraConfig,
    intrinsics,
    opengl_projection_from_intrinsics,
    opengl_view_from_camera_to_world,
)

__all__ = ["RawRender", "SceneRenderer", "ground_distance", "ground_tile", "style_lighting"]

PARKED_POS = [0.0, 0.0, -100.0]  # where a camera's own drone waits during its render
_PARITY_PX = 1  # size of the call that keeps every real render an even getCameraImage call (module docstring)


@dataclass(frozen=True)
class RawRender:
    """Noise-free render of one camera.

    Attributes:
        rgb: (H, W, 3) uint8.
        depth_true_m: (H, W) float32 depth along the optical axis [m]; ``inf``
            where nothing is hit (sky).
        drone_index_mask: (H, W) int16, drone index or -1.
        depth_sensor_m: (H, W) float32 sensor-model depth [m] (NaN invalid),
            when the render pool was asked to apply the sensor model; else None.
    """

    rgb: np.ndarray
    depth_true_m: np.ndarray
    drone_index_mask: np.ndarray
    depth_sensor_m: np.ndarray | None = None


class SceneRenderer:
    """A render-only PyBullet client holding a copy of the scene."""

    def __init__(self, spec: SceneSpec, camera: CameraConfig) -> None:
        self.spec = spec
        self.camera = camera
        self.client = pb.connect(pb.DIRECT)
        build_obstacles(self.client, spec.obstacles, with_collision=False)
        n = spec.n_drones
        self.drone_ids = load_drones(self.client, spec, np.tile(PARKED_POS, (n, 1)), np.tile([0, 0, 0, 1.0], (n, 1)), fixed=True)
        self.lut_body_to_drone = np.full(max(self.drone_ids, default=0) + 2, -1, np.int16)
        for i, b in enumerate(self.drone_ids):
            self.lut_body_to_drone[b + 1] = i
        self.K = intrinsics(camera)
        W, H = camera.width_px, camera.height_px
        self.projection = opengl_projection_from_intrinsics(self.K, W, H, camera.render_near_m, camera.render_far_m)
        # ray directions in the camera frame with unit z, K^-1 [u, v, 1], kept separable:
        # x depends on the column only, y on the row only
        self.ray_x = ((np.arange(W) - self.K[0, 2]) / self.K[0, 0]).astype(np.float32)[None, :]
        self.ray_y = ((np.arange(H) - self.K[1, 2]) / self.K[1, 1]).astype(np.float32)[:, None]
        # the poses last set, as given (a hidden drone is put back from here; module docstring)
        self._poses = [(list(PARKED_POS), [0.0, 0.0, 0.0, 1.0]) for _ in self.drone_ids]

    def close(self) -> None:
        """Disconnect the client."""
        if self.client is not None and pb.isConnected(self.client):
            pb.disconnect(self.client)
        self.client = None

    def set_drone_poses(self, pos_world: np.ndarray, quat_xyzw: np.ndarray) -> None:
        """Place all drones: (N, 3) positions [m], (N, 4) quaternions."""
        self._poses = [(np.asarray(pos_world[i], float).tolist(), np.asarray(quat_xyzw[i], float).tolist()) for i in range(len(self.drone_ids))]
        for b, (pos, quat) in zip(self.drone_ids, self._poses):
            pb.resetBasePositionAndOrientation(b, pos, quat, physicsClientId=self.client)

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
        if own_drone is not None:
            pb.resetBasePositionAndOrientation(self.drone_ids[own_drone], PARKED_POS, [0, 0, 0, 1], physicsClientId=self.client)
        light, light_tile, dark_tile, sky = style_lighting(style)
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
        pb.getCameraImage(_PARITY_PX, _PARITY_PX, renderer=pb.ER_TINY_RENDERER, physicsClientId=self.client)
        if own_drone is not None:
            pos, quat = self._poses[own_drone]
            pb.resetBasePositionAndOrientation(self.drone_ids[own_drone], pos, quat, physicsClientId=self.client)
        T_cw = transform_camera_to_world
        rgb, depth, mask = _compose(
            np.asarray(rgba, np.uint8).reshape(H, W, 4), np.asarray(zbuf, np.float32).reshape(H, W), np.asarray(seg, np.int32).reshape(H, W),
            self.lut_body_to_drone, float(cam.render_near_m), float(cam.render_far_m), self.ray_x[0], self.ray_y[:, 0],
            np.ascontiguousarray(T_cw[:3, :3], dtype=float), np.ascontiguousarray(T_cw[:3, 3], dtype=float), light_tile, dark_tile, sky,
        )
        return RawRender(rgb=rgb, depth_true_m=depth, drone_index_mask=mask)


def style_lighting(style: RenderStyle) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Unit light direction (3,) and the uint8 (3,) colours of the ground's light and dark checker tiles and the sky.

    The ground is a horizontal plane lit like TinyRenderer's diffuse surfaces:
    ``ground_rgb (ambient + diffuse max(l_z, 0))``, the dark tiles darker by ``ground_checker_contrast``.
    """
    light = np.asarray(style.light_direction, float)
    light = light / np.linalg.norm(light)
    shade = style.ambient + style.diffuse * max(light[2], 0.0)
    light_tile = np.clip(np.asarray(style.ground_rgb) * shade * 255.0 + 0.5, 0, 255).astype(np.uint8)
    dark_tile = np.clip(np.asarray(style.ground_rgb) * shade * (1.0 - style.ground_checker_contrast) * 255.0 + 0.5, 0, 255).astype(np.uint8)
    sky = np.clip(np.asarray(style.sky_rgb) * 255.0 + 0.5, 0, 255).astype(np.uint8)
    return light, light_tile, dark_tile, sky


@njit(cache=True)
def _compose(rgba, zbuf, seg, lut, near_m, far_m, ray_x, ray_y, R, t, light_tile, dark_tile, sky):  # pragma: no cover - compiled
    """One pass over TinyRenderer's buffers: rgb (H, W, 3) uint8, depth (H, W) float32 [m], drone mask (H, W) int16.

    Depth along the optical axis from the z-buffer d in [0, 1]:
    z = f n / (f - (f - n) d) (:func:`sim.camera.depth_buffer_to_depth_m`,
    same float64 arithmetic). ``seg`` holds PyBullet body ids (-1: nothing);
    ``lut[id + 1]`` is the drone index or -1. Every background pixel (nothing
    rasterised) gets the ground z = 0 or the sky:

    The pixel ray r_c = K^-1 [u, v, 1] = [ray_x[u], ray_y[v], 1] (unit optical z)
    goes along d_w = R_wc r_c from t_wc and meets z = 0 at
    lambda = -t_z / d_w,z (when d_w,z < 0); lambda is the depth along the
    optical axis. The ground shows a 1 m checker.
    """
    H, W = zbuf.shape
    rgb = np.empty((H, W, 3), np.uint8)
    depth = np.empty((H, W), np.float32)
    mask = np.empty((H, W), np.int16)
    n_lut = lut.shape[0]
    for v in range(H):
        for u in range(W):
            body = seg[v, u]
            if body >= 0:
                for c in range(3):
                    rgb[v, u, c] = rgba[v, u, c]
                depth[v, u] = np.float32(far_m * near_m / (far_m - (far_m - near_m) * np.float64(zbuf[v, u])))
                mask[v, u] = lut[min(body + 1, n_lut - 1)]
                continue
            mask[v, u] = -1
            dx = R[0, 0] * ray_x[u] + R[0, 1] * ray_y[v] + R[0, 2]
            dy = R[1, 0] * ray_x[u] + R[1, 1] * ray_y[v] + R[1, 2]
            dz = R[2, 0] * ray_x[u] + R[2, 1] * ray_y[v] + R[2, 2]
            lam = ground_distance(t[2], dz)
            tile = ground_tile(t[0], t[1], dx, dy, lam, far_m)
            colour = sky if tile == 2 else (dark_tile if tile == 1 else light_tile)
            rgb[v, u, 0], rgb[v, u, 1], rgb[v, u, 2] = colour[0], colour[1], colour[2]
            depth[v, u] = lam if tile != 2 else np.inf
    return rgb, depth, mask


@njit(cache=True)
def ground_distance(t_z, dz):  # pragma: no cover - compiled
    """Ray parameter lambda [m] at which a ray from height ``t_z`` with vertical component ``dz`` meets z = 0 (inf: never)."""
    if dz < -1e-9:
        return -t_z / dz
    return np.inf


@njit(cache=True)
def ground_tile(t_x, t_y, dx, dy, lam, far_m):  # pragma: no cover - compiled
    """What a background pixel shows at ray parameter ``lam`` [m]: 0 the light tile of the 1 m checker, 1 the dark one, 2 the sky (beyond ``far_m``).

    Scalars only, so the per-pixel call costs no array reference counting.
    """
    if lam > far_m:
        return 2
    return (int(np.floor(t_x + lam * dx)) + int(np.floor(t_y + lam * dy))) & 1
