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


def main() -> None:
    store = Path(sys.argv[1])
    spec = json.loads((store / "sweep.json").read_text())["sweep"]
    densities = dict(spec["axes"])["world.obstacle_density_per_100m2"]
    cells = defaultdict(list)
    for line in (store / "results.jsonl").read_text().splitlines():
        r = json.loads(line)
        if not r.get("metrics"):
            continue
        cells[r["cell"]].append(r)
    yaw_values = dict(spec["axes"])["denied.yaw"]
    print(f"{'density /100m^2':>15}  {'method':<20} {'flights':>7}  {'S_obs m^2 mean +- sd':>21}  {'success':>7}  {'95% CI':>9}  {'paper S_obs':>11}")
    summary = {}
    for di, density in enumerate(densities):
        for mi, yaw in enumerate(yaw_values):
            index = di * len(yaw_values) + mi
            rows = cells.get(index, [])
            areas = [r["metrics"]["observed_area_swarm_m2"] for r in rows]
            ok = sum(bool(r["metrics"]["success"]) for r in rows)
            n = len(rows)
            mean = sum(areas) / n if n else float("nan")
            sd = math.sqrt(sum((a - mean) ** 2 for a in areas) / (n - 1)) if n > 1 else float("nan")
            lo, hi = wilson_interval(ok, n) if n else (float("nan"), float("nan"))
            m = method_of(yaw)
            paper = {"zhou": PAPER[di][0], "no_exploring": PAPER[di][1], "ours": PAPER[di][2]}.get(m)
            summary[(di, m)] = mean
            print(f"{density:>15g}  {METHODS[m]:<20} {n:>7d}  {mean:>12.1f} +- {sd:>5.1f}  {100 * ok / max(n, 1):>6.0f}%  {100 * lo:>3.0f}-{100 * hi:<3.0f}%  {'' if paper is None else f'{paper:.1f}':>11}")
    print("\nours against Zhou's, S_obs: measured (paper)")
    for di, density in enumerate(densities):
        ours, zhou = summary.get((di, "ours")), summary.get((di, "zhou"))
        if ours and zhou:
            paper = PAPER[di][2] / PAPER[di][0] - 1
            print(f"  density {density:g}: {100 * (ours / zhou - 1):+.1f} % ({100 * paper:+.0f} %)")


if __name__ == "__main__":
    main()
