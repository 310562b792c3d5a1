"""Property-based: any malformed scenario file is either a checked scenario or one line naming a field, never a crash.

Hypothesis mutates the built-in scenarios (a value replaced by any type or an
extreme, a key removed or invented, a section replaced by a scalar) and their
text (bytes inserted, the file cut short): ``tests/scenario_strategies.py``.
Every file must load into a scenario whose layout and obstacles can be built, or raise
:class:`ConfigError` with a one-line, printable message. The same promise
through the real command line's stderr is ``tests/integration/test_malformed_cli.py``.
"""

from __future__ import annotations

from pathlib import Path

from hypothesis import HealthCheck, given, settings
from scenario_strategies import damaged_texts, mutated_documents  # tests/scenario_strategies.py

from mpcde.config.layout import build_layout, check_layout, resolve_obstacles
from mpcde.config.scenario import load_scenario
from mpcde.errors import ConfigError


def _holds_the_promise(path: Path) -> None:
    try:
        cfg = load_scenario(path)
    except ConfigError as e:
        msg = str(e)
        assert msg.isprintable() and len(msg) < 1000, msg
        return
    starts, goals = build_layout(cfg.drones)
    obstacles = resolve_obstacles(cfg, starts, goals)
    try:
        check_layout(cfg, starts, goals, obstacles)
    except ConfigError as e:
        assert str(e).isprintable()


SETTINGS = settings(max_examples=300, deadline=None, derandomize=True, suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow])


@SETTINGS
@given(text=mutated_documents())
def test_a_mutated_scenario_loads_or_is_refused_in_one_line(tmp_path, text):
    path = tmp_path / "mutated.yaml"
    path.write_text(text)
    _holds_the_promise(path)


@SETTINGS
@given(raw=damaged_texts())
def test_a_damaged_file_loads_or_is_refused_in_one_line(tmp_path, raw):
    path = tmp_path / "damaged.yaml"
    path.write_bytes(raw)
    _holds_the_promise(path)
