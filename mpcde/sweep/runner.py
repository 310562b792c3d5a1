"""``mpcde sweep``: fly every (cell, seed) of a sweep file that its store does not hold yet, appending each row as it lands.

Running the same command again resumes: the flights already in
``DIR/results.jsonl`` (flown or failed) are not flown again, and a folder
made by another sweep file is refused (:mod:`mpcde.sweep.store`). Flights are
ordered seed by seed (a seed's cells fly side by side) and flown by
:func:`mpcde.sweep.engine.run_flights` on local processes or Ray. Every cell
was checked when the sweep file was read; each flight is prepared in its
worker (a seed whose layout is refused, a start inside an obstacle say, is a
failed row naming the field), so the main process stays off the cores the
flights use.
"""

from __future__ import annotations

import time
from dataclasses import replace
from functools import partial
from pathlib import Path
from typing import Any

from mpcde.errors import ConfigError
from mpcde.sweep.engine import FlightOutcome, FlightTask, cpus_of, git_revision, package_version, run_flights, share_cores_count
from mpcde.sweep.spec import Cell, SweepSpec
from mpcde.sweep.store import ResultsStore, flight_row

__all__ = ["RAY_RENDER_WORKERS", "run_sweep", "run_folder_name"]

RAY_RENDER_WORKERS = 1
"""Render workers of a camera flight on Ray whose ``run.render_workers`` is automatic; it reserves one CPU more."""


def prepare_flight(spec: SweepSpec, cell: Cell, seed: int, render_workers: int | None) -> Any:
    """The prepared run of ``cell`` flown with ``seed`` (in the worker); an automatic ``run.render_workers`` set to ``render_workers``."""
    from mpcde.flight.loop import prepare_run

    prepared = prepare_run(spec.scenario(cell, seed))
    run = prepared.config.run
    if render_workers is None or run.render_workers >= 0:
        return prepared
    return replace(prepared, config=replace(prepared.config, run=replace(run, render_workers=render_workers)))


def run_folder_name(cell: int, seed: int) -> str:
    """``runs/<name>``: the run folder of a kept flight."""
    return f"cell{cell:04d}-seed{seed}"


def run_sweep(
    spec: SweepSpec, out: str | Path, jobs: int = 1, backend: str = "local", ray_address: str | None = None, progress: bool = True,
    keep_pools: bool = True,
) -> dict[str, Any]:
    """Fly what ``out``'s store is missing of ``spec``; returns counts: ``total``, ``recorded_before``, ``flown``, ``failed``.

    ``keep_pools``: as in :func:`mpcde.sweep.engine.run_flights` (False: a render pool per flight, the benchmark's baseline).

    Raises:
        ConfigError: a folder of another sweep, a corrupt store (before a
            flight is flown), an unknown backend or an unreachable Ray cluster.
    """
    out = Path(out)
    if isinstance(jobs, bool) or not isinstance(jobs, int) or jobs < 1:
        raise ConfigError("--jobs", jobs, "an integer >= 1")
    done = ResultsStore.read(out).done() if (out / "sweep.json").exists() else set()
    cells = spec.cells()
    by_index = {c.index: c for c in cells}
    todo = [(c, s) for s in spec.seeds for c in cells if (c.index, s) not in done]
    render_workers = RAY_RENDER_WORKERS if backend == "ray" else (share_cores_count(jobs) if jobs > 1 else None)
    cpus = {}  # per cell, what a Ray task reserves (the run options do not depend on the seed)
    if backend == "ray":
        for cell in cells:
            run = spec.scenario(cell, spec.seeds[0]).run
            cpus[cell.index] = cpus_of(replace(run, render_workers=render_workers) if run.render_workers < 0 else run)
    tasks = [
        FlightTask(
            (cell.index, seed), partial(prepare_flight, spec, cell, seed, render_workers),
            out / "runs" / run_folder_name(cell.index, seed) if spec.keep_run_folders else None, spec.keep_videos,
            cpus=cpus.get(cell.index),
        )
        for cell, seed in todo
    ]  # fmt: skip
    holder: dict[str, ResultsStore] = {}

    def open_store() -> list[FlightTask]:
        holder["store"] = ResultsStore.for_sweep(out, spec)  # the sweep file was checked: every cell loads
        return tasks

    version, revision = package_version(), git_revision()
    counts = {"total": len(cells) * len(spec.seeds), "recorded_before": len(done), "flown": 0, "failed": 0}

    from tqdm import tqdm

    bar = tqdm(total=counts["total"], initial=len(done), disable=not progress, desc="sweep", unit="flight", smoothing=0.0)
    t0 = time.perf_counter()

    def on_done(o: FlightOutcome) -> None:
        cell, seed = o.key
        holder["store"].append(flight_row(cell, by_index[cell].values, seed, o, version, revision))
        counts["flown" if o.error is None else "failed"] += 1
        bar.update(1)
        bar.set_postfix(done=counts["flown"] + counts["recorded_before"], failed=counts["failed"])
        if o.error is not None and progress:
            bar.write(f"failed: cell {by_index[cell].label}, seed {seed}: {o.error}")

    try:
        run_flights(open_store, on_done, jobs=jobs, backend=backend, ray_address=ray_address, keep_pools=keep_pools)
    finally:
        bar.close()
    counts["wall_s"] = time.perf_counter() - t0
    return counts
