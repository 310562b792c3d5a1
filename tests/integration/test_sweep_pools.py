"""A sweep's flights keep one render pool per process (mpcde/sweep/engine.py, ``keep_pools``): the same metrics, fewer pools.

Two camera flights of the crossing pair flown one after the other, once with
the pool kept and once with a pool per flight: every metric but the
wall-clock ones (the loop's, and the agents' own millisecond timings) is
identical, the render and detection call counts included, and the kept run
started one pool and loaded the second scene into it. At the end the keeper is
closed: no render worker outlives the run. Then four flights on two workers:
each worker keeps its pool and closes it when the pool shuts down, leaving no
shared memory behind.
"""

from __future__ import annotations

import multiprocessing as mp
import re
import time
from pathlib import Path

import pytest

from mpcde import load_scenario
from mpcde.flight.loop import prepare_run
from mpcde.sweep.engine import FlightTask, run_flights
from sim.rendering import pool_keeper

pytestmark = pytest.mark.slow

_WALL_CLOCK = ("real_time_factor", "wall_time_s")
_MEASURED = re.compile(r"_ms(_|$)")  # the agents' own timings (qp_solve_ms, tracking_ms_median, ...): wall clock too


def _flown(metrics):
    """``metrics`` without what the wall clock measured (``compute_time`` reduced to its call counts)."""
    if isinstance(metrics, dict):
        return {
            k: ({c: v["calls"] for c, v in metrics[k].items()} if k == "compute_time" else _flown(v))
            for k, v in metrics.items() if k not in _WALL_CLOCK and not _MEASURED.search(k)
        }  # fmt: skip
    if isinstance(metrics, list):
        return [_flown(v) for v in metrics]
    return metrics


def _tasks(seeds) -> list[FlightTask]:
    return [FlightTask(seed, prepare_run(load_scenario("crossing", mode="comm", seed=seed, duration_s=1.5))) for seed in seeds]


def _fly(keep_pools: bool, seeds=(0, 1), jobs: int = 1) -> dict[int, dict]:
    outcomes = {}
    run_flights(_tasks(seeds), lambda o: outcomes.__setitem__(o.key, o), jobs=jobs, keep_pools=keep_pools)
    assert sorted(outcomes) == list(seeds) and all(o.error is None for o in outcomes.values()), [o.error for o in outcomes.values()]
    return {k: _flown(o.metrics) for k, o in outcomes.items()}


def _differences(a, b, path: str = "") -> list[str]:
    """The key paths where ``a`` and ``b`` differ (for the assertion message)."""
    if isinstance(a, dict) and isinstance(b, dict):
        return [d for k in sorted(set(a) | set(b), key=str) for d in _differences(a.get(k), b.get(k), f"{path}.{k}")]
    if isinstance(a, list) and isinstance(b, list) and len(a) == len(b):
        return [d for i, (x, y) in enumerate(zip(a, b)) for d in _differences(x, y, f"{path}[{i}]")]
    return [] if a == b else [f"{path}: {a!r} != {b!r}"]


def _segments() -> set[str]:
    return {p.name for p in Path("/dev/shm").glob("psm_*")}  # multiprocessing.shared_memory's names


def _no_new_segments(before: set[str], wait_s: float = 15.0) -> bool:
    """Whether every shared-memory segment made since ``before`` is gone (within ``wait_s``; /dev/shm is the
    machine's, so this assumes no other process makes one meanwhile, as in CI's serial run)."""
    deadline = time.monotonic() + wait_s
    while not _segments() <= before:
        if time.monotonic() > deadline:
            return False
        time.sleep(0.2)
    return True


def test_flights_with_the_pool_kept_are_the_flights_with_a_pool_each(monkeypatch):
    keepers: list[pool_keeper.PoolKeeper] = []

    class Recorded(pool_keeper.PoolKeeper):
        def __init__(self, *args, **kwargs) -> None:
            super().__init__(*args, **kwargs)
            keepers.append(self)

    monkeypatch.setattr(pool_keeper, "PoolKeeper", Recorded)
    children, segments = set(mp.active_children()), _segments()
    kept = _fly(keep_pools=True)
    (keeper,) = keepers
    assert (keeper.started, keeper.reloaded) == (1, 1)
    assert keeper.pool is None  # closed at the end of the run
    assert set(mp.active_children()) <= children and _no_new_segments(segments)  # its render workers and memory are gone
    assert kept[0]["render_workers"] and kept[0]["frames_rendered"] > 0 and kept[1]["compute_time"]["render"] > 0
    each = _fly(keep_pools=False)
    assert [(k.started, k.reloaded) for k in keepers[1:]] == [(2, 0)]  # a new pool per flight
    assert kept == each, "\n".join(_differences(kept, each))


def test_two_workers_keep_their_pools_and_close_them_at_the_end():
    segments = _segments()
    flown = _fly(keep_pools=True, seeds=(0, 1, 2, 3), jobs=2)
    assert all(m["frames_rendered"] > 0 for m in flown.values())
    assert _no_new_segments(segments)  # every worker closed its kept pool before it exited
