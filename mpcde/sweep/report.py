"""``mpcde report DIR``: per cell of a sweep, what its flights did, and what pairs of cells differ by; runs on a partial store.

Per cell (over its recorded flights; ``failed`` ones are counted apart and
left out of every statistic):

* ``flights``, ``failed``; ``success_rate`` with its 95 % Wilson interval
  (:func:`mpcde.sweep.stats.wilson_interval`);
* ``collisions_per_flight``, split into ``drone_drone_per_flight`` and
  ``drone_obstacle_per_flight`` (metrics.json's event counts);
* ``min_distance_m``: the smallest inter-drone centre distance over all its flights;
* ``mission_time_s`` mean and ``mission_time_std_s`` over the flights where
  every drone arrived (``arrived_flights`` of them);
* ``tracking_pos_rmse_m``: mean over the flights that report it.

Paired comparisons: for every two cells whose values differ in exactly one
axis, over the seeds both flew: the difference in success rate and McNemar's
exact p-value (:func:`mpcde.sweep.stats.mcnemar_exact`). Writes
``report.txt``, ``report.md``, ``report.json`` and, for each axis whose
values are all numbers, ``success_<axis>.png``: success rate with its
interval against that axis, one line per combination of the other axes.
"""

from __future__ import annotations

import itertools
import json
from pathlib import Path
from typing import Any

import numpy as np

from mpcde.evals.text_table import cell as fmt
from mpcde.sweep.spec import cell_label
from mpcde.sweep.stats import mcnemar_exact, wilson_interval
from mpcde.sweep.store import ResultsStore, json_safe

__all__ = [
    "CELL_KEYS", "axis_cells", "build_report", "cell_stats", "format_report", "format_table", "paired_success", "rows_by_cell",
    "seed_success", "table_text", "write_report",
]  # fmt: skip

CELL_KEYS = (
    "cell", "label", "flights", "failed", "success_rate", "success_low", "success_high", "collisions_per_flight",
    "drone_drone_per_flight", "drone_obstacle_per_flight", "min_distance_m", "mission_time_s", "mission_time_std_s",
    "arrived_flights", "tracking_pos_rmse_m",
)  # fmt: skip


def cell_stats(index: int, values: dict[str, Any], rows: list[dict[str, Any]]) -> dict[str, Any]:
    """The statistics of one cell (``CELL_KEYS`` and ``values``) over its store ``rows`` (failed rows counted apart)."""
    ok = [r["metrics"] for r in rows if r["status"] == "ok"]
    n = len(ok)
    wins = sum(bool(m["success"]) for m in ok)
    low, high = wilson_interval(wins, n)
    missions = [m["mission_time_s"] for m in ok if m.get("mission_time_s") is not None]
    dists = [m["min_inter_drone_distance_m"] for m in ok if m.get("min_inter_drone_distance_m") is not None]
    rmse = [m["tracking_pos_rmse_m"] for m in ok if m.get("tracking_pos_rmse_m") is not None]

    def per_flight(key: str) -> float | None:
        return float(np.mean([m.get(key, 0) for m in ok])) if n else None

    return {
        "cell": index, "label": cell_label(values), "values": values, "flights": n, "failed": len(rows) - n,
        "success_rate": wins / n if n else None, "success_low": low if n else None, "success_high": high if n else None,
        "collisions_per_flight": per_flight("collisions"), "drone_drone_per_flight": per_flight("drone_drone_collisions"),
        "drone_obstacle_per_flight": per_flight("drone_obstacle_collisions"),
        "min_distance_m": float(min(dists)) if dists else None,
        "mission_time_s": float(np.mean(missions)) if missions else None,
        "mission_time_std_s": float(np.std(missions, ddof=1)) if len(missions) > 1 else None,
        "arrived_flights": len(missions), "tracking_pos_rmse_m": float(np.mean(rmse)) if rmse else None,
    }  # fmt: skip


def axis_cells(sweep: dict[str, Any]) -> list[dict[str, Any]]:
    """The axis values {field: value} of every cell of a stored sweep (``sweep.json``'s ``sweep``), in product order."""
    names = [name for name, _ in sweep["axes"]]
    return [dict(zip(names, combo)) for combo in itertools.product(*(values for _, values in sweep["axes"]))]


def rows_by_cell(rows: list[dict[str, Any]]) -> dict[int, list[dict[str, Any]]]:
    """A store's rows grouped by cell index, each group in the order written."""
    out: dict[int, list[dict[str, Any]]] = {}
    for r in rows:
        out.setdefault(int(r["cell"]), []).append(r)
    return out


def seed_success(rows: list[dict[str, Any]]) -> dict[int, bool]:
    """{seed: success} over one cell's flown rows (failed rows left out)."""
    return {int(r["seed"]): bool(r["metrics"]["success"]) for r in rows if r["status"] == "ok"}


def paired_success(a: dict[int, bool], b: dict[int, bool]) -> tuple[list[int], dict[str, Any]]:
    """The seeds two cells both flew (sorted), and over them: ``paired_seeds``, ``a_only`` and ``b_only`` (seeds
    only that cell succeeded on), ``success_difference`` (a - b, None without seeds) and ``mcnemar_p``."""
    seeds = sorted(a.keys() & b.keys())
    a_only = sum(a[s] and not b[s] for s in seeds)
    b_only = sum(b[s] and not a[s] for s in seeds)
    diff = (a_only - b_only) / len(seeds) if seeds else None
    return seeds, {
        "paired_seeds": len(seeds), "a_only": a_only, "b_only": b_only, "success_difference": diff,
        "mcnemar_p": mcnemar_exact(a_only, b_only),
    }  # fmt: skip


def build_report(folder: str | Path) -> dict[str, Any]:
    """The report of the store in ``folder`` (complete or not) as plain data."""
    store = ResultsStore.read(folder)
    sweep = store.manifest["sweep"]
    rows = store.rows()
    cells_values = axis_cells(sweep)
    by_cell = rows_by_cell(rows)
    cells = [cell_stats(i, v, by_cell.get(i, [])) for i, v in enumerate(cells_values)]
    success = [seed_success(by_cell.get(i, [])) for i in range(len(cells_values))]
    pairs = []
    for i, j in itertools.combinations(range(len(cells_values)), 2):
        differ = [k for k in cells_values[i] if cells_values[i][k] != cells_values[j][k]]
        if len(differ) != 1:
            continue
        _, paired = paired_success(success[i], success[j])
        pairs.append({
            "axis": differ[0], "a": i, "b": j, "a_value": cells_values[i][differ[0]], "b_value": cells_values[j][differ[0]],
            "others": cell_label(rest) if (rest := {k: v for k, v in cells_values[i].items() if k != differ[0]}) else "",
            **paired,
        })  # fmt: skip
    expected = len(cells_values) * len(sweep["seeds"])
    return {"sweep": sweep, "recorded": len(rows), "expected": expected, "cells": cells, "pairs": pairs}


def format_report(report: dict[str, Any], markdown: bool = False) -> str:
    """The per-cell table and the paired comparisons, as text or Markdown."""
    sweep = report["sweep"]
    phead = ["axis", "a", "b", "with", "pairs", "a only", "b only", "success a-b", "McNemar p"]
    prow = [[p["axis"], json.dumps(p["a_value"]), json.dumps(p["b_value"]), p["others"] or "-", str(p["paired_seeds"]),
             str(p["a_only"]), str(p["b_only"]), fmt(None if p["success_difference"] is None else 100 * p["success_difference"], "+.0f").strip() + " pp",
             f"{p['mcnemar_p']:.3g}"] for p in report["pairs"]]  # fmt: skip
    seeds = sweep["seeds"]
    span = f"{seeds[0]}..{seeds[-1]}" if seeds == list(range(seeds[0], seeds[0] + len(seeds))) else ", ".join(map(str, seeds))
    title = f"sweep of {sweep['base_name']}: {report['recorded']} of {report['expected']} flights recorded, seeds {span}"
    return "\n".join([title, "", format_table(report["cells"], markdown), "", "paired cells (same seeds, one axis apart):", "", table_text(phead, prow, markdown)]) + "\n"


def format_table(cells: list[dict[str, Any]], markdown: bool = False) -> str:
    """The per-cell table (one row per :func:`cell_stats` entry, labelled by its ``label``), as text or Markdown."""
    head = ["cell", "flights", "failed", "success", "95% CI", "coll/flight", "drone-drone", "obstacle", "min d m", "mission s", "sd s", "(of)", "trk pos m"]
    rows = []
    for c in cells:
        rate = None if c["success_rate"] is None else 100 * c["success_rate"]
        ci = "-" if c["success_low"] is None else f"{100 * c['success_low']:.0f}-{100 * c['success_high']:.0f}%"
        rows.append([
            c["label"], str(c["flights"]), str(c["failed"]), fmt(rate, ".0f").strip() + ("%" if rate is not None else ""), ci,
            fmt(c["collisions_per_flight"], ".2f"), fmt(c["drone_drone_per_flight"], ".2f"), fmt(c["drone_obstacle_per_flight"], ".2f"),
            fmt(c["min_distance_m"], ".3f"), fmt(c["mission_time_s"], ".2f"), fmt(c["mission_time_std_s"], ".2f"),
            str(c["arrived_flights"]), fmt(c["tracking_pos_rmse_m"], ".3f"),
        ])  # fmt: skip
    return table_text(head, rows, markdown)


def table_text(head: list[str], rows: list[list[str]], markdown: bool) -> str:
    """Rows under a header: right-aligned columns (the first left-aligned), or a Markdown table."""
    if markdown:
        lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
        return "\n".join(lines + ["| " + " | ".join(str(v).strip() for v in r) + " |" for r in rows])
    widths = [max(len(str(x).strip()) for x in [h] + [r[i] for r in rows]) for i, h in enumerate(head)]
    fmt_row = lambda r: "  ".join(str(v).strip().rjust(w) if i else str(v).strip().ljust(w) for i, (v, w) in enumerate(zip(r, widths)))  # noqa: E731
    return "\n".join([fmt_row(head), "-" * (sum(widths) + 2 * (len(widths) - 1))] + [fmt_row(r) for r in rows])


def write_report(folder: str | Path) -> dict[str, Any]:
    """Build the report of ``folder`` and write report.txt, report.md, report.json and the success plots there."""
    folder = Path(folder)
    report = build_report(folder)
    (folder / "report.txt").write_text(format_report(report))
    (folder / "report.md").write_text(format_report(report, markdown=True))
    (folder / "report.json").write_text(json.dumps(json_safe(report), indent=1) + "\n")
    for name, values in report["sweep"]["axes"]:
        if all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in values):
            _plot_success(folder / f"success_{name.replace('.', '_')}.png", report, name, values)
    return report


def _plot_success(path: Path, report: dict[str, Any], axis: str, values: list[float]) -> None:
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(6.0, 4.0))
    FigureCanvasAgg(fig)
    ax = fig.add_subplot(1, 1, 1)
    lines: dict[str, list[dict[str, Any]]] = {}
    for c in report["cells"]:
        others = cell_label({k: v for k, v in c["values"].items() if k != axis})
        lines.setdefault(others, []).append(c)
    for k, (label, cells) in enumerate(lines.items()):
        pts = sorted((c["values"][axis], c) for c in cells if c["success_rate"] is not None)
        if not pts:
            continue
        x = np.array([p[0] for p in pts], float)
        y = np.array([p[1]["success_rate"] for p in pts])
        lo = np.maximum(y - np.array([p[1]["success_low"] for p in pts]), 0.0)  # 0 up to rounding at 0 or n successes
        hi = np.maximum(np.array([p[1]["success_high"] for p in pts]) - y, 0.0)
        ax.errorbar(x + 0.01 * k * (x.max() - x.min() if x.size > 1 else 1), y, yerr=[lo, hi], marker="o", capsize=3, label=label)
    ax.set(xlabel=axis, ylabel="success rate (95 % Wilson)", ylim=(-0.02, 1.02), title=f"success against {axis}")
    if lines:
        ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=100)
