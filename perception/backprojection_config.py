"""The settings of back-projection (:mod:`perception.backprojection`), in a module of their own.

Reading a scenario builds them, and this module imports nothing heavier than
numpy's checks, where :mod:`perception.backprojection` loads the tracker
(scipy's assignment solver, the compiled Kalman kernels).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

from sim.checks import ConfigError

__all__ = ["BackprojectionConfig"]


@dataclass(frozen=True)
class BackprojectionConfig:
    """How depth is read from a box and how uncertain the result is.

    Class constants (:data:`typing.ClassVar`, not fields: no scenario, sweep or
    preset sets them, so a scenario file that names one is refused as an
    unknown key; docs/design.md section 7): every attribute but the two pose
    terms, which :mod:`mpcde.config.resolve` derives from the scenario's
    ``pose_estimate``. The depth-noise pair is the measurement model's, equal
    to the default camera's (``sim.camera.CameraConfig``), not derived from the
    scenario's camera. A test that needs another value overrides one in a
    subclass.

    Attributes:
        window_fraction: side of the central sub-window relative to the box side, in (0, 1].
        foreground_percentile: percentile of the window depths taken as the foreground level, in [0, 50].
        band_m: half width [m] of the foreground band beyond sensor noise.
        surface_to_centre_m: mean distance [m] from the seen surface to the drone centre along the ray.
        depth_noise_base_m: depth noise std at zero range [m] (the D435 model of sim/camera.py).
        depth_noise_quadratic_per_m: depth noise growth q [1/m], std = base + q z^2.
        model_std_m: std [m] of the surface-to-centre offset (the drone's half size).
        centre_std_px: std [px] of the box centre at any size.
        centre_std_box_fraction: extra box-centre std per box side [px/px].
        across_floor_m: std floor [m] across the ray.
        pose_pos_std_m: white-noise std per axis [m] of the drone's own position
            estimate (the VIO's reported uncertainty; default: that of
            ``sim.pose_estimate.PoseEstimateConfig``).
        pose_yaw_std_rad: white-noise std [rad] of the drone's own heading estimate
            (default: ``sim.pose_estimate.PoseEstimateConfig``).
    """

    window_fraction: ClassVar[float] = 0.5
    foreground_percentile: ClassVar[float] = 20.0
    band_m: ClassVar[float] = 0.1
    surface_to_centre_m: ClassVar[float] = 0.03
    depth_noise_base_m: ClassVar[float] = 0.002
    depth_noise_quadratic_per_m: ClassVar[float] = 0.0025
    model_std_m: ClassVar[float] = 0.01
    centre_std_px: ClassVar[float] = 0.15
    centre_std_box_fraction: ClassVar[float] = 0.02
    across_floor_m: ClassVar[float] = 0.0
    pose_pos_std_m: float = 0.01
    pose_yaw_std_rad: float = 0.002

    def __post_init__(self) -> None:
        if not 0.0 < self.window_fraction <= 1.0:
            raise ConfigError("window_fraction", self.window_fraction, "in (0, 1]")
        if not 0.0 <= self.foreground_percentile <= 50.0:
            raise ConfigError("foreground_percentile", self.foreground_percentile, "in [0, 50]")
        for name in ("band_m", "surface_to_centre_m", "depth_noise_base_m", "depth_noise_quadratic_per_m", "model_std_m",
                     "centre_std_px", "centre_std_box_fraction", "across_floor_m", "pose_pos_std_m", "pose_yaw_std_rad"):
            if not getattr(self, name) >= 0.0:
                raise ConfigError(name, getattr(self, name), "must be >= 0")
