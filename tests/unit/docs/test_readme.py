"""The README is a front door (issue 66, item 1): short, and everything it names exists.

Checked: its length; that every verb in its command-line table is a verb of ``mpcde``'s parser and every verb of
the parser is in the table; that every ``--mode`` in its stacks table is a registered stack and every built-in
stack is in the table; that every repository path it names in backticks exists (a ``*`` in a name must match a
file); and, as a slow test, that its Python blocks run.
"""

from __future__ import annotations

import argparse
import re
import subprocess
import sys
from pathlib import Path

import pytest

from mpcde.cli import build_parser
from mpcde.stacks.builtin import BUILTIN

ROOT = Path(__file__).resolve().parents[3]
README = ROOT / "README.md"
MAX_LINES = 150
TOP_LEVEL = ("data/", "docs/", "examples/", "scripts/", "benchmarks/", "tests/", "mpcde/", "sim/", "planners/",
             "perception/")


def readme_lines() -> list[str]:
    return README.read_text().splitlines()


def table_after(heading: str) -> list[list[str]]:
    """The body rows (cells stripped) of the first pipe table after the line ``heading``."""
    lines = readme_lines()
    start = lines.index(heading)
    rows: list[list[str]] = []
    for line in lines[start + 1 :]:
        if line.startswith("|"):
            rows.append([c.strip() for c in line.strip("|").split("|")])
        elif rows:
            break
    return rows[2:] if len(rows) > 1 and set(rows[1][0]) <= set("-: ") else rows[1:]


def prose() -> str:
    """The README without its fenced blocks (whose triple backticks would pair with inline ones)."""
    return re.sub(r"```.*?```", "", README.read_text(), flags=re.S)


def parser_verbs() -> set[str]:
    sub = next(a for a in build_parser()._actions if isinstance(a, argparse._SubParsersAction))
    return set(sub.choices)


def test_readme_is_short() -> None:
    assert len(readme_lines()) <= MAX_LINES


def test_command_table_lists_exactly_the_cli_verbs() -> None:
    listed = {row[0].strip("`") for row in table_after("## Command line")}
    assert listed == parser_verbs()


def test_stack_table_lists_exactly_the_built_in_stacks() -> None:
    listed = {row[0].strip("`") for row in table_after("## The onboard stacks")}
    assert listed == {s.name for s in BUILTIN}


def test_every_path_the_readme_names_exists() -> None:
    named = {
        token.rstrip(".,:;)")
        for span in re.findall(r"`([^`]+)`", prose())
        for token in span.split()
        if token.startswith(TOP_LEVEL)
    }
    assert named, "the README names no repository path"
    missing = [p for p in sorted(named) if not (list(ROOT.glob(p)) if "*" in p else (ROOT / p).exists())]
    assert not missing, f"README.md names paths that do not exist: {missing}"


def test_every_results_page_the_readme_names_exists() -> None:
    pages = {m for m in re.findall(r"`([a-z_-]+\.md)`", prose()) if m not in ("README.md",)}
    missing = [p for p in sorted(pages) if not (ROOT / "docs" / "results" / p).exists() and not (ROOT / "docs" / p).exists()]
    assert not missing, f"README.md names pages that do not exist: {missing}"


@pytest.mark.slow
def test_readme_python_blocks_run(tmp_path: Path) -> None:
    blocks = re.findall(r"```python\n(.*?)```", README.read_text(), flags=re.S)
    assert len(blocks) >= 2
    for i, block in enumerate(blocks):
        script = tmp_path / f"block{i}.py"
        script.write_text(block)
        done = subprocess.run([sys.executable, str(script)], cwd=tmp_path, capture_output=True, text=True, timeout=900)
        assert done.returncode == 0, f"README python block {i} failed:\n{done.stderr[-2000:]}"
