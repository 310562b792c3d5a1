"""The ``mpcde`` command line.

Subcommands: ``fly`` (a headless scenario -> run folder), ``train-detector`` (render a dataset, train the drone
detector on CPU -> weights + model card), ``eval-detector`` (held-out renders -> results.json), ``eval-tracking``
(tracker evaluation -> results.json), ``eval-dmpc`` (on-demand DMPC vs BVC -> results.json), ``compare`` (one scenario
in each mode, paired by seed -> results.json + run folders), ``eval-mlr`` (DMPC-Swarm's message-loss recovery
experiments, or a loss sweep file -> results.json), ``sweep`` (a grid of conditions x seeds on local processes or Ray
-> a resumable results.jsonl + report), ``report`` (a sweep folder's tables and plots), ``paper`` (the paper
reproduction's reports from sweep stores: Table III, the summary, the goals; :mod:`mpcde.paper.commands`), ``explain``
(each collision of a sweep's store re-flown and named) and ``bench`` (the hot-path benchmarks -> their printed figures
+ results.json). Bad input prints one line ``mpcde: error: <field>=<value>: <allowed>`` and exits with status 2,
having written nothing.
"""

from __future__ import annotations

import argparse
import os
import signal
import sys
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

from mpcde import numerics
from mpcde.stacks import stacks
from mpcde.errors import ConfigError, MpcdeError, Terminated
from mpcde.onboard.budget import ComputeBudget
from mpcde.paper import commands as paper

__all__ = ["main"]

EXIT_BAD_INPUT = 2


class _Parser(argparse.ArgumentParser):
    """argparse with a one-line error and exit status 2."""

    def error(self, message: str) -> None:  # type: ignore[override]
        sys.stderr.write(f"mpcde: error: {message}\n")
        raise SystemExit(EXIT_BAD_INPUT)


def _seed(text: str) -> int:
    try:
        v = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"--seed={text!r}: an integer in [0, 2^32)") from None
    if not 0 <= v < 2**32:
        raise argparse.ArgumentTypeError(f"--seed={v}: an integer in [0, 2^32)")
    return v


def build_parser() -> argparse.ArgumentParser:
    """The argument parser of every subcommand."""
    p = _Parser(prog="mpcde", description="Quadrotor swarms in simulation when the radio cannot be trusted.")
    sub = p.add_subparsers(dest="command", required=True, parser_class=_Parser)
    fly = sub.add_parser("fly", help="fly a scenario headless and write a run folder")
    fly.add_argument("scenario", help="scenario YAML, or a built-in name (crossing, antipodal, forest_sparse, ...)")
    fly.add_argument("--out", required=True, type=Path, help="output folder (created; must be empty unless --overwrite)")
    fly.add_argument("--seed", type=_seed, default=None, help="seed of the run (overrides the file's)")
    fly.add_argument("--duration", type=float, default=None, help="time limit [s] (overrides the file's)")
    registered = stacks()  # the built-in stacks and every installed plugin's (mpcde.stacks)
    fly.add_argument(
        "--mode",
        choices=[s.name for s in registered],
        default=None,
        help="onboard stack, overriding the file's planner.kind: "
        + "; ".join(f"{s.name} ({s.summary})" if s.summary else s.name for s in registered),
    )
    fly.add_argument("--video", action="store_true", help="also write video.mp4 (top view beside each camera)")
    fly.add_argument("--no-cameras", action="store_true", help="do not render cameras (faster; no video tiles)")
    fly.add_argument("--overwrite", action="store_true", help="replace an existing non-empty --out")
    fly.add_argument("--quiet", action="store_true", help="no progress bar")
    td = sub.add_parser("train-detector", help="render a training set and train the drone detector on CPU (weights + model card)")
    td.add_argument("--out", required=True, type=Path, help="output folder: drone_detector.pt, model_card.json (and data/ unless --data)")
    td.add_argument("--data", type=Path, default=None, help="dataset folder to reuse or fill (train/ and val/); default OUT/data")
    td.add_argument("--frames", type=int, default=8000, help="training frames (rendered when the dataset has fewer)")
    td.add_argument("--val-frames", type=int, default=640, help="validation frames (threshold choice and the card's metrics)")
    td.add_argument("--epochs", type=int, default=30, help="passes over the training frames")
    td.add_argument("--minutes", type=float, default=24.0, help="wall-clock budget of the optimisation [min]")
    td.add_argument("--seed", type=_seed, default=0, help="seed of the weights init and augmentation")
    td.add_argument("--stem", choices=["conv", "patch"], default="patch", help="network stem: two 3x3 stride-2 convolutions, or one 4x4 stride-4 patch convolution")
    td.add_argument("--widths", type=int, nargs=4, default=[8, 16, 32, 64], metavar=("C1", "C2", "C3", "C4"), help="channel widths at strides 2, 4, 8, 16 (C1 unused by the patch stem)")
    td.add_argument("--threads", type=int, default=2, help="torch CPU threads of the optimisation")
    td.add_argument("--quiet", action="store_true")
    tde = sub.add_parser("eval-detector", help="score the detector on held-out renders -> results.json")
    tde.add_argument("--out", required=True, type=Path)
    tde.add_argument("--weights", type=Path, default=None, help="checkpoint (default: the shipped data/detector/drone_detector.pt)")
    tde.add_argument("--frames", type=int, default=800, help="held-out test frames to render and score")
    tde.add_argument("--workers", type=int, default=2, help="render processes")
    tde.add_argument("--renderer", choices=["tiny", "raycast"], default=None, help="renderer of the held-out frames (default: camera.renderer's default, raycast)")
    tde.add_argument("--precision", choices=["auto", "float32", "bfloat16"], default="auto", help="detector arithmetic, as perception.detector_precision (auto: bfloat16 on a CPU with native bfloat16)")
    tde.add_argument("--quiet", action="store_true")
    ev = sub.add_parser("eval-tracking", help="evaluate the tracker (AKF vs KF) and write results.json")
    ev.add_argument("--out", required=True, type=Path)
    ev.add_argument("--measurements", choices=["synthetic", "pipeline"], nargs="+", default=["synthetic"])
    ev.add_argument("--seeds", type=int, default=10, help="repeats per row (seeds 0..N-1; 10: AKF-KF gaps at 0.5 m/s are within the spread of 3)")
    ev.add_argument("--weights", type=Path, default=None, help="detector checkpoint of the pipeline source (default: the shipped one)")
    ev.add_argument("--quiet", action="store_true")
    ed = sub.add_parser("eval-dmpc", help="on-demand DMPC vs buffered Voronoi cells (the paper's Table 1) -> results.json")
    ed.add_argument("--out", required=True, type=Path)
    ed.add_argument("--methods", nargs="+", choices=["on_demand", "bvc"], default=["on_demand", "bvc"])
    ed.add_argument("--scenarios", nargs="+", default=["formation_square", "antipodal"], help="built-in names or YAML files")
    ed.add_argument("--seeds", type=int, default=1, help="flights per row (seeds 0..N-1)")
    ed.add_argument("--quiet", action="store_true")
    cmp = sub.add_parser("compare", help="fly one scenario in each mode, paired by seed -> results.json + run folders")
    cmp.add_argument("scenario", help="scenario YAML, or a built-in name (crossing, antipodal, forest_sparse, ...)")
    cmp.add_argument("--out", required=True, type=Path, help="output folder (must be empty unless --overwrite)")
    cmp.add_argument(
        "--modes", nargs="+", default=None, metavar="MODE",
        help=f"onboard stacks to fly, of: {', '.join(s.name for s in registered)} (default: comm, denied, auto)",
    )  # fmt: skip
    cmp.add_argument("--seeds", type=int, default=1, help="flights per mode (seeds 0..N-1; a seed: one draw for all)")
    cmp.add_argument("--duration", type=float, default=None, help="time limit [s] (overrides the file's)")
    cmp.add_argument("--overwrite", action="store_true", help="replace an existing non-empty --out")
    cmp.add_argument("--jobs", type=int, default=1, help="flights at once, one process each (metrics do not depend on it)")
    cmp.add_argument("--quiet", action="store_true", help="no progress bar")
    sw = sub.add_parser("sweep", help="fly a sweep file's grid of conditions x seeds; resumable; local processes or Ray")
    sw.add_argument("sweep", type=Path, help="sweep YAML (base scenario, seeds, axes, keep)")
    sw.add_argument("--out", required=True, type=Path, help="results folder (created; the same sweep resumes in it)")
    sw.add_argument("--jobs", type=int, default=1, help="flights at once on local processes (metrics do not depend on it)")
    sw.add_argument("--backend", choices=["local", "ray"], default="local", help="local processes (default) or Ray tasks")
    sw.add_argument("--ray-address", default=None, help="with --backend ray: 'auto' joins a cluster started by 'ray start'")
    sw.add_argument("--quiet", action="store_true", help="no progress bar")
    rp = sub.add_parser("report", help="tables and plots of a sweep folder (also on a partial one); with several, paired across them")
    rp.add_argument("folder", type=Path, nargs="+", help="a folder written by mpcde sweep; several: one base scenario")
    rp.add_argument("--out", type=Path, default=None, help="with several folders: where the cross-store report goes")
    rp.add_argument(
        "--pair-on", nargs="+", default=None, metavar="FIELD",
        help="with several folders: fields two paired cells share (default: each two stores' common fields whose values meet)",
    )  # fmt: skip
    em = sub.add_parser("eval-mlr", help="MLR-DMPC: message-loss recovery, event-triggered compute units (DMPC-Swarm Fig. 3-4)")
    em.add_argument("--out", required=True, type=Path)
    em.add_argument(
        "--experiments", nargs="+", choices=["fig4_swap", "fig3b_cus", "fig3c_triggers"],
        default=["fig4_swap", "fig3b_cus", "fig3c_triggers"], help="which of the paper's experiments (default all)",
    )  # fmt: skip
    em.add_argument("--seeds", type=int, default=1, help="runs per row (seeds 0..N-1)")
    em.add_argument("--sweep", type=Path, default=None, metavar="FILE", help="instead: a loss sweep file (data/sweeps/mlr/)")
    em.add_argument("--jobs", type=int, default=1, help="with --sweep: runs in parallel processes")
    paper.add_parser(sub)
    ex = sub.add_parser("explain", help="re-fly every colliding flight of a sweep's store and name each collision's cause, per cell")
    ex.add_argument("sweep", type=Path, help="the sweep YAML the store was flown from")
    ex.add_argument("store", type=Path, help="its folder (mpcde sweep SWEEP --out STORE); causes go to STORE/collision_causes.jsonl")
    ex.add_argument("--limit", type=int, default=None, help="explain at most this many new flights")
    bn = sub.add_parser("bench", help="run the hot-path benchmarks (benchmarks/) -> their figures + results.json")
    bn.add_argument("names", nargs="*", metavar="NAME", help="benchmarks to run (default all): sim, detector, map, ...")
    bn.add_argument("--out", required=True, type=Path, help="output folder (must be empty unless --overwrite)")
    bn.add_argument("--quick", action="store_true", help="fewer repeats and flights (a smoke run; noisier ratios)")
    bn.add_argument("--overwrite", action="store_true", help="replace an existing non-empty --out")
    bn.add_argument("--quiet", action="store_true", help="no progress lines")
    return p


def _check_out_dir(out: Path) -> None:
    """Refuse an --out that is a file or sits in an unwritable place (before any work)."""
    if out.exists() and not out.is_dir():
        raise ConfigError("--out", str(out), "exists and is not a folder")
    parent = out.resolve()
    while not parent.exists():
        parent = parent.parent
    if not os.access(parent, os.W_OK):
        raise ConfigError("--out", str(out), f"{parent} is not writable")


def _at_least(option: str, value: int, minimum: int) -> None:
    """Refuse an integer option below ``minimum`` (one-line ConfigError)."""
    if value < minimum:
        raise ConfigError(option, value, f"an integer >= {minimum}")


def _cmd_fly(args: argparse.Namespace) -> int:
    from mpcde.api import fly, load_scenario

    # the mode replaces planner.kind before the checks (what a kind derives starts from the file's values)
    cfg = load_scenario(args.scenario, mode=args.mode, seed=args.seed, duration_s=args.duration)
    if args.video and (args.no_cameras or not cfg.run.cameras):
        raise ConfigError("--video", True, "needs cameras (drop --no-cameras or set run.cameras: true)")
    result = fly(
        cfg, cameras=False if args.no_cameras else None, out=args.out, overwrite=args.overwrite, video=args.video,
        progress=not args.quiet,
    )  # fmt: skip
    out = args.out
    m = result.metrics
    print(
        f"{cfg.name} seed {cfg.seed}: success={m['success']} collisions={m['collisions']} "
        f"min_inter_drone={m['min_inter_drone_distance_m']} m min_obstacle={m['min_obstacle_distance_m']} m "
        f"mission_time={m['mission_time_s']} s real_time_factor={m['real_time_factor']:.2f} -> {out}"
    )
    print(f"compute time, largest three: {ComputeBudget.top(m['compute_time'], 3)}")
    return 0


def _cmd_train_detector(args: argparse.Namespace) -> int:
    from mpcde.training.train import run_train_detector
    from perception.detector.model import ModelConfig

    _at_least("--frames", args.frames, 16)
    _at_least("--val-frames", args.val_frames, 8)
    _at_least("--epochs", args.epochs, 1)
    _at_least("--threads", args.threads, 1)
    for name, width in zip(("C1", "C2", "C3", "C4"), args.widths):
        if not 4 <= width <= 256:
            raise ConfigError(f"--widths {name}", width, "an integer in [4, 256]")
    if not (args.minutes > 0):
        raise ConfigError("--minutes", args.minutes, "> 0")
    _check_out_dir(args.out)
    if args.data is not None:
        _check_out_dir(args.data)
    card = run_train_detector(
        args.out, n_train_frames=args.frames, epochs=args.epochs, seed=args.seed, progress=not args.quiet,
        data_dir=args.data, n_val_frames=args.val_frames, max_minutes=args.minutes, threads=args.threads,
        model=ModelConfig(4, *args.widths, stem=args.stem),
    )  # fmt: skip
    v = card["val_metrics"]
    print(
        f"trained {card['training']['epochs_run']} epochs ({card['training']['train_time_s']:.0f} s) on "
        f"{card['data']['train_frames']} frames; validation within 5 m: precision {v['within_5m']['precision']:.3f} "
        f"recall {v['within_5m']['recall']:.3f}; score threshold {card['score_threshold']:.2f} -> {args.out / 'drone_detector.pt'}"
    )
    return 0


def _cmd_eval_detector(args: argparse.Namespace) -> int:
    from mpcde.training.evaluate import run_eval_detector

    _at_least("--frames", args.frames, 1)
    _at_least("--workers", args.workers, 1)
    _check_out_dir(args.out)
    run_eval_detector(args.out, weights=args.weights, n_frames=args.frames, progress=not args.quiet, workers=args.workers, renderer=args.renderer, precision=args.precision)
    print((args.out / "results.txt").read_text().rstrip())
    print(f"-> {args.out / 'results.json'}")
    return 0


def _cmd_eval_tracking(args: argparse.Namespace) -> int:
    from mpcde.evals.tracking import format_table, run_eval_tracking

    _at_least("--seeds", args.seeds, 1)
    _check_out_dir(args.out)
    # run_eval_tracking validates its options before it creates or writes anything
    results = run_eval_tracking(
        args.out, measurements=tuple(args.measurements), seeds=tuple(range(args.seeds)), progress=not args.quiet,
        detector_weights=None if args.weights is None else str(args.weights),
    )  # fmt: skip
    print(format_table(results))
    print(f"-> {args.out / 'results.json'}")
    return 0


def _cmd_eval_dmpc(args: argparse.Namespace) -> int:
    from mpcde.evals.dmpc import format_table, run_eval_dmpc

    _at_least("--seeds", args.seeds, 1)
    _check_out_dir(args.out)
    results = run_eval_dmpc(args.out, methods=tuple(args.methods), scenarios=tuple(args.scenarios), seeds=tuple(range(args.seeds)), progress=not args.quiet)
    print(format_table(results))
    print(f"-> {args.out / 'results.json'}")
    return 0


def _cmd_compare(args: argparse.Namespace) -> int:
    from mpcde.evals.compare import format_table, run_compare

    _at_least("--seeds", args.seeds, 1)
    _at_least("--jobs", args.jobs, 1)
    if args.duration is not None and not args.duration > 0:
        raise ConfigError("--duration", args.duration, "> 0 s")
    _check_out_dir(args.out)
    # run_compare validates modes and prepares every flight before it creates or writes anything
    results = run_compare(
        args.out, args.scenario, modes=args.modes, seeds=tuple(range(args.seeds)), duration_s=args.duration,
        progress=not args.quiet, overwrite=args.overwrite, jobs=args.jobs,
    )  # fmt: skip
    print(format_table(results))
    print(f"-> {args.out / 'results.json'}")
    return 0


def _cmd_sweep(args: argparse.Namespace) -> int:
    from mpcde.sweep.report import format_report, write_report
    from mpcde.sweep.runner import run_sweep
    from mpcde.sweep.spec import load_sweep

    _at_least("--jobs", args.jobs, 1)
    if args.ray_address is not None and args.backend != "ray":
        raise ConfigError("--ray-address", args.ray_address, "only with --backend ray")
    spec = load_sweep(args.sweep)
    try:
        counts = run_sweep(spec, args.out, jobs=args.jobs, backend=args.backend, ray_address=args.ray_address, progress=not args.quiet)
    except (KeyboardInterrupt, Terminated) as e:
        how = "interrupted" if isinstance(e, KeyboardInterrupt) else "terminated"
        sys.stderr.write(f"mpcde: {how}; the flights recorded so far are in {args.out}: run the same command to resume\n")
        return EXIT_INTERRUPTED if isinstance(e, KeyboardInterrupt) else EXIT_TERMINATED
    print(format_report(write_report(args.out)))
    print(
        f"{counts['flown']} flown, {counts['failed']} failed, {counts['recorded_before']} recorded before, of {counts['total']} "
        f"({counts['wall_s']:.0f} s) -> {args.out / 'results.jsonl'}, {args.out / 'report.md'}"
    )
    return 0


def _cmd_report(args: argparse.Namespace) -> int:
    from mpcde.sweep.report import format_report, write_report

    if len(args.folder) > 1 or args.out is not None or args.pair_on is not None:
        from mpcde.sweep.cross_report import format_cross_report, write_cross_report

        if args.out is None:
            raise ConfigError("--out", None, "a report of several sweep folders needs --out DIR")
        print(format_cross_report(write_cross_report(args.folder, args.out, args.pair_on)))
        print(f"-> {args.out / 'report.txt'}, {args.out / 'report.md'}, {args.out / 'report.json'}")
        return 0
    folder = args.folder[0]
    print(format_report(write_report(folder)))
    print(f"-> {folder / 'report.txt'}, {folder / 'report.md'}, {folder / 'report.json'}")
    return 0


def _cmd_eval_mlr(args: argparse.Namespace) -> int:
    from mpcde.evals.mlr import run_eval_mlr
    from mpcde.evals.mlr_loss import load_loss_sweep, run_loss_sweep

    _at_least("--seeds", args.seeds, 1)
    _at_least("--jobs", args.jobs, 1)
    _check_out_dir(args.out)
    if args.sweep is not None:
        run_loss_sweep(load_loss_sweep(args.sweep), args.out, args.jobs)  # prints its table
        print(f"-> {args.out / 'results.json'}, {args.out / 'table.md'}, {args.out / 'arrivals.png'}")
        return 0
    run_eval_mlr(args.out, seeds=args.seeds, experiments=tuple(dict.fromkeys(args.experiments)))  # prints its table
    print(f"-> {args.out / 'results.json'}")
    return 0


def _cmd_explain(args: argparse.Namespace) -> int:
    from mpcde.evals.explain import causes_table, entry_line, explain_store
    from mpcde.sweep.spec import load_sweep

    if args.limit is not None:
        _at_least("--limit", args.limit, 0)
    spec = load_sweep(args.sweep)
    rows, done = explain_store(spec, args.store, args.limit, on_entry=lambda entry: print(entry_line(entry), flush=True))
    print("\n" + causes_table(spec, rows, done))
    return 0


def _cmd_bench(args: argparse.Namespace) -> int:
    from mpcde.evals.bench import format_table, run_bench

    _check_out_dir(args.out)
    results = run_bench(args.out, args.names, quick=args.quick, overwrite=args.overwrite, progress=not args.quiet)
    print(format_table(results))
    print(f"-> {args.out / 'results.json'} (figures: {args.out}/bench_<name>.txt)")
    return 0 if all(r["exit_code"] == 0 for r in results["rows"]) else 1


_COMMANDS = {
    "fly": _cmd_fly, "train-detector": _cmd_train_detector, "eval-detector": _cmd_eval_detector,
    "eval-tracking": _cmd_eval_tracking, "eval-dmpc": _cmd_eval_dmpc, "compare": _cmd_compare,
    "eval-mlr": _cmd_eval_mlr, "sweep": _cmd_sweep, "report": _cmd_report, "paper": paper.run, "explain": _cmd_explain,
    "bench": _cmd_bench,
}  # fmt: skip
EXIT_INTERRUPTED = 130  # 128 + SIGINT, as a shell reports Ctrl-C
EXIT_TERMINATED = 143  # 128 + SIGTERM


@contextmanager
def _sigterm_raises() -> Iterator[None]:
    """Inside the block SIGTERM raises :class:`Terminated` in the main thread, so staging folders are cleaned."""
    def raise_terminated(signum: int, frame: object) -> None:
        raise Terminated()

    try:
        previous = signal.signal(signal.SIGTERM, raise_terminated)
    except ValueError:  # not the main thread (main() called from a thread): leave SIGTERM alone
        yield
        return
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, previous)


def main(argv: list[str] | None = None) -> int:
    """Entry point of the ``mpcde`` console script.

    Exit status: 0 done, 1 a benchmark failed, 2 bad input (one line on
    stderr), 130 Ctrl-C and 143 SIGTERM (one line; whatever was staged is
    removed: a run folder or an evaluation appears only when complete, a
    sweep keeps the rows it recorded).
    """
    code = _run(argv)
    if code in (EXIT_INTERRUPTED, EXIT_TERMINATED):
        # The interpreter's shutdown still joins pool threads; a second Ctrl-C or SIGTERM there
        # (a shell's, or a `timeout` forwarding its own) printed a threading traceback after our line.
        signal.signal(signal.SIGINT, signal.SIG_IGN)
        signal.signal(signal.SIGTERM, signal.SIG_IGN)
    return code


def _signal_in_chain(e: BaseException) -> BaseException | None:
    """The KeyboardInterrupt or Terminated that ``e`` was raised while handling (numba's dispatcher wraps one
    raised by a signal handler during its call in a SystemError), or None."""
    seen = set()
    cur: BaseException | None = e
    while cur is not None and id(cur) not in seen:
        if isinstance(cur, (KeyboardInterrupt, Terminated)):
            return cur
        seen.add(id(cur))
        cur = cur.__cause__ or cur.__context__
    return None


def _run(argv: list[str] | None) -> int:
    """:func:`main` up to its exit status."""
    args = build_parser().parse_args(argv)
    with _sigterm_raises():
        try:
            numerics.requested()  # MPCDE_NUMERICS: refused here with one line, before any flight
            return _COMMANDS[args.command](args)
        except (MpcdeError, ValueError) as e:
            msg = str(e).splitlines()[0] if str(e) else type(e).__name__
            sys.stderr.write(f"mpcde: error: {msg}\n")
            return EXIT_BAD_INPUT
        except OSError as e:  # an output place that cannot be written
            sys.stderr.write(f"mpcde: error: --out={str(getattr(args, 'out', ''))!r}: {e.strerror or e} ({e.filename})\n")
            return EXIT_BAD_INPUT
        except SystemError as e:  # a signal raised inside a compiled (numba) call surfaces wrapped in SystemError
            signal_exc = _signal_in_chain(e)
            if signal_exc is None:
                raise
            how = "interrupted" if isinstance(signal_exc, KeyboardInterrupt) else "terminated"
            sys.stderr.write(f"mpcde: {how}, nothing written\n")
            return EXIT_INTERRUPTED if isinstance(signal_exc, KeyboardInterrupt) else EXIT_TERMINATED
        except KeyboardInterrupt:
            sys.stderr.write("mpcde: interrupted, nothing written\n")
            return EXIT_INTERRUPTED
        except Terminated:
            sys.stderr.write("mpcde: terminated, nothing written\n")
            return EXIT_TERMINATED


if __name__ == "__main__":
    raise SystemExit(main())
