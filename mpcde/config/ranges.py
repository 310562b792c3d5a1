"""The physical range of every number of the components' settings (:mod:`mpcde.config.bounds` says how they apply).

Ranges are deliberately wide (what a researcher may try), not tuned defaults;
each class's own ``__post_init__`` keeps the checks that make it consistent.
The scenario's own sections add theirs in :mod:`mpcde.config.scenario`.
"""

from __future__ import annotations

import math

from mpcde.config.admm import AdmmAgentConfig
from mpcde.config.auto import AutoAgentConfig, FusionConfig
from mpcde.config.denied import DeniedAgentConfig
from mpcde.config.dmpc import CommQpConfig, DmpcAgentConfig
from mpcde.config.mlr import MlrAgentConfig
from perception.backprojection_config import BackprojectionConfig
from perception.map_config import MapConfig
from perception.tracker_config import TrackerConfig
from planners.dmpc.config import DmpcConfig
from planners.limits import KinematicLimits
from planners.yaw.config import YawPlannerConfig
from sim.camera import CameraConfig
from sim.faults import FaultsConfig
from sim.pose_estimate import PoseEstimateConfig
from sim.radio import RadioConfig
from sim.vehicle.params import QuadrotorParams
from sim.vehicle.physics_config import PhysicsConfig

from mpcde.config.bounds import Bound as B

__all__ = ["RANGES"]

PI = math.pi

RANGES: dict[type, dict[str, B]] = {
    FaultsConfig: {
        "frame_drop_probability": B(0, 1), "frame_drop_burst_frames": B(1, 1000, "frames"), "frame_drop_windows_s": B(-1, 3600),
        "detector_miss_probability": B(0, 1), "detector_false_positive_rate": B(0, 50, "per frame"), "drone_failures": B(0, 3600),
    },
    CameraConfig: {
        "width_px": B(16, 1920, "px"), "height_px": B(16, 1080, "px"), "hfov_deg": B(1, 170, "deg"), "vfov_deg": B(1, 170, "deg"),
        "rate_hz": B(0.5, 120, "Hz"), "depth_min_m": B(0.01, 10, "m"), "depth_max_m": B(0.1, 100, "m"),
        "depth_noise_base_m": B(0, 1, "m"), "depth_noise_quadratic_per_m": B(0, 1, "1/m"), "invalid_pixel_fraction": B(0, 1),
        "mount_offset_body_m": B(-1, 1, "m"), "mount_pitch_deg": B(-90, 90, "deg"), "latency_s": B(0, 1, "s"),
        "render_far_m": B(1, 1000, "m"),
    },
    RadioConfig: {
        "rate_hz": B(0.1, 100, "Hz"), "delay_s": B(0, 10, "s"), "loss_probability": B(0, 1), "ge_p_good_to_bad": B(0, 1),
        "ge_p_bad_to_good": B(0, 1), "ge_loss_good": B(0, 1), "ge_loss_bad": B(0, 1),
        "range_m": B(0, 10_000, "m", inf="no range limit"), "jamming_windows_s": B(0, 3600, "s"),
    },
    PoseEstimateConfig: {
        "pos_noise_m": B(0, 10, "m"), "vel_noise_mps": B(0, 10, "m/s"), "yaw_noise_rad": B(0, 1, "rad"),
        "pos_drift_m_per_sqrt_s": B(0, 1, "m/sqrt(s)"), "yaw_drift_rad_per_sqrt_s": B(0, 1, "rad/sqrt(s)"),
    },
    PhysicsConfig: {
        "physics_hz": B(50, 2000, "Hz"), "crash_tilt_rad": B(0.1, PI, "rad"),
    },
    QuadrotorParams: {
        "mass_kg": B(0.01, 100, "kg"), "inertia_kgm2": B(1e-6, 10, "kg m^2"), "arm_length_m": B(0.01, 2, "m"),
        "thrust_coeff": B(1e-10, 1e-2, "N s^2"), "torque_coeff": B(1e-12, 1e-3, "N m s^2"),
        "motor_speed_max_radps": B(10, 100_000, "rad/s"), "motor_time_constant_s": B(0, 1, "s"),
        "linear_drag_coeff": B(0, 10, "N s/m"), "robot_radius_m": B(0.01, 2, "m"), "motor_dirs": B(-1, 1),
        "motor_angles_rad": B(-2 * PI, 2 * PI, "rad"),
    },
    TrackerConfig: {
        "alpha_ema": B(0, 1), "sigma_acc_mps2": B(0, 100, "m/s^2"), "sigma_acc_max_mps2": B(0, 100, "m/s^2"),
        "gate_chi2": B(0, 10_000), "t_hold_s": B(0, 60, "s"), "t_drop_s": B(0, 60, "s"),
    },
    BackprojectionConfig: {
        "pose_pos_std_m": B(0, 10, "m"), "pose_yaw_std_rad": B(0, 1, "rad"),
    },
    DeniedAgentConfig: {
        "clearance_m": B(0, 5, "m"),
        "front_end_clearance_m": B(0, 5, "m"), "replan_period_s": B(0.02, 10, "s"), "yaw_rate_max_radps": B(0, 20, "rad/s"),
        "start_delay_s": B(0, 60, "s"), "swarm_clearance_m": B(0, 10, "m"), "swarm_z_scale": B(0.1, 10),
        "conflict_horizon_s": B(0, 30, "s"),
        "flight_level_spacing_m": B(0.05, 5, "m", inf="no flight levels"), "flight_level_release_m": B(0, 50, "m"),
        "fresh_path_age_s": B(0.01, 60, "s", inf="no look before moving"),
        "fresh_path_glance_age_s": B(0.01, 60, "s", inf="no glances"),
    },
    KinematicLimits: {
        "v_max_mps": B(0, 20, "m/s"), "a_max_mps2": B(0, 100, "m/s^2"), "j_max_mps3": B(0, 1000, "m/s^3", inf="no jerk limit"),
    },
    MapConfig: {
        "voxel_m": B(0.02, 2, "m"), "window_size_m": B(1, 100, "m"), "max_range_m": B(0.1, 100, "m"),
        "neighbour_exclusion_m": B(0, 10, "m"),
    },
    YawPlannerConfig: {
        "period_s": B(0.01, 10, "s"), "yaw_rate_max_radps": B(0, 20, "rad/s"), "alpha": B(0, 100), "beta": B(0, 100),
        "fov_h_deg": B(1, 170, "deg"), "fov_v_deg": B(1, 170, "deg"), "sensing_range_m": B(0.1, 100, "m"),
        "v_max_mps": B(0, 10, "m/s"), "t_hold_s": B(0, 60, "s"),
        "safety_horizon_s": B(0, 60, "s"), "free_max_age_s": B(0, 3600, "s", inf="free space never ages"),
        "tracking_sweep_deg": B(0, 180, "deg"), "tracking_sweep_period_s": B(0.1, 60, "s"),
    },
    DmpcConfig: {
        "horizon_steps": B(1, 100), "step_s": B(0.01, 5, "s"), "weight_goal": B(0, 1e8), "weight_formation": B(0, 1e8),
        "weight_smoothness": B(0, 1e8), "pos_min_world": B(-1000, 1000, "m"),
        "pos_max_world": B(-1000, 1000, "m"),
        "r_min_m": B(0, 10, "m"), "downwash": B(0.1, 10), "max_neighbours": B(1, 64), "max_obstacle_planes": B(0, 64),
    },
    DmpcAgentConfig: {
        "plan_timeout_s": B(0, 60, "s"), "obstacle_margin_m": B(0, 5, "m"), "obstacle_range_m": B(0, 100, "m"),
        "goal_lookahead_m": B(0, 1000, "m"), "state_tolerance_m": B(0, 10, "m"), "state_tolerance_mps": B(0, 10, "m/s"),
        "commit_range_m": B(0, 1000, "m"), "deadlock_turn_deg": B(0, 90, "deg"),
    },
    AutoAgentConfig: {
        "radio_silence_s": B(0, 60, "s"), "plan_memory_s": B(0, 60, "s"),
    },
    FusionConfig: {
        "stale_after_s": B(0, 60, "s"), "gate_m": B(0, 100, "m"),
    },
    MlrAgentConfig: {
        "num_compute_units": B(1, 32), "round_s": B(0.01, 5, "s"), "horizon_rounds": B(1, 100), "d_hat_min_m": B(0, 10, "m"),
        "downwash": B(0.1, 10),
        "altitude_range_m": B(0, 20, "m"), "arena_margin_m": B(0, 100, "m"),
    },
    AdmmAgentConfig: {
        "horizon_steps": B(1, 100), "step_s": B(0.01, 5, "s"), "l_max": B(1, 100), "rho": B(0, 1e6),
        "sqp_iterations": B(1, 100), "d_min_m": B(0, 10, "m"), "downwash": B(1, 10),
        "weight_formation": B(0, 1e8), "weight_tracking": B(0, 1e8), "weight_input": B(0, 1e8),
        "weight_terminal_formation": B(0, 1e8), "weight_terminal_tracking": B(0, 1e8), "weight_slack": B(0, 1e8),
        "altitude_range_m": B(0, 20, "m"),
        "arena_margin_m": B(0, 100, "m"), "max_start_offset_m": B(0, 100, "m"), "state_tolerance_m": B(0, 10, "m"),
        "state_tolerance_mps": B(0, 10, "m/s"),
    },
}
"""Settings class -> field -> its range."""
RANGES[CommQpConfig] = RANGES[DmpcConfig]  # the dmpc.qp section: DmpcConfig with the comm stack's defaults
