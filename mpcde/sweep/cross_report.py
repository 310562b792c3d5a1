"""``mpcde report A B ... --out DIR``: several sweep stores of one base scenario in one table, paired by seed across stores.

A method and its baselines are often separate sweep files (MP-CDE's Fig. 6:
the denied stack on 100 seeds, each communicating baseline on the first 30),
flown into separate stores at separate times. Within one store
:func:`mpcde.sweep.report.build_report` pairs cells one axis apart; this
module pairs cells *across* stores:

* every store must hold the same base scenario (the same ``base`` mapping in
  its ``sweep.json``), so seed s is the same forest and the same start jitter
  in each store, and a pair of flights on seed s differs only in its
  overrides and axis values;
* a cell's *settings* are its store's overrides updated by its axis values;
* two cells of different stores are paired when their settings agree on
  every pairing field of their two stores: the ``pair_on`` fields when
  given, else every field both stores set (as an axis or an override) whose
  values in the two stores overlap (numbers compared as floats). A field
  set in both with no common value (``planner.kind: mpcde`` against
  ``minco_comm``) is what the two stores compare; a field only one store
  sets (``radio.delay_s``) is a variant of that store's method. So a
  1 m/s cell is never paired with a 0.5 m/s one, whether speed is an axis
  or an override. The paired seeds are those both flew without a failure;
* per pair: the success-rate difference over the paired seeds and McNemar's
  exact two-sided p-value (:func:`mpcde.sweep.stats.mcnemar_exact`) of the
  discordant seeds.

Per-cell statistics are :func:`mpcde.sweep.report.cell_stats`, unchanged, each
over all of its cell's recorded flights (so a 100-seed cell and a 30-seed
cell show their own intervals). Writes ``report.txt``, ``report.md`` and
``report.json`` in the output folder.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from mpcde.errors import ConfigError
from mpcde.evals.text_table import cell as fmt
from mpcde.sweep.report import axis_cells, cell_stats, format_table, paired_success, rows_by_cell, seed_success, table_text
from mpcde.sweep.spec import cell_label
from mpcde.sweep.store import ResultsStore, json_safe

__all__ = ["build_cross_report", "default_pair_on", "format_cross_report", "write_cross_report"]


def _norm(value: Any) -> str:
    """A value as compared for pairing: numbers as floats (1 and 1.0 meet), anything else as sorted JSON."""
    if isinstance(value, (int, float)) and not isinstance(value, bool):
        return repr(float(value))
    return json.dumps(value, sort_keys=True)


def _store_values(sweep: dict[str, Any]) -> dict[str, set[str]]:
    """{field: the normalised values its cells fly} over a sweep's overrides and axes."""
    out = {name: {_norm(v)} for name, v in sweep["overrides"].items()}
    for name, values in sweep["axes"]:
        out[name] = {_norm(v) for v in values}
    return out


def default_pair_on(a: dict[str, Any], b: dict[str, Any]) -> list[str]:
    """Fields sweeps ``a`` and ``b`` both set (axis or override) whose values overlap, in ``a``'s order."""
    va, vb = _store_values(a), _store_values(b)
    return [name for name in va if name in vb and va[name] & vb[name]]


def _names(folders: list[str | Path]) -> list[str]:
    """Each folder's name in the report: its last part, or the path as given where two last parts are equal."""
    last = [Path(f).name or str(f) for f in folders]
    return [n if last.count(n) == 1 else str(f) for n, f in zip(last, folders)]


def build_cross_report(folders: list[str | Path], pair_on: list[str] | None = None) -> dict[str, Any]:
    """The cross-store report of ``folders`` (each a sweep store, complete or not) as plain data.

    ConfigError when fewer than two folders are given, one is given twice, their base scenarios
    differ, or a ``pair_on`` field is set in none of a store's cells.
    """
    if len(folders) < 2:
        raise ConfigError("report", " ".join(map(str, folders)), "a cross-store report needs at least two sweep folders")
    seen: dict[Path, str] = {}
    for f in folders:
        real = Path(f).resolve()
        if real in seen:
            raise ConfigError("report", str(f), f"is given twice (as {seen[real]}): each store once")
        seen[real] = str(f)
    stores = [ResultsStore.read(f) for f in folders]
    sweeps = [s.manifest["sweep"] for s in stores]
    for folder, sweep in zip(folders[1:], sweeps[1:]):
        if sweep["base"] != sweeps[0]["base"]:
            raise ConfigError(
                "report", str(folder), f"flies another base scenario than {folders[0]}: seeds pair only on one base"
            )
    if pair_on is not None:
        for folder, sweep in zip(folders, sweeps):
            missing = [key for key in pair_on if key not in _store_values(sweep)]
            if missing:
                raise ConfigError("--pair-on", missing[0], f"is neither an axis nor an override of {folder}")
    names = _names(folders)
    shared = {k: v for k, v in sweeps[0]["overrides"].items() if all(s["overrides"].get(k, object()) == v for s in sweeps)}
    cells: list[dict[str, Any]] = []
    success: list[dict[int, bool]] = []  # per cell of the report: {seed: success}
    recorded = []
    for k, (name, store, sweep) in enumerate(zip(names, stores, sweeps)):
        rows = store.rows()
        recorded.append(len(rows))
        by_cell = rows_by_cell(rows)
        for index, values in enumerate(axis_cells(sweep)):
            settings = {**sweep["overrides"], **values}  # the cell's settings: its store's overrides, then its axes
            shown = {key: v for key, v in settings.items() if key not in shared}
            stats = cell_stats(len(cells), values, by_cell.get(index, []))
            stats.update(store=name, store_index=k, label=f"{name}: {cell_label(shown)}", settings=settings)
            success.append(seed_success(by_cell.get(index, [])))
            cells.append(stats)
    pair_keys = {
        (k, m): list(pair_on) if pair_on is not None else default_pair_on(sweeps[k], sweeps[m])
        for k in range(len(stores)) for m in range(k + 1, len(stores))
    }  # fmt: skip
    pairs = []
    for i, a in enumerate(cells):
        for j in range(i + 1, len(cells)):
            b = cells[j]
            if a["store_index"] == b["store_index"]:
                continue
            keys = pair_keys[(a["store_index"], b["store_index"])]
            if any(_norm(a["settings"][key]) != _norm(b["settings"][key]) for key in keys):
                continue
            seeds, paired = paired_success(success[i], success[j])
            on = {key: a["settings"][key] for key in keys if key not in shared}
            drop = set(keys)
            pairs.append({
                "on": on, "a": i, "b": j,
                "a_label": f"{a['store']}: {cell_label({k: v for k, v in a['settings'].items() if k not in drop and k not in shared})}",
                "b_label": f"{b['store']}: {cell_label({k: v for k, v in b['settings'].items() if k not in drop and k not in shared})}",
                **paired, "a_success_paired": sum(success[i][s] for s in seeds), "b_success_paired": sum(success[j][s] for s in seeds),
            })  # fmt: skip
    pairs.sort(key=lambda p: (json.dumps(list(p["on"].values())), p["a"], p["b"]))
    stores_out = [
        {"folder": str(f), "name": n, "recorded": r, "overrides": sw["overrides"], "axes": sw["axes"], "seeds": sw["seeds"]}
        for f, n, r, sw in zip(folders, names, recorded, sweeps)
    ]  # fmt: skip
    keys_out = [{"stores": [names[k], names[m]], "keys": keys} for (k, m), keys in pair_keys.items()]
    return {"base_name": sweeps[0]["base_name"], "pair_keys": keys_out, "shared_overrides": shared, "stores": stores_out,
            "cells": cells, "pairs": pairs}  # fmt: skip


def format_cross_report(report: dict[str, Any], markdown: bool = False) -> str:
    """The per-cell table of every store and the cross-store pairs, as text or Markdown."""
    lines = [f"stores of {report['base_name']} (shared overrides: {cell_label(report['shared_overrides'])}):"]
    for s in report["stores"]:
        seeds = s["seeds"]
        lines.append(f"  {s['name']}: {s['folder']}, {s['recorded']} flights recorded, seeds {seeds[0]}..{seeds[-1]}")
    lines += ["", format_table(report["cells"], markdown), "", "paired across stores (same seeds; two stores' cells pair on):"]
    lines += [f"  {p['stores'][0]} x {p['stores'][1]}: {', '.join(p['keys']) or 'nothing (every cell with every cell)'}" for p in report["pair_keys"]]
    lines.append("")
    head = ["on", "a", "b", "pairs", "a ok", "b ok", "a only", "b only", "success a-b", "McNemar p"]
    rows = [[
        cell_label(p["on"]), p["a_label"], p["b_label"], str(p["paired_seeds"]), str(p["a_success_paired"]),
        str(p["b_success_paired"]), str(p["a_only"]), str(p["b_only"]),
        fmt(None if p["success_difference"] is None else 100 * p["success_difference"], "+.0f").strip() + " pp",
        f"{p['mcnemar_p']:.3g}",
    ] for p in report["pairs"]]  # fmt: skip
    lines.append(table_text(head, rows, markdown))
    return "\n".join(lines) + "\n"


def write_cross_report(folders: list[str | Path], out: str | Path, pair_on: list[str] | None = None) -> dict[str, Any]:
    """Build the cross-store report and write report.txt, report.md and report.json in ``out`` (created).

    ``out`` may not be a sweep folder or lie inside one (ConfigError); the three files are written
    beside their final names first, then each moved into place.
    """
    out = Path(out)
    for folder in folders:
        root = Path(folder).resolve()
        if out.resolve() == root or root in out.resolve().parents:
            raise ConfigError("--out", str(out), f"is (inside) the sweep folder {folder}: the cross-store report goes elsewhere")
    report = build_cross_report(folders, pair_on)
    texts = {
        "report.txt": format_cross_report(report), "report.md": format_cross_report(report, markdown=True),
        "report.json": json.dumps(json_safe(report), indent=1) + "\n",
    }  # fmt: skip
    try:
        out.mkdir(parents=True, exist_ok=True)
        for name, text in texts.items():
            (out / f".{name}.tmp").write_text(text)
        for name in texts:
            (out / f".{name}.tmp").replace(out / name)
    except OSError as e:
        for name in texts:
            (out / f".{name}.tmp").unlink(missing_ok=True)
        raise ConfigError("--out", str(out), f"cannot be written ({e.strerror})") from None
    return report
