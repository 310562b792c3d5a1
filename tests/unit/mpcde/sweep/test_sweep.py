"""``mpcde sweep`` and ``mpcde report``: the sweep file's checks, the resumable store, local runs, the report."""

from __future__ import annotations

import json
import signal

import pytest

from mpcde.cli import main
from mpcde.errors import ConfigError
from mpcde.sweep.report import build_report
from mpcde.sweep.runner import run_sweep
from mpcde.sweep.spec import load_sweep, sweep_from_dict
from mpcde.sweep.store import ResultsStore, without_wall_clock

TINY = """\
base: crossing
seeds: 2
overrides:
  duration_s: 0.5
  run.cameras: false
axes:
  planner.kind: [min_jerk_line, dmpc]
  planner.cruise_speed_mps: [0.5, 1.0]
"""


@pytest.fixture
def tiny(tmp_path):
    path = tmp_path / "tiny.yaml"
    path.write_text(TINY)
    return load_sweep(path)


def test_cells_are_the_product_of_the_axes_and_every_cell_flies_every_seed(tiny):
    cells = tiny.cells()
    assert [c.values for c in cells] == [
        {"planner.kind": k, "planner.cruise_speed_mps": v} for k in ("min_jerk_line", "dmpc") for v in (0.5, 1.0)
    ]
    a, b = tiny.scenario(cells[0], 1), tiny.scenario(cells[3], 1)
    assert (a.planner.kind, a.planner.cruise_speed_mps, a.seed, a.duration_s) == ("min_jerk_line", 0.5, 1, 0.5)
    assert (b.planner.kind, b.seed, b.run.cameras) == ("dmpc", 1, False)


def test_a_sweep_file_read_as_a_record_skips_the_cell_checks_only(tmp_path):
    """A kept store's file may name a cell today's rules refuse; read as a record its keys and axes are still checked."""
    path = tmp_path / "record.yaml"
    path.write_text(TINY.replace("[0.5, 1.0]", "[0.5, 1.0e+300]"))
    with pytest.raises(ConfigError, match=r"^axes\.planner\.cruise_speed_mps\[1\]"):
        load_sweep(path)
    assert len(load_sweep(path, check_cells=False).cells()) == 4
    path.write_text(TINY.replace("axes:", "axis:"))
    with pytest.raises(ConfigError, match="^axis"):
        load_sweep(path, check_cells=False)


def test_a_held_out_split_is_its_own_seed_range(tmp_path):
    path = tmp_path / "held_out.yaml"
    path.write_text(TINY.replace("seeds: 2", "seeds: {first: 1000, count: 3}"))
    spec = load_sweep(path)
    assert spec.seeds == (1000, 1001, 1002)
    assert spec.scenario(spec.cells()[0], 1002).seed == 1002


@pytest.mark.parametrize(
    "text, field",
    [
        ("base: crossing\nseeds: 2\naxis: {}\n", "axis"),
        ("base: nowhere\nseeds: 2\n", "base"),
        ("base: crossing\nseeds: 0\n", "seeds"),
        ("base: crossing\nseeds: {first: 1000}\n", "seeds.count"),
        ("base: crossing\nseeds: {first: -1, count: 5}\n", "seeds.first"),
        ("base: crossing\nseeds: {first: 10, count: 5, step: 2}\n", "seeds.step"),
        ("base: crossing\nseeds: 2\naxes: {planner.kind: dmpc}\n", "axes.planner.kind"),
        ("base: crossing\nseeds: 2\naxes: {planner.kind: [dmpc, dmpc]}\n", "axes.planner.kind"),
        ("base: crossing\nseeds: 2\naxes: {planner.kind: [dmpc, teleport]}\n", "axes.planner.kind[1]"),
        ("base: crossing\nseeds: 2\naxes: {planner.cruise_speed_mps: [1.0, 1.0e+300]}\n", "axes.planner.cruise_speed_mps[1]"),
        ("base: crossing\nseeds: 2\naxes: {wrold.size: [1, 2]}\n", "axes.wrold.size[0]"),
        ("base: crossing\nseeds: 2\naxes: {seed: [1, 2]}\n", "axes.seed"),
        ("base: crossing\nseeds: 2\nkeep: {videos: true}\n", "keep.videos"),
        ("base: crossing\nseeds: 2\nkeep: {logs: true}\n", "keep.logs"),
    ],
)
def test_a_bad_sweep_file_is_one_line_naming_the_field_exit_2_and_nothing_written(tmp_path, capsys, text, field):
    path = tmp_path / "bad.yaml"
    path.write_text(text)
    out = tmp_path / "out"
    assert main(["sweep", str(path), "--out", str(out), "--quiet"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith(f"mpcde: error: {field}="), err
    assert not out.exists()


def test_a_sweep_records_every_flight_once_and_resumes_after_an_interruption(tmp_path, tiny, monkeypatch):
    out = tmp_path / "out"
    appended = []
    real_append = ResultsStore.append

    def interrupted_append(self, row):  # Ctrl-C after the third recorded flight
        real_append(self, row)
        appended.append((row["cell"], row["seed"]))
        if len(appended) == 3:
            raise KeyboardInterrupt

    monkeypatch.setattr(ResultsStore, "append", interrupted_append)
    with pytest.raises(KeyboardInterrupt):
        run_sweep(tiny, out, progress=False)
    monkeypatch.setattr(ResultsStore, "append", real_append)
    assert len(ResultsStore.read(out).rows()) == 3
    with open(out / "results.jsonl", "a") as f:  # a crash in the middle of a write leaves a cut line
        f.write('{"cell": 3, "seed"')
    counts = run_sweep(tiny, out, progress=False)
    assert (counts["recorded_before"], counts["flown"], counts["failed"]) == (3, 5, 0)
    rows = ResultsStore.read(out).rows()
    keys = [(r["cell"], r["seed"]) for r in rows]
    assert sorted(keys) == sorted((c, s) for c in range(4) for s in range(2)) and len(set(keys)) == 8  # none twice, none lost
    row = rows[0]
    assert row["status"] == "ok" and row["error"] is None and row["version"] and "success" in row["metrics"]
    assert set(row["values"]) == {"planner.kind", "planner.cruise_speed_mps"} and row["wall_s"] > 0
    again = run_sweep(tiny, out, progress=False)
    assert again["flown"] == 0 and again["recorded_before"] == 8  # complete: nothing to fly


def test_two_jobs_record_the_same_rows_as_one(tmp_path, tiny):
    run_sweep(tiny, tmp_path / "one", progress=False)
    run_sweep(tiny, tmp_path / "two", jobs=2, progress=False)

    def rows(folder):
        return {(r["cell"], r["seed"]): without_wall_clock(r["metrics"]) for r in ResultsStore.read(folder).rows()}

    assert rows(tmp_path / "one") == rows(tmp_path / "two")


def test_an_interrupted_pool_has_closed_its_wakeup_pipe_before_the_interrupt_reaches_the_caller(tmp_path, tiny, monkeypatch):
    """Python 3.11's exit hook writes to each process pool's wake-up pipe unless it is marked closed; a pool
    still closing it when the interrupt was raised printed an EBADF traceback after the one-line message (seen in CI)."""
    from concurrent.futures import process

    real_append = ResultsStore.append

    def interrupted_append(self, row):  # Ctrl-C after the first recorded flight, two flights at once
        real_append(self, row)
        raise KeyboardInterrupt

    monkeypatch.setattr(ResultsStore, "append", interrupted_append)
    before = set(process._threads_wakeups)
    sigint = signal.getsignal(signal.SIGINT)  # the interrupt path ignores Ctrl-C from then on; the rest of the session must not
    try:
        with pytest.raises(KeyboardInterrupt):
            run_sweep(tiny, tmp_path / "out", jobs=2, progress=False)
    finally:
        signal.signal(signal.SIGINT, sigint)
    # The sweep's pool: still listed while its manager thread runs (the failure), or gone once the ended thread is freed.
    ours = [(t.is_alive(), w._closed) for t, w in process._threads_wakeups.items() if t not in before]
    assert ours in ([], [(False, True)])


def test_a_folder_of_another_sweep_or_a_corrupt_store_is_refused_in_one_line(tmp_path, tiny, capsys):
    out = tmp_path / "out"
    run_sweep(tiny, out, progress=False)
    other = tmp_path / "other.yaml"
    other.write_text(TINY.replace("seeds: 2", "seeds: 3"))
    assert main(["sweep", str(other), "--out", str(out), "--quiet"]) == 2
    assert "different sweep" in capsys.readouterr().err
    lines = (out / "results.jsonl").read_text().splitlines()
    (out / "results.jsonl").write_text("\n".join(lines[:2] + ["not json"] + lines[2:]) + "\n")
    assert main(["report", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "store line 3" in err[0] and "corrupt" in err[0]
    plain = tmp_path / "plain"
    plain.mkdir()
    (plain / "notes.txt").write_text("mine")
    with pytest.raises(ConfigError, match="holds no sweep"):
        ResultsStore.for_sweep(plain, tiny)


def test_the_report_runs_on_a_partial_store_and_pairs_cells_one_axis_apart(tmp_path, tiny, capsys):
    out = tmp_path / "out"
    run_sweep(tiny, out, progress=False)
    lines = (out / "results.jsonl").read_text().splitlines()
    (out / "results.jsonl").write_text("\n".join(lines[:5]) + "\n")  # a sweep still running
    assert main(["report", str(out)]) == 0
    text = capsys.readouterr().out
    assert "5 of 8 flights recorded" in text
    report = build_report(out)
    assert [c["flights"] for c in report["cells"]] == [2, 1, 1, 1]  # seed by seed: all of seed 0, then cell 0 of seed 1
    assert len(report["pairs"]) == 4  # 2 kinds x 1 speed pair + 2 speeds x 1 kind pair
    assert {p["axis"] for p in report["pairs"]} == {"planner.kind", "planner.cruise_speed_mps"}
    for name in ("report.txt", "report.md", "report.json", "success_planner_cruise_speed_mps.png"):
        assert (out / name).is_file()
    assert json.loads((out / "report.json").read_text())["recorded"] == 5


def test_the_sweep_file_resolves_a_relative_base_next_to_it(tmp_path):
    (tmp_path / "scen.yaml").write_text("name: mine\ndrones: {layout: antipodal, count: 2}\nrun: {cameras: false}\n")
    spec = sweep_from_dict({"base": "scen.yaml", "seeds": 1}, tmp_path)
    assert spec.scenario(spec.cells()[0], 0).name == "mine" and spec.cells()[0].label == "base"


def test_a_flight_that_raises_is_a_failed_row_and_the_sweep_goes_on(tmp_path, tiny, monkeypatch):
    import mpcde.flight.loop as loop

    real = loop.run_scenario

    def flaky(prepared, *args, **kwargs):
        if prepared.config.seed == 1 and prepared.config.planner.kind == "dmpc":
            raise RuntimeError("motor driver\nfault")  # a two-line message: the row keeps one line
        return real(prepared, *args, **kwargs)

    monkeypatch.setattr(loop, "run_scenario", flaky)
    counts = run_sweep(tiny, tmp_path / "out", progress=False)
    assert (counts["flown"], counts["failed"]) == (6, 2)
    failed = [r for r in ResultsStore.read(tmp_path / "out").rows() if r["status"] == "failed"]
    assert sorted(r["cell"] for r in failed) == [2, 3] and all(r["seed"] == 1 and r["metrics"] is None for r in failed)
    assert all(r["error"].startswith("RuntimeError: motor driver at ") and "\n" not in r["error"] for r in failed)
    report = build_report(tmp_path / "out")
    assert [c["failed"] for c in report["cells"]] == [0, 0, 1, 1] and [c["flights"] for c in report["cells"]] == [2, 2, 1, 1]


def test_an_address_where_no_ray_cluster_answers_is_one_line_and_writes_nothing(tmp_path, capsys):
    pytest.importorskip("ray")
    path = tmp_path / "tiny.yaml"
    path.write_text(TINY)
    out = tmp_path / "out"
    assert main(["sweep", str(path), "--out", str(out), "--backend", "ray", "--ray-address", "127.0.0.1:1", "--quiet"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("mpcde: error: --ray-address='127.0.0.1:1': nothing answers there"), err
    assert not out.exists()  # the store is opened only once the cluster answered
