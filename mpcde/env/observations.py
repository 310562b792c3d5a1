"""What a learner observes of its drone: the spaces and the observation dict (all onboard).

An observation is a ``gymnasium.spaces.Dict``; ``time_s`` is always there,
the other entries are chosen by :attr:`mpcde.env.options.EnvOptions.observe`:

* ``time_s`` (1,) float64: the drone's clock [s].
* ``pose``: its own pose estimate (the VIO stand-in, updated at every camera
  tick): ``time_s`` (1,), ``pos_world`` (3,) [m], ``vel_world`` (3,) [m/s],
  ``quat_xyzw`` (4,) body->world, ``ang_vel_body`` (3,) [rad/s]; float64.
* ``goal`` (3,) float64: its goal [m].
* ``camera``: its newest frame: ``rgb`` (H, W, 3) uint8, ``depth_m`` (H, W)
  float32 (0 where depth is invalid: out of range or dropped; valid depth is
  at least ``camera.depth_min_m`` > 0), ``time_s`` (1,) the capture time
  (-1 before the first frame), ``K`` (3, 3) intrinsics [px],
  ``transform_camera_to_world`` (4, 4) the camera pose at capture *as the
  drone estimated it*.
* ``detections``: its own detector's boxes on that frame, best first:
  ``boxes_xyxy`` (D, 4) [px], ``scores`` (D,), ``valid`` (D,) in {0, 1},
  ``time_s`` (1,) the frame's capture time (-1 before the first).
* ``tracks``: its own neighbour tracks (the package's detector, back-projection
  and adaptive Kalman tracker, MP-CDE Sec. IV-B, Eq. 7-12), nearest to its
  estimated position first: ``pos_world`` (S, 3) [m], ``vel_world`` (S, 3)
  [m/s] predicted to now, ``age_s`` (S,) since the track was last seen,
  ``valid`` (S,) in {0, 1}.
* ``radio``: its inbox, the newest plan of each neighbour it has heard, in
  sender order: ``sender`` (P,) (-1 for an empty slot), ``age_s`` (P,) since
  the plan was sent, ``times_s`` (P, K) the plan's sample times relative to now
  [s], ``pos_world`` (P, K, 3) [m], ``vel_world`` (P, K, 3) [m/s], ``valid`` (P,).

Empty slots are zeros with ``valid`` 0. Every observation holds its own
arrays (Gymnasium's checker requires it): an image's invalid depth is
converted once per frame and copied into each observation; with
``copy_images: false`` the observations of one frame share its read-only
RGB and depth arrays instead (for control rates above the camera's).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
from gymnasium import spaces

if TYPE_CHECKING:
    from mpcde.config.scenario import ScenarioConfig
    from mpcde.env.external import ExternalDrone
    from mpcde.env.options import EnvOptions

__all__ = ["ObservationBuilder"]

INF = np.inf


def _box(shape: tuple[int, ...], low: float = -INF, high: float = INF, dtype: type = np.float64) -> spaces.Box:
    return spaces.Box(low=low, high=high, shape=shape, dtype=dtype)


class ObservationBuilder:
    """The observation space of a drone and its observations.

    Args:
        cfg: the scenario (camera size, intrinsics, number of drones).
        options: the environment's options.
        K: (3, 3) camera intrinsics [px].
    """

    def __init__(self, cfg: ScenarioConfig, options: EnvOptions, K: np.ndarray, n_drones: int) -> None:
        self.options = options
        self.keys = options.observe
        self.K = np.asarray(K, float)
        self.n = n_drones
        h, w = cfg.camera.height_px, cfg.camera.width_px
        o = options
        entries: dict[str, spaces.Space] = {"time_s": _box((1,), 0.0)}
        if "pose" in self.keys:
            entries["pose"] = spaces.Dict({
                "time_s": _box((1,), 0.0), "pos_world": _box((3,)), "vel_world": _box((3,)),
                "quat_xyzw": _box((4,), -1.0, 1.0), "ang_vel_body": _box((3,)),
            })  # fmt: skip
        if "goal" in self.keys:
            entries["goal"] = _box((3,))
        if "camera" in self.keys:
            entries["camera"] = spaces.Dict({
                "rgb": spaces.Box(0, 255, (h, w, 3), np.uint8), "depth_m": _box((h, w), 0.0, INF, np.float32),
                "time_s": _box((1,), -1.0), "K": _box((3, 3)), "transform_camera_to_world": _box((4, 4)),
            })  # fmt: skip
        if "detections" in self.keys:
            d = o.detection_slots
            entries["detections"] = spaces.Dict({
                "boxes_xyxy": _box((d, 4)), "scores": _box((d,), 0.0, 1.0), "valid": spaces.MultiBinary(d), "time_s": _box((1,), -1.0),
            })  # fmt: skip
        if "tracks" in self.keys:
            s = o.track_slots
            entries["tracks"] = spaces.Dict({
                "pos_world": _box((s, 3)), "vel_world": _box((s, 3)), "age_s": _box((s,), 0.0), "valid": spaces.MultiBinary(s),
            })  # fmt: skip
        if "radio" in self.keys:
            p, k = o.plan_slots, o.plan_samples
            entries["radio"] = spaces.Dict({
                "sender": spaces.Box(-1, max(n_drones - 1, 0), (p,), np.int64), "age_s": _box((p,), 0.0),
                "times_s": _box((p, k)), "pos_world": _box((p, k, 3)), "vel_world": _box((p, k, 3)), "valid": spaces.MultiBinary(p),
            })  # fmt: skip
        self.space = spaces.Dict(entries)
        self._image_cache: dict[int, tuple[int, np.ndarray, np.ndarray]] = {}

    def observe(self, drone: ExternalDrone, time_s: float, goal: np.ndarray) -> dict:
        """The observation of ``drone`` at ``time_s`` [s] (its goal ``goal`` (3,) [m])."""
        obs: dict = {"time_s": np.array([time_s])}
        keys = self.keys
        if "pose" in keys:
            e = drone.estimate
            obs["pose"] = {
                "time_s": np.array([e.time_s]), "pos_world": np.array(e.pos_world, float), "vel_world": np.array(e.vel_world, float),
                "quat_xyzw": np.clip(np.array(e.quat_xyzw, float), -1.0, 1.0), "ang_vel_body": np.array(e.ang_vel_body, float),
            }  # fmt: skip
        if "goal" in keys:
            obs["goal"] = np.array(goal, float)
        if "camera" in keys:
            obs["camera"] = self._camera(drone)
        if "detections" in keys:
            obs["detections"] = self._detections(drone)
        if "tracks" in keys:
            obs["tracks"] = self._tracks(drone, time_s)
        if "radio" in keys:
            obs["radio"] = self._radio(drone, time_s)
        return obs

    def _camera(self, drone: ExternalDrone) -> dict:
        f = drone.frame
        if f is None:
            h, w = self.space["camera"]["rgb"].shape[:2]
            return {
                "rgb": np.zeros((h, w, 3), np.uint8), "depth_m": np.zeros((h, w), np.float32), "time_s": np.array([-1.0]),
                "K": self.K.copy(), "transform_camera_to_world": np.eye(4),
            }  # fmt: skip
        cached = self._image_cache.get(drone.drone_id)
        if cached is None or cached[0] != drone.frame_serial:  # invalid depth (NaN) -> 0, once per frame
            rgb = f.rgb.copy()
            depth = np.nan_to_num(f.depth_m, nan=0.0, posinf=0.0, neginf=0.0).astype(np.float32, copy=False)
            rgb.flags.writeable = depth.flags.writeable = False
            cached = (drone.frame_serial, rgb, depth)
            self._image_cache[drone.drone_id] = cached
        _, rgb, depth = cached
        if self.options.copy_images:
            rgb, depth = rgb.copy(), depth.copy()
        return {
            "rgb": rgb, "depth_m": depth, "time_s": np.array([f.time_s]),
            "K": np.array(f.K, float), "transform_camera_to_world": np.array(f.transform_camera_to_world, float),
        }  # fmt: skip

    def _detections(self, drone: ExternalDrone) -> dict:
        d = self.options.detection_slots
        boxes, scores, valid = np.zeros((d, 4)), np.zeros(d), np.zeros(d, np.int8)
        dets = drone.detections or []
        for j, det in enumerate(dets[:d]):
            boxes[j], scores[j], valid[j] = det.box_xyxy, det.score, 1
        t = drone.frame.time_s if drone.frame is not None else -1.0
        return {"boxes_xyxy": boxes, "scores": np.clip(scores, 0.0, 1.0), "valid": valid, "time_s": np.array([t])}

    def _tracks(self, drone: ExternalDrone, time_s: float) -> dict:
        s = self.options.track_slots
        pos, vel, age, valid = np.zeros((s, 3)), np.zeros((s, 3)), np.zeros(s), np.zeros(s, np.int8)
        preds = drone.perception.predictions(time_s) if drone.perception is not None else []
        if preds:
            me = drone.estimate.pos_world if drone.estimate is not None else np.zeros(3)
            preds = sorted(preds, key=lambda p: float(np.linalg.norm(p.pos_world[0] - me)))
            for j, p in enumerate(preds[:s]):
                pos[j], vel[j], age[j], valid[j] = p.pos_world[0], p.vel_world[0], max(time_s - p.stamp_s, 0.0), 1
        return {"pos_world": pos, "vel_world": vel, "age_s": age, "valid": valid}

    def _radio(self, drone: ExternalDrone, time_s: float) -> dict:
        p, k = self.options.plan_slots, self.options.plan_samples
        out = {
            "sender": np.full(p, -1, np.int64), "age_s": np.zeros(p), "times_s": np.zeros((p, k)),
            "pos_world": np.zeros((p, k, 3)), "vel_world": np.zeros((p, k, 3)), "valid": np.zeros(p, np.int8),
        }  # fmt: skip
        for j, sender in enumerate(sorted(drone.plans)[:p]):
            plan = drone.plans[sender].payload
            times = np.asarray(plan.times_s, float)
            if times.size == k:
                pos, vel, t = np.asarray(plan.pos_world, float), np.asarray(plan.vel_world, float), times
            else:  # resampled uniformly over the plan's span
                t = np.linspace(times[0], times[-1], k)
                pos = np.stack([np.interp(t, times, plan.pos_world[:, c]) for c in range(3)], axis=1)
                vel = np.stack([np.interp(t, times, plan.vel_world[:, c]) for c in range(3)], axis=1)
            out["sender"][j], out["age_s"][j], out["valid"][j] = sender, max(time_s - plan.time_s, 0.0), 1
            out["times_s"][j], out["pos_world"][j], out["vel_world"][j] = t - time_s, pos, vel
        return out
