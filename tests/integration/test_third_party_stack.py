"""A stack written outside this repository (examples/orca_stack, installed as a package) flies through
``fly``, ``sweep``, ``report``, ``compare`` and the environment with no change to mpcde (docs/stacks.md).

Each command runs in a fresh process whose ``PYTHONPATH`` holds the folder
the example was pip-installed into: the stack arrives only through its
``mpcde.stacks`` entry point.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import textwrap

import pytest
import yaml

pytestmark = pytest.mark.slow


def _run(site, *args, code=None, cwd=None):
    env = {**os.environ, "PYTHONPATH": str(site)}
    cmd = [sys.executable, "-c", code] if code is not None else [sys.executable, "-m", "mpcde", *args]
    return subprocess.run(cmd, env=env, cwd=cwd, capture_output=True, text=True, timeout=600)


def test_the_installed_orca_stack_flies_the_cli_and_writes_its_own_section(orca_site, tmp_path):
    out = tmp_path / "run"
    done = _run(orca_site, "fly", "crossing", "--mode", "orca", "--out", str(out), "--duration", "4", "--quiet")
    assert done.returncode == 0, done.stderr
    metrics = json.loads((out / "metrics.json").read_text())
    assert [a["planner"] for a in metrics["agents"]] == ["orca", "orca"]
    assert all(a["orca_solves"] > 50 for a in metrics["agents"])  # it planned at the camera rate once moving
    config = yaml.safe_load((out / "config.yaml").read_text())
    assert config["planner"]["kind"] == "orca" and config["orca"]["horizon_s"] == 2.0
    again = _run(orca_site, "fly", str(out / "config.yaml"), "--out", str(tmp_path / "again"), "--quiet")
    assert again.returncode == 0, again.stderr  # the run folder's config flies again, plugin section and all
    assert json.loads((tmp_path / "again" / "metrics.json").read_text())["collisions"] == metrics["collisions"]


def test_a_bad_field_of_the_plugins_section_is_one_line_and_exit_2(orca_site, tmp_path):
    bad = tmp_path / "bad.yaml"
    bad.write_text("planner:\n  kind: orca\norca:\n  horizon_s: -1.0\n")
    done = _run(orca_site, "fly", str(bad), "--out", str(tmp_path / "never"))
    assert done.returncode == 2 and done.stderr.strip().count("\n") == 0
    assert "orca.horizon_s=-1.0" in done.stderr and not (tmp_path / "never").exists()
    unknown = _run(orca_site, "fly", "crossing", "--mode", "orka", "--out", str(tmp_path / "never"))
    assert unknown.returncode == 2 and "orca" in unknown.stderr  # the choices name the installed stack


def test_the_orca_stack_sweeps_reports_and_compares_beside_the_built_in_ones(orca_site, tmp_path):
    sweep = tmp_path / "orca.yaml"
    sweep.write_text(textwrap.dedent("""\
        base: crossing
        seeds: 1
        overrides:
          duration_s: 3.0
        axes:
          planner.kind: [orca, min_jerk_line]
          orca.horizon_s: [1.0, 3.0]
    """))
    store = tmp_path / "store"
    done = _run(orca_site, "sweep", str(sweep), "--out", str(store), "--jobs", "1", "--quiet")
    assert done.returncode == 0, done.stderr
    rows = [json.loads(line) for line in (store / "results.jsonl").read_text().splitlines()]
    assert sorted((r["values"]["planner.kind"], r["values"]["orca.horizon_s"]) for r in rows) == [
        ("min_jerk_line", 1.0), ("min_jerk_line", 3.0), ("orca", 1.0), ("orca", 3.0),
    ]  # fmt: skip
    report = _run(orca_site, "report", str(store))
    assert report.returncode == 0, report.stderr
    assert 'planner.kind="orca", orca.horizon_s=3.0' in report.stdout
    cmp = _run(orca_site, "compare", "crossing", "--modes", "orca", "placeholder", "--seeds", "1", "--duration", "3", "--out", str(tmp_path / "cmp"), "--quiet")
    assert cmp.returncode == 0, cmp.stderr
    results = json.loads((tmp_path / "cmp" / "results.json").read_text())
    assert {r["mode"]: r["planner_kind"] for r in results["rows"]} == {"orca": "orca", "placeholder": "min_jerk_line"}


def test_the_orca_stack_flies_an_environments_drones_as_a_policy(orca_site):
    code = textwrap.dedent("""\
        import mpcde
        from mpcde.env import StackPolicy, SwarmParallelEnv
        env = SwarmParallelEnv("crossing", action="reference", observe=("pose", "goal", "camera", "detections", "tracks"), duration_s=2.0)
        policy = StackPolicy("orca", env)
        obs, infos = env.reset(seed=0)
        steps = 0
        while env.agents:
            obs, rewards, terminated, truncated, infos = env.step(policy(obs))
            steps += 1
        print(steps, type(policy.agents["drone_0"]).__name__)
    """)
    done = _run(orca_site, code=code)
    assert done.returncode == 0, done.stderr
    steps, cls = done.stdout.split()[-2:]
    assert int(steps) >= 40 and cls == "OrcaAgent"
