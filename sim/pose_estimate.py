"""Each drone's estimate of its own pose: truth plus noise and drift (a VIO stand-in).

Model per drone (all seeded):
    * position drift b_p: random walk, db_p = sigma_drift_pos dW  [m / sqrt(s)]
    * heading drift b_yaw: random walk, db_yaw = sigma_drift_yaw dW  [rad / sqrt(s)]
    * white noise on position, velocity and heading at every estimate.
The estimate is p_hat = p + b_p + n_p, yaw_hat = yaw + b_yaw + n_yaw (applied
as a rotation about world z), v_hat = v + n_v. Drift integrates with the time
between calls, so the same call times give the same estimates.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from sim.checks import ConfigError
from sim.ground_truth import TrueState
from sim.rotations import quat_xyzw_from_rotation
from sim.types import PoseEstimate

__all__ = ["PoseEstimateConfig", "PoseEstimator"]


@dataclass(frozen=True)
class PoseEstimateConfig:
    """Self-localisation error model.

    Attributes:
        pos_noise_m: white position noise std per axis [m].
        vel_noise_mps: white velocity noise std per axis [m/s].
        yaw_noise_rad: white heading noise std [rad].
        pos_drift_m_per_sqrt_s: position random-walk intensity [m/sqrt(s)].
        yaw_drift_rad_per_sqrt_s: heading random-walk intensity [rad/sqrt(s)].
    """

    pos_noise_m: float = 0.01
    vel_noise_mps: float = 0.02
    yaw_noise_rad: float = 0.002
    pos_drift_m_per_sqrt_s: float = 0.005
    yaw_drift_rad_per_sqrt_s: float = 0.001

    def __post_init__(self) -> None:
        for name in ("pos_noise_m", "vel_noise_mps", "yaw_noise_rad", "pos_drift_m_per_sqrt_s", "yaw_drift_rad_per_sqrt_s"):
            v = getattr(self, name)
            if not (np.isfinite(v) and v >= 0):
                raise ConfigError(name, v, "a finite value >= 0")


class PoseEstimator:
    """Pose estimates of N drones; one verb, :meth:`update`."""

    def __init__(self, config: PoseEstimateConfig, n_drones: int, seed: int) -> None:
        self.config = config
        self.rng = np.random.default_rng([seed, 0x905E])
        self.bias_pos_world = np.zeros((n_drones, 3))
        self.bias_yaw = np.zeros(n_drones)
        self.last_time_s = 0.0
        self.latest: list[PoseEstimate] | None = None

    def update(self, truth: TrueState) -> list[PoseEstimate]:
        """Advance the drift to ``truth.time_s`` and return one estimate per drone."""
        c = self.config
        n = truth.pos_world.shape[0]
        dt = max(truth.time_s - self.last_time_s, 0.0)
        self.last_time_s = truth.time_s
        self.bias_pos_world += c.pos_drift_m_per_sqrt_s * np.sqrt(dt) * self.rng.standard_normal((n, 3))
        self.bias_yaw += c.yaw_drift_rad_per_sqrt_s * np.sqrt(dt) * self.rng.standard_normal(n)
        pos = truth.pos_world + self.bias_pos_world + c.pos_noise_m * self.rng.standard_normal((n, 3))
        vel = truth.vel_world + c.vel_noise_mps * self.rng.standard_normal((n, 3))
        dyaw = self.bias_yaw + c.yaw_noise_rad * self.rng.standard_normal(n)
        cz, sz = np.cos(dyaw), np.sin(dyaw)
        Rz = np.zeros((n, 3, 3))
        Rz[:, 0, 0], Rz[:, 0, 1], Rz[:, 1, 0], Rz[:, 1, 1], Rz[:, 2, 2] = cz, -sz, sz, cz, 1.0
        R_hat = Rz @ truth.rotation_body_to_world
        quat = quat_xyzw_from_rotation(R_hat)
        self.latest = [
            PoseEstimate(
                time_s=truth.time_s,
                pos_world=pos[i],
                vel_world=vel[i],
                quat_xyzw=quat[i],
                ang_vel_body=truth.ang_vel_body[i].copy(),
            )
            for i in range(n)
        ]
        return self.latest
