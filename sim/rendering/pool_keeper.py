"""One render pool kept across flights, so that a flight's start does not start render workers again.

Starting a :class:`sim.rendering.pool.RenderPool` spawns its worker processes,
each of which imports the renderer and builds its frame processor (the
detector); stopping one joins them. Together that is most of a short flight's
set-up: the PettingZoo and Gymnasium environments (:mod:`mpcde.env`) start a
flight at every ``reset``. A :class:`PoolKeeper` hands out the pool it holds
when the next flight's camera, drone count, worker count and processor match
(:meth:`RenderPool.accepts`), with the new flight's scene loaded into the
running workers (:meth:`RenderPool.reload`); otherwise it closes it and starts
a new one. Its owner closes the keeper (and with it the pool) at the end; until
then the pool's worker processes and shared memory stay, between flights too.
A keeper serves one flight at a time: the next :meth:`PoolKeeper.get` reloads
the pool under any flight still using it (the environments close an episode's
session before they start the next).
Measured: ``benchmarks/bench_env_reset.py``.
"""

from __future__ import annotations

from sim.bullet.scene import SceneSpec
from sim.camera import CameraConfig
from sim.rendering.pool import ProcessorSpec, RenderPool

__all__ = ["PoolKeeper"]


class PoolKeeper:
    """Holds at most one :class:`RenderPool` and hands it to consecutive flights (module docstring).

    Args:
        reuse: False: every :meth:`get` closes the held pool and starts a new one (what a flight without a
            keeper does; the benchmark's baseline).

    Attributes:
        pool: the pool held (None before the first :meth:`get` and after :meth:`close`).
        started, reloaded: pools started, and flights that got the held pool with a new scene.
    """

    def __init__(self, reuse: bool = True) -> None:
        self.reuse = reuse
        self.pool: RenderPool | None = None
        self.started = 0
        self.reloaded = 0

    def get(self, spec: SceneSpec, camera: CameraConfig, n_workers: int, processor: ProcessorSpec | None = None) -> RenderPool:
        """A pool rendering ``spec``, as ``RenderPool(spec, camera, n_workers, processor)`` would be.

        The held pool with ``spec`` loaded when it accepts these arguments, else a
        new one (the held one closed first). A held pool that fails to load the
        scene (a worker gone) is closed and replaced.
        """
        if self.reuse and self.pool is not None and self.pool.accepts(spec, camera, n_workers, processor):
            try:
                self.pool.reload(spec)
                self.reloaded += 1
                return self.pool
            except (RuntimeError, OSError, EOFError):  # a worker is gone: start afresh
                pass
        self.close()
        self.pool = RenderPool(spec, camera, n_workers, processor)
        self.started += 1
        return self.pool

    def close(self) -> None:
        """Close the held pool (idempotent)."""
        if self.pool is not None:
            pool, self.pool = self.pool, None
            pool.close()

    def __enter__(self) -> "PoolKeeper":
        return self

    def __exit__(self, *exc) -> None:
        self.close()
