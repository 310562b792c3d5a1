"""The one derivation step (mpcde/config/resolve.py): derived fields, refusals, the resolved run folder."""

from __future__ import annotations

import json
from dataclasses import replace

import pytest
import yaml

import mpcde
from mpcde.cli import main
from mpcde.config.io import from_dict
from mpcde.config.resolve import derivations, resolve
from mpcde.config.scenario import ScenarioConfig, load_scenario
from mpcde.errors import ConfigError
from planners.limits import KinematicLimits


def _get(cfg, path):
    for name in path.split("."):
        cfg = getattr(cfg, name)
    return cfg


def write(tmp_path, text):
    p = tmp_path / "s.yaml"
    p.write_text(text)
    return p


def test_every_derived_field_equals_its_source_after_loading(tmp_path):
    p = write(tmp_path, "pose_estimate:\n  pos_noise_m: 0.05\n  yaw_noise_rad: 0.02\ncamera:\n  hfov_deg: 80.0\n"
                        "denied:\n  limits:\n    v_max_mps: 1.5\nperception:\n  tracker:\n    t_hold_s: 0.8\n")  # fmt: skip
    cfg = load_scenario(p)
    assert cfg.perception.backprojection.pose_pos_std_m == 0.05 and cfg.perception.backprojection.pose_yaw_std_rad == 0.02
    assert (cfg.denied.yaw.v_max_mps, cfg.denied.yaw.t_hold_s, cfg.denied.yaw.fov_h_deg) == (1.5, 0.8, 80.0)
    for d in derivations(cfg):
        if d.applies(cfg):
            assert _get(cfg, d.target) == d.derive(cfg), d.target
    assert resolve(cfg) == cfg  # idempotent


@pytest.mark.parametrize(
    "text, field, source",
    [
        ("denied:\n  yaw:\n    v_max_mps: 5\n", "denied.yaw.v_max_mps", "denied.limits.v_max_mps"),
        ("perception:\n  backprojection:\n    pose_pos_std_m: 0.3\n", "perception.backprojection.pose_pos_std_m", "pose_estimate.pos_noise_m"),
        ("denied:\n  yaw:\n    fov_h_deg: 90\n", "denied.yaw.fov_h_deg", "camera.hfov_deg"),
        ("planner:\n  kind: mpcde\n  cruise_speed_mps: 2.0\ndenied:\n  limits:\n    v_max_mps: 1.0\n", "denied.limits.v_max_mps", "planner.cruise_speed_mps"),
        ("planner:\n  kind: dmpc\n  cruise_speed_mps: 0.5\ndmpc:\n  qp:\n    limits:\n      v_max_mps: 2.0\n", "dmpc.qp.limits.v_max_mps", "planner.cruise_speed_mps"),
        ("planner:\n  kind: admm\nradio:\n  rate_hz: 5.0\nworld:\n  obstacle_density_per_100m2: 0\n"
         "drones:\n  starts: [[0, 0, 1.5], [1, 0, 1.5]]\n  goals: [[3, 0, 1.5], [4, 0, 1.5]]\n", "radio.rate_hz", "2 x the ADMM iterations per step"),
    ],
)  # fmt: skip
def test_a_set_value_that_a_derivation_would_replace_is_refused_in_one_line(tmp_path, text, field, source):
    with pytest.raises(ConfigError) as info:
        load_scenario(write(tmp_path, text))
    assert info.value.field == field and source in info.value.allowed and "\n" not in str(info.value)


@pytest.mark.parametrize("kind", ["min_jerk_line", "mpcde", "dmpc", "auto"])
def test_the_cruise_speed_is_every_stack_s_speed(kind):
    """planner.cruise_speed_mps reaches the stacks that fly it (MP-CDE's optimiser limit, DMPC's per-axis limit,
    the lines' peak speed); unset, each keeps its own default."""
    default = mpcde.load_scenario("forest_swarm", mode={"min_jerk_line": "placeholder", "mpcde": "denied", "dmpc": "comm", "auto": "auto"}[kind])
    assert default.planner.cruise_speed_mps is None and default.planner.line_speed_mps == 1.0
    assert (default.denied.limits.v_max_mps, default.dmpc.qp.limits.v_max_mps) == (1.0, 2.0)
    cfg = load_scenario("forest_swarm", {"planner": {"kind": kind, "cruise_speed_mps": 0.5}})
    assert cfg.planner.line_speed_mps == 0.5
    assert cfg.denied.limits.v_max_mps == (0.5 if kind in ("mpcde", "auto") else 1.0)
    assert cfg.denied.yaw.v_max_mps == cfg.denied.limits.v_max_mps
    assert cfg.dmpc.qp.limits.v_max_mps == (0.5 if kind in ("dmpc", "auto") else 2.0)


def test_mlr_refuses_a_cruise_speed():
    with pytest.raises(ConfigError, match=r"^planner\.cruise_speed_mps=1\.0: null for planner\.kind 'mlr'"):
        load_scenario("antipodal", {"planner": {"kind": "mlr", "cruise_speed_mps": 1.0}, "world": {"obstacle_density_per_100m2": 0}})


def test_a_derived_value_that_breaks_its_section_names_the_whole_path(tmp_path):
    with pytest.raises(ConfigError, match=r"^denied\.yaw\.tracking_sweep_deg=60\.0: allowed 4 \* sweep / tracking_sweep_period_s <= yaw_rate_max_radps=1\.0"):
        load_scenario(write(tmp_path, "denied:\n  yaw_rate_max_radps: 1.0\n"))  # the 60 deg swing needs a faster yaw


def test_a_set_value_equal_to_its_derivation_is_accepted(tmp_path):
    cfg = load_scenario(write(tmp_path, "denied:\n  limits:\n    v_max_mps: 1.5\n  yaw:\n    v_max_mps: 1.5\n"))
    assert cfg.denied.yaw.v_max_mps == 1.5


def test_code_built_configs_are_refused_the_same_way():
    cfg = from_dict(ScenarioConfig, {"denied": {"yaw": {"v_max_mps": 4.0}}})
    with pytest.raises(ConfigError, match=r"^denied\.yaw\.v_max_mps=4\.0: derived from denied\.limits\.v_max_mps"):
        resolve(cfg)
    edited = replace(cfg, denied=replace(cfg.denied, limits=KinematicLimits(4.0, 3.0)))
    assert resolve(edited).denied.yaw.v_max_mps == 4.0


def test_the_cli_refuses_an_overridden_setting_with_exit_status_2_and_writes_nothing(tmp_path, capsys):
    p = write(tmp_path, "denied:\n  yaw:\n    v_max_mps: 5\n")
    assert main(["fly", str(p), "--mode", "denied", "--out", str(tmp_path / "run"), "--quiet"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("mpcde: error: denied.yaw.v_max_mps=5: derived from denied.limits.v_max_mps")
    assert not (tmp_path / "run").exists()


def test_the_run_folder_holds_the_resolved_config_and_flying_it_again_gives_the_same_flight(tmp_path):
    first = mpcde.fly("crossing", mode="comm", seed=4, duration_s=2.0, cameras=False, out=tmp_path / "a")
    written = yaml.safe_load((tmp_path / "a" / "config.yaml").read_text())
    assert written["perception"]["backprojection"]["pose_pos_std_m"] == first.config.pose_estimate.pos_noise_m
    again = mpcde.fly(tmp_path / "a" / "config.yaml", cameras=False, out=tmp_path / "b")
    assert again.config == first.config
    a = json.loads((tmp_path / "a" / "metrics.json").read_text())
    b = json.loads((tmp_path / "b" / "metrics.json").read_text())
    def flight(m):  # everything but wall-clock timings
        if isinstance(m, dict):
            return {k: flight(v) for k, v in m.items() if k not in ("wall_time_s", "real_time_factor", "compute_time") and "_ms" not in k}
        return [flight(v) for v in m] if isinstance(m, list) else m

    assert flight(a) == flight(b) and flight(a)["agents"]


def test_a_committing_dmpc_plans_against_every_obstacle_its_plan_can_reach():
    """dmpc.obstacle_range_m under commit_when_unheard: derived, sqrt(2) v_max K h + the inflation, at load time (it was
    raised silently inside the agent); a file setting another value is refused, and without commitment it is the file's."""
    import math

    cfg = load_scenario("formation_square", {"planner": {"kind": "dmpc", "cruise_speed_mps": 1.0}})
    qp, d = cfg.dmpc.qp, cfg.dmpc
    reach = math.sqrt(2.0) * 1.0 * qp.horizon_steps * qp.step_s + cfg.physics.quadrotor.robot_radius_m + d.obstacle_margin_m
    assert d.commit_when_unheard and d.obstacle_range_m == pytest.approx(max(3.0, reach))
    with pytest.raises(ConfigError, match=r"^dmpc\.obstacle_range_m=5\.0: derived from sqrt\(2\) dmpc\.qp\.limits\.v_max_mps"):
        load_scenario("formation_square", {"planner": {"kind": "dmpc"}, "dmpc": {"obstacle_range_m": 5.0}})
    plain = {"commit_when_unheard": False, "obstacle_range_m": 5.0, "qp": {"collision_mode": "on_demand", "terminal_halt": False}}
    assert load_scenario("formation_square", {"planner": {"kind": "dmpc"}, "dmpc": plain}).dmpc.obstacle_range_m == 5.0
