"""Property-based: any malformed scenario file is either a checked scenario or one line naming a field, never a crash.

Hypothesis mutates the built-in scenarios (a value replaced by any type or an
extreme, a key removed or invented, a section replaced by a scalar) and their
text (bytes inserted, the file cut short). Every file must load into a
scenario whose layout and obstacles can be built, or raise
:class:`ConfigError` with a one-line, printable message. The same promise
through the real command line's stderr is ``tests/integration/test_malformed_cli.py``.
"""

from __future__ import annotations

from pathlib import Path

import yaml
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from mpcde.config.layout import build_layout, check_layout, resolve_obstacles
from mpcde.config.scenario import SCENARIO_DIR, load_scenario
from mpcde.errors import ConfigError

BUILTINS = {p.stem: p.read_text() for p in sorted(SCENARIO_DIR.glob("*.yaml"))}
EXTREMES = [1e300, -1e300, float("inf"), float("-inf"), float("nan"), 2**64, -(2**63), -1, 0, 1e-300, 0.5, "", "x" * 300, [], {}, None, True]

values = st.one_of(
    st.sampled_from(EXTREMES),
    st.none(),
    st.booleans(),
    st.integers(min_value=-(2**70), max_value=2**70),
    st.floats(allow_nan=True, allow_infinity=True),
    st.text(max_size=20),
    st.lists(st.floats(allow_nan=False, width=32), max_size=4),
    st.dictionaries(st.text(max_size=6), st.integers(), max_size=3),
)


def _paths(node: object, prefix: tuple = ()) -> list[tuple]:
    out = [prefix] if prefix else []
    if isinstance(node, dict):
        for k, v in node.items():
            out += _paths(v, prefix + (k,))
    elif isinstance(node, list):
        for i, v in enumerate(node):
            out += _paths(v, prefix + (i,))
    return out


@st.composite
def mutated_documents(draw) -> str:
    doc = yaml.safe_load(BUILTINS[draw(st.sampled_from(sorted(BUILTINS)))])
    for _ in range(draw(st.integers(1, 3))):
        paths = _paths(doc)
        kind = draw(st.sampled_from(["replace", "replace", "delete", "invent"]))
        if kind == "invent" or not paths:
            doc[draw(st.sampled_from(["wrold", "camera", "seed", "drones", "x" * 50]))] = draw(values)
            continue
        path = draw(st.sampled_from(paths))
        parent = doc
        for k in path[:-1]:
            parent = parent[k]
        if kind == "delete":
            del parent[path[-1]]
        else:
            parent[path[-1]] = draw(values)
    return yaml.safe_dump(doc, allow_unicode=True)


@st.composite
def damaged_texts(draw) -> bytes:
    raw = BUILTINS[draw(st.sampled_from(sorted(BUILTINS)))].encode()
    cut = draw(st.integers(0, len(raw)))
    how = draw(st.sampled_from(["truncate", "insert", "replace"]))
    if how == "truncate":
        return raw[:cut]
    chunk = draw(st.one_of(st.binary(max_size=12), st.sampled_from([b": [", b"\t", b"&a ", b"*a", b"!!int ", b"\n- ", b"{", b"\xff\xfe", b"017", b"1:30"])))
    return raw[:cut] + chunk + raw[cut + (len(chunk) if how == "replace" else 0) :]


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
