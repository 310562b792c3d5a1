"""A sweep store as `mpcde sweep` writes it, and the `mpcde` command run in process, for the tests of the paper's
reports (imported by the test files beside it)."""

from __future__ import annotations

import json
from pathlib import Path

from mpcde.cli import main

REV = "0" * 40
"""The revision every written row records."""
YAWS = [{"method": "zhou"}, {"exploring_mode": False}, {"tracking_mode": False}, {}]
"""Table III's four methods as ``denied.yaw`` axis values, in the sweep files' order."""


def write_store(folder: Path, axes: list, rows: list[dict], overrides: dict | None = None, *, base: str = "forest_dense", seeds: int = 10) -> Path:
    """``folder`` (created) holding sweep.json with its digest (a sweep of ``base`` over ``axes`` with ``overrides``,
    seeds 0..``seeds``-1) and results.jsonl with every row key (``rows`` give cell, seed and metrics; a row without
    metrics is a failed flight). Returns ``folder``."""
    folder.mkdir(parents=True)
    sweep = {"axes": axes, "base": {"name": base}, "overrides": overrides or {}, "seeds": list(range(seeds))}
    (folder / "sweep.json").write_text(json.dumps({"digest": "d" * 16, "sweep": sweep}))
    full = [{"values": {}, "status": "ok" if r.get("metrics") else "failed", "error": None if r.get("metrics") else "x",
             "metrics": None, "wall_s": 1.0, "version": "0", "git_rev": REV, **r} for r in rows]  # fmt: skip
    (folder / "results.jsonl").write_text("".join(json.dumps(r) + "\n" for r in full))
    return folder


def mpcde(*argv: object) -> int:
    """The exit status of ``mpcde ARGV...`` run in this process (argparse's refusals exit with SystemExit)."""
    try:
        return main([str(a) for a in argv])
    except SystemExit as e:
        return int(e.code)


AREAS = {0: [500.0, 520.0], 1: [400.0, 410.0], 2: [505.0, 515.0], 3: [440.0, 460.0]}
"""S_obs [m^2] of each cell (method) of :func:`table3_store`, seeds 0 and 1."""


def table3_store(root: Path) -> Path:
    """``root``/table3: a store of density 4, Table III's four methods, two seeds each (:data:`AREAS`); one failure in
    "ours", one failed flight of Zhou's."""
    axes = [["world.obstacle_density_per_100m2", [4.0]], ["denied.yaw", YAWS]]
    rows = []
    for cell, areas in AREAS.items():
        for seed, area in enumerate(areas):
            ok = not (cell == 3 and seed == 1)  # one failure, in "ours"
            rows.append({"cell": cell, "seed": seed, "metrics": {"observed_area_swarm_m2": area, "success": ok}})
    rows.append({"cell": 0, "seed": 2, "metrics": None})  # a failed flight is left out
    return write_store(root / "table3", axes, rows)
