"""The simulation loop: event-driven on simulated time (DESIGN.md section 3).

Physics and the low-level controller tick at ``physics.physics_hz``. Other
components run when simulated time reaches their next tick:

* cameras (``camera.rate_hz``): the true poses at the tick go to the render
  pool, which renders while physics continues; the frame reaches its agent at
  capture time + ``camera.latency_s`` (the loop blocks only if the render is
  not done by then);
* pose estimates: at every camera tick (the VIO stand-in's rate);
* radio rounds (``radio.rate_hz``): each agent broadcasts its plan, inboxes
  are delivered;
* the state log (``run.log_rate_hz``).

The loop owns ground truth; agents get only frames, their own estimate and
their inbox.
"""

from __future__ import annotations

import contextlib
import os
import time
from collections import deque
from dataclasses import dataclass, field
from typing import Any, Callable

import numpy as np

from mpcde.config.layout import build_layout, check_layout, resolve_obstacles
from mpcde.config.resolve import resolve
from mpcde.config.scenario import ScenarioConfig
from mpcde.flight.metrics import MetricsAccumulator, formation_metrics
from mpcde.flight.tracking_score import TrackingScore
from mpcde.onboard.budget import ComputeBudget
from mpcde.onboard.detection import BatchedDetector
from mpcde.onboard.factory import make_agent
from perception.types import Detection
from sim.camera_rig import CameraRig
from sim.faults import FaultInjector
from sim.ground_truth import TrueState
from sim.pose_estimate import PoseEstimator
from sim.radio import Radio
from sim.rendering.pool import RenderPool
from sim.rotations import yaw_from_rotation
from sim.scene import SceneSpec
from sim.types import GroundTruthSegmentation, ObstacleSpec, RgbdFrame
from sim.world import World

__all__ = ["RunLog", "RunResult", "prepare_run", "run_scenario"]


@dataclass
class RunLog:
    """State log at ``run.log_rate_hz``; arrays are stacked at the end.

    Keys of :attr:`arrays` (T samples, N drones): ``time_s`` (T,),
    ``pos_world`` (T, N, 3), ``vel_world`` (T, N, 3), ``yaw`` (T, N),
    ``est_pos_world`` (T, N, 3), ``ref_pos_world`` (T, N, 3), ``failed`` (T, N).
    """

    rows: dict[str, list] = field(default_factory=lambda: {k: [] for k in ("time_s", "pos_world", "vel_world", "yaw", "est_pos_world", "ref_pos_world", "failed")})

    def append(self, **values: Any) -> None:
        """Add one sample (keyword per key)."""
        for k, v in values.items():
            self.rows[k].append(np.asarray(v))

    @property
    def arrays(self) -> dict[str, np.ndarray]:
        """The log as stacked arrays."""
        return {k: np.stack(v) if v else np.zeros((0,)) for k, v in self.rows.items()}


@dataclass
class RunResult:
    """What a run produced (before it is written to disk)."""

    config: ScenarioConfig
    obstacles: tuple[ObstacleSpec, ...]
    starts: np.ndarray
    goals: np.ndarray
    metrics: dict[str, Any]
    log: RunLog


@dataclass(frozen=True)
class PreparedRun:
    """A validated scenario with its resolved layout and obstacles."""

    config: ScenarioConfig
    starts: np.ndarray
    goals: np.ndarray
    obstacles: tuple[ObstacleSpec, ...]


def prepare_run(cfg: ScenarioConfig) -> PreparedRun:
    """Derive the settings that follow from others, resolve layout and obstacles and check them.

    Raises ConfigError, writes nothing. ``PreparedRun.config`` is the resolved
    scenario (:func:`mpcde.config.resolve.resolve`), the one the run folder's
    ``config.yaml`` holds.
    """
    cfg = resolve(cfg)
    starts, goals = build_layout(cfg.drones)
    obstacles = resolve_obstacles(cfg, starts, goals)
    check_layout(cfg, starts, goals, obstacles)
    return PreparedRun(cfg, starts, goals, obstacles)


FrameSink = Callable[[float, TrueState, list[RgbdFrame | None]], None]


def run_scenario(prepared: PreparedRun, frame_sink: FrameSink | None = None, progress: bool = False) -> RunResult:
    """Fly a prepared scenario to its end.

    Args:
        prepared: from :func:`prepare_run`.
        frame_sink: called at every camera delivery with (time, truth, latest
            frame per drone); the video writer is one.
        progress: show a progress bar over simulated time.
    """
    cfg = prepared.config
    starts, goals = prepared.starts, prepared.goals
    n = starts.shape[0]
    d = goals - starts
    start_yaw = np.arctan2(d[:, 1], d[:, 0])
    budget = ComputeBudget()
    agents = [make_agent(cfg, i, goals, prepared.obstacles, budget) for i in range(n)]
    detector = BatchedDetector.for_agents(agents) if cfg.run.cameras else None
    spec = SceneSpec(obstacles=prepared.obstacles, n_drones=n)
    world = World(spec, starts, start_yaw, cfg.physics)
    estimator = PoseEstimator(cfg.pose_estimate, n, cfg.seed)
    rig = CameraRig(cfg.camera, cfg.seed)
    radio = Radio(cfg.radio, n, cfg.seed, line_of_sight=lambda a, b: _line_of_sight(world, a, b))
    faults = FaultInjector(cfg.faults, n, cfg.seed, (cfg.camera.width_px, cfg.camera.height_px))
    track_score = TrackingScore()
    metrics = MetricsAccumulator(goals, prepared.obstacles, cfg.physics.quadrotor.robot_radius_m, cfg.run.goal_tolerance_m)
    log = RunLog()
    workers = cfg.run.render_workers if cfg.run.render_workers >= 0 else (os.cpu_count() or 1)
    pool = RenderPool(spec, cfg.camera, workers) if cfg.run.cameras else None
    bar = None
    if progress:
        from tqdm import tqdm

        bar = tqdm(total=round(cfg.duration_s, 2), unit="sim s", desc=cfg.name, leave=False, dynamic_ncols=True, mininterval=0.5, disable=None)
    cam_period = 1.0 / cfg.camera.rate_hz
    radio_period = 1.0 / cfg.radio.rate_hz
    log_period = 1.0 / cfg.run.log_rate_hz
    next_cam, next_radio, next_log = 0.0, 0.0, 0.0
    invalid_px, pixels = 0, 0  # NaN depth pixels of the frames delivered, and all their pixels
    frame_index = 0
    in_flight: tuple[float, int, list, list] | None = None  # (capture time, index, estimates, true camera poses)
    delivery: deque[tuple[float, list[RgbdFrame]]] = deque()
    latest_frames: list[RgbdFrame | None] = [None] * n
    segmentations: list[GroundTruthSegmentation | None] = [None] * n
    truth = world.true_state()
    for a, e in zip(agents, estimator.update(truth)):
        a.on_pose_estimate(e)
    arrived_at = None
    eps = 1e-9
    wall0 = time.perf_counter()
    threads = contextlib.ExitStack()  # torch on one thread while the loop runs (mpcde/onboard/detection.py)
    if detector is not None:
        threads.enter_context(detector.single_threaded())
    try:
        while world.time_s < cfg.duration_s - eps:
            t = world.time_s
            if t >= next_cam - eps:
                estimates = estimator.update(truth)
                for a, e in zip(agents, estimates):
                    a.on_pose_estimate(e)
                if pool is not None:
                    if in_flight is not None:
                        delivery.append(_finish_frames(pool, rig, in_flight, segmentations, budget))
                    cams = [(i, rig.transform_camera_to_world(truth.pos_world[i], truth.rotation_body_to_world[i])) for i in range(n)]
                    pool.submit(truth.pos_world, truth.quat_xyzw, cams, sensor=(cfg.seed, frame_index))
                    in_flight = (t, frame_index, estimates, [c[1] for c in cams])
                    frame_index += 1
                next_cam += cam_period
            if pool is not None and in_flight is not None and t >= in_flight[0] + cfg.camera.latency_s - eps:
                delivery.append(_finish_frames(pool, rig, in_flight, segmentations, budget))
                in_flight = None
            while delivery and t >= delivery[0][0] + cfg.camera.latency_s - eps:
                _, frames = delivery.popleft()
                if cfg.faults.any:
                    frames = [f for f in frames if not faults.frame_dropped(f.drone_id, f.time_s)]
                invalid_px += sum(int(np.count_nonzero(np.isnan(f.depth_m))) for f in frames)
                pixels += sum(f.depth_m.size for f in frames)
                with budget.measure("detect"):
                    detections = _detect(detector, frames, agents, truth.failed)
                if cfg.faults.any:
                    detections = [None if d is None else _corrupt(faults, d) for d in detections]
                for f, dets in zip(frames, detections):
                    if not truth.failed[f.drone_id]:  # a failed drone's computer is down with its motors
                        agents[f.drone_id].on_frame(f, dets)
                    latest_frames[f.drone_id] = f
                _score_tracks(track_score, agents, t, truth)
                if frame_sink is not None:
                    frame_sink(t, truth, latest_frames)
            if t >= next_radio - eps:
                # a round: read the inbox (plans of earlier rounds), then compute and broadcast
                for a in agents:
                    a.on_radio(radio.receive(a.drone_id, t))
                for a in agents:
                    if not truth.failed[a.drone_id]:
                        a.plan_round(t)
                        msg = a.outgoing(t)
                        if msg is not None:
                            radio.broadcast(a.drone_id, t, msg, truth.pos_world)
                next_radio += radio_period
            refs = [a.reference(t) for a in agents]
            if t >= next_log - eps:
                log.append(
                    time_s=t,
                    pos_world=truth.pos_world,
                    vel_world=truth.vel_world,
                    yaw=yaw_from_rotation(truth.rotation_body_to_world),
                    est_pos_world=[e.pos_world for e in estimator.latest],
                    ref_pos_world=[r.pos_world for r in refs],
                    failed=truth.failed,
                )
                next_log += log_period
            for i in faults.failures_due(t):
                world.fail_drone(i)
            with budget.measure("physics"):
                truth = world.step(refs)
            metrics.update(truth, world.dt_s)
            if bar is not None and int(world.time_s * 10) != int(t * 10):
                bar.n = round(world.time_s, 1)
                bar.refresh()
            if cfg.run.stop_when_arrived and metrics.all_arrived:
                arrived_at = arrived_at if arrived_at is not None else world.time_s
                if world.time_s >= arrived_at + 1.0:
                    break
        wall = time.perf_counter() - wall0
    finally:
        threads.close()
        if pool is not None:
            budget.add("render", pool.render_s, pool.renders)
            pool.close()
        world.close()
        if bar is not None:
            bar.close()
    extra = {
        "radio": radio.stats(),
        "frames_rendered": frame_index * n if pool is not None else 0,
        "render_workers": workers if pool is not None else None,
        "frames_received": int(sum(a.counters.frames for a in agents)),
    }
    extra["compute_time"] = budget.result(world.time_s, wall)
    extra["faults"] = {
        **faults.report(),
        "invalid_depth_pixels": int(invalid_px),
        "invalid_depth_fraction": invalid_px / pixels if pixels else None,
        **pose_error_m(log.arrays),
    }
    extra.update(track_score.result())
    if _flies_formation(cfg):
        extra.update(formation_metrics(log.arrays["pos_world"], goals))
    agent_metrics = [m for m in (a.extra_metrics() for a in agents) if m is not None]
    if agent_metrics:
        extra["agents"] = agent_metrics
    result = metrics.result(wall, truth.failed, extra)
    return RunResult(cfg, prepared.obstacles, starts, goals, result, log)


def _flies_formation(cfg: ScenarioConfig) -> bool:
    """Whether the planner keeps the goals' formation (then the metrics report chi)."""
    kind = cfg.planner.kind
    return kind == "admm" or (kind in ("dmpc", "auto") and cfg.dmpc.formation_from_goals)


def _detect(detector: BatchedDetector | None, frames: list[RgbdFrame], agents: list, failed: np.ndarray) -> list:
    """Each frame's detections for the agents that ask for them (one batch), None for the others."""
    if detector is None:
        return [None] * len(frames)
    wanted = [agents[f.drone_id].detector_request is not None and not failed[f.drone_id] for f in frames]
    return detector.detect(frames, wanted)


def _corrupt(faults: FaultInjector, detections: list[Detection]) -> list[Detection]:
    """One frame's detections after the scenario's detector faults (:meth:`sim.faults.FaultInjector.corrupt`)."""
    boxes = np.array([d.box_xyxy for d in detections], float).reshape(-1, 4)
    scores = np.array([d.score for d in detections], float)
    boxes, scores = faults.corrupt(boxes, scores)
    return [Detection(box_xyxy=b, score=float(s)) for b, s in zip(boxes, scores)]


def pose_error_m(arrays: dict[str, np.ndarray]) -> dict[str, float | None]:
    """The drones' pose-estimate position error over the logged flight [m]: mean, max, and mean at the end (drift)."""
    est, true = arrays.get("est_pos_world"), arrays.get("pos_world")
    if est is None or true is None or est.ndim != 3 or not est.size:
        return {"pose_error_mean_m": None, "pose_error_max_m": None, "pose_error_final_m": None}
    err = np.linalg.norm(est - true, axis=-1)  # (T, N)
    return {"pose_error_mean_m": float(err.mean()), "pose_error_max_m": float(err.max()), "pose_error_final_m": float(err[-1].mean())}


def _score_tracks(score: TrackingScore, agents: list, t: float, truth: TrueState) -> None:
    """Score the perceiving agents' track predictions at ``t`` against the truth (metrics only)."""
    alive = ~np.asarray(truth.failed, bool)
    for a in agents:
        if a.perception is not None and alive[a.drone_id]:
            score.update(a.drone_id, a.perception.predictions(t), t, truth.pos_world, truth.vel_world, alive)


def _finish_frames(
    pool: RenderPool, rig: CameraRig, in_flight: tuple, segmentations: list, budget: ComputeBudget
) -> tuple[float, list[RgbdFrame]]:
    """Collect a render batch and turn it into onboard frames (+ truth labels)."""
    t_capture, index, estimates, true_poses = in_flight
    with budget.measure("render_wait"):
        raws = pool.collect()
    frames = []
    for i, raw in enumerate(raws):
        frames.append(rig.frame(i, index, t_capture, raw, estimates[i]))
        segmentations[i] = rig.segmentation(i, t_capture, raw, true_poses[i])
    return t_capture, frames


def _line_of_sight(world: World, a: np.ndarray, b: np.ndarray) -> bool:
    """Whether the segment a-b (3,) misses every static obstacle (PyBullet ray test)."""
    from sim.bullet import pb

    d = b - a
    length = float(np.linalg.norm(d))
    if length < 0.4:
        return True
    u = d / length
    # start and end outside both drones' bodies (a ray test reports the first body hit)
    hit = pb.rayTest((a + 0.2 * u).tolist(), (b - 0.2 * u).tolist(), physicsClientId=world.client)[0]
    return hit[0] < 0 or hit[0] in world.drone_ids
