"""The simulation loop, one physics tick at a time (DESIGN.md section 3).

:class:`FlightSession` is the loop of ``mpcde fly`` cut at the physics tick,
so that a caller can advance it tick by tick: :func:`mpcde.flight.loop.run_scenario`
steps it to the end, and :class:`mpcde.env.SwarmParallelEnv` steps it between
control steps with some drones' references coming from actions. There is one
loop, not two.

Physics and the low-level controller tick at ``physics.physics_hz``. Other
components run when simulated time reaches their next tick (the *events* of
a time t, :meth:`FlightSession._events`):

* cameras (``camera.rate_hz``): the true poses at the tick go to the render
  pool, which renders while physics continues; the frame reaches its agent at
  capture time + ``camera.latency_s`` (the loop blocks only if the render is
  not done by then);
* pose estimates: at every camera tick (the VIO stand-in's rate);
* radio rounds (``radio.rate_hz``): each agent reads its inbox, plans and
  broadcasts;
* the state log (``run.log_rate_hz``).

One tick (:meth:`FlightSession.step`) reads every agent's reference at t,
logs, applies the failures due, steps physics to t + dt, accumulates the
metrics, then runs the events of t + dt. The session owns ground truth;
agents get only frames, their own estimate and their inbox.
"""

from __future__ import annotations

import contextlib
import os
import time
import warnings
from collections import deque
from typing import TYPE_CHECKING, Any, Callable, Sequence

import numpy as np

from mpcde.flight.metrics import MetricsAccumulator, formation_metrics, pose_error_m
from mpcde.flight.observed_area import ObservedArea
from mpcde.flight.run_types import RunLog, RunResult
from mpcde.flight.tracking_score import TrackingScore
from mpcde.numerics import describe as describe_numerics
from mpcde.numerics import mismatch as numerics_mismatch
from mpcde.onboard.base import OnboardAgent
from mpcde.onboard.budget import ComputeBudget
from mpcde.onboard.detection import BatchedDetector, frame_detector
from perception.types import Detection
from sim.bullet.scene import SceneSpec
from sim.faults import FaultInjector
from sim.ground_truth import TrueState
from sim.pose_estimate import PoseEstimator
from sim.radio import Radio
from sim.rendering.camera_rig import CameraRig
from sim.rendering.pool import RenderPool
from sim.rendering.pool_keeper import PoolKeeper
from sim.rotations import yaw_from_rotation
from sim.types import GroundTruthSegmentation, RgbdFrame
from sim.world import World

if TYPE_CHECKING:
    from mpcde.config.scenario import ScenarioConfig
    from mpcde.flight.run_types import PreparedRun

__all__ = ["FlightSession", "FrameSink", "line_of_sight"]

FrameSink = Callable[[float, TrueState, list[RgbdFrame | None]], None]
EPS_S = 1e-9  # tolerance when simulated time meets a rate's next tick [s]


class FlightSession:
    """One flight of a prepared scenario, advanced one physics tick at a time.

    Args:
        prepared: from :func:`mpcde.flight.loop.prepare_run`.
        agents: one onboard agent per drone (``agents[i].drone_id == i``);
            the session hands each only its own frames, estimate and inbox.
        budget: the compute budget the agents were built with (render, detect
            and physics time are added to it).
        frame_sink: called at every camera delivery with (time, truth, latest
            frame per drone); the video writer is one.
        progress: show a progress bar over simulated time.
        pools: a :class:`sim.rendering.pool_keeper.PoolKeeper` to take the render pool from (a pool
            kept across flights; the keeper's owner closes it), or None: the session starts its own
            pool and closes it with itself.

    Use: :meth:`step` until :attr:`done`, then :meth:`result` (which closes
    the session); :meth:`close` frees PyBullet and the render pool at any time.
    """

    def __init__(
        self, prepared: PreparedRun, agents: Sequence[OnboardAgent], budget: ComputeBudget,
        frame_sink: FrameSink | None = None, progress: bool = False, pools: PoolKeeper | None = None,
    ) -> None:  # fmt: skip
        self.world = self.pool = self.bar = None  # what close() frees, before anything can fail
        self._pools = pools
        self._threads = contextlib.ExitStack()
        self._closed = False
        try:
            self._build(prepared, agents, budget, frame_sink, progress)
        except BaseException:  # a bad argument, or a signal while starting: free what was built
            self.close()
            raise

    def _build(self, prepared: PreparedRun, agents: Sequence[OnboardAgent], budget: ComputeBudget, frame_sink: FrameSink | None, progress: bool) -> None:
        """The constructor's work (see the class docstring)."""
        cfg = self.config = prepared.config
        self.prepared = prepared
        n = self.n = prepared.starts.shape[0]
        if len(agents) != n or any(a.drone_id != i for i, a in enumerate(agents)):
            raise ValueError(f"agents: need one per drone in drone order ({n}), got ids {[a.drone_id for a in agents]}")
        self.agents = list(agents)
        self.budget = budget
        self.frame_sink = frame_sink
        d = prepared.goals - prepared.starts
        start_yaw = np.arctan2(d[:, 1], d[:, 0])
        self.detector = BatchedDetector.for_agents(self.agents) if cfg.run.cameras else None
        spec = SceneSpec(obstacles=prepared.obstacles, n_drones=n)
        self.world = World(spec, prepared.starts, start_yaw, cfg.physics)
        self.estimator = PoseEstimator(cfg.pose_estimate, n, cfg.seed)
        self.rig = CameraRig(cfg.camera, cfg.seed)
        world = self.world
        self.radio = Radio(cfg.radio, n, cfg.seed, line_of_sight=lambda a, b: line_of_sight(world, a, b), in_view=self._in_view)
        self.faults = FaultInjector(cfg.faults, n, cfg.seed, (cfg.camera.width_px, cfg.camera.height_px))
        self.track_score = TrackingScore()
        self.observed = ObservedArea(prepared.obstacles, cfg.world.arena_size_m, n, cfg.camera.hfov_deg, cfg.camera.depth_max_m) if cfg.run.cameras else None
        self.metrics = MetricsAccumulator(prepared.goals, prepared.obstacles, cfg.physics.quadrotor.robot_radius_m, cfg.run.goal_tolerance_m)
        self.log: RunLog = RunLog()
        self.workers = cfg.run.render_workers if cfg.run.render_workers >= 0 else _default_workers(self.agents, self.detector is not None)
        # the detector runs in the render workers when there are any (mpcde/onboard/detection.py)
        processor = (frame_detector, self.detector.request) if self.detector is not None and self.workers > 0 else None
        if cfg.run.cameras:
            pools = self._pools
            self.pool = RenderPool(spec, cfg.camera, self.workers, processor) if pools is None else pools.get(spec, cfg.camera, self.workers, processor)
        self.bar = None
        if progress:
            from tqdm import tqdm

            self.bar = tqdm(total=round(cfg.duration_s, 2), unit="sim s", desc=cfg.name, leave=False, dynamic_ncols=True, mininterval=0.5, disable=None)
        self.cam_period = 1.0 / cfg.camera.rate_hz
        self.radio_period = 1.0 / cfg.radio.rate_hz
        self.log_period = 1.0 / cfg.run.log_rate_hz
        self.next_cam, self.next_radio, self.next_log = 0.0, 0.0, 0.0
        self.invalid_px, self.pixels = 0, 0  # NaN depth pixels of the frames delivered, and all their pixels
        self.frame_index = 0
        self.in_flight: tuple[float, int, list, list] | None = None  # (capture time, index, estimates, true camera poses)
        self.delivery: deque[tuple[float, list[RgbdFrame], list | None]] = deque()  # (capture time, frames, workers' detections)
        self.latest_frames: list[RgbdFrame | None] = [None] * n
        self.segmentations: list[GroundTruthSegmentation | None] = [None] * n
        self.truth = world.true_state()
        self.radio_rounds = 0
        self.arrived_at: float | None = None
        self.stopped = False
        self._wall_s: float | None = None
        if self.detector is not None and processor is None:  # torch on one thread while the loop runs (mpcde/onboard/detection.py)
            self._threads.enter_context(self.detector.single_threaded())
        self.wall0 = time.perf_counter()
        self._events(world.time_s)  # the camera tick at t = 0 gives every agent its first pose estimate

    @property
    def time_s(self) -> float:
        """Simulated time [s] of the current tick."""
        return self.world.time_s

    @property
    def done(self) -> bool:
        """Whether the flight has ended: the time limit, or everyone arrived 1 s ago with ``run.stop_when_arrived``."""
        return self.stopped or self.world.time_s >= self.config.duration_s - EPS_S

    def step(self) -> TrueState:
        """One physics tick from t: references, log, failures, physics, metrics, then the events of t + dt.

        Returns:
            The true state after the tick (metrics, rewards and labels only; never for an agent).
        """
        cfg, world = self.config, self.world
        t = world.time_s
        refs = [a.reference(t) for a in self.agents]
        if t >= self.next_log - EPS_S:
            self.log.append(
                time_s=t,
                pos_world=self.truth.pos_world,
                vel_world=self.truth.vel_world,
                yaw=yaw_from_rotation(self.truth.rotation_body_to_world),
                est_pos_world=[e.pos_world for e in self.estimator.latest],
                ref_pos_world=[r.pos_world for r in refs],
                failed=self.truth.failed,
            )
            self.next_log += self.log_period
        for i in self.faults.failures_due(t):
            world.fail_drone(i)
        with self.budget.measure("physics"):
            self.truth = world.step(refs)
        self.metrics.update(self.truth, world.dt_s)
        if self.bar is not None and int(world.time_s * 10) != int(t * 10):
            self.bar.n = round(world.time_s, 1)
            self.bar.refresh()
        if cfg.run.stop_when_arrived and self.metrics.all_arrived:
            self.arrived_at = self.arrived_at if self.arrived_at is not None else world.time_s
            if world.time_s >= self.arrived_at + 1.0:
                self.stopped = True
        if not self.done:
            self._events(world.time_s)
        return self.truth

    def _events(self, t: float) -> None:
        """What happens at time ``t`` before the references are read: camera tick, frame delivery, radio round."""
        cfg, agents, truth, pool, budget = self.config, self.agents, self.truth, self.pool, self.budget
        if t >= self.next_cam - EPS_S:
            estimates = self.estimator.update(truth)
            for a, e in zip(agents, estimates):
                a.on_pose_estimate(e)
            if pool is not None:
                if self.in_flight is not None:
                    self.delivery.append(self._finish_frames())
                cams = [(i, self.rig.transform_camera_to_world(truth.pos_world[i], truth.rotation_body_to_world[i])) for i in range(self.n)]
                detect = [i for i in range(self.n) if _wants_detections(agents[i], truth.failed[i])] if pool.has_processor else ()
                pool.submit(truth.pos_world, truth.quat_xyzw, cams, sensor=(cfg.seed, self.frame_index), process=detect)
                for i, T in cams:  # the observed-area metric (truth; mpcde/flight/observed_area.py), while the workers render
                    if not truth.failed[i]:
                        self.observed.add_frame(i, T)
                self.in_flight = (t, self.frame_index, estimates, [c[1] for c in cams])
                self.frame_index += 1
            self.next_cam += self.cam_period
        if pool is not None and self.in_flight is not None and t >= self.in_flight[0] + cfg.camera.latency_s - EPS_S:
            self.delivery.append(self._finish_frames())
            self.in_flight = None
        while self.delivery and t >= self.delivery[0][0] + cfg.camera.latency_s - EPS_S:
            _, frames, detected = self.delivery.popleft()
            if cfg.faults.any:
                kept = [k for k, f in enumerate(frames) if not self.faults.frame_dropped(f.drone_id, f.time_s)]
                frames, detected = [frames[k] for k in kept], None if detected is None else [detected[k] for k in kept]
            self.invalid_px += sum(int(np.count_nonzero(np.isnan(f.depth_m))) for f in frames)
            self.pixels += sum(f.depth_m.size for f in frames)
            if detected is not None:  # the render workers ran the detector (a drone failed since capture: nothing)
                detections = [None if truth.failed[f.drone_id] else d for f, d in zip(frames, detected)]
            else:
                with budget.measure("detect"):
                    detections = _detect(self.detector, frames, agents, truth.failed)
            if cfg.faults.any:
                detections = [None if d is None else _corrupt(self.faults, d) for d in detections]
            for f, dets in zip(frames, detections):
                if not truth.failed[f.drone_id]:  # a failed drone's computer is down with its motors
                    agents[f.drone_id].on_frame(f, dets)
                self.latest_frames[f.drone_id] = f
            _score_tracks(self.track_score, agents, t, truth)
            if self.frame_sink is not None:
                self.frame_sink(t, truth, self.latest_frames)
        if t >= self.next_radio - EPS_S:
            # a round: read the inbox (plans of earlier rounds), then compute and broadcast
            for a in agents:
                a.on_radio(self.radio.receive(a.drone_id, t))
            for a in agents:
                if not truth.failed[a.drone_id]:
                    a.plan_round(t)
                    msg = a.outgoing(t)
                    if msg is not None:
                        self.radio.broadcast(a.drone_id, t, msg, truth.pos_world)
            self.radio_rounds += 1
            self.next_radio += self.radio_period

    def _in_view(self, receiver: int, sender: int) -> bool:
        """Whether ``sender`` is in ``receiver``'s camera view now (the view-gated radio): :meth:`view_of` is visible."""
        return self.view_of(receiver, sender) == 0

    def view_of(self, receiver: int, sender: int) -> int:
        """Where ``sender``'s centre truly is for ``receiver``'s true camera, an index into :data:`sim.camera.VIEW`: 0 inside the
        field of view and depth range and not hidden by an obstacle, else the first of those that fails (truth: the
        view-gated radio's physics, and the collision explainer's judge)."""
        truth, cam = self.truth, self.config.camera
        T = self.rig.transform_camera_to_world(truth.pos_world[receiver], truth.rotation_body_to_world[receiver])
        p = T[:3, :3].T @ (truth.pos_world[sender] - T[:3, 3])  # the sender in the receiver's camera frame
        if p[2] <= 0.0 or abs(p[0]) > p[2] * np.tan(np.radians(cam.hfov_deg) / 2):
            return 1
        if abs(p[1]) > p[2] * np.tan(np.radians(cam.vfov_deg) / 2):
            return 2
        if not cam.depth_min_m <= p[2] <= cam.depth_max_m:
            return 3
        return 0 if line_of_sight(self.world, T[:3, 3], truth.pos_world[sender]) else 4

    def _finish_frames(self) -> tuple[float, list[RgbdFrame], list | None]:
        """Collect the render batch in flight: onboard frames (+ truth labels), and the workers' detections if they ran it."""
        t_capture, index, estimates, true_poses = self.in_flight
        with self.budget.measure("render_wait"):
            raws = self.pool.collect()
        frames = []
        for i, raw in enumerate(raws):
            frames.append(self.rig.frame(i, index, t_capture, raw, estimates[i]))
            self.segmentations[i] = self.rig.segmentation(i, t_capture, raw, true_poses[i])
        return t_capture, frames, (list(self.pool.processed) if self.pool.has_processor else None)

    def close(self) -> None:
        """Free the render pool, PyBullet and the progress bar (idempotent); the wall clock stops here."""
        if self._closed:
            return
        self._closed = True
        self._wall_s = time.perf_counter() - self.wall0 if hasattr(self, "wall0") else 0.0
        try:
            self._threads.close()
            if self.pool is not None:
                self.budget.add("render", self.pool.render_s, self.pool.renders)
                if self.pool.has_processor:
                    self.budget.add("detect", self.pool.process_s, self.pool.processed_frames, off_main=True)
                if self._pools is None:  # a kept pool stays with its keeper (its next get() drains it)
                    self.pool.close()
        finally:
            if self.world is not None:
                self.world.close()
            if self.bar is not None:
                self.bar.close()

    def result(self) -> RunResult:
        """Close the session and return what the flight produced: the metrics of ``metrics.json`` and the log."""
        self.close()
        cfg, prepared, agents = self.config, self.prepared, self.agents
        extra: dict[str, Any] = {
            "radio": self.radio.stats(),
            "frames_rendered": self.frame_index * self.n if self.pool is not None else 0,
            "render_workers": self.workers if self.pool is not None else None,
            "frames_received": int(sum(a.counters.frames for a in agents)),
            "detector_precision": self.detector.detector.precision if self.detector is not None else None,
            "numerics": describe_numerics(),
        }
        if (why := numerics_mismatch(extra["numerics"])) is not None:
            warnings.warn(why, RuntimeWarning, stacklevel=2)
        extra["compute_time"] = self.budget.result(self.world.time_s, self._wall_s)
        extra["faults"] = {
            **self.faults.report(),
            "invalid_depth_pixels": int(self.invalid_px),
            "invalid_depth_fraction": self.invalid_px / self.pixels if self.pixels else None,
            **pose_error_m(self.log.arrays),
        }
        extra.update(self.track_score.result())
        if self.observed is not None:
            extra["observed_area_m2"], extra["observed_area_swarm_m2"] = self.observed.areas_m2()
        if _flies_formation(cfg):
            extra.update(formation_metrics(self.log.arrays["pos_world"], prepared.goals))
        agent_metrics = [m for m in (a.extra_metrics() for a in agents) if m is not None]
        if agent_metrics:
            extra["agents"] = agent_metrics
        metrics = self.metrics.result(self._wall_s, self.truth.failed, extra)
        observed = self.observed.raster() if self.observed is not None else None
        return RunResult(cfg, prepared.obstacles, prepared.starts, prepared.goals, metrics, self.log, observed)


def _default_workers(agents: Sequence[OnboardAgent], detects: bool) -> int:
    """Render workers for ``run.render_workers: -1``: one per core, or one fewer when the agents map their frames.

    A mapping stack (``maps_frames``) keeps map insertion, the ESDF and planning
    in the main process, which then needs a core to itself; the workers render
    and, when a detector runs, detect on the rest. Why one fewer only for
    mapping stacks: docs/results/realtime.md#worker-count.
    """
    cores = os.cpu_count() or 1
    if detects and any(getattr(a, "maps_frames", False) for a in agents):
        return max(cores - 1, 1)
    return cores


def _flies_formation(cfg: ScenarioConfig) -> bool:
    """Whether the planner keeps the goals' formation (then the metrics report chi; its registry entry says)."""
    from mpcde.stacks import stack_of

    return bool(stack_of(cfg).flies_formation(cfg))


def _detect(detector: BatchedDetector | None, frames: list[RgbdFrame], agents: list, failed: np.ndarray) -> list:
    """Each frame's detections for the agents that ask for them (one batch), None for the others."""
    if detector is None:
        return [None] * len(frames)
    wanted = [_wants_detections(agents[f.drone_id], failed[f.drone_id]) for f in frames]
    return detector.detect(frames, wanted)


def _wants_detections(agent: OnboardAgent, failed: bool) -> bool:
    """Whether a drone's frame goes through the detector: its agent asks for detections and its computer is up."""
    return getattr(agent, "detector_request", None) is not None and not failed


def _corrupt(faults: FaultInjector, detections: list[Detection]) -> list[Detection]:
    """One frame's detections after the scenario's detector faults (:meth:`sim.faults.FaultInjector.corrupt`)."""
    boxes = np.array([d.box_xyxy for d in detections], float).reshape(-1, 4)
    scores = np.array([d.score for d in detections], float)
    boxes, scores = faults.corrupt(boxes, scores)
    return [Detection(box_xyxy=b, score=float(s)) for b, s in zip(boxes, scores)]


def _score_tracks(score: TrackingScore, agents: list, t: float, truth: TrueState) -> None:
    """Score the perceiving agents' track predictions at ``t`` against the truth (metrics only)."""
    alive = ~np.asarray(truth.failed, bool)
    for a in agents:
        if a.perception is not None and alive[a.drone_id]:
            score.update(a.drone_id, a.perception.predictions(t), t, truth.pos_world, truth.vel_world, alive)


def line_of_sight(world: World, a: np.ndarray, b: np.ndarray) -> bool:
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
