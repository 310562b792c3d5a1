"""The comm stack's scheme is an explicit choice: committing when unheard needs BVC, halting plans and every-step obstacle rows, and nothing replaces a QP setting."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from mpcde.config.dmpc import CommQpConfig, DmpcAgentConfig
from mpcde.config.scenario import load_scenario
from mpcde.errors import ConfigError
from mpcde.stacks.build import make_agent
from planners.dmpc import DmpcConfig


def _write(tmp_path, text):
    p = tmp_path / "s.yaml"
    p.write_text("planner:\n  kind: dmpc\n" + text)
    return p


def test_the_defaults_say_what_the_comm_stack_flies():
    cfg = load_scenario("radio_outage")
    qp = cfg.dmpc.qp
    assert cfg.dmpc.commit_when_unheard and qp.collision_mode == "bvc" and qp.terminal_halt and qp.obstacle_mode == "every_step"
    assert (qp.max_obstacle_planes, DmpcConfig().collision_mode) == (4, "on_demand")  # the planner keeps the paper's default
    goals = np.array([[4.0, 0.0, 1.5], [0.0, 4.0, 1.5]])
    flown = make_agent(replace(cfg, planner=replace(cfg.planner, kind="dmpc")), 0, goals, ()).problem.config
    assert (flown.collision_mode, flown.terminal_halt) == ("bvc", True)


def test_a_file_that_sets_some_qp_fields_keeps_the_section_defaults(tmp_path):
    cfg = load_scenario(_write(tmp_path, "dmpc:\n  qp:\n    max_neighbours: 3\n"))
    assert isinstance(cfg.dmpc.qp, CommQpConfig)
    assert (cfg.dmpc.qp.collision_mode, cfg.dmpc.qp.terminal_halt, cfg.dmpc.qp.max_obstacle_planes) == ("bvc", True, 4)


@pytest.mark.parametrize(
    "qp, field",
    [
        ("collision_mode: on_demand", "dmpc.qp.collision_mode"),
        ("terminal_halt: false", "dmpc.qp.terminal_halt"),
        ("obstacle_avoidance: on_demand", "dmpc.qp.obstacle_avoidance"),
    ],
)
def test_committing_with_a_qp_that_breaks_its_promise_is_refused_naming_both_fields(tmp_path, qp, field):
    with pytest.raises(ConfigError) as info:
        load_scenario(_write(tmp_path, f"dmpc:\n  qp:\n    {qp}\n"))
    assert info.value.field == field and "dmpc.commit_when_unheard" in info.value.allowed and "\n" not in str(info.value)
    # the same QP without committing is a valid choice, flown as set
    load_scenario(_write(tmp_path, f"dmpc:\n  commit_when_unheard: false\n  qp:\n    {qp}\n"))


def test_a_replaced_config_is_checked_too():
    with pytest.raises(ConfigError, match="qp.collision_mode"):
        replace(DmpcAgentConfig(), qp=replace(DmpcAgentConfig().qp, collision_mode="on_demand"))


def test_the_replanning_scheme_is_the_papers_plain_dmpc_and_is_flown_as_set():
    cfg = load_scenario("crossing")
    plain = cfg.dmpc.replanning()
    assert not plain.commit_when_unheard and (plain.qp.collision_mode, plain.qp.terminal_halt) == ("on_demand", False)
    assert cfg.dmpc.replanning("bvc").qp.collision_mode == "bvc"
    goals = np.array([[4.0, 0.0, 1.5], [0.0, 4.0, 1.5]])
    agent = make_agent(replace(cfg, planner=replace(cfg.planner, kind="dmpc"), dmpc=plain), 0, goals, ())
    assert (agent.problem.config.collision_mode, agent.problem.config.terminal_halt) == ("on_demand", False)
    metrics = agent.extra_metrics()
    assert (metrics["collision_mode"], metrics["terminal_halt"], metrics["commit_when_unheard"]) == ("on_demand", False, False)
