"""Issue 65's size goals, held: no source module over 450 lines, no source folder over 15 modules."""

from __future__ import annotations

from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
PACKAGES = ("mpcde", "perception", "planners", "sim")
MAX_LINES = 450
MAX_MODULES = 15


def _folders() -> list[Path]:
    return sorted({p.parent for pkg in PACKAGES for p in (ROOT / pkg).rglob("*.py") if "__pycache__" not in p.parts})


@pytest.mark.parametrize("folder", _folders(), ids=lambda p: str(p.relative_to(ROOT)))
def test_a_source_folder_holds_at_most_15_modules_each_at_most_450_lines(folder: Path) -> None:
    modules = sorted(folder.glob("*.py"))
    assert len(modules) <= MAX_MODULES, f"{folder.relative_to(ROOT)}: {len(modules)} modules"
    long = {str(m.relative_to(ROOT)): n for m in modules if (n := len(m.read_text().splitlines())) > MAX_LINES}
    assert not long, f"modules over {MAX_LINES} lines: {long}"
