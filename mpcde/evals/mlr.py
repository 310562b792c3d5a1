"""The DMPC-Swarm experiments (Sec. 5.3-5.4, Fig. 3b, 3c, 4) in the kinematic MLR-DMPC swarm: ``run_eval_mlr``.

Experiments (16 UAVs; :mod:`mpcde.evals.mlr_swarm` for the model and metrics):

* ``fig4_swap`` (Sec. 5.4, Fig. 4): the UAVs start on a circle of radius 2 m
  at 1.2 m height (each start jittered by up to 5 cm with the run's seed, so
  that seeds differ) and fly to the antipodal point; 3 CUs, deaf from 0 to
  2 s. MLR-DMPC against the DMPC that ignores message loss (Gräfe et al.
  2022). A third row flies MLR-DMPC with 25 % Bernoulli loss on every link.
* ``fig3b_cus`` (Sec. 5.3, Fig. 3b): plane -> pyramid -> cube -> sphere ->
  plane with 1, 2 and 3 CUs (hybrid trigger; the first plane jittered by up to
  5 cm with the seed); the time to reach each
  formation (every UAV within ``arrival_tolerance_m``), ideal radio. UAVs are
  assigned to the next formation's points by a minimum-total-distance
  assignment (scipy's Hungarian solver).
* ``fig3c_triggers`` (Sec. 5.3, Fig. 3c): the same with 3 CUs and the RR, DB
  and HT triggers (the HT row is the 3-CU row of ``fig3b_cus``, reused).

Measured against the paper's Fig. 3b, 3c and 4:
docs/results/mlr_dmpc.md#eval-mlr-fig-3b-3c-and-4-in-the-kinematic-swarm.

Writes ``out_dir/results.json`` (``{"rows": [...]}``, one row per
experiment, variant and seed) and ``out_dir/table.md``, and prints the table.
"""

from __future__ import annotations

import dataclasses
import json
import pathlib
import time
from typing import Any

import numpy as np
from scipy.optimize import linear_sum_assignment

from mpcde.evals.mlr_swarm import MlrSwarmConfig, run_mlr_swarm
from mpcde.evals.text_table import cell
from mpcde.flight.run_folder import staged_output
from planners.dmpc.collision import ellipsoidal_distance
from planners.dmpc.mlr.config import MlrConfig
from sim.radio import RadioConfig

__all__ = ["FORMATIONS", "circle_swap", "formation_points", "format_table", "run_eval_mlr"]

FORMATIONS = ("plane", "pyramid", "cube", "sphere", "plane")


def circle_swap(n: int = 16, radius_m: float = 2.0, height_m: float = 1.2, jitter_m: float = 0.0,
                seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """(start (n, 3), targets (n, 3)) [m]: a circle and its antipodal points; starts jittered by <= ``jitter_m``."""
    ang = 2 * np.pi * np.arange(n) / n
    start = np.c_[radius_m * np.cos(ang), radius_m * np.sin(ang), np.full(n, height_m)]
    rng = np.random.default_rng([seed, 0x5A9])
    start[:, :2] += rng.uniform(-jitter_m, jitter_m, (n, 2)) / np.sqrt(2.0)
    return start, np.c_[-start[:, :2], start[:, 2]]


def formation_points(name: str) -> np.ndarray:
    """The 16 points (16, 3) [m] of a formation of Fig. 3a (our sizes for a 6 m x 6 m x 2.8 m hall).

    plane: 4 x 4 grid, 0.9 m spacing, z = 1 m; pyramid: 8 on a 2.4 m square
    ring at 0.6 m, 4 on a 1 m square at 1.3 m, 3 on a 0.5 m circle at 2.0 m,
    apex at 2.6 m; cube: two 8-point square rings (1.8 m side) at 0.7 and
    2.1 m; sphere: a 16-point Fibonacci sphere of radius 1.2 m centred at 1.45 m.
    """
    if name == "plane":
        g = 0.9 * (np.arange(4) - 1.5)
        x, y = np.meshgrid(g, g)
        return np.c_[x.ravel(), y.ravel(), np.full(16, 1.0)]
    ring = np.array([[a, b] for a in (-1, 0, 1) for b in (-1, 0, 1) if (a, b) != (0, 0)], float)
    if name == "pyramid":
        sq = 0.5 * np.array([[-1, -1], [-1, 1], [1, -1], [1, 1]], float)
        tri = 0.5 * np.c_[np.cos(2 * np.pi * np.arange(3) / 3), np.sin(2 * np.pi * np.arange(3) / 3)]
        return np.vstack([np.c_[1.2 * ring, np.full(8, 0.6)], np.c_[sq, np.full(4, 1.3)],
                          np.c_[tri, np.full(3, 2.0)], [[0.0, 0.0, 2.6]]])
    if name == "cube":
        return np.vstack([np.c_[0.9 * ring, np.full(8, 0.7)], np.c_[0.9 * ring, np.full(8, 2.1)]])
    if name == "sphere":
        i = np.arange(16) + 0.5
        phi, theta = np.arccos(1 - 2 * i / 16), np.pi * (1 + 5**0.5) * i
        return np.c_[1.2 * np.sin(phi) * np.cos(theta), 1.2 * np.sin(phi) * np.sin(theta), 1.45 + 1.2 * np.cos(phi)]
    raise ValueError(f"name={name!r}: one of plane, pyramid, cube, sphere")


def _sequence(names: tuple[str, ...], jitter_m: float = 0.0, seed: int = 0) -> tuple[np.ndarray, list[np.ndarray]]:
    """Start (the first formation, horizontally jittered by <= ``jitter_m``) and the assigned targets of the rest."""
    rng = np.random.default_rng([seed, 0xF0])
    start = formation_points(names[0])
    start[:, :2] += rng.uniform(-jitter_m, jitter_m, (start.shape[0], 2)) / np.sqrt(2.0)
    current = start
    targets = []
    for name in names[1:]:
        pts = formation_points(name)
        cost = np.linalg.norm(current[:, None] - pts[None], axis=2) ** 2
        _, col = linear_sum_assignment(cost)
        current = pts[col]
        targets.append(current)
    return start, targets


def _min_pairwise(points: np.ndarray, downwash: float) -> float:
    iu = np.triu_indices(points.shape[0], 1)
    return float(ellipsoidal_distance(points[iu[0]] - points[iu[1]], downwash).min())


def _row(experiment: str, variant: str, seed: int, cfg: MlrSwarmConfig, result, wall_s: float) -> dict[str, Any]:
    row = {"experiment": experiment, "variant": variant, "seed": seed, "n_cus": cfg.mlr.n_cus,
           "trigger": cfg.mlr.trigger, "wall_s": round(wall_s, 2)}
    row.update(result.metrics())
    return row


def run_eval_mlr(
    out_dir: pathlib.Path,
    seeds: int = 1,
    experiments: tuple[str, ...] = ("fig4_swap", "fig3b_cus", "fig3c_triggers"),
    formation_duration_s: float = 150.0,
    swap_duration_s: float = 40.0,
) -> dict:
    """Run the experiments, write ``results.json`` and ``table.md`` under ``out_dir``, print the table.

    Args:
        out_dir: output folder (created; written all-or-nothing,
            :func:`mpcde.flight.run_folder.staged_output`).
        seeds: seeds 0..seeds-1 per experiment and variant.
        experiments: a subset of ``fig4_swap``, ``fig3b_cus``, ``fig3c_triggers``.
        formation_duration_s: longest simulated time of a formation sequence [s].
        swap_duration_s: longest simulated time of a swap [s].

    Returns:
        ``{"rows": [...]}`` as written to results.json.
    """
    known = ("fig4_swap", "fig3b_cus", "fig3c_triggers")
    for e in experiments:
        if e not in known:
            raise ValueError(f"experiments={experiments!r}: each one of {', '.join(known)}")
    if isinstance(seeds, bool) or not isinstance(seeds, int) or seeds < 1:
        raise ValueError(f"seeds={seeds!r}: an integer >= 1")
    rows: list[dict[str, Any]] = []
    cache: dict[tuple, dict[str, Any]] = {}

    def fly(experiment, variant, seed, cfg, start, goals):
        key = (dataclasses.astuple(cfg.mlr), cfg.ignore_message_loss, cfg.radio, cfg.cu_deaf_windows_s, seed,
               start.tobytes(), tuple(g.tobytes() for g in goals))
        if key not in cache:
            t0 = time.perf_counter()
            res = run_mlr_swarm(cfg, start, goals)
            cache[key] = _row(experiment, variant, seed, cfg, res, time.perf_counter() - t0)
        rows.append({**cache[key], "experiment": experiment, "variant": variant})

    for seed in range(seeds):
        if "fig4_swap" in experiments:
            start, goal = circle_swap(jitter_m=0.05, seed=seed)
            base = MlrSwarmConfig(mlr=MlrConfig(n_uavs=16, n_cus=3), seed=seed, duration_s=swap_duration_s,
                                  cu_deaf_windows_s=((0.0, 2.0),))
            fly("fig4_swap", "mlr_dmpc", seed, base, start, [goal])
            fly("fig4_swap", "ignore_loss", seed, dataclasses.replace(base, ignore_message_loss=True), start, [goal])
            lossy = dataclasses.replace(base, cu_deaf_windows_s=(),
                                        radio=RadioConfig(loss_model="bernoulli", loss_probability=0.25))
            fly("fig4_swap", "mlr_dmpc_bernoulli_0.25", seed, lossy, start, [goal])
        start, goals = _sequence(FORMATIONS, jitter_m=0.05, seed=seed)
        if "fig3b_cus" in experiments:
            for m in (1, 2, 3):
                cfg = MlrSwarmConfig(mlr=MlrConfig(n_uavs=16, n_cus=m, trigger="ht"), seed=seed,
                                     duration_s=formation_duration_s)
                fly("fig3b_cus", f"{m}_cu", seed, cfg, start, goals)
        if "fig3c_triggers" in experiments:
            for trig in ("rr", "db", "ht"):
                cfg = MlrSwarmConfig(mlr=MlrConfig(n_uavs=16, n_cus=3, trigger=trig), seed=seed,
                                     duration_s=formation_duration_s)
                fly("fig3c_triggers", trig, seed, cfg, start, goals)
    results = {"rows": rows, "formations": list(FORMATIONS)}
    table = format_table(results)
    with staged_output(pathlib.Path(out_dir)) as stage:  # all-or-nothing: moved into out_dir when complete
        (stage / "results.json").write_text(json.dumps(results, indent=1, default=float))
        (stage / "table.md").write_text(table + "\n")
    print(table)
    return results


def format_table(results: dict) -> str:
    """Markdown tables: the swap (collisions, distances, arrival, MLR) and the formation times."""
    rows = results["rows"]
    lines = [] if not any(r["experiment"] == "fig4_swap" for r in rows) else [
             "### Fig. 4: 16-UAV circle swap, 3 CUs", "",
             "| variant | seed | collisions | min dist [m] | arrival [s] | MLR rounds | deprecated | requests "
             "| max ref jump [m] | QP median [ms] |", "|---|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        if r["experiment"] == "fig4_swap":
            lines.append(
                f"| {r['variant']} | {r['seed']} | {r['collisions']} | {cell(r['min_distance_m'], '.3f')} "
                f"| {cell(r['arrival_time_s'], '.1f')} | {r['rounds_with_mlr']} | {r['deprecated_trackers']} "
                f"| {r['recovery_requests']} | {cell(r['max_reference_jump_m'], '.3f')} "
                f"| {cell(r['qp_step_ms_median'], '.2f')} |"
            )
    names = results.get("formations", FORMATIONS)
    head = " | ".join(f"-> {n} [s]" for n in names[1:])
    for exp, title in (("fig3b_cus", "Fig. 3b: formation changes vs number of CUs (HT trigger)"),
                       ("fig3c_triggers", "Fig. 3c: formation changes vs event trigger (3 CUs)")):
        sel = [r for r in rows if r["experiment"] == exp]
        if not sel:
            continue
        lines += ([""] if lines else []) + [
                  f"### {title}", "", f"| variant | seed | {head} | total [s] | collisions | min dist [m] |",
                  "|---|---|" + "---|" * (len(names) - 1) + "---|---|---|"]
        for r in sel:
            times = " | ".join(cell(t, ".1f") for t in r["formation_times_s"])
            lines.append(f"| {r['variant']} | {r['seed']} | {times} | {cell(r['arrival_time_s'], '.1f')} "
                         f"| {r['collisions']} | {cell(r['min_distance_m'], '.3f')} |")
    return "\n".join(lines)
