"""MP-CDE's Table III from the store of a Table III sweep file (``mpcde paper table3 STORE_DIR [STORE_DIR ...]``).

The sweep files are data/sweeps/table3_active_perception.yaml, table3_fuel_range.yaml and their variants. The report
gives S_obs (mean +- sd [m^2]) and success per density [obstacles per 100 m^2] and method, ours against Zhou's,
beside the paper's figures; then the paper's two S_obs orderings tested seed by seed, and the share of yaw plans in
each mode.

Several stores are reported as one table when they are flights of one Table III: the same base scenario, overrides,
densities and seeds (so a seed is the same forest in each), each (density, method) cell flown in one store only;
the report then ends with each store's name and the revisions its flights recorded. A reading of Eq. 1's d_free
other than the default (``free_distance``) makes a method of its own ("ours, d_free to occupied"; every method
reads S(0), which triggers replans). The paper's orderings are tested within one reading (ours with a reading
against Zhou's and ours without exploring with the same reading), and ours with a reading against ours.

The store is read as `mpcde report` reads it (:mod:`mpcde.paper.stores`): a cell not flown yet shows 0 flights and
nan. A folder that is not a Table III store (no sweep.json or no results.jsonl, a kept store not unpacked, a
corrupt row, a sweep whose axes are not density then yaw, a flight without S_obs) raises FileNotFoundError or a
one-line :class:`~mpcde.errors.ConfigError`.

The paired lines: for each density, the seeds both methods flew, the mean of (a - b) over them [m^2], on how many
seeds a saw more and on how many the two saw exactly the same, and the two-sided Wilcoxon signed-rank p of the
differences. Equal seeds are dropped from the test (Wilcoxon's convention); p is from the exact distribution when
at most 50 differences remain and no two have the same magnitude, else from the normal approximation with the tie
correction (the method is named explicitly, so the p does not depend on scipy's "auto" rule, which changed in 1.15).
The mode lines: each cell's mean over the flights that recorded it of the drone's ``yaw_mode_fraction`` (the share
of yaw plans made in the exploring / observing / tracking mode; a flight that made no yaw plan records none).
"""

from __future__ import annotations

import math
from collections import defaultdict
from pathlib import Path

from scipy.stats import wilcoxon

from mpcde.errors import ConfigError
from mpcde.paper.stores import MODES, check_mode_fraction, check_place, is_finite, read_store
from mpcde.sweep.stats import wilson_interval
from mpcde.sweep.store import MANIFEST, ResultsStore

__all__ = [
    "D_FREE", "DENSITY_AXIS", "METHODS", "PAIRS", "PAPER", "YAW_AXIS", "cells", "label", "margins", "merged_cells", "method_of",
    "paired", "pairs_of", "paper_margin", "render", "signed_rank_p",
]  # fmt: skip

PAPER = {  # density index -> S_obs [m^2] of Zhou's, ours w/o exploring, ours; the paper's table prints no success
    0: (142.7, 137.1, 167.5),
    1: (132.4, 122.4, 145.9),
    2: (105.7, 94.6, 123.5),
}
METHODS = {"zhou": "Zhou's [26]", "no_exploring": "ours w/o exploring", "no_tracking": "ours w/o tracking", "ours": "ours"}
"""The methods of Table III by key, with their printed names."""
D_FREE = {"occupied": "d_free to occupied", "voxel": "d_free in 3-D"}
"""Eq. 1's readings of d_free besides the default ``horizontal``, with their printed names."""
PAIRS = (("ours", "zhou"), ("ours", "no_exploring"))
"""The paper's two orderings of S_obs: ours above each."""
DENSITY_AXIS, YAW_AXIS = "world.obstacle_density_per_100m2", "denied.yaw"
"""The axes of a Table III sweep, in this order."""


def method_of(yaw: dict) -> str:
    """The method key of a ``denied.yaw`` axis value: a key of METHODS, or ``BASE/READING`` for a method flown with a
    reading of Eq. 1's d_free other than the default. Every method computes S(0) with its reading, and S(0) < tau_thr
    triggers a replan in each (Alg. 1 line 13), so a reading makes a method of its own, Zhou's included."""
    base = "zhou" if yaw.get("method") == "zhou" else "no_exploring" if yaw.get("exploring_mode") is False else (
        "no_tracking" if yaw.get("tracking_mode") is False else "ours")
    reading = yaw.get("free_distance", "horizontal")
    return base if reading == "horizontal" else f"{base}/{reading}"


def label(method: str) -> str:
    """The printed name of a method key (:func:`method_of`)."""
    base, _, reading = method.partition("/")
    return f"{METHODS[base]}, {D_FREE[reading]}" if reading else METHODS[base]


def cells(store: Path) -> list[dict]:
    """One dict per (density, method) cell of the store: density, method, flights, S_obs mean and sd [m^2], successes,
    the Wilson 95 % interval, the paper's S_obs (None where the paper gives none), ``area_by_seed`` ({seed: S_obs}),
    ``modes`` (the mean yaw mode shares, None when no flight recorded them), the store's folder name and the
    revisions the cell's flights recorded."""
    return _cells(read_store(store))


def _cells(results: ResultsStore) -> list[dict]:
    """:func:`cells` of an opened store."""
    axes = results.manifest["sweep"].get("axes")
    names = [a[0] for a in axes] if isinstance(axes, list) and all(isinstance(a, list) and len(a) == 2 for a in axes) else None
    if names != [DENSITY_AXIS, YAW_AXIS] or not all(isinstance(a[1], list) for a in axes):
        raise ConfigError(f"store {results.folder / MANIFEST}: sweep.axes", names if names is not None else axes,
                          f"a Table III sweep: the axes {DENSITY_AXIS} then {YAW_AXIS}, each a list, and no other")
    densities, yaw_values = axes[0][1], axes[1][1]
    if not all(is_finite(d) for d in densities) or not all(isinstance(y, dict) for y in yaw_values):
        raise ConfigError(f"store {results.folder / MANIFEST}: sweep.axes", axes, "densities as finite numbers and yaw settings as mappings")
    if len(set(densities)) < len(densities):
        raise ConfigError(f"store {results.folder / MANIFEST}: sweep.axes[0][1]", densities, "each density once")
    readings = [y.get("free_distance", "horizontal") for y in yaw_values]
    if not all(isinstance(r, str) and r in ("horizontal", *D_FREE) for r in readings):
        raise ConfigError(f"store {results.folder / MANIFEST}: sweep.axes[1][1] free_distance", readings, f"one of horizontal, {', '.join(D_FREE)}")
    kinds = [y.get("method", "mpcde") for y in yaw_values]
    if not all(k in ("mpcde", "zhou") for k in kinds):
        raise ConfigError(f"store {results.folder / MANIFEST}: sweep.axes[1][1] method", kinds, "mpcde or zhou: the methods of Table III")
    methods = [method_of(y) for y in yaw_values]
    if len(set(methods)) < len(methods):
        raise ConfigError(f"store {results.folder / MANIFEST}: sweep.axes[1][1]", [label(m) for m in methods], "each method once per density")
    by_cell = _flights(results, len(densities) * len(yaw_values), results.manifest["sweep"].get("seeds"))
    out = []
    for di, density in enumerate(densities):
        for mi, yaw in enumerate(yaw_values):
            rows = by_cell.get(di * len(yaw_values) + mi, [])
            areas = [r["metrics"]["observed_area_swarm_m2"] for r in rows]
            ok = sum(bool(r["metrics"]["success"]) for r in rows)
            n = len(rows)
            mean = sum(areas) / n if n else float("nan")
            sd = math.sqrt(sum((a - mean) ** 2 for a in areas) / (n - 1)) if n > 1 else float("nan")
            lo, hi = wilson_interval(ok, n) if n else (float("nan"), float("nan"))
            m = method_of(yaw)
            paper = dict(zip(("zhou", "no_exploring", "ours"), PAPER.get(di, (None, None, None)))).get(m)  # the paper has 3 densities
            fractions = [f for r in rows if (f := (r["metrics"].get("agents") or [{}])[0].get("yaw_mode_fraction"))]
            modes = {k: sum(f[k] for f in fractions) / len(fractions) for k in MODES} if fractions else None
            out.append({"store": results.folder.name, "revisions": sorted({str(r["git_rev"])[:7] for r in rows}), "density_index": di, "density": density, "method": m, "flights": n, "s_obs_mean_m2": mean, "s_obs_sd_m2": sd,
                        "successes": ok, "success_low": lo, "success_high": hi, "paper_s_obs_m2": paper,
                        "area_by_seed": {r["seed"]: r["metrics"]["observed_area_swarm_m2"] for r in rows}, "modes": modes})  # fmt: skip
    return out


def merged_cells(stores: list[Path]) -> list[dict]:
    """The cells (:func:`cells`) of several stores of one Table III, ordered by density, then method (METHODS'
    order, the default reading first); ConfigError when a store is given twice, the stores differ in base, overrides,
    densities or seeds, or two fly the same cell (module docstring)."""
    folders = [Path(s).resolve() for s in stores]
    if len(set(folders)) < len(folders):
        raise ConfigError("arguments", [str(s) for s in stores], "each store once")
    table: list[dict] = []
    first = None
    for store in stores:
        results = read_store(store)
        part = _cells(results)  # also checks the axes, so the densities below are there
        spec = results.manifest["sweep"]
        shared = {f"sweep.{k}": spec.get(k) for k in ("base", "overrides", "seeds")}
        shared["sweep.axes[0][1]"] = spec["axes"][0][1]
        if first is None:
            first = shared
        for key in shared:
            if shared[key] != first[key]:
                raise ConfigError(f"store {store}: {key}", shared[key], f"the same as in {stores[0]}: stores reported together fly one Table III")
        flown = {(c["density_index"], c["method"]): c["store"] for c in table}
        for c in part:
            if (c["density_index"], c["method"]) in flown:
                raise ConfigError(f"store {store}: sweep.axes[1][1]", label(c["method"]), f"a method no earlier store flies (store {flown[(c['density_index'], c['method'])]} does)")
        table += part
    order = list(METHODS)
    readings = ["horizontal", *D_FREE]

    def key(c: dict) -> tuple[int, int, int]:
        base, _, reading = c["method"].partition("/")
        return c["density_index"], readings.index(reading or "horizontal"), order.index(base)

    return sorted(table, key=key)


def pairs_of(table: list[dict]) -> list[tuple[str, str]]:
    """The pairs the report tests: the paper's two orderings of S_obs (PAIRS, ours above Zhou's and above ours
    without exploring) within each reading of d_free present, the default first; then ours with each other reading
    against ours with the default. Methods flown under different readings are not compared otherwise."""
    present = set(c["method"] for c in table)
    out = list(PAIRS)
    for reading in D_FREE:
        if f"ours/{reading}" in present:
            out += [(f"{a}/{reading}", f"{b}/{reading}") for a, b in PAIRS] + [(f"ours/{reading}", "ours")]
    return out


def _flights(results: ResultsStore, n_cells: int, seeds: object) -> dict[int, list[dict]]:
    """The store's flights that recorded metrics, by cell index (a store holds one row per cell and seed); a row
    whose fields this report reads are not what `mpcde sweep` writes for this sweep (``n_cells`` cells, ``seeds``)
    is refused (ConfigError, one line)."""
    by_cell = defaultdict(list)
    for line, r in enumerate(results.rows(), start=1):
        where = f"store {results.path} line {line}"
        check_place(r, where, n_cells, seeds)
        m = r["metrics"]
        if m is None:
            continue  # a failed flight
        if not isinstance(m, dict):
            raise ConfigError(f"{where}: metrics", m, "a mapping of the flight's metrics, or null for a failed flight")
        missing = [k for k in ("observed_area_swarm_m2", "success") if k not in m]
        if missing:
            raise ConfigError(f"{where} (cell {r['cell']} seed {r['seed']}): metrics", missing,
                              "a flight's observed_area_swarm_m2 and success (a flight of a package without S_obs?)")
        if not is_finite(m["observed_area_swarm_m2"]) or m["observed_area_swarm_m2"] < 0:
            raise ConfigError(f"{where}: metrics.observed_area_swarm_m2", m["observed_area_swarm_m2"], "a finite area >= 0 [m^2]")
        if not isinstance(m["success"], bool):
            raise ConfigError(f"{where}: metrics.success", m["success"], "true or false")
        agents = m.get("agents")
        if agents is not None and not (isinstance(agents, list) and all(isinstance(a, dict) for a in agents)):
            raise ConfigError(f"{where}: metrics.agents", agents, "a list of per-drone mappings")
        check_mode_fraction((agents or [{}])[0].get("yaw_mode_fraction"), f"{where}: metrics.agents[0].yaw_mode_fraction")
        by_cell[r["cell"]].append(r)
    return by_cell


def signed_rank_p(diff: list[float]) -> float | None:
    """Two-sided Wilcoxon signed-rank p of paired differences, zeros dropped (module docstring); None when fewer
    than two non-zero differences remain."""
    nonzero = [d for d in diff if d != 0]
    if len(nonzero) < 2:
        return None
    mags = [abs(d) for d in nonzero]
    method = "exact" if len(nonzero) <= 50 and len(set(mags)) == len(mags) else "asymptotic"
    return float(wilcoxon(nonzero, method=method).pvalue)


def paired(table: list[dict], a: str, b: str) -> list[dict]:
    """Method ``a`` against ``b`` at every density where both flew: the seeds both flew, mean of a - b [m^2], seeds
    where a saw more, seeds where both saw the same, and the two-sided Wilcoxon signed-rank p (:func:`signed_rank_p`)."""
    by = {(c["density_index"], c["method"]): c for c in table}
    out = []
    for c in table:
        di = c["density_index"]
        if c["method"] != a or (di, b) not in by:
            continue
        sa, sb = c["area_by_seed"], by[(di, b)]["area_by_seed"]
        seeds = sorted(set(sa) & set(sb))
        if not seeds:
            continue
        diff = [sa[s] - sb[s] for s in seeds]
        out.append({"density": c["density"], "seeds": len(seeds), "mean_diff_m2": sum(diff) / len(diff), "a_larger": sum(d > 0 for d in diff),
                    "equal": sum(d == 0 for d in diff), "p": signed_rank_p(diff)})  # fmt: skip
    return out


def render(table: list[dict]) -> str:
    """The report of ``table`` (:func:`cells` or :func:`merged_cells`) as `mpcde paper table3` prints it: the cell table,
    the margins, the paired tests, the modes (and the stores, when several)."""
    w = max([20] + [len(label(c["method"])) for c in table])  # the method column: 20 unless a variant's name is longer
    lines = [f"{'density /100m^2':>15}  {'method':<{w}} {'flights':>7}  {'S_obs m^2 mean +- sd':>21}  {'success':>7}  {'95% CI':>9}  {'paper S_obs':>11}"]
    for c in table:
        n, paper = c["flights"], c["paper_s_obs_m2"]
        lines.append(f"{c['density']:>15g}  {label(c['method']):<{w}} {n:>7d}  {c['s_obs_mean_m2']:>12.1f} +- {c['s_obs_sd_m2']:>5.1f}  "
                     f"{100 * c['successes'] / max(n, 1):>6.0f}%  {100 * c['success_low']:>3.0f}-{100 * c['success_high']:<3.0f}%  "
                     f"{'' if paper is None else f'{paper:.1f}':>11}")  # fmt: skip
    lines.append("\nours against Zhou's, S_obs: measured (paper)")
    for di, density, ours, zhou in margins(table):
        lines.append(f"  density {density:g}: {100 * (ours / zhou - 1):+.1f} % ({paper_margin(di)})")
    for reading in D_FREE:
        for di, density, ours, zhou in margins(table, f"ours/{reading}", f"zhou/{reading}"):
            lines.append(f"  density {density:g}, both {D_FREE[reading]}: {100 * (ours / zhou - 1):+.1f} % ({paper_margin(di)})")
    lines.append("\npaired by seed, S_obs (Wilcoxon signed-rank, two-sided)")
    for a, b in pairs_of(table):
        for r in paired(table, a, b):
            p = "-" if r["p"] is None else f"{r['p']:.2g}"
            lines.append(f"  density {r['density']:g}: {label(a)} - {label(b)}: mean {r['mean_diff_m2']:+.1f} m^2, "
                         f"{label(a)} larger on {r['a_larger']} of {r['seeds']}, equal on {r['equal']}, p = {p}")  # fmt: skip
    lines.append("\nmean share of yaw plans per mode (exploring / observing / tracking)")
    for c in table:
        if c["modes"] is not None:
            lines.append(f"  density {c['density']:g}, {label(c['method'])}: " + " / ".join(f"{c['modes'][k]:.2f}" for k in MODES))
    stores = {}
    for c in table:
        stores.setdefault(c["store"], set()).update(c["revisions"])
    if len(stores) > 1:  # several stores in one table: say which flights were flown at which revision
        lines.append("\nstores (the revisions their flights recorded): " + ", ".join(f"{name} ({', '.join(sorted(revs)) or '-'})" for name, revs in stores.items()))
    return "\n".join(lines) + "\n"


def paper_margin(density_index: int) -> str:
    """The paper's ours-over-Zhou's S_obs margin at its ``density_index``-th density ("+17 %"), "-" past its three."""
    if density_index not in PAPER:
        return "-"
    zhou, _, ours = PAPER[density_index]
    return f"{100 * (ours / zhou - 1):+.0f} %"


def margins(table: list[dict], method: str = "ours", against: str = "zhou") -> list[tuple[int, float, float, float]]:
    """(density index, density, ``method``'s mean S_obs, ``against``'s) for every density where both were flown."""
    mean = {(c["density_index"], c["method"]): c["s_obs_mean_m2"] for c in table if c["flights"]}
    out = []
    for c in table:
        di = c["density_index"]
        if c["method"] == method and (di, method) in mean and (di, against) in mean:
            out.append((di, c["density"], mean[(di, method)], mean[(di, against)]))
    return out

