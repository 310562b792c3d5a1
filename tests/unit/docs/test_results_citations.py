"""Citations of the results pages resolve (issue 66, item 3: "source files cite a page with its section anchor").

Every ``docs/results/<page>.md`` named in a ``.py`` file of the packages, tests, benchmarks, examples and scripts
must exist, and every ``docs/results/<page>.md#<anchor>`` must name a heading of that page, by GitHub's rule
(lowercase; spaces to hyphens; every character but letters, digits, ``_`` and ``-`` dropped) or an explicit
``<a id="...">``.
"""

from __future__ import annotations

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[3]
FOLDERS = ("mpcde", "perception", "planners", "sim", "tests", "benchmarks", "examples", "scripts")
CITATION = re.compile(r"docs/results/((?:history/)?[\w-]+\.md)(?:#([\w-]+))?")


def github_anchor(heading: str) -> str:
    """The anchor GitHub gives a markdown heading's text."""
    text = heading.strip().lower()
    text = re.sub(r"[^\w\- ]", "", text)
    return text.replace(" ", "-")


def anchors(page: Path) -> set[str]:
    """Every anchor of ``page``: its headings' (with GitHub's -1, -2 for repeats) and its explicit ids."""
    seen: dict[str, int] = {}
    out: set[str] = set()
    in_fence = False
    for line in page.read_text().splitlines():
        if line.startswith("```"):
            in_fence = not in_fence
        if in_fence:
            continue
        if m := re.match(r"^#{1,6}\s+(.*)$", line):
            base = github_anchor(m.group(1))
            n = seen.get(base, 0)
            seen[base] = n + 1
            out.add(base if n == 0 else f"{base}-{n}")
        out.update(re.findall(r'<a id="([^"]+)"', line))
    return out


def citations() -> list[tuple[str, int, str, str | None]]:
    found = []
    for folder in FOLDERS:
        for path in sorted((ROOT / folder).rglob("*.py")):
            if ".venv" in path.parts:
                continue
            for number, line in enumerate(path.read_text().splitlines(), 1):
                for m in CITATION.finditer(line):
                    found.append((f"{path.relative_to(ROOT)}:{number}", number, m.group(1), m.group(2)))
    return found


def test_github_anchor_rule() -> None:
    assert github_anchor("Fig. 6: six drones in a forest at 0.5, 1 and 2 m/s") == "fig-6-six-drones-in-a-forest-at-05-1-and-2-ms"
    assert github_anchor("Behind `DmpcConfig`'s defaults") == "behind-dmpcconfigs-defaults"


def test_every_cited_page_and_section_exists() -> None:
    cache: dict[str, set[str]] = {}
    bad = []
    for where, _, page, anchor in citations():
        path = ROOT / "docs" / "results" / page
        if not path.exists():
            bad.append(f"{where}: no page {page}")
            continue
        if anchor is not None:
            names = cache.setdefault(page, anchors(path))
            if anchor not in names:
                bad.append(f"{where}: no section #{anchor} in {page}")
    assert not bad, "\n".join(bad)
