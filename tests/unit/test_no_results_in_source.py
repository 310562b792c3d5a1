"""No commit hashes and no per-seed results in the source (issue 66, item 6).

Measured results live on the pages of ``docs/results/``, which name the
command, commit and date they hold at; a docstring says why a default is what
it is in one sentence and links the page. This test keeps it so. It reads
every ``.py`` file with :mod:`tokenize` and looks only at comments and string
tokens, so code (``seed=3``, ``rng = default_rng(41)``, ``0x1f``) is never
matched. It fails with ``file:line: kind: matched text`` for:

* **a commit hash** (:data:`HASH`), in the four packages ``mpcde/``,
  ``perception/``, ``planners/``, ``sim/`` (comments and every string) and in
  the comments and docstrings of ``tests/``, ``benchmarks/`` and
  ``examples/`` (their other strings are test data: a results page's sample
  text needs a commit to be checked). The token: 7 to 40 lowercase hex
  digits with at least one digit and at least one letter a-f, so neither a
  number (``1000000``) nor a word (``facade``, ``decade``) matches. It must
  stand alone: not inside a longer word, identifier or number (``0x1f2e3d4c``,
  ``run_ab12cd34``, a 64-digit SHA-256); not a piece of a dashed or dotted
  token (a UUID such as ``123e4567-e89b-12d3-a456-426614174000``, a version
  ``1.2.3a4b5c6``, a heading anchor); not a ``#`` colour; not a piece of a
  path or URL (``/`` either side). Excluded: a string token that is nothing
  but one hex token (``"3fa2b1c"``): such a string is a value the code
  computes or compares (a store's digest, a content hash in a manifest, a
  test's fixture for them), not prose, and a reviewer sees it as code.
* **a per-seed result** (:data:`SEED`, :data:`FLIGHTS`, :data:`SUCCESS`), in
  the four packages only, in comments and docstrings (a string that is a
  statement of its own: module, class and function docstrings and attribute
  docstrings) but not in other strings, which are messages and arguments the
  code builds:

  - ``seed 41``, ``seeds 0-39``: the word ``seed`` or ``seeds``, a space and
    a number. Not a range that defines seeds (``seeds 0..19``, ``seeds 0 ..
    N-1``: what a ``seeds:`` entry means), not code quoted in a docstring
    (``fly(..., seed=3)``, ``seeds: 20``);
  - ``183 flights``, ``49 of 50 flights``: a number followed by ``flight`` or
    ``flights``. Not ``0 flights`` alone (how a report shows a cell not flown
    yet) and not a number that belongs to a reference (``Sec. 5 flight``,
    ``Table 2 flights``);
  - ``93 % success``, ``100% successful``: a percentage followed by
    ``success``.

  Tests are not scanned for these: a test may keep the fixed seed it flies and
  the stored figures it asserts against.

What this does not catch, on purpose, since it would fire on legitimate text:
other measured figures (``3.7 ms``, ``1.28x``, ``refused 562 times``), which
read like the units, bounds and derivations a docstring should carry; those
are left to review. Nor uppercase hex, which no git tool prints.

Not scanned: this file (its self-test holds the samples), ``.venv``, and the
matches listed in :data:`KNOWN`, each with its reason.
"""

from __future__ import annotations

import io
import re
import tokenize
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
PACKAGES = ("mpcde", "perception", "planners", "sim")
"""Scanned for commit hashes and per-seed results."""
HASH_ONLY = ("tests", "benchmarks", "examples")
"""Scanned for commit hashes only."""

HASH = re.compile(r"(?<![\w.\-/#])(?=[0-9a-f]*[0-9])(?=[0-9a-f]*[a-f])[0-9a-f]{7,40}(?![\w\-/])(?!\.\w)")
"""A commit hash: 7-40 lowercase hex digits, at least one digit and one letter, standing alone."""
SEED = re.compile(r"\bseeds?\s+\d+\b(?!\s*\.\.)", re.IGNORECASE)
"""``seed 41``, ``seeds 0-39``: the word seed(s), a space and a number that does not open a ``..`` range."""
_NOT_A_REFERENCE = "".join(f"(?<!{ref} )" for ref in (r"Sec\.", r"Fig\.", r"Eq\.", r"Alg\.", "Table", "Step", "Line"))
FLIGHTS = re.compile(
    r"(?<![\w.])" + _NOT_A_REFERENCE + r"(?:\d+\s+of\s+\d+|[1-9]\d*)\s+flights?\b", re.IGNORECASE
)
"""``183 flights``, ``49 of 50 flights``, ``0 of 50 flights``, ``1 flight``; not ``0 flights`` alone, not ``Sec. 5 flight``."""
SUCCESS = re.compile(r"\b\d+(?:\.\d+)?\s*%\s*success", re.IGNORECASE)
"""``93 % success``, ``100% successful``."""
SOLE_HEX = re.compile(r"[0-9a-f]{7,64}")
"""A string token that is only this is a value the code holds, not prose."""

KNOWN: dict[str, tuple[str, ...]] = {}
"""Matches allowed, by file, each with its reason in a comment; none today."""

_STRING_PREFIX = re.compile(r"^[rbuRBUfF]*('''|\"\"\"|'|\")")


def _string_body(token: str) -> str:
    """The text of a string token without its prefix and quotes."""
    match = _STRING_PREFIX.match(token)
    if match is None:
        return token
    quote = match.group(1)
    return token[match.end() : len(token) - len(quote)]


def _is_statement(tokens: list[tokenize.TokenInfo], i: int) -> bool:
    """True if the STRING token ``tokens[i]`` is an expression statement of its own (a docstring)."""
    skip = (tokenize.NL, tokenize.COMMENT)
    j = i - 1
    while j >= 0 and tokens[j].type in skip:
        j -= 1
    before = tokens[j].type if j >= 0 else tokenize.NEWLINE
    k = i + 1
    while k < len(tokens) and tokens[k].type in skip:
        k += 1
    after = tokens[k].type if k < len(tokens) else tokenize.NEWLINE
    starts = before in (tokenize.NEWLINE, tokenize.INDENT, tokenize.DEDENT, tokenize.ENCODING)
    return starts and after in (tokenize.NEWLINE, tokenize.ENDMARKER)


def findings(source: str, *, results: bool = True) -> list[tuple[int, str, str]]:
    """(line, kind, matched text) of every hash (and, if ``results``, per-seed result) in ``source``."""
    found: list[tuple[int, str, str]] = []
    tokens = list(tokenize.generate_tokens(io.StringIO(source).readline))
    for i, tok in enumerate(tokens):
        if tok.type == tokenize.COMMENT:
            text, prose = tok.string, True
        elif tok.type == tokenize.STRING:
            text, prose = tok.string, _is_statement(tokens, i)
            if SOLE_HEX.fullmatch(_string_body(tok.string).strip()):
                continue
        else:
            continue
        checks = [("commit hash", HASH)] if results or prose else []
        if results and prose:
            checks += [("per-seed result", SEED), ("flight count", FLIGHTS), ("success rate", SUCCESS)]
        for offset, line in enumerate(text.splitlines()):
            for kind, pattern in checks:
                for match in pattern.finditer(line):
                    found.append((tok.start[0] + offset, kind, match.group(0)))
    return found


def _files(folders: tuple[str, ...]) -> list[Path]:
    paths = (p for folder in folders for p in (ROOT / folder).rglob("*.py"))
    return sorted(p for p in paths if ".venv" not in p.parts and p.resolve() != Path(__file__).resolve())


def _report(paths: list[Path], *, results: bool) -> list[str]:
    lines = []
    for path in paths:
        name = path.relative_to(ROOT).as_posix()
        for line, kind, text in findings(path.read_text(encoding="utf-8"), results=results):
            if text not in KNOWN.get(name, ()):
                lines.append(f"{name}:{line}: {kind}: {text!r}")
    return lines


def test_the_packages_carry_no_commit_hash_and_no_per_seed_result() -> None:
    bad = _report(_files(PACKAGES), results=True)
    assert not bad, "measured results belong in docs/results/, not the source:\n" + "\n".join(bad)


def test_tests_benchmarks_and_examples_carry_no_commit_hash() -> None:
    bad = _report(_files(HASH_ONLY), results=False)
    assert not bad, "a commit hash in a comment or string (keep one as a bare string value if a test needs it):\n" + "\n".join(bad)


@pytest.mark.parametrize(
    "source",
    [
        "# flown at fb9dc17\n",
        "x = 1  # as at commit 24395bb\n",
        '"""Kept as the store of 481a2b4c."""\n',
        'msg = f"since {n} at e89645d"\n',
        "def f():\n    '''Decided at 9415af4 (CI).'''\n",
        "# commits b24979a..75c2385\n",
        "# (05dcd3c)\n",
        '"""seed 54 at 1 m/s"""\n',
        '"""seeds 0-39, paired"""\n',
        "# refused 562 times, seed 41\n",
        '"""on 183 flights of the forest sweep"""\n',
        "# 49 of 50 flights arrived\n",
        '"""0 of 50 flights with no contact"""\n',
        '"""93 % success at 0.5 m/s"""\n',
        "# 100% successful\n",
    ],
)
def test_the_matcher_finds_hashes_and_per_seed_results(source: str) -> None:
    assert findings(source)


@pytest.mark.parametrize(
    "source",
    [
        "seed = 41\n",
        "rng = default_rng(seed=54)\n",
        "def fly(seed: int = 3) -> None:\n    '''seed: the RNG seed of the flight.'''\n",
        "x = 0x1f2e3d4c  # a mask\n",
        '"""Colour #1f77b4 and id 123e4567-e89b-12d3-a456-426614174000."""\n',
        'digest = "3fa2b1c9d0"\n',
        "# 1000000 steps, 12345678 bytes, deadbeef, facade\n",
        '"""A path runs/ab12cd3/x and a version 1.2.3a4b5c6."""\n',
        'args = ["--seeds", "0", "1"]\n',
        '"""Example: ``mpcde.fly("forest_swarm", seed=3)``; ``seeds: 20`` means seeds 0..19 (seeds 0 .. N-1)."""\n',
        '"""A cell not flown yet shows 0 flights; on-demand DMPC Sec. 5 flight: 0.4 m."""\n',
        'raise ValueError(f"seed {seed}: 3 flights failed")\n',
        '"""Flights run one at a time; every flight has its seed."""\n',
        '"""Eq. 11, 85 deg x 58 deg, 0.15 m, 1e-4, 20 % Bernoulli loss."""\n',
        '"""Sha256 of 64 hex: ' + "ab" * 32 + '."""\n',
    ],
)
def test_the_matcher_leaves_code_and_legitimate_text(source: str) -> None:
    assert findings(source) == []


def test_the_matcher_scans_only_the_prose_of_tests_for_hashes() -> None:
    source = '# seed 41 at fb9dc17\npage = "Flown at abc1234, seed 3"\n'
    assert findings(source, results=False) == [(1, "commit hash", "fb9dc17")]
