"""A sweep store as `mpcde sweep` writes it, for the tests of the report scripts (imported by test_paper_summary.py,
test_paper_goals.py and test_swarm_modes_report.py)."""

from __future__ import annotations

import json
from pathlib import Path

REV = "0" * 40
"""The revision every written row records."""


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
