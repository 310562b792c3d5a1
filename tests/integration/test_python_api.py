"""The Python API (mpcde.fly, mpcde.load_scenario) and the examples/ scripts."""

from __future__ import annotations

import importlib.util
import json
import subprocess
import sys
from pathlib import Path

import pytest

import mpcde

ROOT = Path(__file__).resolve().parents[2]


def test_reading_a_scenario_loads_no_simulator_detector_solver_or_agent():
    heavy = ("torch", "pybullet", "osqp", "open3d", "cv2", "mpcde.onboard", "mpcde.flight", "planners.dmpc.qp", "planners.yaw.planner")
    code = f"import sys, mpcde; mpcde.load_scenario('forest_swarm'); print(sorted(m for m in sys.modules if m.startswith({heavy!r})))"
    out = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True, check=True).stdout
    assert out.strip() == "[]"


def test_load_scenario_applies_mode_seed_and_duration_and_refuses_an_unknown_mode():
    cfg = mpcde.load_scenario("forest_swarm", mode="denied", seed=7, duration_s=2.5)
    assert (cfg.planner.kind, cfg.seed, cfg.duration_s) == ("mpcde", 7, 2.5)
    with pytest.raises(mpcde.ConfigError, match=r"^mode='flying': one of placeholder"):
        mpcde.load_scenario("forest_swarm", mode="flying")


def test_fly_returns_the_metrics_and_writes_the_same_run_folder_as_the_cli(tmp_path):
    r = mpcde.fly("crossing", seed=2, duration_s=1.0, cameras=False, out=tmp_path / "run")
    written = json.loads((tmp_path / "run" / "metrics.json").read_text())
    assert written == json.loads(json.dumps(r.metrics))
    assert (tmp_path / "run" / "config.yaml").exists() and r.log.arrays["pos_world"].shape[1] == 2
    again = mpcde.fly("crossing", seed=2, duration_s=1.0, cameras=False)
    assert again.metrics["min_inter_drone_distance_m"] == r.metrics["min_inter_drone_distance_m"]


def test_fly_refuses_bad_input_before_writing_anything(tmp_path):
    with pytest.raises(mpcde.ConfigError, match="duration_s"):
        mpcde.fly("crossing", duration_s=-1.0, out=tmp_path / "run")
    with pytest.raises(mpcde.ConfigError, match="video"):
        mpcde.fly("crossing", duration_s=1.0, video=True)  # no out folder to write it into
    assert not any(tmp_path.iterdir())


def test_a_plain_script_without_a_main_guard_flies_with_render_workers(tmp_path):
    """The render pool spawns workers; they must not re-run the user's unguarded script."""
    script = tmp_path / "unguarded.py"
    script.write_text(
        "import mpcde\n"
        "r = mpcde.fly('crossing', duration_s=0.3, seed=1)\n"
        "print('frames', r.metrics['frames_rendered'], 'workers', r.metrics['render_workers'])\n"
    )
    proc = subprocess.run([sys.executable, str(script)], cwd=ROOT, capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert proc.stdout.count("frames") == 1  # the script ran once, not once per worker
    assert "workers 0" not in proc.stdout


def _example(name: str):
    spec = importlib.util.spec_from_file_location(f"example_{name}", ROOT / "examples" / f"{name}.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_every_example_has_a_main():
    names = sorted(p.stem for p in (ROOT / "examples").glob("*.py"))
    assert names, "examples/ is empty"
    for name in names:
        assert callable(getattr(_example(name), "main", None)), name


def test_example_custom_scenario_runs_headless():
    """The swap built in code arrives without a contact (the comm stack on a fixed seed)."""
    m = _example("custom_scenario").main()
    assert m["success"] is True and m["collisions"] == 0 and m["min_inter_drone_distance_m"] > 0.2


@pytest.mark.slow
def test_example_fly_denied_runs_headless(tmp_path):
    m = _example("fly_denied").main(duration_s=1.0, out=str(tmp_path / "run"))
    assert (tmp_path / "run" / "metrics.json").exists() and m["frames_received"] > 0


@pytest.mark.slow
def test_example_compare_radio_runs_headless():
    rows = _example("compare_radio").main(duration_s=1.0)
    assert set(rows) == {"comm", "denied", "auto"}


@pytest.mark.slow
def test_example_env_random_and_denied_runs_headless():
    m = _example("env_random_and_denied").main(duration_s=1.0)
    assert m["frames_received"] > 0 and m["n_drones"] == 6
