"""A sweep on a local Ray instance gives the local backend's rows; Ctrl-C leaves a store the same command completes."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time

import pytest

from mpcde.sweep.runner import run_sweep
from mpcde.sweep.spec import sweep_from_dict
from mpcde.sweep.store import ResultsStore, without_wall_clock

from interruptible import start_interruptible  # tests/integration/interruptible.py

pytestmark = pytest.mark.slow

TINY = {
    "base": "crossing", "seeds": 2, "overrides": {"duration_s": 0.5, "run.cameras": False},
    "axes": {"planner.kind": ["min_jerk_line", "dmpc"], "planner.cruise_speed_mps": [0.5, 1.0]},
}  # fmt: skip


def _rows(folder):
    return {(r["cell"], r["seed"]): (r["values"], r["status"], without_wall_clock(r["metrics"])) for r in ResultsStore.read(folder).rows()}


@pytest.fixture
def local_ray():
    ray = pytest.importorskip("ray")
    ray.init(num_cpus=2, include_dashboard=False, log_to_driver=False, configure_logging=False)
    yield ray
    ray.shutdown()


def test_ray_and_local_backends_record_identical_rows(tmp_path, local_ray):
    spec = sweep_from_dict(TINY)
    run_sweep(spec, tmp_path / "local", jobs=2, progress=False)
    counts = run_sweep(spec, tmp_path / "ray", backend="ray", progress=False)
    assert counts["flown"] == 8 and counts["failed"] == 0
    local, ray_rows = _rows(tmp_path / "local"), _rows(tmp_path / "ray")
    assert len(local) == 8 and local == ray_rows  # wall-clock metrics aside, the same flights


def test_ctrl_c_records_what_finished_and_the_same_command_flies_only_the_rest(tmp_path):
    sweep = tmp_path / "s.yaml"
    sweep.write_text(
        "base: crossing\nseeds: 6\noverrides: {duration_s: 15.0, run.cameras: false}\naxes: {planner.kind: [min_jerk_line, dmpc]}\n"
    )
    out = tmp_path / "out"
    cmd = [sys.executable, "-m", "mpcde", "sweep", str(sweep), "--out", str(out), "--jobs", "2", "--quiet"]
    p = start_interruptible(cmd)
    deadline = time.monotonic() + 120
    while time.monotonic() < deadline and not ((out / "results.jsonl").exists() and len((out / "results.jsonl").read_text().splitlines()) >= 2):
        time.sleep(0.2)
    os.killpg(p.pid, signal.SIGINT)  # what a terminal's Ctrl-C does: the whole process group
    _, err = p.communicate(timeout=120)
    assert p.returncode == 130
    assert err.strip().splitlines() == [f"mpcde: interrupted; the flights recorded so far are in {out}: run the same command to resume"]
    before = {(r["cell"], r["seed"]) for r in ResultsStore.read(out).rows()}
    assert 2 <= len(before) < 12
    r = subprocess.run(cmd, capture_output=True, text=True, timeout=600)
    assert r.returncode == 0, r.stderr[-2000:]
    keys = [(row["cell"], row["seed"]) for row in ResultsStore.read(out).rows()]
    assert sorted(keys) == sorted((c, s) for c in range(2) for s in range(6))  # none lost, none twice
    assert f"{12 - len(before)} flown, 0 failed, {len(before)} recorded before, of 12" in r.stdout
