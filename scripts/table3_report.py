"""MP-CDE's Table III from a store of data/sweeps/table3_active_perception.yaml: S_obs (mean +- sd) and success per
density and method, ours against Zhou's, beside the paper's figures.

Usage: .venv/bin/python scripts/table3_report.py STORE_DIR   (the store `mpcde sweep ... --out STORE_DIR` wrote)
"""

from __future__ import annotations

import json
import math
import sys
from collections import defaultdict
from pathlib import Path

from mpcde.sweep.stats import wilson_interval

PAPER = {  # Table III, S_obs [m^2]: Zhou's, ours w/o exploring, ours; success is not printed in the paper's table
    0: (142.7, 137.1, 167.5),
    1: (132.4, 122.4, 145.9),
    2: (105.7, 94.6, 123.5),
}
METHODS = {"zhou": "Zhou's [26]", "no_exploring": "ours w/o exploring", "no_tracking": "ours w/o tracking", "ours": "ours"}


def method_of(yaw: dict) -> str:
    if yaw.get("method") == "zhou":
        return "zhou"
    if yaw.get("exploring_mode") is False:
        return "no_exploring"
    if yaw.get("tracking_mode") is False:
        return "no_tracking"
    return "ours"


def cells(store: Path) -> list[dict]:
    """One dict per (density, method) cell of the store: density, method, flights, S_obs mean and sd [m^2], successes,
    the Wilson 95 % interval and the paper's S_obs (None where the paper gives none)."""
    spec = json.loads((store / "sweep.json").read_text())["sweep"]
    densities = dict(spec["axes"])["world.obstacle_density_per_100m2"]
    by_cell = defaultdict(list)
    for line in (store / "results.jsonl").read_text().splitlines():
        r = json.loads(line)
        if r.get("metrics"):
            by_cell[r["cell"]].append(r)
    yaw_values = dict(spec["axes"])["denied.yaw"]
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
            paper = {"zhou": PAPER[di][0], "no_exploring": PAPER[di][1], "ours": PAPER[di][2]}.get(m)
            out.append({"density_index": di, "density": density, "method": m, "flights": n, "s_obs_mean_m2": mean, "s_obs_sd_m2": sd,
                        "successes": ok, "success_low": lo, "success_high": hi, "paper_s_obs_m2": paper})  # fmt: skip
    return out


def main() -> None:
    table = cells(Path(sys.argv[1]))
    print(f"{'density /100m^2':>15}  {'method':<20} {'flights':>7}  {'S_obs m^2 mean +- sd':>21}  {'success':>7}  {'95% CI':>9}  {'paper S_obs':>11}")
    for c in table:
        n, paper = c["flights"], c["paper_s_obs_m2"]
        print(f"{c['density']:>15g}  {METHODS[c['method']]:<20} {n:>7d}  {c['s_obs_mean_m2']:>12.1f} +- {c['s_obs_sd_m2']:>5.1f}  "
              f"{100 * c['successes'] / max(n, 1):>6.0f}%  {100 * c['success_low']:>3.0f}-{100 * c['success_high']:<3.0f}%  "
              f"{'' if paper is None else f'{paper:.1f}':>11}")  # fmt: skip
    print("\nours against Zhou's, S_obs: measured (paper)")
    for di, density, ours, zhou in margins(table):
        paper = PAPER[di][2] / PAPER[di][0] - 1
        print(f"  density {density:g}: {100 * (ours / zhou - 1):+.1f} % ({100 * paper:+.0f} %)")


def margins(table: list[dict]) -> list[tuple[int, float, float, float]]:
    """(density index, density, ours' mean S_obs, Zhou's) for every density where both were flown."""
    mean = {(c["density_index"], c["method"]): c["s_obs_mean_m2"] for c in table if c["flights"]}
    out = []
    for c in table:
        di = c["density_index"]
        if c["method"] == "ours" and (di, "ours") in mean and (di, "zhou") in mean:
            out.append((di, c["density"], mean[(di, "ours")], mean[(di, "zhou")]))
    return out

if __name__ == "__main__":
    main()
