"""Fuzz the scenario loader: N hypothesis-generated malformed files (mutated and damaged built-ins), counting outcomes.

The same strategies as ``tests/unit/mpcde/config/test_malformed_scenarios.py``, run
with fresh random draws and many more examples; any exception other than a
one-line ConfigError stops the run with hypothesis's shrunk example.

Run: ``.venv/bin/python scripts/fuzz_scenarios.py [N]`` (default 3000 of each kind).
"""

from __future__ import annotations

import collections
import sys
import tempfile
from pathlib import Path

from hypothesis import HealthCheck, Phase, given, settings

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests" / "unit" / "mpcde" / "config"))

import test_malformed_scenarios as strategies  # noqa: E402

from mpcde.config.scenario import load_scenario  # noqa: E402
from mpcde.errors import ConfigError  # noqa: E402


def main() -> None:
    n = int(sys.argv[1]) if len(sys.argv) > 1 else 3000
    counts: collections.Counter = collections.Counter()
    folder = Path(tempfile.mkdtemp())
    opts = settings(max_examples=n, deadline=None, database=None, suppress_health_check=list(HealthCheck), phases=[Phase.generate])

    def check(kind: str, path: Path) -> None:
        try:
            load_scenario(path)
            counts[f"{kind} loaded"] += 1
        except ConfigError:
            counts[f"{kind} refused in one line"] += 1
        strategies._holds_the_promise(path)  # raises on anything else

    @opts
    @given(text=strategies.mutated_documents())
    def mutated(text: str) -> None:
        (folder / "m.yaml").write_text(text)
        check("mutated", folder / "m.yaml")

    @opts
    @given(raw=strategies.damaged_texts())
    def damaged(raw: bytes) -> None:
        (folder / "d.yaml").write_bytes(raw)
        check("damaged", folder / "d.yaml")

    mutated()
    damaged()
    for key, value in sorted(counts.items()):
        print(f"{key:32s} {value:6d}")
    print(f"{sum(counts.values())} files, 0 crashes")


if __name__ == "__main__":
    main()
