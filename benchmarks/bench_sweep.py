"""Benchmark: what the sweep machinery costs per flight, and flights per hour of the denied stack with cameras.

Overhead (issue 27's goal: ``--jobs 2`` within 1.2x of back-to-back / 2):
``--flights`` 1-second flights of ``crossing`` without cameras (min-jerk
line and DMPC alternating, seeds 0..), first flown back to back in this
process by :func:`mpcde.sweep.engine.fly_task` (the baseline: the flight
alone, no store, no pool), then as one ``mpcde sweep`` with ``--jobs 2``
(spawned workers, the task pickled out and back, a row appended and fsynced
per flight, the progress bar, the report at the end). Printed: the median
flight of the baseline, both totals, the ratio sweep / (back-to-back / 2),
per-flight overhead and flights per hour.

Denied with cameras: ``--denied-flights`` flights of ``radio_outage`` in
``--mode denied`` (MP-CDE: cameras, detector, tracks, map, yaw planner,
MINCO), ``--jobs 2``, the scenario's own 40-s limit (a flight ends 1 s after
every drone arrived): flights per hour on this machine.

Render pool kept: ``--pool-flights`` 2-second camera flights of ``crossing``
over the radio (DMPC; each renders and detects), ``--jobs 2``, once with a
render pool per flight (the baseline, ``keep_pools=False``) and once with each
worker keeping its pool across its flights (the default), after an untimed
2-flight sweep: the wall time of each sweep and the ratio kept / baseline.

Run: ``.venv/bin/python benchmarks/bench_sweep.py [--flights 200] [--denied-flights 4] [--pool-flights 8]``
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import numpy as np

from mpcde.flight.loop import prepare_run
from mpcde.sweep.engine import FlightTask, fly_task
from mpcde.sweep.runner import run_sweep
from mpcde.sweep.spec import sweep_from_dict


def _tiny(flights: int) -> dict:
    return {
        "base": "crossing", "seeds": max(1, flights // 2), "overrides": {"duration_s": 1.0, "run.cameras": False},
        "axes": {"planner.kind": ["min_jerk_line", "dmpc"]},
    }  # fmt: skip


def _pools(flights: int) -> None:
    camera = {"base": "crossing", "overrides": {"duration_s": 2.0, "planner.kind": "dmpc"}}
    spec = sweep_from_dict({**camera, "seeds": flights})
    walls = {}
    with tempfile.TemporaryDirectory() as tmp:  # untimed: the detector's and the renderer's files read once, numba's caches warm
        run_sweep(sweep_from_dict({**camera, "seeds": 2}), Path(tmp) / "warm", jobs=2, progress=False)
    for keep in (False, True):
        with tempfile.TemporaryDirectory() as tmp:
            t0 = time.perf_counter()
            counts = run_sweep(spec, Path(tmp) / "pools", jobs=2, progress=False, keep_pools=keep)
            walls[keep] = time.perf_counter() - t0
            assert counts["flown"] == flights, counts
    print(f"render pool kept: {flights} flights of crossing over the radio (DMPC, cameras), 2 s simulated, --jobs 2")
    print(f"  a pool per flight (baseline)            {walls[False]:8.1f} s   {1e3 * walls[False] / flights:8.0f} ms per flight")
    print(f"  each worker keeps its pool              {walls[True]:8.1f} s   {1e3 * walls[True] / flights:8.0f} ms per flight")
    print(f"  ratio kept / baseline                   {walls[True] / walls[False]:8.3f}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--flights", type=int, default=200, help="1-second no-camera flights (even)")
    ap.add_argument("--denied-flights", type=int, default=4, help="radio_outage denied flights with cameras (0: skip)")
    ap.add_argument("--pool-flights", type=int, default=8, help="2-s camera flights per sweep, pool kept vs one per flight (0: skip)")
    ap.add_argument("--quick", action="store_true", help="40 tiny flights, 2 denied ones, 4 per pool sweep")
    args = ap.parse_args()
    if args.quick:
        args.flights, args.denied_flights, args.pool_flights = 40, 2, 4
    spec = sweep_from_dict(_tiny(args.flights))
    tasks = [FlightTask((c.index, s), prepare_run(spec.scenario(c, s))) for s in spec.seeds for c in spec.cells()]
    fly_task(tasks[0])  # warm: numba caches, imports
    walls = []
    t0 = time.perf_counter()
    for t in tasks:
        t1 = time.perf_counter()
        assert fly_task(t).error is None
        walls.append(time.perf_counter() - t1)
    back_to_back = time.perf_counter() - t0
    with tempfile.TemporaryDirectory() as tmp:
        t0 = time.perf_counter()
        counts = run_sweep(spec, Path(tmp) / "sweep", jobs=2, progress=False)
        sweep_s = time.perf_counter() - t0
        from mpcde.sweep.report import write_report

        write_report(Path(tmp) / "sweep")
        report_s = time.perf_counter() - t0 - sweep_s
    n = len(tasks)
    ideal = back_to_back / 2
    print(f"sweep overhead: {n} flights of crossing, 1 s simulated, no cameras, min_jerk_line + dmpc")
    print(f"  one flight (median of {n}, in-process)   {1e3 * float(np.median(walls)):8.1f} ms")
    print(f"  back to back, one process (baseline)    {back_to_back:8.1f} s")
    print(f"  run_sweep --jobs 2 (workers' start, prepare, flights, store)  {sweep_s:8.1f} s   ({counts['flown']} flown, {counts['failed']} failed)")
    print(f"  + report at the end                     {report_s:8.1f} s")
    for label, total in (("sweep", sweep_s), ("sweep + report", sweep_s + report_s)):
        ratio = total / ideal
        print(f"  ratio {label} / (baseline / 2)   {ratio:8.2f}   goal <= 1.20: {'met' if ratio <= 1.2 else 'NOT met'}")
    print(f"  overhead per flight                     {1e3 * (sweep_s - ideal) / n:8.1f} ms   flights per hour {3600 * n / sweep_s:8.0f}")
    if args.pool_flights > 0:
        _pools(args.pool_flights)
    if args.denied_flights > 0:
        denied = sweep_from_dict({"base": "radio_outage", "seeds": args.denied_flights, "axes": {"planner.kind": ["mpcde"]}})
        with tempfile.TemporaryDirectory() as tmp:
            t0 = time.perf_counter()
            counts = run_sweep(denied, Path(tmp) / "denied", jobs=2, progress=False)
            wall = time.perf_counter() - t0
            from mpcde.sweep.store import ResultsStore

            sims = [r["metrics"]["sim_time_s"] for r in ResultsStore.read(Path(tmp) / "denied").rows() if r["metrics"]]
        print(f"denied stack with cameras: radio_outage --mode denied, seeds 0..{args.denied_flights - 1}, --jobs 2")
        print(f"  {counts['flown']} flown, {counts['failed']} failed in {wall:.0f} s; simulated {np.mean(sims):.1f} s per flight (mean)")
        print(f"  flights per hour                        {3600 * counts['flown'] / wall:8.1f}")


if __name__ == "__main__":
    main()
