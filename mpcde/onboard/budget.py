"""Per-component compute time of a flight (DESIGN.md section 6, "per-component compute time").

One :class:`ComputeBudget` per run. The loop times physics, detection and
the wait for renders; the render workers time their own renders and report
them with each batch; the agents time their pieces (track, map insertion,
ESDF, yaw planning, front end, optimiser, DMPC QP). ``metrics.json`` carries
the result under ``compute_time`` and ``mpcde fly`` prints the three
largest. These are wall-clock figures of this machine, so like
``real_time_factor`` they are not part of a run's reproducible metrics.

Components (seconds spent inside each, summed over drones; wall time of the
main process, so on a loaded machine a figure includes the time the process
was descheduled):

* ``render``: the CPU time of rendering the cameras and applying the depth
  sensor model (in the render workers when there are any, so it overlaps
  the main process); ``render_wait``: wall time the main process blocked
  waiting for a render batch;
* ``physics``: PyBullet step, SE(3) controller and motor model at 240 Hz;
* ``detect``: the batched detector (pre-processing, forward, decoding); its
  CPU time in the render workers when they run it (then, like ``render``, it
  overlaps the main process), the main process's wall time otherwise;
* ``track``: back-projection and the Kalman tracker;
* ``map_insert``: depth-frame integration into the occupancy map;
* ``esdf``: Euclidean distance transforms of the map;
* ``yaw``: the active yaw planner;
* ``front_end``: A* path search (with the neighbour capsules);
* ``optimiser``: MINCO problem set-up and L-BFGS;
* ``dmpc_qp``: the DMPC round (QP set-up and OSQP);
* ``other``: the rest of the main process (loop, radio, metrics, logging).
"""

from __future__ import annotations

import time
from collections.abc import Iterator
from contextlib import contextmanager
from typing import Any

__all__ = ["COMPONENTS", "ComputeBudget"]

COMPONENTS = (
    "render", "render_wait", "physics", "detect", "track", "map_insert", "esdf",
    "yaw", "front_end", "optimiser", "dmpc_qp",
)  # fmt: skip
# measured outside the main process (they overlap it): not subtracted from the main process' wall time
_OFF_MAIN = frozenset({"render"})


class ComputeBudget:
    """Accumulates seconds and calls per component name."""

    def __init__(self) -> None:
        self.total_s: dict[str, float] = {}
        self.calls: dict[str, int] = {}
        self.off_main: set[str] = set(_OFF_MAIN)

    def add(self, name: str, seconds: float, calls: int = 1, off_main: bool = False) -> None:
        """Add ``seconds`` [s] and ``calls`` calls to component ``name``.

        ``off_main``: the seconds were spent outside the main process (CPU time of a
        worker), so :meth:`result` does not subtract them from the main process's wall time.
        """
        self.total_s[name] = self.total_s.get(name, 0.0) + float(seconds)
        self.calls[name] = self.calls.get(name, 0) + int(calls)
        if off_main:
            self.off_main.add(name)

    @contextmanager
    def measure(self, name: str) -> Iterator[None]:
        """Time the body of a ``with`` block as one call of ``name``."""
        t0 = time.perf_counter()
        try:
            yield
        finally:
            self.add(name, time.perf_counter() - t0)

    def result(self, sim_time_s: float, main_wall_s: float | None = None) -> dict[str, dict[str, Any]]:
        """Per component: ``total_s``, ``calls``, ``ms_per_call`` and ``ms_per_sim_s``, largest total first.

        ``main_wall_s``: the main process' wall time of the run [s]; when given,
        ``other`` is what of it no main-process component accounts for.
        """
        totals = dict(self.total_s)
        calls = dict(self.calls)
        if main_wall_s is not None:
            on_main = sum(v for k, v in totals.items() if k not in self.off_main)
            totals["other"] = max(main_wall_s - on_main, 0.0)
            calls["other"] = 1
        out = {}
        for name in sorted(totals, key=lambda k: -totals[k]):
            n = calls[name]
            out[name] = {
                "total_s": round(totals[name], 4),
                "calls": n,
                "ms_per_call": round(1e3 * totals[name] / n, 4) if n else None,
                "ms_per_sim_s": round(1e3 * totals[name] / sim_time_s, 3) if sim_time_s > 0 else None,
            }
        return out

    @staticmethod
    def top(result: dict[str, dict[str, Any]], k: int = 3) -> str:
        """One line naming the ``k`` largest components of a :meth:`result`."""
        items = sorted(result.items(), key=lambda kv: -kv[1]["total_s"])[:k]
        return ", ".join(f"{name} {v['total_s']:.1f} s ({v['ms_per_call']:.2f} ms x {v['calls']})" for name, v in items)
