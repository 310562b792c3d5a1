"""Ctrl-C and SIGTERM during a flight: one stderr line, exit 130 / 143, no --out, no staging folder, no traceback.

Each case starts ``python -m mpcde fly`` in its own process group (as a
terminal's foreground job is), waits until the run folder is being staged,
and sends the signal: SIGINT to the whole group (what Ctrl-C does, so the
render workers get it too), SIGTERM to the main process (what ``kill`` does).
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from mpcde.errors import MpcdeError
from mpcde.flight.run_folder import RunFolder

from interruptible import start_interruptible  # tests/integration/interruptible.py

pytestmark = pytest.mark.slow


def _start_and_signal(tmp_path: Path, sig: int, group: bool) -> tuple[int, str, Path]:
    out = tmp_path / "run"
    cmd = [sys.executable, "-m", "mpcde", "fly", "forest_swarm", "--mode", "denied", "--duration", "20", "--out", str(out), "--quiet"]
    p = start_interruptible(cmd)
    deadline = time.monotonic() + 120
    while time.monotonic() < deadline and not list(tmp_path.glob(".run.partial-*")):
        time.sleep(0.1)
    time.sleep(3.0)  # flying, render workers up
    if group:
        os.killpg(p.pid, sig)
    else:
        os.kill(p.pid, sig)
    _, err = p.communicate(timeout=120)
    return p.returncode, err, out


@pytest.mark.parametrize("sig, group, code, line", [
    (signal.SIGINT, True, 130, "mpcde: interrupted, nothing written"),
    (signal.SIGTERM, False, 143, "mpcde: terminated, nothing written"),
])  # fmt: skip
def test_a_signal_during_a_flight_is_one_line_and_leaves_nothing(tmp_path, sig, group, code, line):
    rc, err, out = _start_and_signal(tmp_path, sig, group)
    assert rc == code, err[-3000:]
    assert err.strip().splitlines() == [line], err[-3000:]
    assert not out.exists() and not list(tmp_path.glob(".run.partial-*"))


def test_publishing_never_deletes_a_folder_that_appeared_during_the_run(tmp_path):
    out = tmp_path / "run"
    folder = RunFolder(out, overwrite=False)
    (folder.staging / "metrics.json").write_text("{}")
    out.mkdir()  # someone else's folder appears while the run flies
    (out / "theirs.txt").write_text("keep me")
    with pytest.raises(MpcdeError, match="appeared during the run") as e:
        folder.publish()
    assert (out / "theirs.txt").read_text() == "keep me" and sorted(p.name for p in out.iterdir()) == ["theirs.txt"]
    kept = tmp_path / f"run.kept-{os.getpid()}"
    assert (kept / "metrics.json").exists() and str(kept) in str(e.value)
    empty = tmp_path / "empty"
    folder = RunFolder(empty, overwrite=False)
    empty.mkdir()  # an empty folder is taken over
    assert folder.publish() == empty and not list(tmp_path.glob(".empty.partial-*"))


def _start_camera_sweep(tmp_path: Path, seeds: int, duration_s: float, wait_s: float) -> tuple[subprocess.Popen, Path]:
    """Start a --jobs 2 sweep of comm camera flights on radio_outage in its own process group; return once its first row landed."""
    out = tmp_path / "sweep"
    sweep = tmp_path / "cameras.yaml"
    sweep.write_text(f"base: radio_outage\nseeds: {seeds}\noverrides:\n  duration_s: {duration_s}\naxes:\n  planner.kind: [dmpc]\n")
    cmd = [sys.executable, "-m", "mpcde", "sweep", str(sweep), "--out", str(out), "--jobs", "2", "--quiet"]
    p = start_interruptible(cmd, cwd=Path(__file__).resolve().parents[2])
    deadline = time.monotonic() + wait_s
    while time.monotonic() < deadline and not (out / "results.jsonl").exists():
        time.sleep(0.1)
    return p, out


def test_a_second_ctrl_c_while_a_sweep_shuts_down_adds_no_traceback(tmp_path):
    """Ctrl-C twice during camera flights in a --jobs 2 sweep (a user who presses again, or a `timeout` forwarding
    its own): the one line, exit 130; the flights in progress are stopped (their render workers leave quietly)."""
    p, _ = _start_camera_sweep(tmp_path, seeds=6, duration_s=4.0, wait_s=120)
    os.killpg(p.pid, signal.SIGINT)
    time.sleep(0.5)
    if p.poll() is None:
        os.killpg(p.pid, signal.SIGINT)
    _, err = p.communicate(timeout=120)
    assert p.returncode == 130, err[-3000:]
    assert len(err.strip().splitlines()) == 1 and err.startswith("mpcde: interrupted;"), err[-3000:]


def test_sigterm_to_a_sweep_stops_its_workers_and_starts_no_queued_flight(tmp_path):
    """`kill` (SIGTERM to the main process only) during a --jobs 2 camera sweep with flights queued: 143 within
    seconds, every worker and render worker gone, no further row. Each worker used to stop its flight and then
    take the one its pool had queued for it, and the sweep's exit waited for those."""
    p, out = _start_camera_sweep(tmp_path, seeds=10, duration_s=6.0, wait_s=180)
    time.sleep(1.0)  # the next flights are running, more are queued
    os.kill(p.pid, signal.SIGTERM)
    t0 = time.monotonic()
    _, err = p.communicate(timeout=60)
    assert p.returncode == 143 and time.monotonic() - t0 < 30, err[-3000:]
    rows = (out / "results.jsonl").read_text().count("\n")
    deadline = time.monotonic() + 15
    while time.monotonic() < deadline:
        try:
            os.killpg(p.pid, 0)  # anyone left in the sweep's process group?
        except ProcessLookupError:
            break
        time.sleep(0.2)
    else:
        pytest.fail("sweep workers still running 15 s after the sweep exited")
    assert (out / "results.jsonl").read_text().count("\n") == rows < 10
