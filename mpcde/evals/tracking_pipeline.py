"""The ``pipeline`` measurement source of ``mpcde eval-tracking``: render -> detect -> back-project.

For one :class:`mpcde.evals.tracking.TrackingScenario` this renders, at every
frame time, the observer's forward RGB-D camera (:class:`sim.camera.CameraConfig`,
the renderer ``camera.renderer`` names, :func:`sim.rendering.pool.make_renderer`),
applies the depth sensor model (:func:`sim.rendering.camera_rig.sensor_depth`),
runs the shipped detector (:class:`perception.detector.detector.DroneDetector`,
batched over ``batch_frames`` frames) on the RGB-D frame alone and back-projects every
detection (MP-CDE Eq. 7-8, :func:`perception.backprojection.backproject`) with
the observer's *estimated* camera pose. The tracker then sees exactly what an
onboard tracker would: world-frame positions with their covariances, misses,
false positives and the self-localisation error.

Choices (written here because the issue is silent on them):

* **Targets.** The target drones are placed, frame by frame, at the scenario's
  flat-output path (position and velocity) with the attitude differential
  flatness gives for it (thrust axis along ``a + g e_z``, heading along the
  horizontal velocity; Mellinger & Kumar 2011), so they show the tilt a real
  flight at that acceleration would. They are rendered, not flown: this module
  evaluates perception and tracking, and a flown target would only add the
  controller's few-centimetre tracking error to a truth the tracker never sees.
* **Observer.** Hovers at the scenario's ``observer_pos_world`` with heading
  ``observer_yaw_rad``, level. Its camera pose
  comes from :class:`sim.pose_estimate.PoseEstimator` (default
  :class:`sim.pose_estimate.PoseEstimateConfig`: 1 cm white noise, 5 mm/sqrt(s)
  drift, 2 mrad heading noise), so measurements carry the observer's own
  localisation error as on a real drone; the truth they are scored against
  does not.
* **Background.** ``n_background_trees`` seeded trees 9-16 m in front of the
  observer, so detections have clutter behind them. No obstacle stands between
  the observer and the targets' region (occlusion between targets still
  happens).
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from mpcde.evals.tracking_scenario import TrackingScenario, camera_pose, hover_truth, in_camera_view
from perception.backprojection import BackprojectionConfig, backproject
from perception.tracker import Measurement
from sim.bullet.scene import SceneSpec
from sim.camera import CameraConfig
from sim.checks import ConfigError
from sim.pose_estimate import PoseEstimateConfig, PoseEstimator
from sim.rendering.camera_rig import CameraRig
from sim.rotations import quat_xyzw_from_rotation, rotation_from_thrust_axis_and_yaw
from sim.types import ObstacleSpec
from sim.vehicle.params import GRAVITY_MPS2

__all__ = ["PipelineMeasurements", "PipelineRun", "background_trees", "flat_attitudes"]

_TREE_COLOURS = ((0.45, 0.32, 0.2, 1.0), (0.3, 0.3, 0.3, 1.0), (0.25, 0.45, 0.2, 1.0), (0.6, 0.55, 0.45, 1.0))


def flat_attitudes(vel_world: np.ndarray, acc_world: np.ndarray) -> np.ndarray:
    """Body-to-world rotations (..., 3, 3) of quadrotors flying at ``vel_world`` with ``acc_world``.

    Differential flatness (Mellinger & Kumar 2011): the thrust axis is
    ``z_b = (a + g e_z) / |a + g e_z|`` and the heading follows the horizontal
    velocity (kept at +x world when the drone is nearly still).

    Args:
        vel_world: (..., 3) velocities [m/s].
        acc_world: (..., 3) accelerations [m/s^2].
    """
    thrust = np.asarray(acc_world, float) + np.array([0.0, 0.0, GRAVITY_MPS2])
    z_b = thrust / np.linalg.norm(thrust, axis=-1, keepdims=True)
    v = np.asarray(vel_world, float)
    yaw = np.where(np.hypot(v[..., 0], v[..., 1]) > 0.05, np.arctan2(v[..., 1], v[..., 0]), 0.0)
    return rotation_from_thrust_axis_and_yaw(z_b, yaw)


def background_trees(seed: int, n: int, observer_pos_world: np.ndarray, observer_yaw_rad: float) -> tuple[ObstacleSpec, ...]:
    """``n`` seeded trees 9-16 m ahead of the observer within +-40 deg of its heading."""
    rng = np.random.default_rng([seed, 0x7EE5])
    trees = []
    for _ in range(n):
        r, az = rng.uniform(9.0, 16.0), observer_yaw_rad + np.radians(rng.uniform(-40.0, 40.0))
        xy = np.asarray(observer_pos_world[:2], float) + r * np.array([np.cos(az), np.sin(az)])
        colour = _TREE_COLOURS[int(rng.integers(len(_TREE_COLOURS)))]
        trees.append(ObstacleSpec("tree", (float(xy[0]), float(xy[1])), float(rng.uniform(3.0, 6.0)), radius_m=float(rng.uniform(0.12, 0.4)), rgba=colour))
    return tuple(trees)


@dataclass(frozen=True)
class PipelineRun:
    """Measurements of one scenario and what happened on the way.

    Attributes:
        frames: per frame time, the back-projected measurements.
        n_detections: detections over all frames.
        n_without_depth: detections dropped for lack of valid depth.
        n_visible: (frame, target) pairs whose target centre is inside the camera's view
            (:func:`mpcde.evals.tracking.in_camera_view`, no margin).
    """

    frames: list[list[Measurement]]
    n_detections: int
    n_without_depth: int
    n_visible: int


@dataclass(frozen=True)
class PipelineMeasurements:
    """Render -> detect -> back-project measurements of a tracking scenario (see the module docstring).

    Attributes:
        name: the source's name in results (``"pipeline"``).
        camera: the observer's camera.
        pose_estimate: the observer's self-localisation error model.
        backprojection: depth window and covariance model of the back-projection;
            its pose-noise terms (``pose_pos_std_m``, ``pose_yaw_std_rad``) are
            replaced by ``pose_estimate``'s white noise, the uncertainty the
            observer's own localisation reports.
        weights: detector checkpoint; None: the shipped weights.
        n_background_trees: clutter trees behind the targets' region.
        batch_frames: frames per detector forward pass (as 6 drones' frames would be).
    """

    name: str = "pipeline"
    camera: CameraConfig = field(default_factory=CameraConfig)
    pose_estimate: PoseEstimateConfig = field(default_factory=PoseEstimateConfig)
    backprojection: BackprojectionConfig = field(default_factory=BackprojectionConfig)
    weights: str | None = None
    n_background_trees: int = 10
    batch_frames: int = 6
    _detector: Any = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        if not (isinstance(self.n_background_trees, int) and self.n_background_trees >= 0):
            raise ConfigError("n_background_trees", self.n_background_trees, "an integer >= 0")
        if not (isinstance(self.batch_frames, int) and self.batch_frames >= 1):
            raise ConfigError("batch_frames", self.batch_frames, "an integer >= 1")
        from perception.detector.detector import DroneDetector

        # loaded once: a missing or corrupt checkpoint fails at construction, and every run reuses it
        object.__setattr__(self, "_detector", DroneDetector.load(self.weights))

    def measure(self, scenario: TrackingScenario, seed: int) -> list[list[Measurement]]:
        """Per-frame measurements of ``scenario`` (seeded by ``seed``: depth noise, pose error, background)."""
        return self.run(scenario, seed).frames

    def run(self, scenario: TrackingScenario, seed: int) -> PipelineRun:
        """:meth:`measure` with the run's detection counts."""
        from sim.rendering.pool import make_renderer

        detector = self._detector
        times = np.asarray(scenario.times_s, float)
        pos = np.asarray(scenario.target_pos_world, float)
        vel = np.asarray(scenario.target_vel_world, float)
        n_frames, n_targets = pos.shape[:2]
        acc = np.gradient(vel, times, axis=0) if n_frames > 1 else np.zeros_like(vel)
        quat = quat_xyzw_from_rotation(flat_attitudes(vel, acc).reshape(-1, 3, 3)).reshape(n_frames, n_targets, 4)

        observer = np.asarray(scenario.observer_pos_world, float)
        yaw = float(scenario.observer_yaw_rad)
        rig = CameraRig(self.camera, seed)
        cam_pos_world, R_cw = camera_pose(scenario, self.camera)
        T_true = np.eye(4)
        T_true[:3, :3], T_true[:3, 3] = R_cw, cam_pos_world
        estimator = PoseEstimator(self.pose_estimate, 1, seed)
        pe = self.pose_estimate
        backprojection = replace(self.backprojection, pose_pos_std_m=pe.pos_noise_m, pose_yaw_std_rad=pe.yaw_noise_rad)
        spec = SceneSpec(obstacles=background_trees(seed, self.n_background_trees, observer, yaw), n_drones=n_targets)
        renderer = make_renderer(spec, self.camera)
        frames: list[list[Measurement]] = []
        n_det = n_nodepth = n_visible = 0
        pending = []
        try:
            for k, t in enumerate(times):
                renderer.set_drone_poses(pos[k], quat[k])
                raw = renderer.render(T_true, own_drone=None)
                n_visible += int(np.count_nonzero(in_camera_view(pos[k], cam_pos_world, R_cw, self.camera, 0.0)))
                estimate = estimator.update(hover_truth(float(t), observer, yaw))[0]
                pending.append(rig.frame(0, k, float(t), raw, estimate))  # depth noise seeded by (seed, 0, k)
                if len(pending) == self.batch_frames or k == n_frames - 1:
                    for frame, dets in zip(pending, detector.detect(pending)):
                        result = backproject(frame, dets, backprojection)
                        n_det += len(dets)
                        n_nodepth += int(result.skipped.size)
                        frames.append(list(result.measurements))
                    pending = []
        finally:
            renderer.close()
        return PipelineRun(frames=frames, n_detections=n_det, n_without_depth=n_nodepth, n_visible=n_visible)

