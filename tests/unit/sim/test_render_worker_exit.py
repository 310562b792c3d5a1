"""A render worker whose flight is gone (interrupted during its warm-up) leaves quietly: no traceback on stderr."""

from __future__ import annotations

import multiprocessing
from multiprocessing import shared_memory

from sim.bullet.scene import SceneSpec
from sim.camera import CameraConfig
from sim.rendering.pool import SLOT_BYTES_PER_PX, _send, _worker_main


def test_send_reports_a_closed_pipe_instead_of_raising() -> None:
    parent, child = multiprocessing.Pipe()
    assert _send(child, ("ready",)) and parent.recv() == ("ready",)
    parent.close()
    assert _send(child, ("ready",)) is False


def test_a_worker_whose_flight_closed_the_pipe_during_warm_up_returns_quietly(capfd) -> None:
    camera = CameraConfig(width_px=64, height_px=48)
    shm = shared_memory.SharedMemory(create=True, size=2 * 64 * 48 * SLOT_BYTES_PER_PX)
    parent, child = multiprocessing.Pipe()
    parent.close()  # the flight's process is gone before the worker says "ready"
    try:
        _worker_main(child, SceneSpec(obstacles=(), n_drones=2), camera, shm.name, 2, None, 0)
    finally:
        shm.close()
        shm.unlink()
    assert "Traceback" not in capfd.readouterr().err
