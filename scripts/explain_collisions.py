"""Name the cause of every collision in a sweep's store: re-fly each colliding flight with the recorder of
mpcde/evals/collision_causes.py and tabulate the causes per cell (issue 29, part 5).

Usage: .venv/bin/python scripts/explain_collisions.py SWEEP.yaml STORE_DIR [--limit N]

Reads STORE_DIR/results.jsonl (written by `mpcde sweep SWEEP.yaml --out STORE_DIR`), flies again every
(cell, seed) whose metrics count a collision (flights are deterministic: the re-flight must count the same
collisions, or the row is reported as not reproduced), appends one JSON line per flight to
STORE_DIR/collision_causes.jsonl (flights already there are skipped, so it resumes) and prints the
causes per cell.
"""

from __future__ import annotations

import argparse
import json
from collections import Counter
from pathlib import Path

from mpcde.evals.collision_causes import CAUSES, explain_flight
from mpcde.sweep.spec import load_sweep
from mpcde.sweep.store import ResultsStore


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("sweep", type=Path)
    ap.add_argument("store", type=Path)
    ap.add_argument("--limit", type=int, default=None, help="explain at most this many new flights")
    args = ap.parse_args()
    spec = load_sweep(args.sweep)
    cells = {c.index: c for c in spec.cells()}
    rows = ResultsStore.read(args.store).rows()
    out_path = args.store / "collision_causes.jsonl"
    done = {}
    if out_path.exists():
        for line in out_path.read_text().splitlines():
            r = json.loads(line)
            done[(r["cell"], r["seed"])] = r
    todo = [r for r in rows if (r.get("metrics") or {}).get("collisions") and (r["cell"], r["seed"]) not in done]
    for r in todo[: args.limit]:
        cfg = spec.scenario(cells[r["cell"]], r["seed"])
        metrics, causes = explain_flight(cfg)
        entry = {
            "cell": r["cell"], "label": cells[r["cell"]].label, "seed": r["seed"],
            "reproduced": metrics["collisions"] == r["metrics"]["collisions"],
            "causes": [{"time_s": c.time_s, "kind": c.kind, "drones": c.drones, "cause": c.cause, "detail": c.detail} for c in causes],
        }  # fmt: skip
        with out_path.open("a") as f:
            f.write(json.dumps(entry) + "\n")
        done[(r["cell"], r["seed"])] = entry
        print(f"{entry['label']} seed {entry['seed']}: " + ", ".join(f"{c['kind']} {c['drones']} {c['cause']}" for c in entry["causes"]), flush=True)
    flights = Counter(r["cell"] for r in rows if r.get("metrics"))
    print(f"\n{'cell':<52} {'flights':>7} {'with coll.':>10}  causes (events)")
    for index in sorted(flights):
        entries = [e for (c, _), e in done.items() if c == index]
        counts = Counter(c["cause"] for e in entries for c in e["causes"])
        text = ", ".join(f"{k} {counts[k]}" for k in CAUSES if counts[k]) or "-"
        not_rep = sum(not e["reproduced"] for e in entries)
        print(f"{cells[index].label:<52} {flights[index]:>7} {len(entries):>10}  {text}" + (f"  ({not_rep} not reproduced)" if not_rep else ""))


if __name__ == "__main__":
    main()
