"""`mpcde explain` (mpcde.evals.explain): which flights of a store are re-flown, what is appended, how it resumes
and how the causes are counted per cell. The re-flight itself (mpcde.evals.collision_causes.explain_flight) is
replaced by a stand-in here; test_collision_causes.py flies it."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from mpcde.errors import ConfigError
from mpcde.evals import explain
from mpcde.evals.collision_causes import CollisionCause
from mpcde.sweep.spec import load_sweep

REV = "0" * 40


def _sweep(tmp_path: Path) -> Path:
    path = tmp_path / "sweep.yaml"
    path.write_text("base: crossing\nseeds: 3\naxes:\n  planner.cruise_speed_mps: [0.5, 1.0]\n")
    return path


def _store(folder: Path, collisions: dict[tuple[int, int], int]) -> Path:
    """A store of the two cells x three seeds; ``collisions`` by (cell, seed), 0 elsewhere; cell 1 seed 2 failed."""
    folder.mkdir()
    (folder / "sweep.json").write_text(json.dumps({"digest": "d" * 16, "sweep": {"axes": [], "seeds": [0, 1, 2]}}))
    rows = []
    for cell in (0, 1):
        for seed in (0, 1, 2):
            metrics = None if (cell, seed) == (1, 2) else {"collisions": collisions.get((cell, seed), 0)}
            rows.append({"cell": cell, "values": {}, "seed": seed, "status": "ok" if metrics else "failed", "error": None, "metrics": metrics,
                         "wall_s": 1.0, "version": "0", "git_rev": REV})  # fmt: skip
    (folder / "results.jsonl").write_text("".join(json.dumps(r) + "\n" for r in rows))
    return folder


@pytest.fixture
def flown(monkeypatch):
    """The flights the stand-in re-flew, (seed, cruise speed [m/s]); it counts one collision more on seed 2."""
    seen = []

    def fake(cfg):  # noqa: ANN001, ANN202
        seen.append((cfg.seed, cfg.planner.cruise_speed_mps))
        causes = [CollisionCause(3.0, "drone", [0, 1], "never in view"), CollisionCause(4.0, "obstacle", [1], "map miss")]
        return {"collisions": 2 + (cfg.seed == 2)}, causes

    monkeypatch.setattr(explain, "explain_flight", fake)
    return seen


def test_each_colliding_flight_is_flown_once_appended_and_counted_per_cell(tmp_path, flown):
    spec = load_sweep(_sweep(tmp_path))
    store = _store(tmp_path / "store", {(0, 1): 2, (0, 2): 2, (1, 0): 2})
    printed = []
    rows, done = explain.explain_store(spec, store, limit=2, on_entry=lambda e: printed.append(explain.entry_line(e)))
    assert flown == [(1, 0.5), (2, 0.5)] and len(done) == 2  # the limit: the first two, in the store's order
    assert printed[0] == "planner.cruise_speed_mps=0.5 seed 1: drone [0, 1] never in view, obstacle [1] map miss"
    assert len((store / explain.CAUSES_FILE).read_text().splitlines()) == 2
    rows, done = explain.explain_store(spec, store)  # resumes: only what is left
    assert flown == [(1, 0.5), (2, 0.5), (0, 1.0)] and len(done) == 3
    explain.explain_store(spec, store)
    assert len(flown) == 3  # nothing left to fly
    assert explain.causes_table(spec, rows, done).splitlines() == [
        f"{'cell':<52} {'flights':>7} {'with coll.':>10}  causes (events)",
        f"{'planner.cruise_speed_mps=0.5':<52} {3:>7} {2:>10}  never in view 2, map miss 2  (1 not reproduced)",  # seed 2: 3 != 2
        f"{'planner.cruise_speed_mps=1.0':<52} {2:>7} {1:>10}  never in view 1, map miss 1",  # a failed flight has no metrics
    ]


def test_a_row_outside_the_sweep_or_a_corrupt_causes_file_is_one_line(tmp_path, flown):
    spec = load_sweep(_sweep(tmp_path))
    store = _store(tmp_path / "store", {(0, 1): 2})
    (store / explain.CAUSES_FILE).write_text("{not json\n")
    with pytest.raises(ConfigError, match="collision_causes.jsonl line 1="):
        explain.explain_store(spec, store)
    (store / explain.CAUSES_FILE).unlink()
    text = (store / "results.jsonl").read_text()
    (store / "results.jsonl").write_text(text.replace('"cell": 1,', '"cell": 7,', 1))
    with pytest.raises(ConfigError, match=r"^store line 4: cell=7: a cell of the sweep file, 0\.\.1"):
        explain.explain_store(spec, store)
    assert flown == []
