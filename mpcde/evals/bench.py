"""``mpcde bench``: run the hot-path benchmarks of ``benchmarks/`` and collect what they print.

Each benchmark is a script ``benchmarks/bench_<name>.py`` that prints its own
figures (median of repeats and a ratio against a baseline measured in the same
run; see the script's docstring). This module runs the chosen ones one after
the other, each in a fresh interpreter (``sys.executable``, so a numba cache or
torch thread pool of one does not warm or slow the next) with
``OMP_NUM_THREADS=1`` unless the caller set it, and writes::

    OUT/bench_<name>.txt   what the script printed (stdout and stderr)
    OUT/results.json       {"quick": bool, "machine": {...},
                            "rows": [{"name", "command", "exit_code", "wall_s", "output_file"}]}

all or nothing (:class:`mpcde.flight.run_folder.RunFolder`): into a staging folder beside ``OUT`` that is renamed to
``OUT`` at the end (an interrupted run leaves no half-written ``OUT``).

The figures stay text: each script's table has its own columns, and the
scripts remain the one place that defines them. Timings are of a shared,
noisy machine; compare ratios printed in one run, not absolute figures across
machines (``results.json`` records the CPU count and load average at the start).

``quick`` passes each script fewer repeats or flights (:data:`BENCHMARKS`), for
a smoke run in about a tenth of the time; the printed ratios are noisier.
It needs a source checkout (``benchmarks/`` is not part of the installed package).
"""

from __future__ import annotations

import json
import os
import platform
import subprocess
import sys
import time
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

from mpcde.errors import ConfigError

__all__ = ["BENCHMARKS", "Benchmark", "benchmarks_dir", "format_table", "run_bench"]


@dataclass(frozen=True)
class Benchmark:
    """One benchmark script.

    Attributes:
        name: short name (``benchmarks/bench_<name>.py``).
        what: the hot path it measures, one line.
        quick_args: arguments of a quick run (fewer repeats or flights).
    """

    name: str
    what: str
    quick_args: tuple[str, ...] = ()


BENCHMARKS: tuple[Benchmark, ...] = (
    Benchmark("sim", "physics step, camera render per frame, real-time factor of every stack with its budget, PyFlyt peer", ("--quick",)),
    Benchmark("detector", "batched detector inference vs one frame at a time", ("--repeats", "10")),
    Benchmark("map", "depth insertion, ESDF, A* vs numpy / scipy / open3d baselines"),
    Benchmark("tracker", "tracker update (batched AKF and KF + Hungarian) vs filterpy per track", ("--frames", "300")),
    Benchmark("yaw", "active yaw planner (Dijkstra on the yaw lattice)", ("--repeats", "50")),
    Benchmark("minco", "MINCO evaluation and replan vs scipy L-BFGS"),
    Benchmark("dmpc", "DMPC QP: on-demand vs buffered Voronoi cells", ("--seeds", "1")),
    Benchmark("admm", "ADMM formation DMPC vs the centralized QP", ("--seeds", "1")),
    Benchmark("mlr", "MLR-DMPC compute-unit step (trackers, trigger, QP) vs the DMPC QP in bvc mode"),
    Benchmark("sweep", "mpcde sweep --jobs 2 vs the same flights back to back; denied flights per hour", ("--quick",)),
    Benchmark("env", "PettingZoo env steps/s without cameras vs PyFlyt's MA QuadX env; with cameras vs mpcde fly", ("--quick",)),
    Benchmark("env_reset", "an environment's reset with the render pool kept vs a new pool per episode", ("--quick",)),
    # quick: the crossing pair over the radio, whose stack compiles far fewer numba kernels for the native
    # profile (a cold cache) than the denied forest's MINCO and L-BFGS: the same script path, faster
    # (docs/results/ci_time.md#the-numerics-benchmarks-quick-run)
    Benchmark("numerics", "a perceiving flight under the portable numerics profile vs the CPU's native kernels",
              ("--scenario", "crossing", "--mode", "comm", "--duration", "1", "--repeats", "1")),
)
_BY_NAME = {b.name: b for b in BENCHMARKS}


def benchmarks_dir() -> Path:
    """The ``benchmarks/`` folder of the source checkout this package runs from.

    Raises:
        ConfigError: there is none (an installed package without its checkout).
    """
    folder = Path(__file__).resolve().parents[2] / "benchmarks"
    if not (folder / "timing.py").is_file():
        raise ConfigError("benchmarks", str(folder), "not found: mpcde bench runs from a source checkout")
    return folder


def _resolve(names: Sequence[str] | None) -> list[Benchmark]:
    if not names:
        return list(BENCHMARKS)
    for n in names:
        if n not in _BY_NAME:
            raise ConfigError("benchmark", n, f"one of {', '.join(_BY_NAME)}")
    return [_BY_NAME[n] for n in dict.fromkeys(names)]  # in the order given, once each


def run_bench(
    out: Path,
    names: Sequence[str] | None = None,
    *,
    quick: bool = False,
    overwrite: bool = False,
    progress: bool = True,
) -> dict:
    """Run the benchmarks ``names`` (default all, in :data:`BENCHMARKS` order) and write ``out``.

    Args:
        out: output folder; must be absent or empty unless ``overwrite``.
        names: benchmark names (see :data:`BENCHMARKS`).
        quick: pass each script its ``quick_args``.
        overwrite: replace a non-empty ``out``.
        progress: print one line per benchmark as it finishes.

    Returns:
        the ``results.json`` content. A benchmark that exits non-zero is
        recorded with its exit code (the others still run).

    Raises:
        ConfigError: an unknown name, a bad ``out``, no source checkout
            (before anything runs or is written).
    """
    from mpcde.flight.run_folder import RunFolder  # the all-or-nothing staging of every output folder

    chosen = _resolve(names)
    folder = benchmarks_dir()
    target = RunFolder(Path(out), overwrite)  # checks --out, stages in a hidden sibling folder
    staging = target.staging
    env = dict(os.environ)
    env.setdefault("OMP_NUM_THREADS", "1")
    rows = []
    machine = {
        "cpu_count": os.cpu_count(),
        "load_average_1min": os.getloadavg()[0],
        "platform": platform.platform(),
        "python": platform.python_version(),
        "omp_num_threads": env["OMP_NUM_THREADS"],
    }
    try:
        for i, bench in enumerate(chosen):
            script = folder / f"bench_{bench.name}.py"
            args = list(bench.quick_args) if quick else []
            t0 = time.perf_counter()
            proc = subprocess.run(
                [sys.executable, str(script), *args], cwd=folder.parent, env=env,
                stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
            )  # fmt: skip
            wall = time.perf_counter() - t0
            name = f"bench_{bench.name}.txt"
            (staging / name).write_text(proc.stdout)
            command = " ".join(["python", f"benchmarks/bench_{bench.name}.py", *args])
            rows.append({"name": bench.name, "command": command, "exit_code": proc.returncode,
                         "wall_s": round(wall, 2), "output_file": name})  # fmt: skip
            if progress:
                state = "ok" if proc.returncode == 0 else f"FAILED (exit {proc.returncode})"
                print(f"[{i + 1}/{len(chosen)}] {bench.name:<9} {wall:7.1f} s  {state}", flush=True)
        results = {"quick": quick, "machine": machine, "rows": rows}
        (staging / "results.json").write_text(json.dumps(results, indent=2) + "\n")
    except BaseException:
        target.discard()
        raise
    target.publish()
    return results


def format_table(results: dict) -> str:
    """A short table: benchmark, what it measures, wall time, status."""
    lines = [f"{'benchmark':<10} {'wall s':>7}  status  measures", "-" * 72]
    for row in results["rows"]:
        status = "ok" if row["exit_code"] == 0 else f"exit {row['exit_code']}"
        lines.append(f"{row['name']:<10} {row['wall_s']:7.1f}  {status:<6}  {_BY_NAME[row['name']].what}")
    return "\n".join(lines)
