"""The layers' import rules (docs/design.md section 1), checked on every import statement.

Every ``import``/``from`` in ``sim/``, ``perception/``, ``planners/``, the
onboard room ``mpcde/onboard/`` and the environments' onboard side (the
learner's drone ``mpcde/env/external.py``, its held action
``mpcde/env/actions.py``, and the stacks-as-policies ``mpcde/env/policies.py``) is parsed (top level and inside functions,
``TYPE_CHECKING`` blocks included) and compared with what its layer may use.
"""

from __future__ import annotations

import ast
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
OURS = ("sim", "perception", "planners", "mpcde")

# layer -> (allowed module prefixes of ours, forbidden third-party or own prefixes)
RULES: dict[str, tuple[tuple[str, ...], tuple[str, ...]]] = {
    "sim": (("sim",), ()),
    "perception": (("perception", "sim.types", "sim.checks", "sim.kernel_cache"), ("pybullet",)),
    "planners": (("planners", "sim.types", "sim.checks", "sim.kernel_cache", "perception.types"), ("pybullet", "torch")),
    "mpcde/onboard": (
        ("mpcde.onboard", "mpcde.config", "mpcde.errors", "perception", "planners", "sim.types", "sim.checks", "sim.rotations"),
        ("pybullet",),
    ),
}
ONBOARD = RULES["mpcde/onboard"][0]
for _file in ("mpcde/env/external.py", "mpcde/env/actions.py", "mpcde/env/policies.py"):
    RULES[_file] = (ONBOARD + ("mpcde.env.actions", "mpcde.stacks"), ("pybullet",))


def imports_of(path: Path) -> list[tuple[int, str]]:
    """(line, absolute module) of every import in ``path``."""
    out = []
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Import):
            out += [(node.lineno, a.name) for a in node.names]
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            out.append((node.lineno, node.module))
        elif isinstance(node, ast.ImportFrom) and node.level > 0:
            out.append((node.lineno, "<relative import>"))
    return out


def violations(layer: str) -> list[str]:
    allowed, forbidden = RULES[layer]
    bad = []
    target = ROOT / layer
    for py in [target] if target.is_file() else sorted(target.rglob("*.py")):
        for line, mod in imports_of(py):
            top = mod.split(".")[0]
            ours = top in OURS
            ok_ours = any(mod == a or mod.startswith(a + ".") for a in allowed)
            if mod == "<relative import>" or (ours and not ok_ours) or any(mod == f or mod.startswith(f + ".") for f in forbidden):
                bad.append(f"{py.relative_to(ROOT)}:{line}: {mod}")
    return bad


@pytest.mark.parametrize("layer", sorted(RULES))
def test_layer_imports_only_what_its_rule_allows(layer):
    assert violations(layer) == []


def test_the_checker_sees_a_forbidden_edge(tmp_path, monkeypatch):
    """The rule check itself: a planner importing the world, or onboard code importing ground truth, is caught."""
    fake = tmp_path / "planners"
    fake.mkdir()
    (fake / "bad.py").write_text("def f():\n    from sim.world import World\n    import mpcde.flight.loop\n")
    onboard = tmp_path / "mpcde" / "onboard"
    onboard.mkdir(parents=True)
    (onboard / "bad.py").write_text("from sim.ground_truth import TrueState\nfrom .base import AgentCounters\n")
    monkeypatch.setattr(sys.modules[__name__], "ROOT", tmp_path)
    assert [v.split(": ")[1] for v in violations("planners")] == ["sim.world", "mpcde.flight.loop"]
    assert [v.split(": ")[1] for v in violations("mpcde/onboard")] == ["sim.ground_truth", "<relative import>"]
