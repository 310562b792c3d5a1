"""docs/stacks.md's minimal stack registers and flies as the page says; the registry's refusals are one line."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

import mpcde
from mpcde.stacks import registry

DOC = Path(__file__).resolve().parents[4] / "docs" / "stacks.md"


@pytest.fixture
def scratch_registry(monkeypatch):
    """The registry as it is, restored after the test (a registration does not leak into other tests)."""
    registry._load()
    monkeypatch.setattr(registry, "_BY_NAME", dict(registry._BY_NAME))
    monkeypatch.setattr(registry, "_BY_KIND", dict(registry._BY_KIND))


def _minimal_stack_code() -> str:
    section = DOC.read_text().split("## A minimal stack", 1)[1]
    return re.search(r"```python\n(.*?)```", section, re.S).group(1)


@pytest.mark.slow
def test_the_docs_minimal_stack_registers_from_a_script_and_flies(scratch_registry, capsys):
    exec(compile(_minimal_stack_code(), str(DOC), "exec"), {"__name__": "docs_stacks"})
    collisions, min_distance = capsys.readouterr().out.split()
    assert int(collisions) == 0 and float(min_distance) > 0.3  # it waited for the drone its camera saw
    assert "cautious_line" in [s.name for s in mpcde.all_stacks()]


def test_a_name_or_kind_taken_is_refused_unless_replacing(scratch_registry):
    stack = mpcde.Stack("denied", lambda ctx: None)
    with pytest.raises(ValueError, match="already registered"):
        mpcde.register_stack(stack)
    with pytest.raises(ValueError, match="already registered"):
        mpcde.register_stack(mpcde.Stack("mine", lambda ctx: None, kind="dmpc"))
    with pytest.raises(ValueError, match="section 'dmpc' is already a scenario section"):
        mpcde.register_stack(mpcde.Stack("mine", lambda ctx: None, section="dmpc", config_type=dict))


def test_an_unknown_mode_or_kind_names_every_registered_stack_in_one_line(scratch_registry):
    with pytest.raises(mpcde.ConfigError) as mode:
        mpcde.get_stack("orka")
    assert mode.value.field == "mode" and all(s.name in mode.value.allowed for s in mpcde.all_stacks())
    from mpcde.config.scenario import scenario_from_dict

    with pytest.raises(mpcde.ConfigError) as kind:
        scenario_from_dict({"planner": {"kind": "teleport"}})
    assert kind.value.field == "planner.kind" and "'mpcde'" in kind.value.allowed and "\n" not in str(kind.value)
