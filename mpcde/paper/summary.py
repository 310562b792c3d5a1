"""MP-CDE's Sec. V-B figures beside ours, one markdown row each (``mpcde paper summary [RUNS_DIR]``, default runs/).

Each row is: paper figure | paper | ours | command | commit | date, read from the stores and reports that the
experiment commands write (issue 28, deliverable 4):

* RUNS_DIR/fig10/report.json (`mpcde report`);
* RUNS_DIR/fig6/report.json: the cross-store report of the denied sweep, the view-gated baselines and whatever
  else it pairs (e.g. auto). A store of the denied stack with other settings (e.g. look before moving) gets
  MP-CDE's rows of its own besides its pairs. The denied sweep's store itself, reported alone, gives MP-CDE's rows
  only;
* RUNS_DIR/table3: a sweep store (:func:`mpcde.paper.table3.cells`);
* RUNS_DIR/akf_pipeline/results.json (`mpcde eval-tracking`).

The commit column lists the code revisions the stores' flights recorded, the date their commit dates; for
`eval-tracking`, the revision its results.json records ("not recorded" where it records none). A missing input (or
a store with no flight recorded yet) leaves its rows out, with an HTML comment saying which; a cell not flown yet
has no row. A corrupt input (a store's row, a report that is not JSON) raises a one-line
:class:`~mpcde.errors.ConfigError`.
"""

from __future__ import annotations

import json
import subprocess
from pathlib import Path

from mpcde.errors import ConfigError
from mpcde.paper.stores import read_store
from mpcde.paper.table3 import cells, label, margins, paper_margin

__all__ = [
    "AKF_PAPER", "FIG6_PAPER", "HEAD", "MALFORMED", "akf", "commit_date", "fig10", "fig6", "fig6_row", "pct", "read_json", "revisions",
    "summary_table", "table3", "table_text", "variant_of",
]  # fmt: skip

HERE = Path(__file__).resolve().parent
"""Where ``git`` looks for the repository whose commit dates the rows cite (the checkout this package is in)."""
FIG6_PAPER = {0.5: 0.98, 1.0: 0.95, 2.0: 0.90}
"""MP-CDE's success rate in Fig. 6 by cruise speed [m/s], as issue 28 reads the figure (its goals)."""
AKF_PAPER = {"low": (0.06, 0.25), "high": (0.23, 0.34)}
"""The AKF's position [m] and velocity [m/s] RMSE at low and high speed (Sec. V-B2)."""
DENIED_KINDS = ("mpcde", "mpcde_paper")
"""The ``planner.kind`` values of the denied stack: ``mpcde`` (``denied``, and MP-CDE as published in stores flown
before 2026-12-03) and ``mpcde_paper``."""


def revisions(*stores: Path) -> tuple[str, str]:
    """(short revisions, their commit dates) recorded by the flights of ``stores``, first seen first."""
    revs: list[str] = []
    for store in stores:
        for row in read_store(store).rows():
            rev = row["git_rev"]
            if rev and rev[:7] not in revs:
                revs.append(rev[:7])
    dates = []
    for rev in revs:
        date = commit_date(rev)
        if date not in dates:
            dates.append(date)
    return ", ".join(revs) or "-", ", ".join(dates) or "-"


def read_json(path: Path) -> dict:
    """The JSON object in ``path`` (FileNotFoundError when absent; ConfigError, one line, when it is not JSON)."""
    text = path.read_text()
    try:
        return json.loads(text)
    except ValueError:
        raise ConfigError(str(path), text[:40], "JSON, as `mpcde report` or `mpcde eval-tracking` writes it") from None


def commit_date(rev: str) -> str:
    """The commit date (YYYY-MM-DD) of revision ``rev``, "?" where git does not know it."""
    out = subprocess.run(["git", "-C", str(HERE), "show", "-s", "--format=%cs", rev], capture_output=True, text=True)
    return out.stdout.strip() if out.returncode == 0 else "?"


def pct(x: float) -> str:
    """A fraction as whole per cent ("93 %")."""
    return f"{100 * x:.0f} %"


def fig10(runs: Path) -> list[str]:
    """The rows of Fig. 10, from RUNS_DIR/fig10/report.json: collisions and minimum distance, yaw planning on and off."""
    report = read_json(runs / "fig10" / "report.json")
    commit, date = revisions(runs / "fig10")
    rows = []
    for c in report["cells"]:
        on = c["values"]["denied.active_yaw"]
        paper = "no collision" if on else "the pair collides"
        ours = f"{c['collisions_per_flight']:.2f} collisions per flight over {c['flights']} seeds, minimum distance {c['min_distance_m']:.3f} m"
        rows.append(f"| Fig. 10, yaw planning {'on' if on else 'off'} | {paper} | {ours} | `mpcde sweep data/sweeps/fig10_crossing_yaw.yaml` | {commit} | {date} |")
    return rows


def fig6_row(c: dict, command: str, commit: str, date: str, variant: str = "") -> str:
    """The row of one of MP-CDE's Fig. 6 cells ``c`` (a cell of `mpcde report`); ``variant``: the settings that set
    a store of the denied stack apart from MP-CDE's (e.g. ``denied.fresh_path_age_s=1.0``), empty for MP-CDE's own."""
    v = c["values"]["planner.cruise_speed_mps"]
    ours = (f"{pct(c['success_rate'])} ({100 * c['success_low']:.0f}-{pct(c['success_high'])}) of {c['flights']}, "
            f"{c['collisions_per_flight']:.2f} collisions per flight")  # fmt: skip
    name = f"MP-CDE with {variant}" if variant else "MP-CDE"
    return f"| Fig. 6, {name} at {v:g} m/s | about {pct(FIG6_PAPER[v])} | {ours} | {command} | {commit} | {date} |"


def fig6(runs: Path) -> list[str]:
    """The rows of Fig. 6, from RUNS_DIR/fig6/report.json: MP-CDE's (and each denied-stack variant's) success per speed,
    then every store paired with them (view-gated baselines, and the stores beside)."""
    report = read_json(runs / "fig6" / "report.json")
    if "stores" not in report:  # the denied sweep's own store, reported alone: MP-CDE's rows, nothing to pair
        commit, date = revisions(runs / "fig6")
        return [fig6_row(c, "`mpcde sweep data/sweeps/forest_swarm_denied.yaml`", commit, date) for c in report["cells"] if c["flights"]]
    folders = {st["name"]: Path(st["folder"]) for st in report["stores"]}
    revs = {name: revisions(folder) for name, folder in folders.items()}
    command = f"`mpcde report {' '.join(str(f) for f in folders.values())} --out runs/fig6`"
    first = report["stores"][0]["name"]
    rows = []
    for c in report["cells"]:
        if c["store"] == first and c["flights"]:  # a cell not flown yet has no row
            rows.append(fig6_row(c, command, *revs[first]))
    gated = {st["name"]: bool(st["overrides"].get("radio.view_gated")) for st in report["stores"]}
    # what sets a store apart: its cell's settings less the overrides every store shares, as `mpcde report` labels it
    # (so a store-wide override no axis names, e.g. the levels store's denied.flight_level_spacing_m, is shown)
    skip = ("planner.cruise_speed_mps", "radio.view_gated", *report["shared_overrides"])
    # a variant of the denied stack (another store of planner.kind mpcde) gets MP-CDE's rows of its own too
    variants = {}  # store -> the settings that set it apart from MP-CDE's
    for c in report["cells"]:
        if (variant := variant_of(c, first, skip)) is not None:
            variants[c["store"]] = variant
            rows.append(fig6_row(c, "(same)", *revs[c["store"]], variant=variant))
    for p in report["pairs"]:
        a, b = report["cells"][p["a"]], report["cells"][p["b"]]
        if a["store"] != first or not p["paired_seeds"]:  # a cell not flown yet pairs no seed
            continue
        # the paper ranks MP-CDE against view-gated baselines; another store (auto over the scenario's radio) sits beside it
        role, paper, radio = ("baseline", "below MP-CDE", "view-gated") if gated[b["store"]] else ("beside", "-", "scenario's radio (not view-gated)")
        if b["settings"].get("planner.kind") in DENIED_KINDS:
            radio = "the denied stack (no radio)"  # a variant of MP-CDE itself (flight levels): the radio plays no part
        against = f"against MP-CDE's {p['a_success_paired']}"
        rows.append(_pair_row(role, paper, a, b, p, p["b_success_paired"], radio, against, skip, revs))
    # the paired goal holds for a variant of the denied stack too only if it beats the view-gated baselines itself
    for p in report["pairs"]:
        a, b = report["cells"][p["a"]], report["cells"][p["b"]]
        ok_a, ok_b = p["a_success_paired"], p["b_success_paired"]
        if b["store"] in variants:  # a pair lists its stores in the report's order: the variant may come second
            a, b, ok_a, ok_b = b, a, ok_b, ok_a
        if a["store"] not in variants or not gated[b["store"]] or not p["paired_seeds"]:
            continue
        against = f"against {ok_a} of MP-CDE with {variants[a['store']]} ({a['store']})"
        rows.append(_pair_row("baseline", "below MP-CDE", a, b, p, ok_b, "view-gated", against, skip, revs))
    return rows


def variant_of(c: dict, first: str, skip: tuple) -> str | None:
    """What sets cell ``c`` of the cross-store report apart from MP-CDE's store ``first`` when it is a variant of the
    denied stack (a flown cell of another store of planner.kind mpcde): its settings less ``skip`` and planner.kind;
    None for any other cell."""
    if c["store"] == first or not c["flights"] or c["settings"].get("planner.kind") not in DENIED_KINDS:
        return None
    return ", ".join(f"{k}={val}" for k, val in c["settings"].items() if k not in skip and k != "planner.kind")


def _pair_row(role: str, paper: str, a: dict, b: dict, p: dict, ok_b: int, radio: str, against: str, skip: tuple, revs: dict) -> str:
    """The row of pair ``p`` of the cross-store report: store ``b``'s cell (its settings less ``skip``, flown over
    ``radio``) with ``ok_b`` successes ``against`` the denied-stack cell ``a``, on their paired seeds."""
    v = a["settings"]["planner.cruise_speed_mps"]
    what = ", ".join(f"{k}={val}" for k, val in b["settings"].items() if k not in skip)
    ours = (f"{b['store']} ({what}), {radio}: {ok_b} success{'' if ok_b == 1 else 'es'} {against} "
            f"on {p['paired_seeds']} paired seeds, McNemar p = {p['mcnemar_p']:.2g}")  # fmt: skip
    return f"| Fig. 6, {role} at {v:g} m/s | {paper} | {ours} | (same) | {' | '.join(revs[b['store']])} |"


def table3(runs: Path) -> list[str]:
    """The rows of Table III, from the store RUNS_DIR/table3: each flown cell, then ours against Zhou's per density."""
    table = cells(runs / "table3")
    commit, date = revisions(runs / "table3")
    rows = []
    for c in table:
        if not c["flights"]:  # a cell not flown yet has no row
            continue
        paper = "-" if c["paper_s_obs_m2"] is None else f"{c['paper_s_obs_m2']:.1f} m^2"
        ours = f"{c['s_obs_mean_m2']:.1f} +- {c['s_obs_sd_m2']:.1f} m^2, success {c['successes']} of {c['flights']}"
        rows.append(f"| Table III, {label(c['method'])}, density {c['density']:g} | {paper} | {ours} | `mpcde sweep data/sweeps/table3_active_perception.yaml` | {commit} | {date} |")
    for di, density, ours, zhou in margins(table):
        rows.append(f"| Table III, ours against Zhou's, density {density:g} | {paper_margin(di)} | {100 * (ours / zhou - 1):+.1f} % | (same) | {commit} | {date} |")
    return rows


def akf(runs: Path) -> list[str]:
    """The rows of AKF vs KF, from RUNS_DIR/akf_pipeline/results.json: position and velocity RMSE per filter and speed."""
    results = read_json(runs / "akf_pipeline" / "results.json")
    rows_in, rev = results["rows"], (results.get("run") or {}).get("git_rev")  # older results record no revision
    commit, date = "not recorded", "-"
    if rev:
        commit, date = rev[:7] + ("+dirty" if rev.endswith("+dirty") else ""), commit_date(rev[:40])
    rows = []
    for r in rows_in:
        band = {0.5: "low", 2.0: "high"}.get(r["speed_mps"])
        paper = "-" if band is None or r["filter"] != "akf" else f"{AKF_PAPER[band][0]} m, {AKF_PAPER[band][1]} m/s"
        ours = f"position {r['pos_rmse_m']:.3f} m, velocity {r['vel_rmse_mps']:.3f} m/s"
        rows.append(f"| AKF vs KF, {r['filter'].upper()} at {r['speed_mps']:g} m/s | {paper} | {ours} | `mpcde eval-tracking --measurements pipeline --seeds 10` | {commit} | {date} |")
    return rows


MALFORMED = (ConfigError, KeyError, TypeError, ValueError, IndexError, AttributeError, ZeroDivisionError, OSError)
"""What reading a store or report that is not what `mpcde sweep` / `mpcde report` writes can raise."""


def table_text(head: list[str], parts: tuple, runs: Path) -> str:
    """``head`` and every part's rows for ``runs``, one line each (the text ends with a newline).

    A part whose input is missing (FileNotFoundError) leaves an HTML comment naming it; a malformed input
    (:data:`MALFORMED`) stops the table with a one-line ConfigError naming the part and what is wrong."""
    lines = list(head)
    for part in parts:
        try:
            lines += part(runs)
        except FileNotFoundError as e:
            lines.append(f"<!-- {part.__name__}: {e.filename} missing -->")
        except ConfigError:
            raise
        except MALFORMED as e:
            raise ConfigError(f"{part.__name__}: {type(e).__name__}", str(e), "not what `mpcde report` writes") from None
    return "\n".join(lines) + "\n"


HEAD = ["| paper figure | paper | ours | command | commit | date |", "|---|---|---|---|---|---|"]
"""The summary table's header."""


def summary_table(runs: Path | str = "runs") -> str:
    """The summary of the stores and reports under ``runs`` (module docstring), as `mpcde paper summary` prints it."""
    return table_text(HEAD, (fig10, fig6, table3, akf), Path(runs))
