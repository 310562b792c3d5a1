"""`mpcde bench`: runs the benchmark scripts, collects their output, all or nothing; bad input is exit 2."""

import json
from pathlib import Path

import pytest

import mpcde.evals.bench as bench
from mpcde.cli import main

REPO = Path(__file__).resolve().parents[4]


def test_every_benchmark_script_is_listed_and_every_listed_one_exists():
    scripts = {p.stem.removeprefix("bench_") for p in (REPO / "benchmarks").glob("bench_*.py")}
    assert scripts == {b.name for b in bench.BENCHMARKS}


@pytest.mark.parametrize("argv, field", [(["teleport"], "benchmark"), (["tracker", "nope"], "benchmark")])
def test_unknown_benchmark_is_one_line_exit_2_and_writes_nothing(tmp_path, capsys, argv, field):
    out = tmp_path / "b"
    assert main(["bench", *argv, "--out", str(out), "--quiet"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith(f"mpcde: error: {field}=") and "one of sim, detector" in err[0]
    assert list(tmp_path.iterdir()) == []


def test_a_non_empty_out_is_refused_without_overwrite(tmp_path, capsys):
    out = tmp_path / "b"
    out.mkdir()
    (out / "keep.txt").write_text("x")
    assert main(["bench", "tracker", "--out", str(out), "--quiet"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("mpcde: error: --out=")
    assert [p.name for p in out.iterdir()] == ["keep.txt"]


def _fake_benchmarks(folder: Path, exit_codes: dict[str, int]) -> Path:
    """A benchmarks/ folder whose scripts print their argv and exit with the given codes."""
    folder.mkdir()
    (folder / "timing.py").write_text("")
    for name, code in exit_codes.items():
        (folder / f"bench_{name}.py").write_text(
            f"import os, sys\nprint('{name}', sys.argv[1:], 'omp', os.environ['OMP_NUM_THREADS'])\nsys.exit({code})\n"
        )
    return folder


def test_outputs_exit_codes_and_quick_args_are_collected(tmp_path, monkeypatch, capsys):
    fake = _fake_benchmarks(tmp_path / "benchmarks", {"tracker": 0, "dmpc": 3})
    monkeypatch.setattr(bench, "benchmarks_dir", lambda: fake)
    monkeypatch.delenv("OMP_NUM_THREADS", raising=False)
    out = tmp_path / "b"
    assert main(["bench", "dmpc", "tracker", "--out", str(out), "--quick", "--quiet"]) == 1  # one failed
    results = json.loads((out / "results.json").read_text())
    assert results["quick"] is True and results["machine"]["omp_num_threads"] == "1"
    assert [(r["name"], r["exit_code"]) for r in results["rows"]] == [("dmpc", 3), ("tracker", 0)]  # order given
    assert results["rows"][0]["command"] == "python benchmarks/bench_dmpc.py --seeds 1"
    assert (out / "bench_tracker.txt").read_text() == "tracker ['--frames', '300'] omp 1\n"
    assert [p.name for p in tmp_path.iterdir() if p.name.startswith(".")] == []  # no staging left
    assert "exit 3" in capsys.readouterr().out


def test_overwrite_replaces_the_old_folder(tmp_path, monkeypatch):
    fake = _fake_benchmarks(tmp_path / "benchmarks", {"map": 0})
    monkeypatch.setattr(bench, "benchmarks_dir", lambda: fake)
    out = tmp_path / "b"
    out.mkdir()
    (out / "old.txt").write_text("x")
    assert main(["bench", "map", "--out", str(out), "--overwrite", "--quiet"]) == 0
    assert sorted(p.name for p in out.iterdir()) == ["bench_map.txt", "results.json"]
    assert (out / "bench_map.txt").read_text() == "map [] omp 1\n"


@pytest.mark.slow
def test_the_real_tracker_benchmark_runs_and_prints_its_figures(tmp_path):
    out = tmp_path / "b"
    assert main(["bench", "tracker", "--out", str(out), "--quick", "--quiet"]) == 0
    results = json.loads((out / "results.json").read_text())
    assert [(r["name"], r["exit_code"]) for r in results["rows"]] == [("tracker", 0)]
    text = (out / "bench_tracker.txt").read_text()
    assert "median of 300 frames" in text and "(baseline)" in text and "speed-up x" in text
