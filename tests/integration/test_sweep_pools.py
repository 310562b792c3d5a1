"""A sweep's flights keep one render pool per process (mpcde/sweep/engine.py, ``keep_pools``): the same metrics, fewer pools.

Two camera flights of the crossing pair flown one after the other, once with
the pool kept and once with a pool per flight: every metric but the
wall-clock ones (the loop's, and the agents' own millisecond timings) is
identical, and the kept run started one pool and loaded the second scene into
it. At the end the keeper is closed: no render worker outlives the run.
"""

from __future__ import annotations

import multiprocessing as mp
import re

import pytest

from mpcde import load_scenario
from mpcde.flight.loop import prepare_run
from mpcde.sweep import engine
from mpcde.sweep.engine import FlightTask, run_flights
from sim.rendering import pool_keeper

pytestmark = pytest.mark.slow

_WALL_CLOCK = ("real_time_factor", "compute_time", "wall_time_s")
_MEASURED = re.compile(r"_ms(_|$)")  # the agents' own timings (qp_solve_ms, tracking_ms_median, ...): wall clock too


def _flown(metrics):
    """``metrics`` without what the wall clock measured."""
    if isinstance(metrics, dict):
        return {k: _flown(v) for k, v in metrics.items() if k not in _WALL_CLOCK and not _MEASURED.search(k)}
    if isinstance(metrics, list):
        return [_flown(v) for v in metrics]
    return metrics


def _tasks() -> list[FlightTask]:
    return [FlightTask(seed, prepare_run(load_scenario("crossing", mode="comm", seed=seed, duration_s=1.5))) for seed in (0, 1)]


def _fly(keep_pools: bool) -> dict[int, dict]:
    outcomes = {}
    run_flights(_tasks(), lambda o: outcomes.__setitem__(o.key, o), jobs=1, keep_pools=keep_pools)
    assert all(o.error is None for o in outcomes.values()), [o.error for o in outcomes.values()]
    return {k: _flown(o.metrics) for k, o in outcomes.items()}


def test_flights_with_the_pool_kept_are_the_flights_with_a_pool_each(monkeypatch):
    keepers: list[pool_keeper.PoolKeeper] = []

    class Recorded(pool_keeper.PoolKeeper):
        def __init__(self, *args, **kwargs) -> None:
            super().__init__(*args, **kwargs)
            keepers.append(self)

    monkeypatch.setattr(pool_keeper, "PoolKeeper", Recorded)
    kept = _fly(keep_pools=True)
    (keeper,) = keepers
    assert (keeper.started, keeper.reloaded) == (1, 1)
    assert keeper.pool is None and engine._KEEPER is None  # closed at the end of the run
    assert not mp.active_children()  # its render workers are gone
    assert kept[0]["render_workers"] and kept[0]["frames_rendered"] > 0  # camera flights, rendered by workers
    each = _fly(keep_pools=False)
    assert keepers == [keeper]  # no keeper without keep_pools
    assert kept == each, "\n".join(_differences(kept, each))


def _differences(a, b, path: str = "") -> list[str]:
    """The key paths where ``a`` and ``b`` differ (for the assertion message)."""
    if isinstance(a, dict) and isinstance(b, dict):
        return [d for k in sorted(set(a) | set(b), key=str) for d in _differences(a.get(k), b.get(k), f"{path}.{k}")]
    if isinstance(a, list) and isinstance(b, list) and len(a) == len(b):
        return [d for i, (x, y) in enumerate(zip(a, b)) for d in _differences(x, y, f"{path}[{i}]")]
    return [] if a == b else [f"{path}: {a!r} != {b!r}"]
