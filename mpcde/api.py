"""The Python API: load a scenario and fly it from a script or a notebook.

    import mpcde

    result = mpcde.fly("forest_swarm", mode="denied", seed=3, duration_s=10.0, out="runs/denied-3")
    print(result.metrics["success"], result.metrics["tracking_pos_rmse_m"])

:func:`fly` is what ``mpcde fly`` runs: the same checks (a bad field raises
:class:`mpcde.errors.ConfigError` naming it, before anything is written), the
same flight, the same run folder when ``out`` is given. It works from a plain
script without an ``if __name__ == "__main__":`` guard (the render workers do
not re-run the script, :mod:`sim.spawn`).
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path
from typing import TYPE_CHECKING

from mpcde import numerics
from mpcde.stacks import get_stack
from mpcde.config.scenario import ScenarioConfig
from mpcde.config.scenario import load_scenario as _load_file
from mpcde.errors import ConfigError

if TYPE_CHECKING:
    from mpcde.flight.loop import RunResult

__all__ = ["fly", "load_scenario"]


def load_scenario(
    scenario: str | Path, *, mode: str | None = None, seed: int | None = None, duration_s: float | None = None
) -> ScenarioConfig:
    """Read and check a scenario (a YAML path, or a built-in name such as ``"forest_swarm"``).

    Args:
        scenario: the file, or the name of one in ``data/scenarios/``.
        mode: onboard stack replacing the file's ``planner.kind``, by its
            registry name (:func:`mpcde.all_stacks`: ``"placeholder"``, ``"denied"``,
            ``"mpcde_paper"``, ``"comm"``, ``"auto"``, ``"mlr"``, ``"admm"``, ``"minco_comm"`` or a
            registered third-party stack); None keeps the file's (a file without one flies ``auto``).
        seed: replaces the file's ``seed``.
        duration_s: replaces the file's ``duration_s`` [s].

    Raises:
        ConfigError: a missing file or any invalid field (one line naming it).
    """
    kind = None if mode is None else get_stack(mode).kind
    overrides = {}
    if seed is not None:
        overrides["seed"] = seed
    if duration_s is not None:
        overrides["duration_s"] = duration_s
    return _load_file(scenario, overrides, planner_kind=kind)


def fly(
    scenario: str | Path | ScenarioConfig,
    *,
    mode: str | None = None,
    seed: int | None = None,
    duration_s: float | None = None,
    cameras: bool | None = None,
    out: str | Path | None = None,
    overwrite: bool = False,
    video: bool = False,
    progress: bool = False,
) -> RunResult:
    """Fly a scenario headless to its end; optionally write its run folder.

    Args:
        scenario: a :class:`ScenarioConfig` (from :func:`load_scenario`), a
            YAML path or a built-in name.
        mode, seed, duration_s: as :func:`load_scenario` (for a path or a name only).
        cameras: False skips rendering (faster; only for stacks that do not
            perceive); None keeps ``run.cameras``.
        out: run folder to write (``config.yaml``, ``metrics.json``,
            ``states.npz``, ``obstacles.json``, plots, ``video.mp4`` with
            ``video``), all or nothing; None writes nothing.
        overwrite: replace a non-empty ``out``.
        video: also write ``video.mp4`` (needs ``out`` and cameras).
        progress: show a progress bar over simulated time.

    Returns:
        The :class:`mpcde.flight.loop.RunResult`: ``metrics`` (the dict written
        to ``metrics.json``), ``log`` (the state log), the resolved ``config``,
        ``obstacles``, ``starts`` and ``goals``.

    Raises:
        ConfigError: any invalid input, before anything is flown or written
            (``MPCDE_NUMERICS`` included: mpcde/numerics.py).
    """
    numerics.requested()
    if isinstance(scenario, ScenarioConfig):
        if mode is not None or seed is not None or duration_s is not None:
            raise ConfigError("mode/seed/duration_s", (mode, seed, duration_s), "only with a scenario path or name; use dataclasses.replace on a ScenarioConfig")
        cfg = scenario
    else:
        cfg = load_scenario(scenario, mode=mode, seed=seed, duration_s=duration_s)
    if cameras is not None:
        cfg = replace(cfg, run=replace(cfg.run, cameras=bool(cameras)))
    if video and not cfg.run.cameras:
        raise ConfigError("video", True, "needs cameras (run.cameras: true)")
    if video and out is None:
        raise ConfigError("video", True, "needs an out folder to write video.mp4 into")
    from mpcde.flight.loop import prepare_run, run_scenario  # the simulator, imported when a flight starts

    prepared = prepare_run(cfg)  # validates everything before anything is written
    if out is None:
        return run_scenario(prepared, progress=progress)
    from mpcde.flight.run_folder import RunFolder
    from mpcde.flight.video import VideoWriter

    folder = RunFolder(Path(out), overwrite)
    writer = None
    try:
        if video:
            size = (cfg.camera.width_px, cfg.camera.height_px)
            writer = VideoWriter(folder.path("video.mp4"), prepared.obstacles, prepared.goals, cfg.world.arena_size_m, cfg.camera.rate_hz, size)
        result = run_scenario(prepared, frame_sink=writer, progress=progress)
        if writer is not None:
            writer.close()
            writer = None
        folder.write_result(result)
        folder.publish()
    except BaseException:
        if writer is not None:
            writer.close()
        folder.discard()
        raise
    return result
