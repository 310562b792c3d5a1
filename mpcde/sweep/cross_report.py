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
  every ``pair_on`` field (default: every axis that all stores sweep and
  whose value sets overlap, e.g. ``planner.cruise_speed_mps``); the paired
  seeds are those both flew without a failure;
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
from mpcde.sweep.report import cell_stats, format_table, table_text
from mpcde.sweep.spec import cell_label
from mpcde.sweep.stats import mcnemar_exact
from mpcde.sweep.store import ResultsStore, json_safe

__all__ = ["build_cross_report", "default_pair_on", "format_cross_report", "write_cross_report"]


def _store_cells(store: ResultsStore) -> list[dict[str, Any]]:
    """(index, values, settings) of every cell of ``store``'s sweep, in product order."""
    sweep = store.manifest["sweep"]
    names = [name for name, _ in sweep["axes"]]
    combos: list[tuple[Any, ...]] = [()]
    for _, values in sweep["axes"]:
        combos = [c + (v,) for c in combos for v in values]
    return [
        {"index": i, "values": dict(zip(names, combo)), "settings": {**sweep["overrides"], **dict(zip(names, combo))}}
        for i, combo in enumerate(combos)
    ]


def default_pair_on(sweeps: list[dict[str, Any]]) -> list[str]:
    """Axes every sweep has whose value sets overlap in every pair of sweeps, in the first sweep's axis order."""
    axis_values = [{name: values for name, values in s["axes"]} for s in sweeps]
    out = []
    for name, _ in sweeps[0]["axes"]:
        if not all(name in a for a in axis_values):
            continue
        sets = [{json.dumps(v) for v in a[name]} for a in axis_values]
        if all(x & y for i, x in enumerate(sets) for y in sets[i + 1 :]):
            out.append(name)
    return out


def build_cross_report(folders: list[str | Path], pair_on: list[str] | None = None) -> dict[str, Any]:
    """The cross-store report of ``folders`` (each a sweep store, complete or not) as plain data.

    ConfigError when fewer than two folders are given, when their base scenarios differ, or when a
    ``pair_on`` field is set in none of a store's cells.
    """
    if len(folders) < 2:
        raise ConfigError("report", " ".join(map(str, folders)), "a cross-store report needs at least two sweep folders")
    stores = [ResultsStore.read(f) for f in folders]
    sweeps = [s.manifest["sweep"] for s in stores]
    for folder, sweep in zip(folders[1:], sweeps[1:]):
        if sweep["base"] != sweeps[0]["base"]:
            raise ConfigError(
                "report", str(folder), f"flies another base scenario than {folders[0]}: seeds pair only on one base"
            )
    keys = default_pair_on(sweeps) if pair_on is None else list(pair_on)
    names = [Path(f).name or str(f) for f in folders]
    shared = {k: v for k, v in sweeps[0]["overrides"].items() if all(s["overrides"].get(k, object()) == v for s in sweeps)}
    cells: list[dict[str, Any]] = []
    success: dict[tuple[int, int], bool] = {}
    for k, (name, store) in enumerate(zip(names, stores)):
        rows = store.rows()
        by_cell: dict[int, list[dict[str, Any]]] = {}
        for r in rows:
            by_cell.setdefault(int(r["cell"]), []).append(r)
        for c in _store_cells(store):
            missing = [key for key in keys if key not in c["settings"]]
            if missing:
                raise ConfigError("--pair-on", missing[0], f"is neither an axis nor an override of {folders[k]}")
            shown = {key: v for key, v in c["settings"].items() if key not in shared}
            stats = cell_stats(len(cells), c["values"], by_cell.get(c["index"], []))
            rest = {key: v for key, v in shown.items() if key not in keys}
            stats.update(store=name, label=f"{name}: {cell_label(shown)}", short=f"{name}: {cell_label(rest)}", settings=c["settings"])
            for r in by_cell.get(c["index"], []):
                if r["status"] == "ok":
                    success[(len(cells), int(r["seed"]))] = bool(r["metrics"]["success"])
            cells.append(stats)
    pairs = []
    for i, a in enumerate(cells):
        for j in range(i + 1, len(cells)):
            b = cells[j]
            if a["store"] == b["store"] or any(a["settings"][key] != b["settings"][key] for key in keys):
                continue
            seeds = sorted({s for (c, s) in success if c == i} & {s for (c, s) in success if c == j})
            a_only = sum(success[(i, s)] and not success[(j, s)] for s in seeds)
            b_only = sum(success[(j, s)] and not success[(i, s)] for s in seeds)
            diff = (a_only - b_only) / len(seeds) if seeds else None
            pairs.append({
                "on": {key: a["settings"][key] for key in keys}, "a": i, "b": j, "a_label": a["short"], "b_label": b["short"],
                "paired_seeds": len(seeds), "a_only": a_only, "b_only": b_only, "success_difference": diff,
                "a_success_paired": sum(success[(i, s)] for s in seeds), "b_success_paired": sum(success[(j, s)] for s in seeds),
                "mcnemar_p": mcnemar_exact(a_only, b_only),
            })  # fmt: skip
    pairs.sort(key=lambda p: (json.dumps(list(p["on"].values())), p["a"], p["b"]))
    stores_out = [
        {"folder": str(f), "name": n, "recorded": len(s.rows()), "overrides": sw["overrides"], "axes": sw["axes"], "seeds": sw["seeds"]}
        for f, n, s, sw in zip(folders, names, stores, sweeps)
    ]  # fmt: skip
    return {"base_name": sweeps[0]["base_name"], "pair_on": keys, "shared_overrides": shared, "stores": stores_out,
            "cells": cells, "pairs": pairs}  # fmt: skip


def format_cross_report(report: dict[str, Any], markdown: bool = False) -> str:
    """The per-cell table of every store and the cross-store pairs, as text or Markdown."""
    lines = [f"stores of {report['base_name']} (shared overrides: {cell_label(report['shared_overrides'])}):"]
    for s in report["stores"]:
        seeds = s["seeds"]
        lines.append(f"  {s['name']}: {s['folder']}, {s['recorded']} flights recorded, seeds {seeds[0]}..{seeds[-1]}")
    lines += ["", format_table(report["cells"], markdown), ""]
    lines.append(f"paired across stores (same seeds, same {', '.join(report['pair_on']) or 'nothing'}):")
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
    """Build the cross-store report and write report.txt, report.md and report.json in ``out`` (created)."""
    report = build_cross_report(folders, pair_on)
    out = Path(out)
    for folder in folders:
        if out.resolve() == Path(folder).resolve():
            raise ConfigError("--out", str(out), "is one of the sweep folders: the cross-store report goes elsewhere")
    try:
        out.mkdir(parents=True, exist_ok=True)
        for name, text in (
            ("report.txt", format_cross_report(report)),
            ("report.md", format_cross_report(report, markdown=True)),
            ("report.json", json.dumps(json_safe(report), indent=1) + "\n"),
        ):
            tmp = out / f".{name}.tmp"
            tmp.write_text(text)
            tmp.replace(out / name)
    except OSError as e:
        raise ConfigError("--out", str(out), f"cannot be written ({e.strerror})") from None
    return report
