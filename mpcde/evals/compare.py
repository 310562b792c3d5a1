"""``mpcde compare``: one scenario flown by each onboard stack, paired by seed.

What is compared: the stacks of :func:`mpcde.stacks.stacks` (``comm``, DMPC on
plans exchanged over the radio; ``denied``, MP-CDE on the drone's own
perception; ``auto``, DMPC falling back to the drone's tracks and to MP-CDE
when the radio fails; ``placeholder``, a blind straight line), each flying the same scenario with only ``planner.kind`` changed. The
comparison is paired: for a given seed every mode gets the same obstacles,
starts and goals, the same sensor and pose noise and the same radio faults
(the scenario's ``radio`` settings, seeded by the run's seed), so a difference
between two rows of one seed comes from the stack, not from the draw.

Rows, one per (mode, seed), keys :data:`ROW_KEYS` (null where a value is not
defined, never a made-up number; values from the run's ``metrics.json``,
:mod:`mpcde.flight.metrics`):

* ``mode``: the ``--modes`` name; ``planner_kind``: its ``planner.kind``; ``seed``;
* ``success``: every drone reached its goal before the time limit and nothing collided;
* ``arrived``: drones that reached their goal; ``n_drones``: drones flown;
* ``collisions``: drone-drone events (centre distance below 2 r_robot, once
  per entry) plus drone-obstacle/ground contact events;
* ``min_distance_m``: minimum inter-drone centre distance over the flight [m]
  (null with one drone);
* ``min_obstacle_clearance_m``: minimum distance from a drone centre to an
  obstacle surface minus r_robot [m] (null without obstacles);
* ``mission_time_s``: time the last drone arrived [s] (null if some did not);
* ``path_length_m``: travelled path length [m], mean over drones;
* ``mean_speed_mps``: speed [m/s], mean over time and drones;
* ``tracking_pos_rmse_m`` / ``tracking_vel_rmse_mps``: RMS error [m], [m/s] of
  the onboard neighbour-track predictions against the truth (null when no
  agent perceives its neighbours, e.g. ``placeholder``, or no track matched);
* ``radio_delivered_fraction``: delivered / (delivered + lost) radio messages,
  counted per receiver (null if nothing was delivered or lost);
* ``real_time_factor``: simulated time / wall time of the loop (includes
  camera rendering when the scenario renders cameras).

With more than one seed, ``summary`` pools the seeds per mode (keys
:data:`SUMMARY_KEYS`): ``runs`` (seeds flown), ``success_rate`` (fraction of
seeds with success), ``collisions`` (total), ``min_distance_m`` (minimum over
seeds [m]), ``mission_time_s`` (mean over the seeds where it is defined [s]) and
``mission_time_runs`` (how many such seeds), ``path_length_m`` (mean over seeds [m]).

Outputs in ``out_dir`` (staged in a hidden sibling folder and renamed into
place only when every flight succeeded, so an interrupted compare leaves no
half-written ``out_dir``):

* ``results.json``: ``{"scenario", "modes", "seeds", "rows", "summary"}``
  (``summary`` is ``[]`` with one seed);
* ``results.txt``: the table of :func:`format_table` and each mode's run folders;
* ``results.png``: minimum inter-drone distance over time per mode (first
  seed) with the collision distance 2 r_robot dashed, beside a top view per
  mode (tracks, starts o, goals x, obstacles);
* ``runs/<mode>-seed<seed>/``: each flight's run folder (:class:`mpcde.flight.run_folder.RunFolder`);
* ``results.jsonl`` and ``sweep.json``: the rows as ``mpcde sweep`` keeps them
  (:mod:`mpcde.sweep.store`), so ``mpcde report OUT`` gives a comparison the
  sweep report (Wilson intervals, McNemar's test between modes).

A comparison is a preset of the sweep machinery (:func:`compare_sweep`: the
scenario with one axis, ``planner.kind``); only its table, plot and
all-or-nothing publishing are its own.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any, Sequence

import numpy as np

from mpcde.stacks import get_stack, stacks
from mpcde.config.scenario import SCENARIO_DIR, load_scenario
from mpcde.config.yaml_reader import read_yaml
from mpcde.errors import ConfigError, MpcdeError
from mpcde.evals.text_table import cell
from mpcde.flight.loop import RunResult, prepare_run
from mpcde.sweep.engine import FlightOutcome, FlightTask, git_revision, package_version, run_flights, share_cores
from mpcde.sweep.spec import SweepSpec
from mpcde.sweep.store import ResultsStore, flight_row

__all__ = [
    "DEFAULT_MODES", "ROW_KEYS", "SUMMARY_KEYS", "check_modes", "compare_sweep", "default_modes", "format_table",
    "row_from_metrics", "run_compare", "summarize",
]  # fmt: skip

DEFAULT_MODES = ("comm", "denied", "auto")
ROW_KEYS = (
    "mode", "planner_kind", "seed", "success", "arrived", "n_drones", "collisions", "min_distance_m",
    "min_obstacle_clearance_m", "mission_time_s", "path_length_m", "mean_speed_mps", "tracking_pos_rmse_m",
    "tracking_vel_rmse_mps", "radio_delivered_fraction", "real_time_factor",
)  # fmt: skip
SUMMARY_KEYS = (
    "mode", "planner_kind", "runs", "success_rate", "collisions", "min_distance_m", "mission_time_s",
    "mission_time_runs", "path_length_m",
)  # fmt: skip


def default_modes() -> tuple[str, ...]:
    """:data:`DEFAULT_MODES`: the communicating, the denied and the switching stack."""
    return DEFAULT_MODES


def _kind(mode: str) -> str:
    """The ``planner.kind`` of the registered stack ``mode``."""
    return get_stack(mode, "--modes").kind


def check_modes(modes: Sequence[str]) -> tuple[str, ...]:
    """``modes`` as a tuple; raises ConfigError("--modes", ...) if empty, unknown or repeated."""
    modes = tuple(modes)
    names = [s.name for s in stacks()]
    allowed = f"allowed: {', '.join(names)}"
    if not modes:
        raise ConfigError("--modes", [], f"at least one mode; {allowed}")
    for m in modes:
        if m not in names:
            raise ConfigError("--modes", m, allowed)
    if len(set(modes)) != len(modes):
        raise ConfigError("--modes", list(modes), f"each mode at most once; {allowed}")
    return modes


def _check_seeds(seeds: Sequence[int]) -> tuple[int, ...]:
    """``seeds`` as a tuple of distinct non-negative ints; ConfigError otherwise."""
    seeds = tuple(seeds)
    if not seeds:
        raise ConfigError("seeds", [], "at least one seed")
    for s in seeds:
        if isinstance(s, bool) or not isinstance(s, (int, np.integer)) or not 0 <= s < 2**32:
            raise ConfigError("seeds", s, "integers in [0, 2^32)")
    if len(set(seeds)) != len(seeds):
        raise ConfigError("seeds", list(seeds), "each seed at most once")
    return tuple(int(s) for s in seeds)


def _radio_delivered_fraction(radio: dict[str, Any] | None) -> float | None:
    """delivered / (delivered + lost) of the metrics' ``radio`` counts; None if nothing was delivered or lost."""
    if not radio:
        return None
    delivered = int(radio.get("delivered", 0))
    lost = radio.get("lost", {})
    lost = int(sum(lost.values())) if isinstance(lost, dict) else int(lost)
    return delivered / (delivered + lost) if delivered + lost > 0 else None


def row_from_metrics(mode: str, seed: int, metrics: dict[str, Any]) -> dict[str, Any]:
    """One results row (keys :data:`ROW_KEYS`) from a run's metrics dict (:mod:`mpcde.flight.metrics`)."""
    m = metrics
    return {
        "mode": mode,
        "planner_kind": _kind(mode),
        "seed": int(seed),
        "success": bool(m["success"]),
        "arrived": int(m["arrived"]),
        "n_drones": int(m["n_drones"]),
        "collisions": int(m["collisions"]),
        "min_distance_m": m.get("min_inter_drone_distance_m"),
        "min_obstacle_clearance_m": m.get("min_obstacle_distance_m"),
        "mission_time_s": m.get("mission_time_s"),
        "path_length_m": m.get("path_length_m"),
        "mean_speed_mps": m.get("mean_speed_mps"),
        "tracking_pos_rmse_m": m.get("tracking_pos_rmse_m"),  # only when some agent perceives
        "tracking_vel_rmse_mps": m.get("tracking_vel_rmse_mps"),
        "radio_delivered_fraction": _radio_delivered_fraction(m.get("radio")),
        "real_time_factor": m.get("real_time_factor"),
    }


def summarize(rows: Sequence[dict[str, Any]], modes: Sequence[str]) -> list[dict[str, Any]]:
    """Per mode, its rows pooled over seeds (keys :data:`SUMMARY_KEYS`)."""
    out = []
    for mode in modes:
        rs = [r for r in rows if r["mode"] == mode]
        dists = [r["min_distance_m"] for r in rs if r["min_distance_m"] is not None]
        missions = [r["mission_time_s"] for r in rs if r["mission_time_s"] is not None]
        paths = [r["path_length_m"] for r in rs if r["path_length_m"] is not None]
        out.append({
            "mode": mode,
            "planner_kind": _kind(mode),
            "runs": len(rs),
            "success_rate": sum(r["success"] for r in rs) / len(rs) if rs else None,
            "collisions": int(sum(r["collisions"] for r in rs)),
            "min_distance_m": float(min(dists)) if dists else None,
            "mission_time_s": float(np.mean(missions)) if missions else None,
            "mission_time_runs": len(missions),
            "path_length_m": float(np.mean(paths)) if paths else None,
        })  # fmt: skip
    return out


def format_table(results: dict) -> str:
    """Human-readable table of ``results["rows"]`` and, when present, of ``results["summary"]``."""
    head = (
        f"{'mode':<12} {'seed':>4} {'ok':>3} {'arrived':>7} {'coll':>4} {'min d m':>7} {'obs clr m':>9} "
        f"{'mission s':>9} {'path m':>7} {'speed m/s':>9} {'trk pos m':>9} {'trk vel m/s':>11} {'radio':>6} {'rtf':>5}"
    )
    lines = [f"scenario {results.get('scenario', '?')}", head, "-" * len(head)]
    for r in results["rows"]:
        radio = None if r["radio_delivered_fraction"] is None else 100.0 * r["radio_delivered_fraction"]
        lines.append(
            f"{r['mode']:<12} {r['seed']:>4d} {'yes' if r['success'] else 'no':>3} "
            f"{str(r['arrived']) + '/' + str(r['n_drones']):>7} {r['collisions']:>4d} "
            f"{cell(r['min_distance_m'], '7.3f')} {cell(r['min_obstacle_clearance_m'], '9.3f')} "
            f"{cell(r['mission_time_s'], '9.2f')} {cell(r['path_length_m'], '7.2f')} "
            f"{cell(r['mean_speed_mps'], '9.2f')} "
            f"{cell(r['tracking_pos_rmse_m'], '9.3f')} {cell(r['tracking_vel_rmse_mps'], '11.3f')} "
            f"{cell(radio, '5.1f')}% {cell(r['real_time_factor'], '5.2f')}"
        )
    summary = results.get("summary") or []
    if summary:
        head = (
            f"{'mode':<12} {'runs':>4} {'success':>7} {'coll':>4} {'min d m':>7} {'mission s':>9} {'(of)':>4} "
            f"{'path m':>7}"
        )
        lines += ["", "pooled over seeds:", head, "-" * len(head)]
        for s in summary:
            rate = None if s["success_rate"] is None else 100.0 * s["success_rate"]
            lines.append(
                f"{s['mode']:<12} {s['runs']:>4d} {cell(rate, '6.0f')}% {s['collisions']:>4d} "
                f"{cell(s['min_distance_m'], '7.3f')} {cell(s['mission_time_s'], '9.2f')} {s['mission_time_runs']:>4d} "
                f"{cell(s['path_length_m'], '7.2f')}"
            )
    return "\n".join(lines)


def _plot(path: Path, flights: dict[str, RunResult], seed: int) -> None:
    """results.png: min inter-drone distance over time per mode, beside a top view per mode (one seed)."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    from mpcde.flight.plots import draw_obstacles, min_inter_drone_distance

    ncol = 1 + len(flights)
    fig = Figure(figsize=(4.6 * ncol, 4.6))
    FigureCanvasAgg(fig)
    ax_d = fig.add_subplot(1, ncol, 1)
    collision_m = None
    for mode, r in flights.items():
        arrays = r.log.arrays
        collision_m = 2 * r.config.physics.quadrotor.robot_radius_m
        if arrays["time_s"].size and arrays["pos_world"].shape[1] > 1:
            ax_d.plot(arrays["time_s"], min_inter_drone_distance(arrays["pos_world"]), lw=1.2, label=mode)
    if collision_m is not None:
        ax_d.axhline(collision_m, color="r", ls="--", lw=1.0, label=f"collision ({collision_m:.2f} m)")
    ax_d.set(title=f"min inter-drone distance, seed {seed}", xlabel="time [s]", ylabel="distance [m]")
    ax_d.set_ylim(bottom=0)
    ax_d.legend(fontsize=7)
    for c, (mode, r) in enumerate(flights.items()):
        ax = fig.add_subplot(1, ncol, 2 + c)
        draw_obstacles(ax, r.obstacles)
        pos = r.log.arrays["pos_world"]
        for i in range(r.starts.shape[0]):
            colour = f"C{i % 10}"
            if pos.ndim == 3:
                ax.plot(pos[:, i, 0], pos[:, i, 1], color=colour, lw=1.0)
            ax.plot(*r.starts[i, :2], "o", color=colour, ms=3)
            ax.plot(*r.goals[i, :2], "x", color=colour, ms=5)
        sx, sy = r.config.world.arena_size_m
        ax.set(xlim=(-sx / 2, sx / 2), ylim=(-sy / 2, sy / 2), aspect="equal", xlabel="x [m]", ylabel="y [m]")
        ax.set_title(f"{mode} ({_kind(mode)}): {r.metrics['collisions']} collisions", fontsize=9)
    fig.tight_layout()
    fig.savefig(path, dpi=100)


_share_cores = share_cores  # the name this module had before the sweep machinery held it


def compare_sweep(scenario: str | Path, modes: Sequence[str], seeds: Sequence[int], duration_s: float | None) -> SweepSpec:
    """The sweep a comparison is: ``scenario`` with one axis, ``planner.kind`` over ``modes``' kinds, on ``seeds``."""
    p = Path(scenario)
    if not p.is_file() and (SCENARIO_DIR / f"{scenario}.yaml").is_file():
        p = SCENARIO_DIR / f"{scenario}.yaml"
    if not p.is_file():
        load_scenario(scenario)  # raises the loader's one line (scenario=...: no such file; built-in scenarios: ...)
    base = read_yaml(p)
    if not isinstance(base, dict):
        load_scenario(p)  # raises the loader's one line for an empty or non-mapping file
    base.setdefault("name", p.stem)
    overrides = {} if duration_s is None else {"duration_s": float(duration_s)}
    return SweepSpec(base, str(scenario), tuple(seeds), overrides, (("planner.kind", tuple(_kind(m) for m in modes)),))


def run_compare(
    out_dir: Path | str,
    scenario: str,
    modes: Sequence[str] | None = None,
    seeds: Sequence[int] = (0,),
    duration_s: float | None = None,
    progress: bool = True,
    overwrite: bool = False,
    jobs: int = 1,
    backend: str = "local",
    ray_address: str | None = None,
) -> dict:
    """Fly ``scenario`` in every mode for every seed and write the paired comparison.

    A preset over the sweep machinery (:mod:`mpcde.sweep`): the sweep of
    :func:`compare_sweep` (one axis, ``planner.kind``), its flights flown by
    :func:`mpcde.sweep.engine.run_flights`, its rows kept in ``results.jsonl``
    (so ``mpcde report`` reads a comparison too), plus this module's table and
    plot. Unlike ``mpcde sweep`` it publishes all or nothing.

    Args:
        out_dir: output folder (must not exist or be empty unless ``overwrite``);
            gets ``results.json``, ``results.txt``, ``results.png``,
            ``results.jsonl`` + ``sweep.json`` (:mod:`mpcde.sweep.store`) and
            ``runs/<mode>-seed<seed>/``.
        scenario: scenario YAML path or built-in name.
        modes: keys of :func:`mpcde.stacks.stacks`; default :func:`default_modes`.
        seeds: one flight per seed and mode; the same seed gives every mode the same draw.
        duration_s: override the scenario's time limit [s].
        progress: a progress bar and one line per flight.
        overwrite: replace a non-empty ``out_dir`` when done.
        jobs: flights run at once, each in its own process (1: one after the
            other in this process). A flight's metrics do not depend on it
            (everything is seeded and stepped in simulated time, and a render
            does not depend on which worker made it: sim/rendering/tiny.py) except the
            wall-clock ones (``real_time_factor``, compute times). With more
            than one job, a flight whose ``run.render_workers`` is automatic
            (-1) renders with ``max(1, cpu_count // jobs)`` workers (at most 16), so the
            jobs share the cores instead of each taking all of them.
        backend, ray_address: as ``mpcde sweep`` (:func:`mpcde.sweep.engine.run_flights`).

    Returns:
        The results dict written to ``results.json`` (module docstring).

    Raises:
        mpcde.errors.ConfigError: unknown, repeated or no mode; bad seeds or
            duration; an unusable ``out_dir``; a scenario that does not load or
            validate in some mode (all before anything is written).
        mpcde.errors.MpcdeError: a flight failed (nothing is published).
    """
    modes = check_modes(default_modes() if modes is None else modes)
    seeds = _check_seeds(seeds)
    if duration_s is not None and not duration_s > 0:
        raise ConfigError("duration_s", duration_s, "> 0 s")
    if isinstance(jobs, bool) or not isinstance(jobs, int) or jobs < 1:
        raise ConfigError("jobs", jobs, "an integer >= 1")
    spec = compare_sweep(scenario, modes, seeds, duration_s)
    mode_of = dict(zip(range(len(modes)), modes))  # cell index -> mode (the one axis, in --modes order)
    prepared = {}
    for seed in seeds:
        for c in spec.cells():  # not `cell`: that name is the table formatter the progress lines use
            run = prepare_run(spec.scenario(c, seed))  # the kind is set before the checks
            prepared[(mode_of[c.index], seed)] = share_cores(run, jobs) if jobs > 1 else run
    name = prepared[(modes[0], seeds[0])].config.name

    from tqdm import tqdm

    from mpcde.flight.run_folder import RunFolder

    target = RunFolder(Path(out_dir), overwrite)  # checks --out, stages in a hidden sibling folder
    staging = target.staging
    order = [(mode, seed) for seed in seeds for mode in modes]  # interleaved: a seed's modes fly under the same load
    tasks = [
        FlightTask((mode, seed), prepared[(mode, seed)], staging / "runs" / f"{mode}-seed{seed}", keep_result=seed == seeds[0])
        for mode, seed in order
    ]  # fmt: skip
    store = ResultsStore.for_sweep(staging, spec)
    cell_of = {m: i for i, m in mode_of.items()}
    version, revision = package_version(), git_revision()
    bar = tqdm(total=len(tasks), disable=not progress, desc="compare", unit="flight")
    outcomes: dict[tuple[str, int], FlightOutcome] = {}

    def on_done(o: FlightOutcome) -> None:
        mode, seed = o.key
        if o.error is not None:
            raise MpcdeError(f"compare: the {mode} flight of seed {seed} failed: {o.error}")
        outcomes[o.key] = o
        store.append(flight_row(cell_of[mode], {"planner.kind": _kind(mode)}, seed, o, version, revision))
        row = row_from_metrics(mode, seed, o.metrics)
        bar.update(1)
        if progress:
            bar.write(
                f"{mode} seed {seed}: success={row['success']} arrived {row['arrived']}/{row['n_drones']} "
                f"collisions={row['collisions']} min_distance={cell(row['min_distance_m'], '.3f')} m "
                f"mission_time={cell(row['mission_time_s'], '.2f')} s"
            )

    try:
        run_flights(tasks, on_done, jobs=jobs, backend=backend, ray_address=ray_address)
        rows = [row_from_metrics(mode, seed, outcomes[(mode, seed)].metrics) for mode, seed in order]  # in this order whatever order they finished in
        results = {
            "scenario": name,
            "modes": list(modes),
            "seeds": list(seeds),
            "rows": rows,
            "summary": summarize(rows, modes) if len(seeds) > 1 else [],
        }
        (staging / "results.json").write_text(json.dumps(results, indent=2) + "\n")
        folders = [f"  {m}: " + ", ".join(f"runs/{m}-seed{s}" for s in seeds) for m in modes]
        text = format_table(results) + "\n\nrun folders:\n" + "\n".join(folders) + "\n"
        (staging / "results.txt").write_text(text)
        _plot(staging / "results.png", {m: outcomes[(m, seeds[0])].result for m in modes}, seeds[0])
        target.publish()
    except BaseException:
        target.discard()
        raise
    finally:
        bar.close()
    return results
