"""Re-fly chosen flights of a sweep with extra overrides and print their safety figures (a screen, not a result).

Usage:
    .venv/bin/python scripts/screen_flights.py SWEEP.yaml (--store STORE_DIR | --flights CELL:SEED ...)
        [--set FIELD=YAML_VALUE ...] [--jobs 2]

``--store`` picks every flight of the store STORE_DIR that counted a
collision; ``--flights`` names them (``1:36`` is cell 1, seed 36). ``--set``
overrides a scenario field for every flight (``denied.yaw.free_max_age_s=1.5``),
on top of the sweep's own overrides and the cell's axes. Prints one line per
flight (collisions, drones arrived, minimum inter-drone distance, mission
time) and the totals; ``--jsonl FILE`` also appends each flight's metrics there.

``--into STORE_DIR`` writes each flight as a row of the sweep's own store (created if absent, as `mpcde
sweep SWEEP.yaml --out STORE_DIR` creates it; flights already there are skipped), so that chosen flights can
be flown first, in a chosen order, and `mpcde sweep` resumes the rest. Refused with ``--set``: the store
holds the sweep's flights, not variants of them.

A screen is chosen *because* the flights collided, so what it shows is that a
change removes those collisions, never a success rate: a change is judged on
a sweep whose seeds were fixed before the first flight.
"""

from __future__ import annotations

import argparse
import json
import signal
import sys
from functools import partial
from pathlib import Path

import yaml

from mpcde.errors import Terminated
from mpcde.sweep.engine import FlightTask, git_revision, package_version, run_flights, share_cores_count
from mpcde.sweep.runner import prepare_flight
from mpcde.sweep.spec import load_sweep
from mpcde.sweep.store import ResultsStore, flight_row


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("sweep", type=Path)
    ap.add_argument("--store", type=Path, help="re-fly every flight of this store that collided")
    ap.add_argument("--flights", nargs="*", default=[], help="CELL:SEED pairs")
    ap.add_argument("--set", dest="sets", action="append", default=[], help="FIELD=YAML_VALUE override")
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--jsonl", type=Path, help="also append each flight's {cell, seed, git_rev, metrics} to this file")
    ap.add_argument("--into", type=Path, help="write each flight as a row of this store of the sweep (no --set)")
    args = ap.parse_args()
    if args.into is not None and args.sets:
        raise SystemExit("screen_flights: --into STORE_DIR writes the sweep's own flights: drop --set")
    spec = load_sweep(args.sweep)
    sets = {}
    for item in args.sets:
        name, _, value = item.partition("=")
        sets[name] = yaml.safe_load(value)
    cells = {c.index: c for c in spec.cells()}
    for c in cells.values():
        c.values.update(sets)  # applied after the cell's axes (an axis may set a whole mapping the override is inside)
    keys: list[tuple[int, int]] = [tuple(int(x) for x in f.split(":")) for f in args.flights]  # type: ignore[misc]
    if args.store is not None:
        keys += [(r["cell"], r["seed"]) for r in ResultsStore.read(args.store).rows() if (r.get("metrics") or {}).get("collisions")]
    store = ResultsStore.for_sweep(args.into, spec) if args.into is not None else None
    if store is not None:
        done = store.done()
        keys = [k for k in keys if k not in done]
    render_workers = share_cores_count(args.jobs) if args.jobs > 1 else None  # as `mpcde sweep` shares the cores
    tasks = [FlightTask((c, s), partial(prepare_flight, spec, cells[c], s, render_workers)) for c, s in keys]
    totals = {"flights": 0, "collisions": 0, "with_collision": 0, "all_arrived": 0}
    rev = git_revision() if args.jsonl is not None or store is not None else None  # once: every flight flies the same code
    version = package_version()

    def on_done(o) -> None:  # noqa: ANN001
        c, s = o.key
        if store is not None:
            store.append(flight_row(c, cells[c].values, s, o, version, rev))
        if o.metrics is None:
            print(f"{cells[c].label} seed {s}: FAILED {o.error}", flush=True)
            return
        m = o.metrics
        if args.jsonl is not None:
            with args.jsonl.open("a") as f:
                f.write(json.dumps({"cell": c, "seed": s, "git_rev": rev, "metrics": m}) + "\n")
        totals["flights"] += 1
        totals["collisions"] += m["collisions"]
        totals["with_collision"] += m["collisions"] > 0
        totals["all_arrived"] += m["arrived"] == m["n_drones"]
        d = m["min_inter_drone_distance_m"]
        print(f"{cells[c].label} seed {s}: collisions {m['collisions']}, arrived {m['arrived']}/{m['n_drones']}, "
              f"min distance {d if d is None else round(d, 3)} m, mission {m['mission_time_s']}"
              + (f", S_obs {m['observed_area_swarm_m2']:.1f} m^2" if "observed_area_swarm_m2" in m else ""), flush=True)  # fmt: skip

    def raise_terminated(signum: int, frame: object) -> None:
        raise Terminated()

    # SIGTERM unwinds like Ctrl-C, so the engine stops its pool workers (they used to outlive the script)
    signal.signal(signal.SIGTERM, raise_terminated)
    try:
        run_flights(tasks, on_done, jobs=args.jobs)
    except (KeyboardInterrupt, Terminated) as e:
        signal.signal(signal.SIGINT, signal.SIG_IGN)
        signal.signal(signal.SIGTERM, signal.SIG_IGN)
        print(f"screen_flights: {'interrupted' if isinstance(e, KeyboardInterrupt) else 'terminated'} after "
              f"{totals['flights']} flights (rows written stay)", file=sys.stderr)
        sys.exit(130 if isinstance(e, KeyboardInterrupt) else 143)
    print(f"total: {totals['flights']} flights, {totals['collisions']} collisions in {totals['with_collision']} flights, "
          f"{totals['all_arrived']} with every drone arrived")  # fmt: skip


if __name__ == "__main__":
    main()
