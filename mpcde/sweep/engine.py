"""Flights as tasks: one prepared scenario in, its metrics (and optionally its run folder) out, on local processes or Ray.

:func:`run_flights` is the one machinery behind ``mpcde sweep`` and ``mpcde
compare``. Each :class:`FlightTask` is flown by :func:`fly_task` in a worker:
in this process (``jobs=1``), in ``spawn`` processes of a local pool, or as a
Ray remote task (``backend="ray"``) that reserves the CPUs its flight uses (the
main loop plus its render workers). A flight that raises becomes a failed
:class:`FlightOutcome` carrying its error, never an exception of the run, and
``on_done`` is called in this process as each flight finishes, in finishing
order. A flight's metrics do not depend on where it flew (everything is
seeded and stepped in simulated time; a render does not depend on the worker
that made it), except the wall-clock ones (``wall_time_s``, ``real_time_factor``,
``compute_time``'s times, and the agents' millisecond timings such as ``qp_solve_ms``).
"""

from __future__ import annotations

import contextlib
import multiprocessing as mp
import os
import signal
import socket
import subprocess
import time
import traceback
from collections.abc import Callable, Iterator, Sequence
from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait
from contextlib import contextmanager
from dataclasses import dataclass, replace
from importlib import metadata
from pathlib import Path
from typing import Any

from mpcde import numerics
from mpcde.errors import ConfigError
from sim.spawn import main_module_hidden, sigint_ignored

__all__ = ["BACKENDS", "FlightOutcome", "FlightTask", "cpus_of", "fly_task", "git_revision", "package_version", "run_flights", "share_cores", "share_cores_count"]

BACKENDS = ("local", "ray")


@dataclass(frozen=True)
class FlightTask:
    """One flight: ``key`` (any hashable the caller chooses), the prepared run, and what to write.

    Attributes:
        key: the caller's name for the flight ((cell, seed) in a sweep).
        prepared: a :class:`mpcde.flight.loop.PreparedRun`, or a picklable
            function that returns one, called by the worker (so a sweep's
            main process does not prepare hundreds of flights on the cores
            its workers fly on; an error there is the flight's failure).
        run_folder: write the flight's run folder here (None: metrics only).
        video: also write ``video.mp4`` into the run folder.
        keep_result: return the whole :class:`mpcde.flight.loop.RunResult` (the log too).
        cpus: CPUs the flight keeps busy (what a Ray task reserves); None: :func:`cpus_of` the prepared run.
    """

    key: Any
    prepared: Any
    run_folder: Path | None = None
    video: bool = False
    keep_result: bool = False
    cpus: int | None = None


@dataclass(frozen=True)
class FlightOutcome:
    """What came back: ``metrics`` (None when failed), ``error`` (one line, None when flown), wall time [s]."""

    key: Any
    metrics: dict[str, Any] | None
    error: str | None
    wall_s: float
    result: Any = None


def fly_task(task: FlightTask, pools: Any = None) -> FlightOutcome:
    """Fly ``task`` to its end (top level, so it pickles); any exception becomes a failed outcome.

    ``pools``: the :class:`sim.rendering.pool_keeper.PoolKeeper` to take the render pool from; None: this
    process's :data:`_KEEPER` (a pool worker's), if any. A flight with a run folder (``mpcde.fly``) starts its own.
    """
    from mpcde.api import fly
    from mpcde.flight.loop import run_scenario

    from mpcde.errors import Terminated

    t0 = time.perf_counter()
    global _FLYING
    _FLYING = True
    try:
        prepared = task.prepared() if callable(task.prepared) else task.prepared
        out = task.run_folder
        if out is None:
            result = run_scenario(prepared, pools=pools if pools is not None else _KEEPER)
        else:  # mpcde.fly writes the run folder (and the video) all or nothing
            result = fly(prepared.config, out=out, overwrite=True, video=task.video)
    except Terminated:
        if _IN_POOL:  # the flight has closed its session on the way here; a stopped worker takes no further flight
            _exit_stopped()
        raise
    except Exception as e:  # a failed flight is a result of the sweep, not the end of it
        last = traceback.extract_tb(e.__traceback__)[-1] if e.__traceback__ else None
        where = f" at {Path(last.filename).name}:{last.lineno}" if last else ""
        return FlightOutcome(task.key, None, f"{type(e).__name__}: {str(e).splitlines()[0] if str(e) else ''}{where}", time.perf_counter() - t0)
    finally:
        _FLYING = False
    return FlightOutcome(task.key, result.metrics, None, time.perf_counter() - t0, result if task.keep_result else None)


_IN_POOL = False
"""Whether this process is a local pool's worker (set by :func:`_warm`)."""
_FLYING = False
"""Whether this process is inside :func:`fly_task` (a SIGTERM then unwinds the flight; otherwise it exits at once)."""
_KEEPER: Any = None
"""A local pool worker's :class:`sim.rendering.pool_keeper.PoolKeeper` (set by :func:`_warm`; None: each flight
starts its own render pool). Its camera flights without a run folder load their scene into the running render
workers instead of spawning new ones (benchmarks/bench_sweep.py); ``jobs=1`` keeps one the same way."""


def _exit_stopped() -> None:
    """A stopped pool worker's end: close its kept render pool, then exit with 143 at once.

    Once one worker has exited, the pool's manager sends SIGTERM to the others: a second SIGTERM must not cut
    the close short (it stretched the sweep's exit: docs/results/sweeps.md#the-render-pool-kept-across-a-workers-flights),
    so further ones are ignored (already from the first, :func:`_warm`)."""
    _close_at_exit()
    os._exit(143)


def _close_at_exit() -> None:
    """A worker's finalizer at the pool's shutdown: close the kept render pool, if any, not to be cut short by a
    late SIGTERM (never raises)."""
    global _KEEPER
    signal.signal(signal.SIGTERM, signal.SIG_IGN)
    keeper, _KEEPER = _KEEPER, None
    if keeper is not None:
        with contextlib.suppress(Exception):
            keeper.close()


def _started() -> None:
    """A no-op task: submitted once per worker, it starts the workers (and their :func:`_warm`) early."""


def share_cores_count(jobs: int, cpus: int | None = None) -> int:
    """Render workers of one of ``jobs`` flights at once: its share of ``cpus`` (default: this machine's), 1 to 16."""
    return min(16, max(1, (cpus or os.cpu_count() or 1) // jobs))  # 16: run.render_workers' limit


def share_cores(prepared: Any, jobs: int, cpus: int | None = None) -> Any:
    """``prepared`` with an automatic ``run.render_workers`` (-1) set to one job's share of ``cpus`` (default: this machine's)."""
    run = prepared.config.run
    if run.render_workers >= 0:
        return prepared
    return replace(prepared, config=replace(prepared.config, run=replace(run, render_workers=share_cores_count(jobs, cpus))))


def cpus_of(run: Any) -> int:
    """CPUs a flight with run options ``run`` (``ScenarioConfig.run``) keeps busy: its loop, plus its render workers when it renders cameras."""
    return 1 + (max(run.render_workers, 0) if run.cameras else 0)


def run_flights(
    tasks: Sequence[FlightTask] | Callable[[], Sequence[FlightTask]],
    on_done: Callable[[FlightOutcome], None],
    jobs: int = 1,
    backend: str = "local",
    ray_address: str | None = None,
    keep_pools: bool = True,
) -> None:
    """Fly every task and call ``on_done`` with each outcome as it finishes.

    Args:
        tasks: the flights, submitted in this order; or a function returning
            them, called once the workers have started, so that they import
            the simulator while this process prepares the flights.
        on_done: called in this process for each outcome (it may write; an
            exception it raises stops the run, flights in progress are abandoned).
        jobs: flights at once on the local backend (1: one after the other
            in this process); with Ray, the cluster's free CPUs decide.
        backend: ``"local"`` or ``"ray"``.
        ray_address: with Ray, ``"auto"`` (or a ``ray start`` address) joins an
            existing cluster; None starts a local Ray instance.
        keep_pools: on the local backend, each process keeps one render pool
            across its camera flights (:data:`_KEEPER`); False starts one per
            flight (the benchmark's baseline). A flight's metrics are the same
            either way (tests/integration/test_sweep_pools.py).
    """
    if backend not in BACKENDS:
        raise ConfigError("--backend", backend, f"one of {', '.join(BACKENDS)}")
    if backend == "ray":
        _run_ray(tasks, on_done, ray_address)
    elif jobs <= 1:
        _run_here(tasks, on_done, keep_pools)
    else:
        _run_pool(tasks, on_done, jobs, keep_pools)


def _run_here(tasks: Sequence[FlightTask] | Callable[[], Sequence[FlightTask]], on_done: Callable[[FlightOutcome], None], keep_pools: bool) -> None:
    """The flights one after the other in this process, with one kept render pool (closed at the end, whatever happens)."""
    from sim.rendering.pool_keeper import PoolKeeper

    keeper = PoolKeeper(reuse=keep_pools)  # reuse=False: a new pool for every flight, as without a keeper
    try:
        for task in tasks() if callable(tasks) else tasks:
            on_done(fly_task(task, keeper))
    finally:
        keeper.close()


def _warm(keep_pools: bool = True) -> None:
    """A pool worker's initializer (run once in each, before its first task): import the simulator and the
    stacks (what every flight needs) before a flight waits on it.

    It also makes SIGTERM raise :class:`mpcde.errors.Terminated` in the worker, so that a flight stopped by
    an interrupted sweep closes its session (render pool, shared memory) on the way out; the worker then
    exits (:func:`fly_task`) instead of taking the flight its pool had already queued for it (it used to:
    one SIGTERM stopped one flight, and the sweep's exit waited for the next). It ignores
    SIGINT: Ctrl-C reaches the whole process group, and the main process answers it by stopping the
    workers with SIGTERM (a second Ctrl-C must not interrupt that cleanup).

    With ``keep_pools`` it starts the worker's :data:`_KEEPER`, closed when the worker exits: at a SIGTERM
    (either way above), and at the pool's shutdown by a finalizer that multiprocessing runs before it stops
    the worker's own (daemonic) children, the render workers. From the first SIGTERM on, further ones are
    ignored: the pool's manager sends one to every other worker once one has exited, and a second
    ``Terminated`` must neither cut a close short nor escape :func:`fly_task` (the worker would then take
    its next queued flight).
    """
    import mpcde.flight.loop  # noqa: F401
    import mpcde.onboard.admm, mpcde.onboard.auto, mpcde.onboard.minco_comm, mpcde.onboard.mlr  # noqa: F401, E401 (the agents)
    from mpcde.errors import Terminated

    global _IN_POOL, _KEEPER
    _IN_POOL = True
    if keep_pools:
        from multiprocessing import util

        from sim.rendering.pool_keeper import PoolKeeper

        _KEEPER = PoolKeeper()
        util.Finalize(None, _close_at_exit, exitpriority=10)

    def raise_terminated(signum: int, frame: object) -> None:
        signal.signal(signal.SIGTERM, signal.SIG_IGN)
        if not _FLYING:  # idle, between flights: only the kept pool to close, and no next flight may start
            _exit_stopped()
        raise Terminated()

    signal.signal(signal.SIGTERM, raise_terminated)
    signal.signal(signal.SIGINT, signal.SIG_IGN)


_ONE_THREAD = {
    "OPENBLAS_NUM_THREADS": "1", "OMP_NUM_THREADS": "1", "MKL_NUM_THREADS": "1",
    # A flight stopped by an interrupted sweep while its render pool starts can leave a shared-memory
    # segment to multiprocessing's resource tracker, which unlinks it at exit with a UserWarning on the
    # terminal after our one line (seen in tests/integration/test_signals.py's sweep runs); the
    # segment is freed either way, so the tracker started by a worker keeps the notice to itself.
    "PYTHONWARNINGS": "ignore::UserWarning:multiprocessing.resource_tracker",
}  # fmt: skip
"""Each pool worker's BLAS and OpenMP libraries run one thread: ``jobs`` flights already fill the cores, and
two processes each spinning two OpenBLAS threads oversubscribe them
(measured: docs/results/sweeps.md#overhead-of-the-machinery-issue-27s-goal--12x-back-to-back--2)."""


@contextmanager
def _environment(values: dict[str, str]) -> Iterator[None]:
    """``os.environ`` with ``values`` set inside the block (children started inside inherit them)."""
    saved = {k: os.environ.get(k) for k in values}
    os.environ.update(values)
    try:
        yield
    finally:
        for k, v in saved.items():
            if v is None:
                os.environ.pop(k, None)
            else:
                os.environ[k] = v


def _run_pool(tasks: Sequence[FlightTask] | Callable[[], Sequence[FlightTask]], on_done: Callable[[FlightOutcome], None], jobs: int, keep_pools: bool) -> None:
    with _environment(_ONE_THREAD):  # the pool's queues start multiprocessing's resource tracker, with this environment
        pool = ProcessPoolExecutor(max_workers=jobs, mp_context=mp.get_context("spawn"), initializer=_warm, initargs=(keep_pools,))
    try:
        with main_module_hidden(), _environment(_ONE_THREAD), sigint_ignored():  # the workers start on these first submits (sim/spawn.py)
            started = [pool.submit(_started) for _ in range(jobs)]  # each worker runs _warm once, as it starts
            pending = {pool.submit(fly_task, t) for t in (tasks() if callable(tasks) else tasks)}
        for future in started:
            future.result()
        while pending:
            done, pending = wait(pending, return_when=FIRST_COMPLETED)
            for future in done:
                on_done(future.result())
    except BaseException:
        # Do not wait for flights in progress (their rows would be discarded): cancel what is queued and
        # stop the workers, or the interpreter's exit joins them for up to a flight's length after the
        # one-line message (Python 3.11 has no public terminate for a ProcessPoolExecutor).
        with contextlib.suppress(ValueError):  # off the main thread signals stay as they are
            signal.signal(signal.SIGINT, signal.SIG_IGN)  # a second Ctrl-C must not cut the workers' cleanup short
        workers = list((getattr(pool, "_processes", None) or {}).values())
        manager = getattr(pool, "_executor_manager_thread", None)  # shutdown() drops the reference
        pool.shutdown(wait=False, cancel_futures=True)
        for w in workers:
            w.terminate()  # SIGTERM: the flight raises Terminated and closes its session (_warm)
        for w in workers:
            w.join(timeout=10)
        # The manager thread closes the pool's wake-up pipe as it ends. Python 3.11's exit hook
        # (concurrent.futures.process._python_exit) writes to that pipe without the lock it is closed
        # under: a sweep that raised while the thread was still closing it printed an "OSError: [Errno 9]
        # Bad file descriptor" traceback after our one line (seen in CI). Once the thread has ended, the
        # pipe is marked closed and the hook skips it.
        if manager is not None:
            manager.join(timeout=10)
        raise
    pool.shutdown()


def _check_reachable(address: str | None) -> None:
    """Refuse a ``host:port`` (or ``ray://host:port``) address where nothing accepts a connection within 5 s.

    Ray's own connect retries for minutes before it gives up; ``auto`` and
    None are left to Ray, which answers at once when no local cluster runs.
    """
    if address is None or address == "auto":
        return
    host, _, port = address.removeprefix("ray://").rpartition(":")
    try:
        socket.create_connection((host or "127.0.0.1", int(port)), timeout=5.0).close()
    except (OSError, ValueError):
        raise ConfigError("--ray-address", address, "nothing answers there: start the head with 'ray start --head' and pass the address it prints, or 'auto'") from None


def _run_ray(
    tasks: Sequence[FlightTask] | Callable[[], Sequence[FlightTask]], on_done: Callable[[FlightOutcome], None], address: str | None
) -> None:
    try:
        import ray
    except ImportError:
        raise ConfigError("--backend", "ray", "needs Ray: pip install 'mpcde[ray]'") from None
    started = False
    if not ray.is_initialized():
        _check_reachable(address)
        try:
            ray.init(address=address, include_dashboard=False, log_to_driver=False, configure_logging=False)
        except (ConnectionError, RuntimeError, ValueError) as e:
            raise ConfigError("--ray-address", address, f"no Ray cluster there ({str(e).splitlines()[0][:120]})") from None
        started = True
    refs: dict = {}
    try:
        remote = ray.remote(fly_task)
        # The driver's numerics profile, not the environment a `ray start` gave the cluster's workers; each
        # worker's `import mpcde` then sets its pins for its own CPU (mpcde/numerics.py).
        runtime_env = {"env_vars": {numerics.VARIABLE: numerics.requested()}}
        for t in tasks() if callable(tasks) else tasks:  # a sweep opens its store only once the cluster answered
            refs[remote.options(num_cpus=t.cpus or cpus_of(t.prepared.config.run), runtime_env=runtime_env).remote(t)] = t.key
        pending = list(refs)
        while pending:
            done, pending = ray.wait(pending, num_returns=1)
            for ref in done:
                try:
                    outcome = ray.get(ref)
                except Exception as e:  # the worker itself died (fly_task catches the flight's own errors)
                    outcome = FlightOutcome(refs[ref], None, f"{type(e).__name__}: {str(e).splitlines()[0][:200]}", 0.0)
                on_done(outcome)
    except BaseException:
        for ref in refs:
            ray.cancel(ref, force=True)
        raise
    finally:
        if started:
            ray.shutdown()


def package_version() -> str:
    """mpcde's installed version."""
    try:
        return metadata.version("mpcde")
    except metadata.PackageNotFoundError:
        return "unknown"


def git_revision() -> str | None:
    """The commit of the source tree mpcde runs from (``+dirty`` with uncommitted changes), None outside git."""
    root = Path(__file__).resolve().parents[2]
    try:
        rev = subprocess.run(["git", "-C", str(root), "rev-parse", "HEAD"], capture_output=True, text=True, timeout=10)
        if rev.returncode != 0:
            return None
        dirty = subprocess.run(["git", "-C", str(root), "status", "--porcelain", "--untracked-files=no"], capture_output=True, text=True, timeout=10)
        return rev.stdout.strip() + ("+dirty" if dirty.stdout.strip() else "")
    except (OSError, subprocess.SubprocessError):
        return None
