"""The forward RGB-D camera: configuration, intrinsics, and the only conversions
between PyBullet's OpenGL camera and the OpenCV optical frame / metric depth.

Conventions:
    * ``K`` follows OpenCV: pixel centres at integer coordinates, so a
      W x H image has its centre at ``((W - 1) / 2, (H - 1) / 2)``.
    * camera frame: x right, y down, z forward (OpenCV optical).
    * ``depth_m``: metric depth along the optical axis [m] (z in the camera
      frame), NaN where invalid.
    * ``depth_buffer``: PyBullet's non-linear z-buffer in [0, 1].
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from sim.checks import ConfigError

__all__ = [
    "VIEW",
    "CameraConfig",
    "apply_depth_sensor_model",
    "depth_buffer_to_depth_m",
    "intrinsics",
    "opengl_projection_from_intrinsics",
    "opengl_view_from_camera_to_world",
    "rotation_camera_to_body",
]

VIEW = ("visible", "outside horizontal view", "outside vertical view", "beyond depth range", "behind an obstacle")
"""Where a point truly is for a camera, by index (``FlightSession.view_of``): in view, or the first test that failed
(in front of the camera and within its horizontal field of view, a point behind the image plane counting as
outside it; within the vertical one; within the depth range; unoccluded)."""


@dataclass(frozen=True)
class CameraConfig:
    """Per-drone forward camera (defaults: Intel RealSense D435i, as in MP-CDE).

    Attributes:
        width_px: image width [px].
        height_px: image height [px].
        hfov_deg: horizontal field of view [deg] (D435i: 85).
        vfov_deg: vertical field of view [deg] (D435i: 58). With 320 x 240
            the pixels are not square (fx != fy); K says so.
        rate_hz: capture rate [Hz] (MP-CDE perception: 25 Hz).
        depth_min_m: nearest valid depth [m]; nearer pixels are NaN.
        depth_max_m: farthest valid depth [m]; farther pixels are NaN.
        depth_noise_base_m: depth noise std at zero range [m].
        depth_noise_quadratic_per_m: stereo depth noise grows as z^2: std =
            base + q z^2 [1/m] (D435: subpixel 0.08 px at 50 mm baseline gives
            q ~ 0.0025 at 640 px width).
        invalid_pixel_fraction: share of random valid pixels dropped to NaN
            (stereo matching holes).
        mount_offset_body_m: camera position in the body frame (3,) [m].
        mount_pitch_deg: camera pitch down from the body x axis [deg].
        latency_s: time from capture to delivery to the drone [s]; the render
            of the next frame overlaps with this.
        render_far_m: far clipping plane of the RGB render [m] (objects
            beyond ``depth_max_m`` still show in colour).
        renderer: ``"raycast"`` (default: the analytic renderer of
            :mod:`sim.rendering.raycast`, exact depth) or ``"tiny"``
            (PyBullet's TinyRenderer, :mod:`sim.rendering.tiny`, whose images the
            shipped detector was trained on); their cost and the detector's
            scores on each are in ``docs/results/realtime.md#the-analytic-renderer``.
    """

    width_px: int = 320
    height_px: int = 240
    hfov_deg: float = 85.0
    vfov_deg: float = 58.0
    rate_hz: float = 25.0
    depth_min_m: float = 0.2
    depth_max_m: float = 10.0
    depth_noise_base_m: float = 0.002
    depth_noise_quadratic_per_m: float = 0.0025
    invalid_pixel_fraction: float = 0.0
    mount_offset_body_m: tuple[float, float, float] = (0.07, 0.0, 0.01)
    mount_pitch_deg: float = 0.0
    latency_s: float = 0.04
    render_far_m: float = 30.0
    renderer: str = "raycast"

    def __post_init__(self) -> None:
        for name in ("width_px", "height_px"):
            v = getattr(self, name)
            if not (isinstance(v, int) and 16 <= v <= 4096):
                raise ConfigError(name, v, "an integer in [16, 4096]")
        for name in ("hfov_deg", "vfov_deg"):
            v = getattr(self, name)
            if not 1.0 <= v <= 170.0:
                raise ConfigError(name, v, "a field of view in [1, 170] deg")
        if not self.rate_hz > 0:
            raise ConfigError("rate_hz", self.rate_hz, "must be > 0")
        if not 0 < self.depth_min_m < self.depth_max_m:
            raise ConfigError("depth_max_m", self.depth_max_m, f"must exceed depth_min_m={self.depth_min_m!r} > 0")
        if self.render_far_m < self.depth_max_m:
            raise ConfigError("render_far_m", self.render_far_m, f"must be >= depth_max_m={self.depth_max_m!r}")
        if self.depth_noise_base_m < 0 or self.depth_noise_quadratic_per_m < 0:
            bad = "depth_noise_base_m" if self.depth_noise_base_m < 0 else "depth_noise_quadratic_per_m"
            raise ConfigError(bad, getattr(self, bad), "a number >= 0")
        if not 0.0 <= self.invalid_pixel_fraction < 1.0:
            raise ConfigError("invalid_pixel_fraction", self.invalid_pixel_fraction, "in [0, 1)")
        if self.latency_s < 0:
            raise ConfigError("latency_s", self.latency_s, "must be >= 0")
        if self.renderer not in ("tiny", "raycast"):
            raise ConfigError("renderer", self.renderer, "allowed 'tiny' or 'raycast'")

    @property
    def render_near_m(self) -> float:
        """Near clipping plane of the render [m] (below ``depth_min_m``)."""
        return min(0.05, 0.5 * self.depth_min_m)


def intrinsics(cfg: CameraConfig) -> np.ndarray:
    """Pinhole intrinsics K (3, 3) for ``cfg`` (OpenCV convention)."""
    fx = (cfg.width_px / 2.0) / np.tan(np.radians(cfg.hfov_deg) / 2.0)
    fy = (cfg.height_px / 2.0) / np.tan(np.radians(cfg.vfov_deg) / 2.0)
    return np.array([[fx, 0.0, (cfg.width_px - 1) / 2.0], [0.0, fy, (cfg.height_px - 1) / 2.0], [0.0, 0.0, 1.0]])


def rotation_camera_to_body(mount_pitch_deg: float = 0.0) -> np.ndarray:
    """(3, 3) rotation from the camera optical frame to the body frame.

    Optical z = body x (forward), optical x = -body y (right), optical y =
    -body z (down), then pitched down by ``mount_pitch_deg`` about body y.
    """
    R0 = np.array([[0.0, 0.0, 1.0], [-1.0, 0.0, 0.0], [0.0, -1.0, 0.0]])
    a = np.radians(mount_pitch_deg)
    pitch_down = np.array([[np.cos(a), 0.0, np.sin(a)], [0.0, 1.0, 0.0], [-np.sin(a), 0.0, np.cos(a)]])
    return pitch_down @ R0


def opengl_view_from_camera_to_world(transform_camera_to_world: np.ndarray) -> list[float]:
    """PyBullet view matrix (16 floats, column-major) for an OpenCV camera pose.

    The OpenGL camera looks down its -z with y up: T_gl_from_cv = diag(1, -1, -1).
    view = T_gl_from_cv @ inv(transform_camera_to_world).
    """
    T = np.asarray(transform_camera_to_world, float)
    R, t = T[:3, :3], T[:3, 3]
    view = np.eye(4)
    view[:3, :3] = R.T
    view[:3, 3] = -R.T @ t
    view = np.diag([1.0, -1.0, -1.0, 1.0]) @ view
    return view.T.reshape(-1).tolist()


def opengl_projection_from_intrinsics(K: np.ndarray, width_px: int, height_px: int, near_m: float, far_m: float) -> list[float]:
    """PyBullet projection matrix (16 floats, column-major) reproducing K exactly.

    With this matrix the window coordinates are ``x_w = fx X/Z + cx_gl`` and
    ``y_w = H - fy Y/Z - cy_gl`` (camera frame X right, Y down, Z forward).
    PyBullet's TinyRenderer covers pixel column ``i`` when its centre
    ``x_w = i`` is inside a triangle (centres at integer window coordinates,
    not at +0.5 as in OpenGL proper) and stores window row ``y_w`` as image
    row ``H - 1 - y_w``. OpenCV's pixel ``(u, v)`` has its centre at integer
    ``(u, v)``, so K is reproduced with ``cx_gl = cx`` and ``cy_gl = cy + 1``.
    Measured (``tests/unit/sim/test_camera.py``): the silhouette edges of boxes
    fall within the first covered pixel, with no half-pixel shift
    (``c_gl = c + 0.5`` would shift every render by +0.5 px in u and -0.5 px
    in v, which back-projection reads as a lateral bias). With image
    row 0 at the top::

        P = [[2 fx / W, 0, 1 - 2 cx_gl / W, 0],
             [0, 2 fy / H, 2 cy_gl / H - 1, 0],
             [0, 0, -(f + n) / (f - n), -2 f n / (f - n)],
             [0, 0, -1, 0]]
    """
    fx, fy = K[0, 0], K[1, 1]
    cx, cy = K[0, 2], K[1, 2] + 1.0  # TinyRenderer's pixel centres and row flip (docstring)
    W, H, n, f = float(width_px), float(height_px), float(near_m), float(far_m)
    P = np.array(
        [
            [2 * fx / W, 0.0, 1.0 - 2 * cx / W, 0.0],
            [0.0, 2 * fy / H, 2 * cy / H - 1.0, 0.0],
            [0.0, 0.0, -(f + n) / (f - n), -2 * f * n / (f - n)],
            [0.0, 0.0, -1.0, 0.0],
        ]
    )
    return P.T.reshape(-1).tolist()


def depth_buffer_to_depth_m(depth_buffer: np.ndarray, near_m: float, far_m: float) -> np.ndarray:
    """Metric depth along the optical axis [m] from PyBullet's z-buffer in [0, 1].

    z = f n / (f - (f - n) d); the far plane (d = 1, nothing rendered) maps to ``far_m``.
    """
    d = np.asarray(depth_buffer, np.float64)
    return (far_m * near_m / (far_m - (far_m - near_m) * d)).astype(np.float32)


def apply_depth_sensor_model(depth_true_m: np.ndarray, rng: np.random.Generator, cfg: CameraConfig) -> np.ndarray:
    """Noisy, range-limited depth [m] (H, W) float32 from the true depth (H, W).

    std(z) = base + q z^2 (stereo); pixels outside [depth_min_m, depth_max_m]
    (after noise) and a random ``invalid_pixel_fraction`` are NaN.
    """
    z = np.asarray(depth_true_m, np.float32)
    invalid = ~((z >= cfg.depth_min_m) & (z <= cfg.depth_max_m))  # also catches inf (sky)
    z_valid = np.where(invalid, np.float32(0.0), z)
    sigma = cfg.depth_noise_base_m + cfg.depth_noise_quadratic_per_m * z_valid * z_valid
    noisy = z_valid + sigma * rng.standard_normal(z.shape, dtype=np.float32)
    if cfg.invalid_pixel_fraction > 0:
        invalid |= rng.random(z.shape, dtype=np.float32) < cfg.invalid_pixel_fraction
    noisy[invalid] = np.nan
    return noisy
