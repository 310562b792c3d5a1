"""Render many cameras in parallel: one render-only PyBullet client per worker process.

The physics client never renders. At a camera tick the loop :meth:`submit` s
the true poses of all drones and the cameras due; each worker (its own
PyBullet DIRECT client holding a copy of the scene) places the drones, renders
its share of the cameras into shared memory and answers; :meth:`collect`
waits for the answers and copies the images out. The constructor returns once
every worker has built its scene (and frame processor), so a flight's first
camera tick does not wait for a worker's start-up. Between the two calls the
main process keeps stepping physics, so rendering overlaps with it. With
``n_workers = 0`` everything runs in-process (tests, dataset generation).

Renders are deterministic. When asked (``sensor``), the workers also
apply the depth sensor model, seeded per (seed, drone, frame index) by
:func:`sim.rendering.camera_rig.sensor_depth`, so results do not depend on the
worker count and the noise costs the main process nothing.

A pool may also carry a *frame processor*: onboard work that needs only a
drone's own image and depth (the detector, :func:`mpcde.onboard.detection.frame_detector`).
Each worker builds it once from a picklable ``(factory, argument)`` pair and
runs it over its share of a tick's frames right after rendering them, so that
work runs on the render workers' core, beside the main process instead of in
it (measured: docs/results/realtime.md#where-the-time-goes). Its outputs come back with the
renders (:attr:`RenderPool.processed`), one per camera of the request, None
for the drones not asked.
"""

from __future__ import annotations

import multiprocessing as mp
import pickle
import time
from multiprocessing import shared_memory
from typing import Any, Callable, Sequence

import numpy as np

from sim.bullet.scene import RenderStyle, SceneSpec
from sim.camera import CameraConfig
from sim.rendering.camera_rig import sensor_depth
from sim.rendering.raycast import RaycastRenderer
from sim.rendering.tiny import RawRender, SceneRenderer
from sim.spawn import main_module_hidden, sigint_ignored

__all__ = ["CameraRequest", "FrameProcessor", "ProcessorSpec", "RenderPool", "make_renderer"]

CameraRequest = tuple[int, np.ndarray]  # (drone index, true transform_camera_to_world (4, 4))
FrameProcessor = Callable[[list[np.ndarray], list[np.ndarray]], list[Any]]
"""Onboard work on B frames: (B rgb (H, W, 3) uint8, B sensor depth (H, W) [m]) -> B picklable outputs."""
ProcessorSpec = tuple[Callable[[Any], FrameProcessor], Any]
"""(module-level factory, picklable argument): each worker calls ``factory(argument)`` once."""


SLOT_BYTES_PER_PX = 3 + 4 + 2 + 4  # rgb, true depth, mask, sensor depth


def _slot_views(buf: memoryview, n_slots: int, H: int, W: int) -> list[tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]]:
    views = []
    for s in range(n_slots):
        off = s * H * W * SLOT_BYTES_PER_PX
        rgb = np.ndarray((H, W, 3), np.uint8, buf, off)
        depth = np.ndarray((H, W), np.float32, buf, off + H * W * 3)
        mask = np.ndarray((H, W), np.int16, buf, off + H * W * 7)
        sensor = np.ndarray((H, W), np.float32, buf, off + H * W * 9)
        views.append((rgb, depth, mask, sensor))
    return views


def make_renderer(spec: SceneSpec, camera: CameraConfig) -> SceneRenderer | RaycastRenderer:
    """The renderer ``camera.renderer`` names, holding a copy of the scene."""
    if camera.renderer == "raycast":
        return RaycastRenderer(spec, camera)
    return SceneRenderer(spec, camera)


def _render_one(renderer: SceneRenderer | RaycastRenderer, drone: int, T_cw: np.ndarray, style, sensor: tuple[int, int] | None) -> RawRender:
    r = renderer.render(T_cw, drone, style)
    if sensor is None:
        return r
    seed, frame_index = sensor
    return RawRender(r.rgb, r.depth_true_m, r.drone_index_mask, sensor_depth(r.depth_true_m, renderer.camera, seed, drone, frame_index))


def _process(processor: FrameProcessor, frames: list[tuple[int, np.ndarray, np.ndarray]]) -> tuple[dict[int, Any], float]:
    """Run ``processor`` over ``(key, rgb, depth)`` frames: ({key: output}, CPU seconds)."""
    if not frames:
        return {}, 0.0
    t0 = time.process_time()
    outs = processor([f[1] for f in frames], [f[2] for f in frames])
    return {f[0]: o for f, o in zip(frames, outs)}, time.process_time() - t0


def _warm_up(renderer: SceneRenderer | RaycastRenderer, process: FrameProcessor | None, batch: int) -> None:
    """One throw-away render and processor call, so the first camera tick pays no compilation or first-call set-up."""
    T = np.eye(4)
    T[:3, :3] = np.array([[0.0, 0.0, 1.0], [-1.0, 0.0, 0.0], [0.0, -1.0, 0.0]])  # level, looking along +x
    T[2, 3] = 1.5
    r = renderer.render(T, None, None)
    if process is not None and batch > 0:
        process([r.rgb] * batch, [r.depth_true_m] * batch)


def _send(conn, msg: tuple) -> bool:
    """Send ``msg`` to the flight's process; False if it is gone (interrupted while this worker was busy)."""
    try:
        conn.send(msg)
    except OSError:  # BrokenPipeError and the like: the other end is closed
        return False
    return True


def _worker_main(conn, spec: SceneSpec, camera: CameraConfig, shm_name: str, n_slots: int, processor: ProcessorSpec | None, batch: int) -> None:  # pragma: no cover - runs in a child
    shm = shared_memory.SharedMemory(name=shm_name)
    renderer = make_renderer(spec, camera)
    process = processor[0](processor[1]) if processor is not None else None
    views = _slot_views(shm.buf, n_slots, camera.height_px, camera.width_px)
    try:
        _warm_up(renderer, process, batch)
        if not _send(conn, ("ready",)):  # the flight was stopped during the warm-up: leave quietly
            return
        while True:
            try:
                msg = conn.recv()
            except (EOFError, OSError):  # the flight's process is gone without a "stop": leave quietly
                break
            if msg[0] == "stop":
                break
            if msg[0] == "scene":  # another flight's scene (RenderPool.reload): same camera, slots and processor
                fresh = make_renderer(msg[1], camera)  # built first: a failure leaves the old one to the finally
                renderer.close()
                renderer = fresh
                _warm_up(renderer, None, 0)
                if not _send(conn, ("ready",)):
                    break
                continue
            _, pos, quat, jobs, style, sensor, wanted = msg
            t0 = time.process_time()
            renderer.set_drone_poses(pos, quat)
            todo = []
            for slot, drone, T_cw in jobs:
                r = _render_one(renderer, drone, T_cw, style, sensor)
                rgb, depth, mask, sensor_view = views[slot]
                rgb[:], depth[:], mask[:] = r.rgb, r.depth_true_m, r.drone_index_mask
                if r.depth_sensor_m is not None:
                    sensor_view[:] = r.depth_sensor_m
                if process is not None and drone in wanted:
                    todo.append((slot, rgb, sensor_view if r.depth_sensor_m is not None else depth))
            render_s = time.process_time() - t0
            outs, process_s = _process(process, todo) if process is not None else ({}, 0.0)
            if not _send(conn, ("done", len(jobs), render_s, outs, len(todo), process_s)):
                break
    finally:
        del views
        renderer.close()
        shm.close()
        conn.close()


class RenderPool:
    """Parallel renderer of the drones' cameras.

    Args:
        spec: the scene (each worker builds its own copy).
        camera: camera settings (all drones share them).
        n_workers: worker processes; 0 renders in the calling process.
        processor: a frame processor to run after rendering (module docstring), or None.

    Attributes:
        processed: after :meth:`collect`, the processor's output per camera of the
            request (None where not asked, or without a processor).
        render_s, renders: CPU time [s] spent rendering (in the workers, or here
            with none), and renders made.
        process_s, processed_frames: the same for the frame processor.
    """

    def __init__(self, spec: SceneSpec, camera: CameraConfig, n_workers: int, processor: ProcessorSpec | None = None) -> None:
        if n_workers < 0:
            raise ValueError(f"n_workers={n_workers!r}: must be >= 0")
        self.spec = spec
        self.camera = camera
        self.n_workers = n_workers
        self._pending: list[tuple[int, list[tuple[int, int]]]] | None = None
        self._local: SceneRenderer | RaycastRenderer | None = None
        self._local_result: list[RawRender] | None = None
        self._local_processor: FrameProcessor | None = None
        self._local_processed: list[Any] = []
        self._workers, self._conns, self._shms, self._views = [], [], [], []
        self.render_s = 0.0
        self.renders = 0
        self.process_s = 0.0
        self.processed_frames = 0
        self.processed: list[Any] = []
        self.processor = processor
        self.has_processor = processor is not None
        self.closed = False
        # set while a message exchange with the workers is under way (cleared when it completes): one cut short by
        # an exception or Ctrl-C leaves requests and answers out of step, and such a pool is not reloaded (accepts)
        self._exchanging = False
        if n_workers == 0:
            self._local = make_renderer(spec, camera)
            self._local_processor = processor[0](processor[1]) if processor is not None else None
            return
        ctx = mp.get_context("spawn")
        H, W = camera.height_px, camera.width_px
        n_slots = spec.n_drones
        try:  # a signal while starting (a stopped sweep flight) must not leave shared memory or workers behind
            for _ in range(n_workers):
                shm = shared_memory.SharedMemory(create=True, size=max(1, n_slots * H * W * SLOT_BYTES_PER_PX))
                self._shms.append(shm)
                parent, child = ctx.Pipe()
                batch = -(-n_slots // n_workers)  # the most cameras a worker gets per tick
                proc = ctx.Process(target=_worker_main, args=(child, spec, camera, shm.name, n_slots, processor, batch), daemon=True)
                with main_module_hidden(), sigint_ignored():  # no __main__ guard needed (sim/spawn.py); no Ctrl-C traceback
                    proc.start()
                child.close()
                self._workers.append(proc)
                self._conns.append(parent)
                self._views.append(_slot_views(shm.buf, n_slots, H, W))
            self._await_ready("starting")  # built their scene and processor (started together, so in parallel)
        except BaseException:
            self.close()
            raise

    def _await_ready(self, doing: str) -> None:
        """Wait for every worker's "ready" (a start, or :meth:`reload`); RuntimeError naming ``doing`` if one is gone."""
        for w, conn in enumerate(self._conns):
            try:
                reply = conn.recv()
            except EOFError:
                raise RuntimeError(f"render worker {w} exited while {doing} (exit code {self._workers[w].exitcode})") from None
            if reply[0] != "ready":  # pragma: no cover - defensive
                raise RuntimeError(f"render worker {w} failed while {doing}: {reply!r}")

    def accepts(self, spec: SceneSpec, camera: CameraConfig, n_workers: int, processor: ProcessorSpec | None = None) -> bool:
        """Whether :meth:`reload` can take ``spec``: a pool built with these arguments would differ only in its scene
        (the same drone count, hence shared-memory slots, camera, worker count and processor), and the pool is open
        with no exchange with its workers cut short (an exception or Ctrl-C inside :meth:`submit`, :meth:`collect`
        or :meth:`reload`: such a pool is closed, which bounds its waits, and a new one started)."""
        return (
            not self.closed
            and not self._exchanging
            and spec.n_drones == self.spec.n_drones
            and camera == self.camera
            and n_workers == self.n_workers
            and processor == self.processor
        )

    def reload(self, spec: SceneSpec) -> None:
        """Load another flight's scene ``spec`` into the running workers, instead of starting new ones.

        A worker's start (a spawned process that imports the renderer and builds
        its processor, e.g. loads the detector) costs seconds; building a scene
        costs a fraction of that (measured: ``benchmarks/bench_env_reset.py``).
        Each worker builds the new scene's renderer, renders once (as at its
        start) and answers, so :meth:`reload` returns ready for the first camera
        tick. A batch never collected is collected first and dropped. The
        counters (:attr:`render_s`, :attr:`renders`, :attr:`process_s`,
        :attr:`processed_frames`) start again from zero, so they count the new
        flight's work only. Renders depend only on the scene, the poses and the
        (seed, frame index) of :meth:`submit`, so a reloaded pool renders what
        a new one would.

        Raises:
            ValueError: ``spec`` has another drone count, or the pool is closed (see :meth:`accepts`).
            RuntimeError: a worker is gone (the pool is then unusable: close it).
        """
        if self.closed or spec.n_drones != self.spec.n_drones:
            why = "the pool is closed" if self.closed else f"the scene has {spec.n_drones} drones, the pool's slots {self.spec.n_drones}"
            raise ValueError(f"reload: {why}")
        if self._pending is not None:
            self.collect()
        if self._local is not None:
            fresh = make_renderer(spec, self.camera)
            self._local.close()
            self._local = fresh
        else:
            self._exchanging = True
            for conn in self._conns:
                conn.send(("scene", spec))
            self._await_ready("loading a scene")
            self._exchanging = False
        self.spec = spec
        self.render_s, self.renders, self.process_s, self.processed_frames = 0.0, 0, 0.0, 0
        self.processed = []

    def submit(
        self,
        pos_world: np.ndarray,
        quat_xyzw: np.ndarray,
        cameras: Sequence[CameraRequest],
        style: RenderStyle | None = None,
        sensor: tuple[int, int] | None = None,
        process: Sequence[int] = (),
    ) -> None:
        """Start rendering ``cameras`` with the drones at (N, 3) / (N, 4) true poses.

        Args:
            sensor: (run seed, frame index) to also apply the depth sensor
                model (``RawRender.depth_sensor_m``); None for true depth only.
            process: drones whose frames the pool's processor runs on (sensor depth
                when ``sensor`` is given, true depth otherwise); ignored without one.
        """
        if self._pending is not None:
            raise RuntimeError("RenderPool.submit: collect() the previous batch first")
        wanted = frozenset(int(d) for d in process) if self.has_processor else frozenset()
        if self._local is not None:
            t0 = time.process_time()
            self._local.set_drone_poses(pos_world, quat_xyzw)
            self._local_result = [_render_one(self._local, d, T, style, sensor) for d, T in cameras]
            self.render_s += time.process_time() - t0
            self.renders += len(cameras)
            todo = [
                (k, r.rgb, r.depth_sensor_m if r.depth_sensor_m is not None else r.depth_true_m)
                for k, ((d, _), r) in enumerate(zip(cameras, self._local_result))
                if int(d) in wanted
            ]
            outs, process_s = _process(self._local_processor, todo) if self._local_processor is not None else ({}, 0.0)
            self.process_s += process_s
            self.processed_frames += len(todo)
            self._local_processed = [outs.get(k) for k in range(len(cameras))]
            self._pending = []
            return
        assign: list[list[tuple[int, int, np.ndarray]]] = [[] for _ in range(self.n_workers)]
        order: list[tuple[int, int]] = []
        for k, (drone, T_cw) in enumerate(cameras):
            w = k % self.n_workers
            slot = len(assign[w])
            assign[w].append((slot, int(drone), np.asarray(T_cw, float)))
            order.append((w, slot))
        self._exchanging = True
        for w, jobs in enumerate(assign):
            if jobs:
                self._conns[w].send(("render", np.asarray(pos_world, float), np.asarray(quat_xyzw, float), jobs, style, sensor, wanted))
        self._pending = [(w, []) for w, jobs in enumerate(assign) if jobs]
        self._exchanging = False
        self._order = order
        self._sensor = sensor is not None

    def collect(self) -> list[RawRender]:
        """Wait for the submitted batch; renders in the order of the request (processor outputs in :attr:`processed`)."""
        if self._pending is None:
            raise RuntimeError("RenderPool.collect: nothing submitted")
        if self._local is not None:
            out, self._local_result, self._pending = self._local_result, None, None
            self.processed = self._local_processed
            return out
        outs: dict[tuple[int, int], Any] = {}
        self._exchanging = True
        for w, _ in self._pending:
            reply = self._conns[w].recv()
            if reply[0] != "done":  # pragma: no cover - defensive
                raise RuntimeError(f"render worker {w} failed: {reply!r}")
            _, n_rendered, render_s, processed, n_processed, process_s = reply
            self.renders += n_rendered
            self.render_s += render_s
            self.processed_frames += n_processed
            self.process_s += process_s
            outs.update({(w, slot): o for slot, o in processed.items()})
        self._exchanging = False
        self._pending = None  # every answer read: a copy below that raises must not leave a batch to wait for again
        self.processed = [outs.get(key) for key in self._order]
        out = []
        for w, slot in self._order:
            rgb, depth, mask, sensor = self._views[w][slot]
            out.append(
                RawRender(rgb=rgb.copy(), depth_true_m=depth.copy(), drone_index_mask=mask.copy(), depth_sensor_m=sensor.copy() if self._sensor else None)
            )
        return out

    def render(
        self,
        pos_world: np.ndarray,
        quat_xyzw: np.ndarray,
        cameras: Sequence[CameraRequest],
        style: RenderStyle | None = None,
        sensor: tuple[int, int] | None = None,
        process: Sequence[int] = (),
    ) -> list[RawRender]:
        """Synchronous :meth:`submit` + :meth:`collect`."""
        self.submit(pos_world, quat_xyzw, cameras, style, sensor, process)
        return self.collect()

    @property
    def busy(self) -> bool:
        """Whether a batch awaits :meth:`collect`."""
        return self._pending is not None

    def close(self) -> None:
        """Stop the workers and free shared memory (idempotent)."""
        self.closed = True
        if self._local is not None:
            self._local.close()
            self._local = None
        busy = {w for w, _ in self._pending} if self._pending else set()
        for w, (conn, proc) in enumerate(zip(self._conns, self._workers)):
            try:
                # drain the answer of a batch never collected; bounded, since a Ctrl-C that cut a recv short
                # leaves the pipe mid-message and a blocking recv would wait for ever
                if w in busy and conn.poll(5.0):
                    conn.recv()
                conn.send(("stop",))
            except (BrokenPipeError, EOFError, OSError, ValueError, pickle.UnpicklingError):
                pass
            proc.join(timeout=5)
            if proc.is_alive():  # pragma: no cover
                proc.terminate()
                proc.join(timeout=5)
        self._pending = None
        self._views = []
        for shm in self._shms:
            shm.close()
            shm.unlink()
        self._workers, self._conns, self._shms = [], [], []

    def __enter__(self) -> "RenderPool":
        return self

    def __exit__(self, *exc) -> None:
        self.close()
