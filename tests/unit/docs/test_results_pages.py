"""The current pages of ``docs/results/`` say what holds today, and where each figure comes from.

A current page is every ``docs/results/*.md`` except ``README.md`` (the index); the dated history lives in
``docs/results/history/``, which these checks leave alone. What is checked, on each current page:

- it is at most ``MAX_LINES`` long (issue 66: "at most about 300 lines");
- within its first ``OPENING_LINES`` lines, a line says "What holds" and names a commit and a date;
- every results table names its provenance: within the ``PROVENANCE_LINES`` lines above it there is a
  command in backticks, a commit hash and a date. A results table is a markdown pipe table (a row of ``|``
  cells followed by a ``|---`` separator) or a fenced block without a language (a report's printed table),
  that holds a digit. A table that records no measurement (a list of definitions or of files) is exempted by
  an ``<!-- not a result -->`` comment on one of the lines just above it, so that the exemption is visible.

And on the index, ``docs/results/README.md``: every current page is listed, with a command that regenerates it.
"""

from __future__ import annotations

import re
from pathlib import Path

import pytest

RESULTS = Path(__file__).resolve().parents[3] / "docs" / "results"
MAX_LINES = 320
OPENING_LINES = 12
PROVENANCE_LINES = 8
EXEMPT = "<!-- not a result -->"

# a short hash mixes digits and a-f; one of digits only (git prints those too) counts after "at" or "commit"
COMMIT = re.compile(r"\b(?=[0-9a-f]*\d)(?=[0-9a-f]*[a-f])[0-9a-f]{7,40}\b|(?<=\bat )\d{7,12}\b|(?<=\bcommit )\d{7,12}\b")
DATE = re.compile(r"\b20\d\d-[01]\d-[0-3]\d\b")
COMMAND = re.compile(r"`[^`]*\b(mpcde|make|python|pytest)\b[^`]*`")


def current_pages() -> list[Path]:
    return sorted(p for p in RESULTS.glob("*.md") if p.name != "README.md")


def results_tables(lines: list[str]) -> list[int]:
    """0-based first line of each results table in ``lines`` (see the module docstring)."""
    starts = []
    i = 0
    while i < len(lines):
        line = lines[i]
        if line.startswith("```"):
            info = line[3:].strip()
            j = i + 1
            while j < len(lines) and not lines[j].startswith("```"):
                j += 1
            if not info and any(ch.isdigit() for ch in "".join(lines[i + 1 : j])):
                starts.append(i)
            i = j + 1
            continue
        if line.startswith("|") and i + 1 < len(lines) and re.match(r"^\|\s*:?-{3,}", lines[i + 1]):
            j = i
            while j < len(lines) and lines[j].startswith("|"):
                j += 1
            if any(ch.isdigit() for ch in "".join(lines[i + 2 : j])):
                starts.append(i)
            i = j
            continue
        i += 1
    return starts


def provenance_missing(lines: list[str], start: int) -> list[str]:
    """What the lines above the table at ``start`` fail to name: 'command', 'commit', 'date'; [] if exempt."""
    above = lines[max(0, start - PROVENANCE_LINES) : start]
    if any(EXEMPT in line for line in above[-3:]):
        return []
    text = "\n".join(above)
    missing = []
    if not COMMAND.search(text):
        missing.append("command")
    if not COMMIT.search(text):
        missing.append("commit")
    if not DATE.search(text):
        missing.append("date")
    return missing


@pytest.mark.parametrize("page", current_pages(), ids=lambda p: p.name)
def test_current_page_is_short_and_opens_with_what_holds(page: Path) -> None:
    lines = page.read_text().splitlines()
    assert len(lines) <= MAX_LINES, f"{page.name}: {len(lines)} lines; move the history to docs/results/history/"
    opening = [line for line in lines[:OPENING_LINES] if "What holds" in line]
    assert opening, f"{page.name}: no 'What holds at commit X on D' in its first {OPENING_LINES} lines"
    assert any(COMMIT.search(line) and DATE.search(line) for line in opening), (
        f"{page.name}: the 'What holds' line names no commit and date: {opening[0]!r}"
    )


@pytest.mark.parametrize("page", current_pages(), ids=lambda p: p.name)
def test_every_results_table_names_command_commit_and_date(page: Path) -> None:
    lines = page.read_text().splitlines()
    bad = [
        f"line {start + 1} lacks {', '.join(missing)}"
        for start in results_tables(lines)
        if (missing := provenance_missing(lines, start))
    ]
    assert not bad, f"{page.name}: " + "; ".join(bad)


def test_index_lists_every_current_page_with_a_command() -> None:
    index = (RESULTS / "README.md").read_text().splitlines()
    for page in current_pages():
        rows = [line for line in index if f"`{page.name}`" in line or f"({page.name})" in line]
        assert rows, f"docs/results/README.md does not list {page.name}"
        assert any(COMMAND.search(row) for row in rows), f"docs/results/README.md: no command for {page.name}"


def test_the_table_finder_sees_pipe_tables_and_report_blocks() -> None:
    lines = [
        "Flown with `mpcde sweep x.yaml` at abc1234, 2026-12-02:",
        "",
        "| a | b |",
        "|---|---|",
        "| 1 | 2 |",
        "",
        "```",
        "cell  success",
        "x     98%",
        "```",
        "```sh",
        "mpcde fly 3",
        "```",
        "| name | what |",
        "|---|---|",
        "| x | y |",
    ]
    assert results_tables(lines) == [2, 6]
    assert provenance_missing(lines, 2) == []
    assert provenance_missing(["plain words", "| a |"], 1) == ["command", "commit", "date"]
    assert provenance_missing([EXEMPT, "| a |"], 1) == []
    assert COMMIT.search("What holds at 3369254 on 2026-12-02") and not COMMIT.search("seeds 1000-1049, 2026-12-02")
