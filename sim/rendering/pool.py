"""Render many cameras in parallel: one render-only PyBullet client per worker process.

The physics client never renders. At a camera tick the loop :meth:`submit` s
the true poses of all drones and the cameras due; each worker (its own
PyBullet DIRECT client holding a copy of the scene) places the drones, renders
its share of the cameras into shared memory and answers; :meth:`collect`
waits for the answers and copies the images out. Between the two calls the
main process keeps stepping physics, so rendering overlaps with it. With
``n_workers = 0`` everything runs in-process (tests, dataset generation).

Renders are deterministic. When asked (``sensor``), the workers also
apply the depth sensor model, seeded per (seed, drone, frame index) by
:func:`sim.camera_rig.sensor_depth`, so results do not depend on the worker
count and the noise costs the main process nothing.
"""

from __future__ import annotations

import multiprocessing as mp
import pickle
import time
from multiprocessing import shared_memory
from typing import Sequence

import numpy as np

from sim.camera import CameraConfig
from sim.camera_rig import sensor_depth
from sim.rendering.raycast import RaycastRenderer
from sim.rendering.tiny import RawRender, SceneRenderer
from sim.scene import RenderStyle, SceneSpec
from sim.spawn import main_module_hidden, sigint_ignored

__all__ = ["CameraRequest", "RenderPool", "make_renderer"]

CameraRequest = tuple[int, np.ndarray]  # (drone index, true transform_camera_to_world (4, 4))


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


def _worker_main(conn, spec: SceneSpec, camera: CameraConfig, shm_name: str, n_slots: int) -> None:  # pragma: no cover - runs in a child
    shm = shared_memory.SharedMemory(name=shm_name)
    renderer = make_renderer(spec, camera)
    views = _slot_views(shm.buf, n_slots, camera.height_px, camera.width_px)
    try:
        while True:
            try:
                msg = conn.recv()
            except (EOFError, OSError):  # the flight's process is gone without a "stop": leave quietly
                break
            if msg[0] == "stop":
                break
            _, pos, quat, jobs, style, sensor = msg
            t0 = time.process_time()
            renderer.set_drone_poses(pos, quat)
            for slot, drone, T_cw in jobs:
                r = _render_one(renderer, drone, T_cw, style, sensor)
                rgb, depth, mask, sensor_view = views[slot]
                rgb[:], depth[:], mask[:] = r.rgb, r.depth_true_m, r.drone_index_mask
                if r.depth_sensor_m is not None:
                    sensor_view[:] = r.depth_sensor_m
            conn.send(("done", len(jobs), time.process_time() - t0))
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
    """

    def __init__(self, spec: SceneSpec, camera: CameraConfig, n_workers: int) -> None:
        if n_workers < 0:
            raise ValueError(f"n_workers={n_workers!r}: must be >= 0")
        self.spec = spec
        self.camera = camera
        self.n_workers = n_workers
        self._pending: list[tuple[int, list[tuple[int, int]]]] | None = None
        self._local: SceneRenderer | RaycastRenderer | None = None
        self._local_result: list[RawRender] | None = None
        self._workers, self._conns, self._shms, self._views = [], [], [], []
        self.render_s = 0.0  # CPU time [s] spent rendering (in the workers, or here with none), and renders made
        self.renders = 0
        if n_workers == 0:
            self._local = make_renderer(spec, camera)
            return
        ctx = mp.get_context("spawn")
        H, W = camera.height_px, camera.width_px
        n_slots = spec.n_drones
        try:  # a signal while starting (a stopped sweep flight) must not leave shared memory or workers behind
            for _ in range(n_workers):
                shm = shared_memory.SharedMemory(create=True, size=max(1, n_slots * H * W * SLOT_BYTES_PER_PX))
                self._shms.append(shm)
                parent, child = ctx.Pipe()
                proc = ctx.Process(target=_worker_main, args=(child, spec, camera, shm.name, n_slots), daemon=True)
                with main_module_hidden(), sigint_ignored():  # no __main__ guard needed (sim/spawn.py); no Ctrl-C traceback
                    proc.start()
                child.close()
                self._workers.append(proc)
                self._conns.append(parent)
                self._views.append(_slot_views(shm.buf, n_slots, H, W))
        except BaseException:
            self.close()
            raise

    def submit(
        self,
        pos_world: np.ndarray,
        quat_xyzw: np.ndarray,
        cameras: Sequence[CameraRequest],
        style: RenderStyle | None = None,
        sensor: tuple[int, int] | None = None,
    ) -> None:
        """Start rendering ``cameras`` with the drones at (N, 3) / (N, 4) true poses.

        Args:
            sensor: (run seed, frame index) to also apply the depth sensor
                model (``RawRender.depth_sensor_m``); None for true depth only.
        """
        if self._pending is not None:
            raise RuntimeError("RenderPool.submit: collect() the previous batch first")
        if self._local is not None:
            t0 = time.process_time()
            self._local.set_drone_poses(pos_world, quat_xyzw)
            self._local_result = [_render_one(self._local, d, T, style, sensor) for d, T in cameras]
            self.render_s += time.process_time() - t0
            self.renders += len(cameras)
            self._pending = []
            return
        assign: list[list[tuple[int, int, np.ndarray]]] = [[] for _ in range(self.n_workers)]
        order: list[tuple[int, int]] = []
        for k, (drone, T_cw) in enumerate(cameras):
            w = k % self.n_workers
            slot = len(assign[w])
            assign[w].append((slot, int(drone), np.asarray(T_cw, float)))
            order.append((w, slot))
        for w, jobs in enumerate(assign):
            if jobs:
                self._conns[w].send(("render", np.asarray(pos_world, float), np.asarray(quat_xyzw, float), jobs, style, sensor))
        self._pending = [(w, []) for w, jobs in enumerate(assign) if jobs]
        self._order = order
        self._sensor = sensor is not None

    def collect(self) -> list[RawRender]:
        """Wait for the submitted batch; renders in the order of the request."""
        if self._pending is None:
            raise RuntimeError("RenderPool.collect: nothing submitted")
        if self._local is not None:
            out, self._local_result, self._pending = self._local_result, None, None
            return out
        for w, _ in self._pending:
            reply = self._conns[w].recv()
            if reply[0] != "done":  # pragma: no cover - defensive
                raise RuntimeError(f"render worker {w} failed: {reply!r}")
            self.renders += reply[1]
            self.render_s += reply[2]
        out = []
        for w, slot in self._order:
            rgb, depth, mask, sensor = self._views[w][slot]
            out.append(
                RawRender(rgb=rgb.copy(), depth_true_m=depth.copy(), drone_index_mask=mask.copy(), depth_sensor_m=sensor.copy() if self._sensor else None)
            )
        self._pending = None
        return out

    def render(
        self,
        pos_world: np.ndarray,
        quat_xyzw: np.ndarray,
        cameras: Sequence[CameraRequest],
        style: RenderStyle | None = None,
        sensor: tuple[int, int] | None = None,
    ) -> list[RawRender]:
        """Synchronous :meth:`submit` + :meth:`collect`."""
        self.submit(pos_world, quat_xyzw, cameras, style, sensor)
        return self.collect()

    @property
    def busy(self) -> bool:
        """Whether a batch awaits :meth:`collect`."""
        return self._pending is not None

    def close(self) -> None:
        """Stop the workers and free shared memory."""
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
