"""Hypothesis strategies of malformed scenario files: the built-in scenarios mutated (a value replaced by any type or
an extreme, a key removed or invented) and their text damaged (bytes inserted or replaced, the file cut short).

Shared by ``tests/unit/mpcde/config/test_malformed_scenarios.py`` (in process) and
``tests/integration/test_malformed_cli.py`` (through the real command line); importable from any test because
pytest puts this folder, the one of ``tests/conftest.py``, on the import path.
"""

from __future__ import annotations

import yaml
from hypothesis import strategies as st

from mpcde.config.scenario import SCENARIO_DIR

__all__ = ["BUILTINS", "EXTREMES", "damaged_texts", "mutated_documents", "values"]

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
