"""``mpcde eval-dmpc``: on-demand DMPC vs the buffered-Voronoi-cell baseline in the full simulator.

Reproduces Table 1 of the on-demand DMPC paper
(``papers/on-demand-dmpc-formation.txt``: average trajectory length, speed,
acceleration, QP solve time and mission time) on this package's scenarios,
flown closed-loop with the quadrotor physics and SE(3) controller (cameras
off: the DMPC agents plan from the radio and their own pose estimate only, so
rendering would change nothing but the wall time). Each (scenario, method,
obstacles) variant is flown once per seed with the scenario's own settings,
``planner.kind: dmpc`` and the replanning scheme of the paper
(:meth:`mpcde.config.dmpc.DmpcAgentConfig.replanning`: every round replanned,
no halting terminal constraint, ``dmpc.commit_when_unheard`` off), with
``dmpc.qp.collision_mode`` set to the method and ``dmpc.qp.obstacle_avoidance``
to the obstacle mode, so that two variants differ in their constraints only;
variants are interleaved in one process so they see the same machine load.
The comm stack's default committing scheme needs BVC (it refuses on-demand
rows), so it cannot be one side of this comparison.

Variants: each method with its paired obstacle mode (the paper's comparison:
on-demand collision AND obstacle avoidance, on-demand DMPC Sec. 3.4, vs BVC
with an obstacle row at every step), plus, in scenarios with obstacles and
when ``every_step_variant`` is set, on-demand collision avoidance with
every-step obstacle rows (the two halves of the mechanism separately).

Per row (pooled over seeds): what the agents flew, read back from the QPs they
built (``flown``: collision mode, resolved obstacle mode or null without
obstacles, terminal halt, commit when unheard; a row whose flown QP is not its
label's is an error, nothing is written), the obstacle mode (null without
obstacles), collisions (drone-drone + drone-obstacle events, summed), the
minimum inter-drone centre distance [m], the minimum obstacle clearance [m]
(surface distance minus the robot radius, :mod:`mpcde.flight.metrics`; null
without obstacles), the median, 95th percentile and mean of every solved
round's QP time [ms] over all drones (OSQP's wall time per round: data update,
refactorisation when the constraints changed, warm start and solve; the
Python that builds the constraints is reported separately in
``details.json``; the mean is the paper's Table 1 statistic, "Average QP
Solve Time", and the goal's), the QP's own statistics per solved round (mean
active collision rows, mean OSQP iterations, the share of rounds that
refactorised the KKT system), mission time [s] (the time the last drone
arrived, mean over seeds; null if some drone did not arrive in some seed),
and path length [m], mean speed [m/s] and mean acceleration [m/s^2] per drone
(mean over drones and seeds; :mod:`mpcde.flight.metrics`).

Outputs in ``out_dir``: ``results.json`` (exactly ``{"rows": [...]}``, keys
below), ``results.txt`` (the table, Table 1 beside the paper's figures, and
notes), ``details.json`` (per-run figures: arrivals, fallbacks, stale plans,
iterations, formation error) and ``results.png``.
"""

from __future__ import annotations

import json
import pathlib
from dataclasses import replace
from typing import Any, Sequence

import numpy as np

from mpcde.config.scenario import load_scenario
from mpcde.evals.text_table import cell
from mpcde.flight.loop import prepare_run, run_scenario
from mpcde.flight.run_folder import staged_output
from mpcde.stacks import get_stack

__all__ = ["FLOWN_KEYS", "ROW_KEYS", "format_table", "formation_error", "run_eval_dmpc", "table1"]

ROW_KEYS = (
    "method", "obstacles", "scenario", "flown", "collisions", "min_distance_m", "min_obstacle_clearance_m",
    "qp_ms_median", "qp_ms_p95", "qp_ms_mean", "collision_rows_mean", "iterations_mean", "refactor_share",
    "mission_time_s", "path_length_m", "mean_speed_mps", "mean_accel_mps2",
)  # fmt: skip
FLOWN_KEYS = ("collision_mode", "obstacle_avoidance", "terminal_halt", "commit_when_unheard")
"""What a row's agents flew (``row["flown"]``), as each agent reports it in ``metrics.json`` (:meth:`DmpcAgent.extra_metrics`)."""
_METHODS = ("on_demand", "bvc")
_PAIRED = {"on_demand": "on_demand", "bvc": "every_step"}  # DmpcConfig.obstacle_avoidance = "auto"
_PAPER = {"on_demand": (3.94, 27.66, 21.3, 0.77, 0.48), "bvc": (12.91, 30.65, 22.0, 0.72, 0.66)}
_TABLE1 = (  # (label, row key, index in _PAPER, format)
    ("average trajectory length [m]", "path_length_m", 2, "8.2f"),
    ("average speed [m/s]", "mean_speed_mps", 3, "8.2f"),
    ("average acceleration [m/s^2]", "mean_accel_mps2", 4, "8.2f"),
    ("average QP solve time [ms]", "qp_ms_mean", 0, "8.3f"),
    ("total mission time [s]", "mission_time_s", 1, "8.2f"),
)


def formation_error(pos_world: np.ndarray, offsets_world: np.ndarray) -> np.ndarray:
    """chi(k) = sum_i sum_{j != i} (||p_j(k) - p_i(k)|| - ||d_ij||)^2 [m^2] (on-demand DMPC Sec. 4).

    Args:
        pos_world: (T, N, 3) positions [m].
        offsets_world: (N, N, 3) desired offsets d_ij = p_j - p_i [m].

    Returns:
        (T,) formation error per sample.
    """
    pos = np.asarray(pos_world, float)
    dist = np.linalg.norm(pos[:, None, :, :] - pos[:, :, None, :], axis=-1)  # (T, i, j) ||p_j - p_i||
    ref = np.linalg.norm(np.asarray(offsets_world, float), axis=-1)  # (i, j)
    n = pos.shape[1]
    off_diag = ~np.eye(n, dtype=bool)
    return np.sum(((dist - ref[None]) ** 2)[:, off_diag], axis=1)


def _fly(scenario: str, method: str, obstacles: str, seed: int, duration_s: float | None) -> dict[str, Any]:
    """One closed-loop flight (``obstacles``: the obstacle mode); returns its metrics, pooled QP times and details."""
    overrides: dict[str, Any] = {"seed": int(seed)}
    if duration_s is not None:
        overrides["duration_s"] = float(duration_s)
    cfg = load_scenario(scenario, overrides)
    dmpc = cfg.dmpc.replanning(method)  # the paper's DMPC; the two methods differ in their constraints only
    cfg = replace(
        cfg,
        planner=replace(cfg.planner, kind=get_stack("comm").kind),
        dmpc=replace(dmpc, qp=replace(dmpc.qp, obstacle_avoidance=obstacles)),
        run=replace(cfg.run, cameras=False),
    )
    prepared = prepare_run(cfg)
    result = run_scenario(prepared)
    m = dict(result.metrics)
    agents = m.pop("agents", [])
    qp_ms = np.concatenate([np.asarray(a["qp_solve_ms"], float) for a in agents]) if agents else np.zeros(0)
    solves = int(sum(a["solves"] for a in agents))

    def per_solve(key: str) -> float | None:  # an agent's per-round mean, pooled over all solved rounds
        got = [(a[key], a["solves"]) for a in agents if a[key] is not None and a["solves"]]
        return float(sum(v * n for v, n in got) / sum(n for _, n in got)) if got else None

    detail = {
        "scenario": scenario, "method": method, "obstacles": obstacles if prepared.obstacles else None,
        "flown": _flown(agents), "seed": int(seed), "success": m["success"],
        "arrived": m["arrived"], "n_drones": m["n_drones"], "collisions": m["collisions"],
        "min_distance_m": m["min_inter_drone_distance_m"], "min_obstacle_distance_m": m["min_obstacle_distance_m"],
        "mission_time_s": m["mission_time_s"], "sim_time_s": m["sim_time_s"], "real_time_factor": m["real_time_factor"],
        "solves": solves, "fallbacks": int(sum(a["fallbacks"] for a in agents)),
        "refactorisations": int(sum(a["refactorisations"] for a in agents)),
        "mean_collision_rows": per_solve("mean_collision_rows"),
        "commits": int(sum(a["commits"] for a in agents)), "deadlock_turns": int(sum(a["deadlock_turns"] for a in agents)),
        "state_resets": int(sum(a["state_resets"] for a in agents)),
        "obstacle_row_rounds": int(sum(a["obstacle_row_rounds"] for a in agents)),
        "stale_plans": int(sum(a["stale_plans"] for a in agents)),
        "fresh_plans": int(sum(a["fresh_plans"] for a in agents)),
        "mean_iterations": per_solve("mean_iterations"),
        "qp_build_ms_median": float(np.median([a["qp_build_ms_median"] for a in agents if a["qp_build_ms_median"] is not None])) if agents else None,
    }  # fmt: skip
    if cfg.dmpc.formation_from_goals:
        goals = prepared.goals
        chi = formation_error(result.log.arrays["pos_world"], goals[None, :, :] - goals[:, None, :])
        detail["formation_error_mean_m2"] = float(chi.mean())
        detail["formation_error_max_m2"] = float(chi.max())
    return {"metrics": m, "qp_ms": qp_ms, "detail": detail, "log": result.log.arrays, "prepared": prepared}


def _flown(agents: list[dict]) -> dict[str, Any]:
    """The QP the agents of one flight flew (:data:`FLOWN_KEYS`, from their metrics); RuntimeError if they differ."""
    seen = {tuple(a[k] for k in FLOWN_KEYS) for a in agents}
    if len(seen) != 1:
        raise RuntimeError(f"the agents of one flight flew different QPs: {sorted(seen, key=str)}")
    return dict(zip(FLOWN_KEYS, seen.pop()))


def _check_flown(method: str, obstacles: str | None, scenario: str, flown: dict[str, Any]) -> None:
    """RuntimeError unless the row's agents flew its label: ``method`` rows, ``obstacles`` rows, the paper's replanning DMPC."""
    want = {"collision_mode": method, "obstacle_avoidance": obstacles, "terminal_halt": False, "commit_when_unheard": False}
    if flown != want:
        raise RuntimeError(f"{scenario} {_label(method, obstacles)}: the agents flew {flown}, not {want}")


def _row(method: str, obstacles: str | None, scenario: str, runs: list[dict]) -> dict[str, Any]:
    """Pool one (method, obstacles, scenario) over its seeds into a results row."""
    ms = [r["metrics"] for r in runs]
    details = [r["detail"] for r in runs]
    flown = details[0]["flown"]
    if any(d["flown"] != flown for d in details):
        raise RuntimeError(f"{scenario} {_label(method, obstacles)}: seeds flew different QPs")
    _check_flown(method, obstacles, scenario, flown)
    qp = np.concatenate([r["qp_ms"] for r in runs])
    missions = [m["mission_time_s"] for m in ms]
    dists = [m["min_inter_drone_distance_m"] for m in ms if m["min_inter_drone_distance_m"] is not None]
    clear = [m["min_obstacle_distance_m"] for m in ms if m["min_obstacle_distance_m"] is not None]
    solves = sum(d["solves"] for d in details)

    def per_solve(key: str) -> float | None:
        got = [(d[key], d["solves"]) for d in details if d[key] is not None and d["solves"]]
        return float(sum(v * n for v, n in got) / sum(n for _, n in got)) if got else None

    return {
        "method": method,
        "obstacles": obstacles,
        "scenario": scenario,
        "flown": flown,
        "collisions": int(sum(m["collisions"] for m in ms)),
        "min_distance_m": float(min(dists)) if dists else None,
        "min_obstacle_clearance_m": float(min(clear)) if clear else None,
        "qp_ms_median": float(np.median(qp)) if qp.size else None,
        "qp_ms_p95": float(np.percentile(qp, 95)) if qp.size else None,
        "qp_ms_mean": float(np.mean(qp)) if qp.size else None,  # the paper's Table 1 statistic
        "collision_rows_mean": per_solve("mean_collision_rows"),
        "iterations_mean": per_solve("mean_iterations"),
        "refactor_share": float(sum(d["refactorisations"] for d in details) / solves) if solves else None,
        "mission_time_s": float(np.mean(missions)) if all(t is not None for t in missions) else None,
        "path_length_m": float(np.mean([m["path_length_m"] for m in ms])),
        "mean_speed_mps": float(np.mean([m["mean_speed_mps"] for m in ms])),
        "mean_accel_mps2": float(np.mean([m["mean_accel_mps2"] for m in ms])),
    }


def format_table(results: dict) -> str:
    """Human-readable table of ``results["rows"]`` (scenario x variant), QP-time ratios BVC / on-demand, and Table 1.

    The ``flown`` column is the collision mode and obstacle mode the agents'
    QPs had (``row["flown"]``), not the row's label.
    """
    head = (
        f"{'scenario':<17} {'method':<10} {'obstacles':<10} {'flown':<20} {'coll':>4} {'min d m':>7} {'obs clr m':>9} "
        f"{'QP med ms':>9} {'QP p95 ms':>9} {'QP mean':>8} {'rows':>5} {'iter':>5} {'refac':>5} "
        f"{'mission s':>9} {'path m':>7} {'speed m/s':>9} {'acc m/s2':>8}"
    )
    lines = [head, "-" * len(head)]
    rows = results["rows"]
    for r in rows:
        f = r["flown"]
        flown = f["collision_mode"] + (f"/{f['obstacle_avoidance']}" if f["obstacle_avoidance"] else "")
        lines.append(
            f"{r['scenario']:<17} {r['method']:<10} {r['obstacles'] or '-':<10} {flown:<20} {r['collisions']:>4d} "
            f"{cell(r['min_distance_m'], '7.3f')} {cell(r['min_obstacle_clearance_m'], '9.3f')} "
            f"{cell(r['qp_ms_median'], '9.3f')} {cell(r['qp_ms_p95'], '9.3f')} {cell(r['qp_ms_mean'], '8.3f')} "
            f"{cell(r['collision_rows_mean'], '5.1f')} {cell(r['iterations_mean'], '5.0f')} {cell(r['refactor_share'], '5.2f')} "
            f"{cell(r['mission_time_s'], '9.2f')} "
            f"{r['path_length_m']:>7.2f} {r['mean_speed_mps']:>9.2f} {r['mean_accel_mps2']:>8.2f}"
        )
    lines.append(
        "rows: mean active collision rows per solved round; iter: mean OSQP iterations; "
        "refac: share of solved rounds that refactorised the KKT system"
    )
    ratios = []
    for scen in dict.fromkeys(r["scenario"] for r in rows):
        b = next((r for r in rows if r["scenario"] == scen and r["method"] == "bvc"), None)
        for a in (r for r in rows if r["scenario"] == scen and r["method"] == "on_demand"):
            if b and a["qp_ms_median"] and b["qp_ms_median"]:
                label = f"on-demand ({a['obstacles']} obstacles)" if a["obstacles"] else "on-demand"
                ratios.append(
                    f"{scen}: QP mean BVC / {label} = {b['qp_ms_mean'] / a['qp_ms_mean']:.2f}x "
                    f"(median {b['qp_ms_median'] / a['qp_ms_median']:.2f}x, p95 {b['qp_ms_p95'] / a['qp_ms_p95']:.2f}x)"
                )
    if ratios:
        paper_bvc, paper_od = _PAPER["bvc"][0], _PAPER["on_demand"][0]
        lines += [""] + ratios + [f"(paper, Table 1: mean {paper_bvc} / {paper_od} ms = {paper_bvc / paper_od:.2f}x)"]
    for scen in dict.fromkeys(r["scenario"] for r in rows):
        lines += table1(rows, scen)
    return "\n".join(lines)


def table1(rows: Sequence[dict], scenario: str) -> list[str]:
    """The paper's Table 1 for ``scenario``: its five metrics, ours (the paired rows) beside the paper's.

    The paired rows are on-demand collision and obstacle rows against BVC with
    every-step obstacle rows (without obstacles: the two methods). Empty when
    either method's row is missing.
    """
    def paired(method: str) -> dict | None:
        return next((r for r in rows if r["scenario"] == scenario and r["method"] == method and r["obstacles"] in (None, _PAIRED[method])), None)

    od, bvc = paired("on_demand"), paired("bvc")
    if od is None or bvc is None:
        return []
    head = f"{'metric':<30} {'on-demand':>9} {'paper':>8} {'BVC':>8} {'paper':>8} {'BVC/on-demand':>13} {'paper':>6}"
    out = ["", f"Table 1 on {scenario} (ours: mean over drones and seeds; paper: MATLAB, N = 4, square formation)", head, "-" * len(head)]
    for label, key, i, spec in _TABLE1:
        a, b = od[key], bvc[key]
        ratio = cell(b / a if a and b is not None else None, "13.2f")
        out.append(
            f"{label:<30} {cell(a, '9' + spec[1:])} {_PAPER['on_demand'][i]:>8.2f} {cell(b, spec)} {_PAPER['bvc'][i]:>8.2f} "
            f"{ratio} {_PAPER['bvc'][i] / _PAPER['on_demand'][i]:>6.2f}"
        )
    return out


def _label(method: str, obstacles: str | None) -> str:
    """A variant's short name: the method, plus ``/<obstacle mode>`` where there are obstacles."""
    return method if obstacles is None else f"{method}/{obstacles}"


def _plot(out_dir: pathlib.Path, results: dict, flights: dict[tuple[str, str], dict]) -> None:
    """Bars of QP time and mission time per (scenario, variant), and top views of the first seed's flights."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    from mpcde.flight.plots import box_corners_xy

    rows = results["rows"]
    scenarios = list(dict.fromkeys(r["scenario"] for r in rows))
    variants = list(dict.fromkeys((r["method"], r["obstacles"] or _PAIRED[r["method"]]) for r in rows))
    by = {(r["scenario"], r["method"], r["obstacles"] or _PAIRED[r["method"]]): r for r in rows}
    ncol = 2 + len(flights)
    fig = Figure(figsize=(4.2 * ncol, 4.2))
    FigureCanvasAgg(fig)
    ax_qp, ax_mission = fig.add_subplot(1, ncol, 1), fig.add_subplot(1, ncol, 2)
    width = 0.8 / max(len(variants), 1)
    x = np.arange(len(scenarios))
    for k, variant in enumerate(variants):
        name = _label(*variant)
        got = [by.get((s, *variant)) for s in scenarios]
        med = [(r["qp_ms_median"] or 0.0) if r else 0.0 for r in got]
        p95 = [(r["qp_ms_p95"] or 0.0) if r else 0.0 for r in got]
        mission = [(r["mission_time_s"] or 0.0) if r else 0.0 for r in got]
        bars = ax_qp.bar(x + k * width, med, width, label=f"{name} median")
        ax_qp.scatter(x + k * width, p95, marker="_", s=200, color=bars.patches[0].get_facecolor(), label=f"{name} p95")
        ax_mission.bar(x + k * width, mission, width, label=name)
    for ax, title, unit in ((ax_qp, "QP solve time", "[ms]"), (ax_mission, "mission time", "[s]")):
        ax.set_xticks(x + width * (len(variants) - 1) / 2, scenarios)
        ax.set(title=title, ylabel=unit)
        ax.legend(fontsize=7)
    ax_qp.set_yscale("log")
    for c, ((scen, name), flight) in enumerate(flights.items()):
        ax = fig.add_subplot(1, ncol, 3 + c)
        prepared = flight["prepared"]
        for ob in prepared.obstacles:
            if ob.kind == "tree":
                t = np.linspace(0, 2 * np.pi, 40)
                ax.fill(ob.center_xy[0] + ob.radius_m * np.cos(t), ob.center_xy[1] + ob.radius_m * np.sin(t), color="0.6")
            else:
                ax.fill(*box_corners_xy(ob).T, color="0.6")
        pos = flight["log"]["pos_world"]
        for i in range(pos.shape[1]):
            ax.plot(pos[:, i, 0], pos[:, i, 1], lw=1.0)
        ax.plot(*prepared.starts[:, :2].T, "ko", ms=3)
        ax.plot(*prepared.goals[:, :2].T, "kx", ms=5)
        ax.set(title=f"{scen}, {name}", xlabel="x [m]", ylabel="y [m]", aspect="equal")
    fig.tight_layout()
    fig.savefig(out_dir / "results.png", dpi=100)


def run_eval_dmpc(
    out_dir: pathlib.Path,
    methods: Sequence[str] = _METHODS,
    scenarios: Sequence[str] = ("formation_square", "antipodal"),
    seeds: Sequence[int] = (0,),
    progress: bool = True,
    duration_s: float | None = None,
    every_step_variant: bool = True,
) -> dict:
    """Fly every (scenario, variant, seed) with DMPC and write the Table 1 comparison.

    Args:
        out_dir: output folder (created; written all-or-nothing, see
            :func:`mpcde.flight.run_folder.staged_output`); gets ``results.json``
            (``{"rows": [{method, obstacles, scenario, flown, collisions,
            min_distance_m, min_obstacle_clearance_m, qp_ms_median, qp_ms_p95, qp_ms_mean,
            collision_rows_mean, iterations_mean, refactor_share,
            mission_time_s, path_length_m, mean_speed_mps, mean_accel_mps2}]}``;
            ``flown``: {collision_mode, obstacle_avoidance, terminal_halt,
            commit_when_unheard} as the agents' QPs had them),
            ``results.txt``, ``details.json`` and ``results.png``.
        methods: collision-avoidance methods, ``"on_demand"`` and/or ``"bvc"``,
            each flown with its paired obstacle mode (on_demand -> on_demand,
            bvc -> every_step), both under the replanning scheme.
        scenarios: scenario names or files (flown with ``planner.kind: dmpc``).
        seeds: one flight per seed and (scenario, variant).
        progress: show a tqdm progress bar over flights.
        duration_s: override every scenario's time limit [s] (short test runs).
        every_step_variant: also fly ``on_demand`` with every-step obstacle
            rows in scenarios that have obstacles (when ``on_demand`` is asked).

    Returns:
        The results dict written to ``results.json``.

    Raises:
        ValueError: unknown method, no scenario or no seed (before anything is written).
        mpcde.errors.ConfigError: a scenario that does not load or validate.
        RuntimeError: a row whose agents flew another QP than its label says
            (nothing is written).
    """
    methods, scenarios, seeds = tuple(methods), tuple(scenarios), tuple(int(s) for s in seeds)
    bad = [m for m in methods if m not in _METHODS]
    if not methods or bad:
        raise ValueError(f"methods={methods!r}: a non-empty selection of {', '.join(_METHODS)}")
    if not scenarios:
        raise ValueError("scenarios=(): at least one scenario")
    if not seeds:
        raise ValueError("seeds=(): at least one seed")
    if duration_s is not None and not duration_s > 0:
        raise ValueError(f"duration_s={duration_s!r}: > 0 [s]")
    has_obstacles = {}  # fail on a bad scenario before flying anything
    for scen in scenarios:
        prepared = prepare_run(load_scenario(scen, {"duration_s": duration_s} if duration_s is not None else None))
        has_obstacles[scen] = bool(prepared.obstacles)

    from tqdm import tqdm

    variants: dict[str, list[tuple[str, str | None]]] = {}  # per scenario: (method, obstacle mode or None)
    for scen in scenarios:
        variants[scen] = [(m, _PAIRED[m] if has_obstacles[scen] else None) for m in methods]
        if has_obstacles[scen] and every_step_variant and "on_demand" in methods:
            variants[scen].append(("on_demand", "every_step"))
    bar = tqdm(total=sum(map(len, variants.values())) * len(seeds), disable=not progress, desc="eval-dmpc")
    runs: dict[tuple[str, str, str | None], list[dict]] = {(s, *v): [] for s in scenarios for v in variants[s]}
    flights: dict[tuple[str, str], dict] = {}
    for scen in scenarios:
        for seed in seeds:
            for method, obstacles in variants[scen]:  # interleaved: all variants under the same machine load
                flight = _fly(scen, method, obstacles or _PAIRED[method], seed, duration_s)
                runs[(scen, method, obstacles)].append(flight)
                if seed == seeds[0]:
                    flights[(scen, _label(method, obstacles))] = flight
                bar.update(1)
    bar.close()
    results = {"rows": [_row(m, o, s, runs[(s, m, o)]) for s in scenarios for m, o in variants[s]]}
    details = [f["detail"] for key in runs for f in runs[key]]
    paper = "\n".join(
        f"  {m:<10} QP {p[0]:.2f} ms, mission {p[1]:.2f} s, path {p[2]:.1f} m, speed {p[3]:.2f} m/s, acc {p[4]:.2f} m/s^2"
        for m, p in _PAPER.items()
    )
    notes = "\n".join(
        f"  {d['scenario']:<17} {_label(d['method'], d['obstacles']):<20} seed {d['seed']}: "
        f"arrived {d['arrived']}/{d['n_drones']}, {d['solves']} solves, {d['fallbacks']} fallbacks, "
        f"{d['stale_plans']} stale plans, {d['obstacle_row_rounds']} rounds with obstacle rows, "
        f"{d['refactorisations']} refactorisations, {d['deadlock_turns']} deadlock turns, "
        f"mean {cell(d['mean_iterations'], '.0f')} OSQP iterations, build {cell(d['qp_build_ms_median'], '.3f')} ms (median)"
        + (f", formation error mean {d['formation_error_mean_m2']:.3f} m^2" if "formation_error_mean_m2" in d else "")
        for d in details
    )
    text = (
        format_table(results)
        + f"\n\nseeds {seeds}; full physics, cameras off; both methods replan every round without a halting "
        + "terminal constraint (the paper's DMPC); QP time = OSQP wall time per round (update + solve).\n"
        + "per flight:\n" + notes
        + "\n\non-demand DMPC paper, Table 1 (MATLAB, N = 4 square formation):\n" + paper + "\n"
    )
    with staged_output(pathlib.Path(out_dir)) as stage:  # all-or-nothing: moved into out_dir when complete
        (stage / "results.json").write_text(json.dumps(results, indent=2) + "\n")
        (stage / "details.json").write_text(json.dumps(details, indent=2) + "\n")
        (stage / "results.txt").write_text(text)
        _plot(stage, results, flights)
    return results
