"""MLR-DMPC under message loss, from a sweep file: ``mpcde eval-mlr --sweep FILE`` (:func:`run_loss_sweep`).

A loss sweep flies the circle swap of the kinematic swarm
(:mod:`mpcde.evals.mlr_swarm`; :func:`mpcde.evals.mlr.circle_swap`) for every
swarm size, radio condition, variant and seed the file names, and answers
whether the swarm stays safe *and* keeps moving (DMPC-Swarm's point, Sec. 4):
per cell, the runs that arrive within the duration and their mean arrival
time, the runs with a collision, the closest ellipsoidal distance, and where
the rounds went (rounds with a CU in recovery, CU rounds that computed).

The file (``data/sweeps/mlr/*.yaml``)::

    swarm: {uavs: [12, 16], compute_units: 3, duration_s: 35.0, radius_m: 2.0, height_m: 1.2, jitter_m: 0.05}
    seeds: {first: 0, count: 20}
    conditions: {NAME: <a sim.radio.RadioConfig mapping>, ...}
    variants: {NAME: {compute_units: M, ignore_message_loss: bool, mlr: <MlrConfig fields>}, ...}

A variant's ``mlr`` mapping sets :class:`planners.dmpc.mlr.config.MlrConfig`
fields over the defaults (not ``n_uavs`` or ``n_cus``: the swarm's). Writes
``results.json`` (one row per run), ``table.md`` and ``arrivals.png``
(arrivals against loss) under ``out_dir``, all or nothing.
"""

from __future__ import annotations

import dataclasses
import json
import pathlib
import time
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass
from typing import Any

import numpy as np

from mpcde.config.io import from_dict, load_yaml
from mpcde.errors import ConfigError
from mpcde.evals.mlr import circle_swap
from mpcde.evals.mlr_swarm import MlrSwarmConfig, run_mlr_swarm
from mpcde.evals.text_table import cell
from mpcde.flight.run_folder import staged_output
from planners.dmpc.mlr.config import MlrConfig
from sim.checks import require_at_least, require_integer_at_least
from sim.radio import RadioConfig

__all__ = ["LossSweep", "Variant", "format_loss_table", "load_loss_sweep", "run_loss_sweep"]


@dataclass(frozen=True)
class Variant:
    """One way to fly the swarm: its compute units, the baseline flag and its MlrConfig fields."""

    compute_units: int
    ignore_message_loss: bool
    mlr: tuple[tuple[str, Any], ...]


@dataclass(frozen=True)
class LossSweep:
    """A loss sweep file, checked (module docstring)."""

    uavs: tuple[int, ...]
    duration_s: float
    radius_m: float
    height_m: float
    jitter_m: float
    seeds: tuple[int, ...]
    conditions: tuple[tuple[str, RadioConfig], ...]
    variants: tuple[tuple[str, Variant], ...]

    def runs(self) -> list[tuple[int, str, str, int]]:
        """(UAVs, condition, variant, seed) of every run, in the order the table lists them."""
        return [(n, c, v, s) for n in self.uavs for c, _ in self.conditions for v, _ in self.variants for s in self.seeds]


def _mapping(data: Any, path: str, keys: set[str]) -> dict:
    if not isinstance(data, dict):
        raise ConfigError(path, data, "a mapping")
    for key in data:
        if key not in keys:
            raise ConfigError(f"{path}.{key}", data[key], f"unknown key; allowed keys: {', '.join(sorted(keys))}")
    return data


def _integer(value: Any, path: str, low: int) -> int:
    require_integer_at_least(path, value, low)
    return int(value)


def _number(value: Any, path: str, low: float, strict: bool = False) -> float:
    require_at_least(path, value, low, strict)
    return float(value)


def _names(data: Any, path: str) -> dict:
    if not isinstance(data, dict) or not data:
        raise ConfigError(path, data, "a non-empty mapping of names")
    for name in data:
        if not isinstance(name, str) or not name.replace("_", "").isalnum():
            raise ConfigError(f"{path}.{name}", name, "a name of letters, digits and _")
    return data


def load_loss_sweep(path: pathlib.Path) -> LossSweep:
    """Read and check a loss sweep file.

    Raises:
        ConfigError: one line naming the field path, the value and what is allowed.
    """
    data = _mapping(load_yaml(pathlib.Path(path)), "sweep", {"swarm", "seeds", "conditions", "variants"})
    for key in ("swarm", "seeds", "conditions", "variants"):
        if key not in data:
            raise ConfigError(key, None, "required")
    swarm = _mapping(data["swarm"], "swarm", {"uavs", "compute_units", "duration_s", "radius_m", "height_m", "jitter_m"})
    uavs = swarm.get("uavs", [16])
    if not isinstance(uavs, list) or not uavs:
        raise ConfigError("swarm.uavs", uavs, "a non-empty list of swarm sizes")
    sizes = tuple(_integer(n, f"swarm.uavs[{i}]", 2) for i, n in enumerate(uavs))
    m = _integer(swarm.get("compute_units", 3), "swarm.compute_units", 1)
    seeds = _mapping(data["seeds"], "seeds", {"first", "count"})
    first = _integer(seeds.get("first", 0), "seeds.first", 0)
    count = _integer(seeds.get("count", 1), "seeds.count", 1)
    conditions = tuple(
        (name, from_dict(RadioConfig, radio, f"conditions.{name}")) for name, radio in _names(data["conditions"], "conditions").items()
    )  # fmt: skip
    variants = []
    for name, v in _names(data["variants"], "variants").items():
        v = _mapping(v or {}, f"variants.{name}", {"compute_units", "ignore_message_loss", "mlr"})
        cus = _integer(v.get("compute_units", m), f"variants.{name}.compute_units", 1)
        ignore = v.get("ignore_message_loss", False)
        if not isinstance(ignore, bool):
            raise ConfigError(f"variants.{name}.ignore_message_loss", ignore, "true or false")
        mlr = _mapping(v.get("mlr") or {}, f"variants.{name}.mlr", {f.name for f in dataclasses.fields(MlrConfig)} - {"n_uavs", "n_cus"})
        for n in sizes:  # every field checked by MlrConfig itself, at every size
            if cus >= n:
                raise ConfigError(f"variants.{name}.compute_units", cus, f"an integer < swarm.uavs = {n} (M < N)")
            from_dict(MlrConfig, {**mlr, "n_uavs": n, "n_cus": cus}, f"variants.{name}.mlr")
        variants.append((name, Variant(cus, ignore, tuple(sorted(mlr.items())))))
    return LossSweep(
        sizes, _number(swarm.get("duration_s", 35.0), "swarm.duration_s", 0.0, strict=True),
        _number(swarm.get("radius_m", 2.0), "swarm.radius_m", 0.0, strict=True), _number(swarm.get("height_m", 1.2), "swarm.height_m", 0.0),
        _number(swarm.get("jitter_m", 0.05), "swarm.jitter_m", 0.0), tuple(range(first, first + count)), conditions, tuple(variants),
    )  # fmt: skip


def _fly(task: tuple[LossSweep, int, str, str, int]) -> dict[str, Any]:
    sweep, n, condition, variant, seed = task
    radio, v = dict(sweep.conditions)[condition], dict(sweep.variants)[variant]
    mlr = from_dict(MlrConfig, {**dict(v.mlr), "n_uavs": n, "n_cus": v.compute_units})
    cfg = MlrSwarmConfig(mlr=mlr, radio=radio, seed=seed, duration_s=sweep.duration_s, ignore_message_loss=v.ignore_message_loss)
    start, goal = circle_swap(n, sweep.radius_m, sweep.height_m, sweep.jitter_m, seed)
    t0 = time.perf_counter()
    metrics = run_mlr_swarm(cfg, start, [goal]).metrics()
    return {"uavs": n, "condition": condition, "variant": variant, "seed": seed, "wall_s": round(time.perf_counter() - t0, 2), **metrics}


def run_loss_sweep(sweep: LossSweep, out_dir: pathlib.Path, jobs: int = 1) -> list[dict[str, Any]]:
    """Fly every run of ``sweep`` on ``jobs`` processes; write results.json, table.md and arrivals.png; print the table."""
    tasks = [(sweep, *run) for run in sweep.runs()]
    if jobs > 1:
        with ProcessPoolExecutor(jobs) as pool:
            rows = list(pool.map(_fly, tasks))
    else:
        rows = [_fly(t) for t in tasks]
    table = format_loss_table(rows)
    with staged_output(pathlib.Path(out_dir)) as stage:  # all-or-nothing: moved into out_dir when complete
        (stage / "results.json").write_text(json.dumps({"rows": rows}, indent=1, default=float))
        (stage / "table.md").write_text(table + "\n")
        _plot_arrivals(rows, sweep, stage / "arrivals.png")
    print(table)
    return rows


def _cells(rows: list[dict[str, Any]]) -> dict[tuple[int, str, str], list[dict[str, Any]]]:
    cells: dict[tuple[int, str, str], list[dict[str, Any]]] = {}
    for r in rows:
        cells.setdefault((r["uavs"], r["condition"], r["variant"]), []).append(r)
    return cells


def format_loss_table(rows: list[dict[str, Any]]) -> str:
    """One markdown row per (UAVs, condition, variant): arrivals, mean arrival, collisions, closest, rounds."""
    lines = [
        "| UAVs | radio | variant | runs | arrived | mean arrival [s] | runs with a collision | min dist [m] "
        "| rounds in recovery | CU rounds computing | requests answered |",
        "|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for (n, condition, variant), cell_rows in _cells(rows).items():
        arrived = [r["arrival_time_s"] for r in cell_rows if np.isfinite(r["arrival_time_s"])]
        recovery = np.mean([r["rounds_with_mlr"] / r["rounds"] for r in cell_rows])
        computing = np.mean([r["cu_modes"]["compute"] / max(r["cu_rounds"], 1) for r in cell_rows])
        asked = sum(r["recovery_requests"] for r in cell_rows)
        answered = f"{sum(r['recovery_answered'] for r in cell_rows) / asked:.0%}" if asked else "-"
        lines.append(
            f"| {n} | {condition} | {variant} | {len(cell_rows)} | {len(arrived)} | {cell(np.mean(arrived) if arrived else float('nan'), '.1f')} "
            f"| {sum(r['collisions'] > 0 for r in cell_rows)} | {min(r['min_distance_m'] for r in cell_rows):.3f} "
            f"| {recovery:.0%} | {computing:.0%} | {answered} |"
        )
    return "\n".join(lines)


def _stationary_loss(radio: RadioConfig) -> float:
    if radio.loss_model == "bernoulli":
        return radio.loss_probability
    if radio.loss_model == "gilbert_elliott":
        bad = radio.ge_p_good_to_bad / (radio.ge_p_good_to_bad + radio.ge_p_bad_to_good)
        return bad * radio.ge_loss_bad + (1 - bad) * radio.ge_loss_good
    return 0.0


def _plot_arrivals(rows: list[dict[str, Any]], sweep: LossSweep, path: pathlib.Path) -> None:
    """Arrivals (fraction of runs) against the stationary loss rate, one line per (UAVs, variant); bursts as markers."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    loss = {name: _stationary_loss(radio) for name, radio in sweep.conditions}
    bursty = {name for name, radio in sweep.conditions if radio.loss_model == "gilbert_elliott"}
    fig, ax = plt.subplots(figsize=(6.4, 4.0))
    cells = _cells(rows)
    for n in sweep.uavs:
        for variant, _ in sweep.variants:
            frac = {c: np.mean([np.isfinite(r["arrival_time_s"]) for r in cells[(n, c, variant)]]) for c, _ in sweep.conditions}
            plain = sorted((loss[c], f) for c, f in frac.items() if c not in bursty)
            (line,) = ax.plot([x for x, _ in plain], [f for _, f in plain], "o-", label=f"{variant}, {n} UAVs")
            for c in sorted(bursty, key=lambda c: dict(sweep.conditions)[c].ge_p_bad_to_good, reverse=True):
                burst = 1.0 / dict(sweep.conditions)[c].ge_p_bad_to_good
                ax.plot(loss[c], frac[c], "s", color=line.get_color(), markersize=4 + burst)
    ax.set_xlabel("stationary message loss (squares: Gilbert-Elliott bursts, size ~ mean burst)")
    ax.set_ylabel("runs that arrive")
    ax.set_ylim(-0.05, 1.05)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)
