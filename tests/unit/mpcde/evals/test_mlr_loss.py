"""Loss sweeps of the kinematic MLR-DMPC swarm (mpcde eval-mlr --sweep): the file's checks, the run, the table."""

from __future__ import annotations

import json
import math
from pathlib import Path

import pytest

from mpcde.cli import main
from mpcde.errors import ConfigError
from mpcde.evals.mlr_loss import format_loss_table, load_loss_sweep, run_loss_sweep

ROOT = Path(__file__).resolve().parents[4]

TINY = """\
swarm: {uavs: [3], compute_units: 2, duration_s: 2.0}
seeds: {first: 4, count: 2}
conditions:
  ideal: {loss_model: none}
  lossy: {loss_model: bernoulli, loss_probability: 0.3}
variants:
  plain: {mlr: {}}
  ignore: {ignore_message_loss: true}
"""


def _write(tmp_path: Path, text: str) -> Path:
    path = tmp_path / "sweep.yaml"
    path.write_text(text)
    return path


@pytest.mark.parametrize(
    ("edit", "message"),
    [
        (("uavs: [3]", "uavs: [3], speed: 2"), "swarm.speed=2: unknown key"),
        (("loss_probability: 0.3", "loss_probability: 1.5"), "conditions.lossy.loss_probability=1.5: "),
        (("mlr: {}", "mlr: {repeat_trajectory: 1}"), "variants.plain.mlr.repeat_trajectory=1: "),
        (("mlr: {}", "mlr: {n_uavs: 5}"), "variants.plain.mlr.n_uavs=5: unknown key"),
        (("mlr: {}", "mlr: {soft_weight: -1.0}"), "variants.plain.mlr.soft_weight=-1.0: "),
        (("compute_units: 2", "compute_units: 3"), "variants.plain.compute_units=3: an integer < swarm.uavs = 3"),
        (("count: 2", "count: 0"), "seeds.count=0: an integer >= 1"),
        (("uavs: [3]", "uavs: []"), "swarm.uavs=[]: a non-empty list"),
    ],
)
def test_a_bad_sweep_file_is_one_line_naming_the_field(tmp_path, edit, message):
    with pytest.raises(ConfigError) as e:
        load_loss_sweep(_write(tmp_path, TINY.replace(*edit)))
    assert str(e.value).startswith(message) and "\n" not in str(e.value)


def test_the_cli_refuses_it_with_exit_status_2_and_writes_nothing(tmp_path, capsys):
    path = _write(tmp_path, TINY.replace("count: 2", "count: -1"))
    assert main(["eval-mlr", "--sweep", str(path), "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "seeds.count=-1" in err[0] and not (tmp_path / "out").exists()


def test_the_kept_sweep_files_load():
    paths = sorted((ROOT / "data" / "sweeps" / "mlr").glob("*.yaml"))
    assert paths
    for path in paths:
        sweep = load_loss_sweep(path)
        assert sweep.runs() and len(sweep.seeds) >= 10


@pytest.mark.slow
def test_a_sweep_flies_every_run_the_same_way_twice_and_tabulates_them(tmp_path, capsys):
    sweep = load_loss_sweep(_write(tmp_path, TINY))
    rows = run_loss_sweep(sweep, tmp_path / "a", jobs=1)
    assert [(r["uavs"], r["condition"], r["variant"], r["seed"]) for r in rows] == sweep.runs() and len(rows) == 8
    again = json.loads((tmp_path / "a" / "results.json").read_text())["rows"]
    assert [r["min_distance_m"] for r in again] == pytest.approx([r["min_distance_m"] for r in rows])
    assert (tmp_path / "a" / "arrivals.png").stat().st_size > 0
    table = (tmp_path / "a" / "table.md").read_text().strip()
    assert table == format_loss_table(rows) and len(table.splitlines()) == 2 + 4
    ideal = [r for r in rows if r["condition"] == "ideal" and r["variant"] == "plain"]
    assert all(r["rounds_with_mlr"] == 0 and r["collisions"] == 0 for r in ideal)
    lossy = [r for r in rows if r["condition"] == "lossy" and r["variant"] == "plain"]
    assert sum(r["rounds_with_mlr"] for r in lossy) > 0 and all(r["collisions"] == 0 for r in lossy)
    rerun = run_loss_sweep(sweep, tmp_path / "b", jobs=2)  # the same seed gives the same metrics, in processes too
    for r1, r2 in zip(rows, rerun):
        assert {k: v for k, v in r1.items() if "ms" not in k and k != "wall_s"} == {
            k: v for k, v in r2.items() if "ms" not in k and k != "wall_s"
        } or (math.isnan(r1["arrival_time_s"]) and math.isnan(r2["arrival_time_s"]))
