"""The cause of every collision in a sweep's store, per cell (``mpcde explain SWEEP.yaml STORE_DIR [--limit N]``).

Each (cell, seed) of the store whose metrics count a collision is flown again with the recorder of
:mod:`mpcde.evals.collision_causes` (flights are deterministic: the re-flight must count the same collisions, or
the entry says it was not reproduced). One JSON line per explained flight is appended to
``STORE_DIR/collision_causes.jsonl`` (:data:`CAUSES_FILE`); flights already there are not flown again, so a run
resumes where it stopped. The table gives, per cell, the flights recorded, those with a collision explained and
the causes' counts (events).
"""

from __future__ import annotations

import json
from collections import Counter
from collections.abc import Callable
from pathlib import Path
from typing import Any

from mpcde.errors import ConfigError
from mpcde.evals.collision_causes import CAUSES, explain_flight
from mpcde.sweep.spec import SweepSpec
from mpcde.sweep.store import ResultsStore

__all__ = ["CAUSES_FILE", "causes_table", "entry_line", "explain_store", "explained"]

CAUSES_FILE = "collision_causes.jsonl"
"""The file in the store that holds one explained flight per line."""


def explained(folder: Path) -> dict[tuple[int, int], dict[str, Any]]:
    """The flights of ``folder``'s :data:`CAUSES_FILE` by (cell, seed) ({} when there is none); ConfigError (one line)
    for a line that is not an entry :func:`explain_store` writes."""
    path = Path(folder) / CAUSES_FILE
    done: dict[tuple[int, int], dict[str, Any]] = {}
    if not path.exists():
        return done
    for i, line in enumerate(path.read_text().splitlines(), start=1):
        try:
            entry = json.loads(line)
            done[(entry["cell"], entry["seed"])] = entry
        except (ValueError, KeyError, TypeError):
            raise ConfigError(f"{path} line {i}", line[:60], "an entry `mpcde explain` wrote (cell, label, seed, reproduced, causes)") from None
    return done


def entry_line(entry: dict[str, Any]) -> str:
    """One explained flight as the command prints it: its cell's label, seed, and each event's kind, drones and cause."""
    return f"{entry['label']} seed {entry['seed']}: " + ", ".join(f"{c['kind']} {c['drones']} {c['cause']}" for c in entry["causes"])


def explain_store(
    spec: SweepSpec, folder: Path, limit: int | None = None, on_entry: Callable[[dict[str, Any]], None] | None = None,
) -> tuple[list[dict[str, Any]], dict[tuple[int, int], dict[str, Any]]]:  # fmt: skip
    """Explain the colliding flights of ``folder``'s store that are not explained yet, at most ``limit`` of them.

    Each new entry is appended to :data:`CAUSES_FILE` as it is made and handed to ``on_entry``. Returns (the store's
    rows, every explained flight by (cell, seed)). ConfigError (one line): not a store, a corrupt row or causes
    file, or a row whose cell ``spec`` does not have.
    """
    folder = Path(folder)
    cells = {c.index: c for c in spec.cells()}
    rows = ResultsStore.read(folder).rows()
    for i, r in enumerate(rows, start=1):
        if not isinstance(r["cell"], int) or r["cell"] not in cells:
            raise ConfigError(f"store line {i}: cell", r["cell"], f"a cell of the sweep file, 0..{len(cells) - 1}: the sweep the store was flown from")
    done = explained(folder)
    todo = [r for r in rows if (r.get("metrics") or {}).get("collisions") and (r["cell"], r["seed"]) not in done]
    for r in todo[:limit]:
        metrics, causes = explain_flight(spec.scenario(cells[r["cell"]], r["seed"]))
        entry = {
            "cell": r["cell"], "label": cells[r["cell"]].label, "seed": r["seed"],
            "reproduced": metrics["collisions"] == r["metrics"]["collisions"],
            "causes": [{"time_s": c.time_s, "kind": c.kind, "drones": c.drones, "cause": c.cause, "detail": c.detail} for c in causes],
        }  # fmt: skip
        with (folder / CAUSES_FILE).open("a") as f:
            f.write(json.dumps(entry) + "\n")
        done[(r["cell"], r["seed"])] = entry
        if on_entry is not None:
            on_entry(entry)
    return rows, done


def causes_table(spec: SweepSpec, rows: list[dict[str, Any]], done: dict[tuple[int, int], dict[str, Any]]) -> str:
    """The causes per cell (one line each under a header, no last newline): the cell's label, its flights with
    metrics, those with a collision explained, each cause's count of events (:data:`CAUSES`' order) and how many
    re-flights did not reproduce the store's collisions."""
    cells = {c.index: c for c in spec.cells()}
    flights = Counter(r["cell"] for r in rows if r.get("metrics"))
    lines = [f"{'cell':<52} {'flights':>7} {'with coll.':>10}  causes (events)"]
    for index in sorted(flights):
        entries = [e for (c, _), e in done.items() if c == index]
        counts = Counter(c["cause"] for e in entries for c in e["causes"])
        text = ", ".join(f"{k} {counts[k]}" for k in CAUSES if counts[k]) or "-"
        not_rep = sum(not e["reproduced"] for e in entries)
        lines.append(f"{cells[index].label:<52} {flights[index]:>7} {len(entries):>10}  {text}" + (f"  ({not_rep} not reproduced)" if not_rep else ""))
    return "\n".join(lines)
