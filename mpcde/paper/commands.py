"""``mpcde paper``: the paper reproduction's reports from sweep stores, one subcommand each.

``table3 STORE_DIR ...`` (:mod:`~mpcde.paper.table3`), ``summary [RUNS_DIR]`` (:mod:`~mpcde.paper.summary`),
``goals [RUNS_DIR]`` (:mod:`~mpcde.paper.goals`), ``modes STORE_DIR ... [--seeds N]``
(:mod:`~mpcde.paper.swarm_modes`) and ``ceiling [SWEEP] --flights CELL:SEED ...`` (:mod:`~mpcde.paper.ceiling`,
the one that flies). Each prints its report on stdout; bad input (a folder that is not a store, a corrupt row or
report, a bad option) is one line ``mpcde: error: <field>=<value>: <allowed>`` on stderr with nothing on stdout,
and exit status 2, as every ``mpcde`` subcommand. The modules load when their subcommand runs.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from mpcde.errors import ConfigError

__all__ = ["add_parser", "run"]


def add_parser(sub: argparse._SubParsersAction) -> None:
    """Add ``paper`` and its subcommands to the ``mpcde`` subparsers ``sub``."""
    paper = sub.add_parser("paper", help="MP-CDE's paper reproduction from sweep stores: Table III, the summary, the goals, the swarm's modes")
    verbs = paper.add_subparsers(dest="paper_command", required=True, metavar="REPORT", parser_class=type(paper))
    t3 = verbs.add_parser("table3", help="Table III from one or more stores of a Table III sweep (one table when they fly one Table III)")
    t3.add_argument("stores", type=Path, nargs="+", metavar="STORE_DIR", help="a folder `mpcde sweep ... --out` wrote")
    for name, what in (("summary", "the paper's Sec. V-B figures beside ours, one markdown row each"), ("goals", "issue 28's goals, met or missed, one markdown row each")):
        p = verbs.add_parser(name, help=f"{what}, from the stores and reports under RUNS_DIR")
        p.add_argument("runs", type=Path, nargs="?", default=Path("runs"), metavar="RUNS_DIR", help="default runs/ (fig10, fig6, table3, akf_pipeline, ...)")
    md = verbs.add_parser("modes", help="the denied swarm's contacts by kind, yaw modes, yaw replans and mission time per cell")
    md.add_argument("stores", type=Path, nargs="+", metavar="STORE_DIR", help="a folder `mpcde sweep ... --out` wrote")
    md.add_argument("--seeds", type=int, default=None, help="only seeds 0..N-1 (N >= 1)")
    cl = verbs.add_parser("ceiling", help="fly Table III flights again: S_obs beside what a camera seeing all round saw on the same path")
    cl.add_argument("sweep", type=Path, nargs="?", default=None, help="sweep YAML (default data/sweeps/table3_active_perception.yaml)")
    cl.add_argument("--flights", nargs="+", required=True, metavar="CELL:SEED", help="the flights to fly, one after the other")


def run(args: argparse.Namespace) -> int:
    """Run the ``paper`` subcommand that ``args`` names; 0, or ConfigError for bad input."""
    try:
        return _REPORTS[args.paper_command](args)
    except FileNotFoundError as e:
        if e.filename is None:
            raise
        raise ConfigError("store", str(Path(e.filename).parent), f"no {Path(e.filename).name} there ({e.filename}): "
                          "a folder `mpcde sweep` wrote, with at least one flight recorded") from None  # fmt: skip


def _table3(args: argparse.Namespace) -> int:
    from mpcde.paper.table3 import merged_cells, render

    print(render(merged_cells(args.stores)), end="")
    return 0


def _summary(args: argparse.Namespace) -> int:
    from mpcde.paper.summary import summary_table

    print(summary_table(args.runs), end="")
    return 0


def _goals(args: argparse.Namespace) -> int:
    from mpcde.paper.goals import goals_table

    print(goals_table(args.runs), end="")
    return 0


def _modes(args: argparse.Namespace) -> int:
    from mpcde.paper.swarm_modes import cell_lines, render

    if args.seeds is not None and args.seeds < 1:
        raise ConfigError("--seeds", args.seeds, "an integer >= 1")
    print(render([line for store in args.stores for line in cell_lines(store, args.seeds)]))
    return 0


def _ceiling(args: argparse.Namespace) -> int:
    from mpcde.paper.ceiling import DEFAULT_SWEEP, ceiling_lines
    from mpcde.sweep.spec import load_sweep

    spec = load_sweep(args.sweep if args.sweep is not None else DEFAULT_SWEEP)
    for line in ceiling_lines(spec, args.flights):
        print(line, flush=True)
    return 0


_REPORTS = {"table3": _table3, "summary": _summary, "goals": _goals, "modes": _modes, "ceiling": _ceiling}
