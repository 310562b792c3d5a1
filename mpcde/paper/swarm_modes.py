"""What the denied swarm's yaw planner did in each cell of one or more sweep stores (``mpcde paper modes STORE_DIR ...``).

Contacts by kind, the share of yaw plans in each mode, yaw replans and mission time (issue 28: the tracking mode's
safety role in the swarm). `mpcde report` gives each cell's success rate, its interval, collisions per flight and
the minimum distance; this report adds, per cell (one line each, labelled as `mpcde report` labels it: the store's
folder name and the cell's axis values; with ``seeds`` only the flights of seeds 0..seeds-1, so a store of more
seeds is read on the seeds a smaller one flew):

* ``flights``: the flights that recorded metrics (a failed flight records none);
* ``ok``: the flights that succeeded (every drone arrived, no contact);
* ``with d-d`` / ``with d-o``: flights with at least one drone-drone / drone-obstacle contact (``drone_drone_collisions``,
  ``drone_obstacle_collisions``);
* ``explore`` / ``observe`` / ``track``: the mean of ``yaw_mode_fraction`` (the share of a drone's yaw plans made in
  each of MP-CDE's modes, Alg. 1), in per cent, over the drones and flights that made a yaw plan;
* ``yaw repl.``: yaw replans per drone and flight: trajectory replans that Alg. 1's trigger forced (S(0) below
  tau_thr, Eq. 2, or the nearest neighbour closer than C_s) and that succeeded;
* ``mission s``: mean ``mission_time_s`` [s] over the flights in which every drone arrived (with or without a
  contact), as `mpcde report`'s column of that name.

A cell with no flight recorded yet prints ``nan``. A folder that is not a store (no sweep.json or no results.jsonl,
a kept store not unpacked) raises FileNotFoundError or ConfigError; a row this report cannot read (a cell or seed
out of the sweep, metrics without the fields above) a one-line ConfigError. A store still being flown is read as
`mpcde report` reads it (a last line cut short is left out).
"""

from __future__ import annotations

from pathlib import Path

from mpcde.errors import ConfigError
from mpcde.paper.stores import MODES, check_mode_fraction, check_place, is_finite, read_store
from mpcde.sweep.report import axis_cells, rows_by_cell
from mpcde.sweep.spec import cell_label

__all__ = ["cell_lines", "render"]


def cell_lines(store: Path, seeds: int | None = None) -> list[dict]:
    """One dict per cell of ``store`` (see the module docstring), over seeds below ``seeds`` when given."""
    results = read_store(store)
    sweep = results.manifest["sweep"]
    cells = axis_cells(sweep)
    checked = [_checked(r, f"store {results.path} line {line}", len(cells), sweep.get("seeds")) for line, r in enumerate(results.rows(), start=1)]
    by_cell = rows_by_cell(checked)
    out = []
    for index, values in enumerate(cells):
        rows = [r for r in by_cell.get(index, []) if r["metrics"] is not None and (seeds is None or r["seed"] < seeds)]
        shares = {k: [] for k in MODES}
        replans = []
        for r in rows:
            for agent in r["metrics"]["agents"]:
                fraction = agent.get("yaw_mode_fraction")
                if fraction:
                    for k in MODES:
                        shares[k].append(fraction[k])
                if "yaw_replans" in agent:
                    replans.append(agent["yaw_replans"])
        missions = [r["metrics"]["mission_time_s"] for r in rows if r["metrics"]["mission_time_s"] is not None]
        out.append({
            "label": f"{results.folder.name}: {cell_label(values)}",
            "flights": len(rows),
            "ok": sum(r["metrics"]["success"] for r in rows),
            "drone_drone": sum(r["metrics"]["drone_drone_collisions"] > 0 for r in rows),
            "drone_obstacle": sum(r["metrics"]["drone_obstacle_collisions"] > 0 for r in rows),
            "shares": {k: (sum(v) / len(v) if v else float("nan")) for k, v in shares.items()},
            "yaw_replans": sum(replans) / len(replans) if replans else float("nan"),
            "mission_s": sum(missions) / len(missions) if missions else float("nan"),
        })  # fmt: skip
    return out


def _checked(r: dict, where: str, n_cells: int, seeds: object) -> dict:
    """Row ``r`` (at ``where``) if this report can read it, else ConfigError (one line)."""
    check_place(r, where, n_cells, seeds)
    m = r["metrics"]
    if m is None:
        return r  # a failed flight
    if not isinstance(m, dict):
        raise ConfigError(f"{where}: metrics", m, "a mapping of the flight's metrics, or null for a failed flight")
    if not isinstance(m.get("success"), bool):
        raise ConfigError(f"{where}: metrics.success", m.get("success"), "true or false")
    for key in ("drone_drone_collisions", "drone_obstacle_collisions"):
        if not isinstance(m.get(key), int) or isinstance(m.get(key), bool) or m[key] < 0:
            raise ConfigError(f"{where}: metrics.{key}", m.get(key), "an integer >= 0")
    mission = m.get("mission_time_s", "absent")
    if mission is not None and not is_finite(mission):
        raise ConfigError(f"{where}: metrics.mission_time_s", mission, "a time [s], or null when a drone did not arrive")
    agents = m.get("agents")
    if not isinstance(agents, list) or not all(isinstance(a, dict) for a in agents):
        raise ConfigError(f"{where}: metrics.agents", agents, "a list of per-drone mappings")
    for i, a in enumerate(agents):
        check_mode_fraction(a.get("yaw_mode_fraction"), f"{where}: metrics.agents[{i}].yaw_mode_fraction")
        if "yaw_replans" in a and not (is_finite(a["yaw_replans"]) and a["yaw_replans"] >= 0):
            raise ConfigError(f"{where}: metrics.agents[{i}].yaw_replans", a["yaw_replans"], "a count >= 0")
    return r


def render(lines: list[dict]) -> str:
    """The table of :func:`cell_lines`' dicts, one line per cell under a header, as `mpcde paper modes` prints it
    (without the last newline)."""
    head = f"{'flights':>7} {'ok':>4} {'with d-d':>8} {'with d-o':>8} {'explore':>7} {'observe':>7} {'track':>6} {'yaw repl.':>9} {'mission s':>9}  cell"
    out = [head, "-" * len(head)]
    for c in lines:
        s = c["shares"]
        out.append(
            f"{c['flights']:>7} {c['ok']:>4} {c['drone_drone']:>8} {c['drone_obstacle']:>8} {100 * s['exploring']:>6.1f}% "
            f"{100 * s['observing']:>6.1f}% {100 * s['tracking']:>5.1f}% {c['yaw_replans']:>9.1f} {c['mission_s']:>9.2f}  {c['label']}"
        )
    return "\n".join(out)
