"""The output folder of a run, written all-or-nothing.

Everything goes into a sibling staging folder ``<out>.partial-<pid>`` that is
renamed to ``<out>`` only when complete, so a failed or interrupted run leaves
no half-written ``<out>``. Contents: ``config.yaml`` (the resolved scenario),
``metrics.json``, ``states.npz`` (the state log), ``obstacles.json``,
``top_down.png``, ``min_distance.png``, ``yaw.png``, ``observed_area.png``
(with cameras) and, with video,
``video.mp4``.
"""

from __future__ import annotations

import json
import os
import shutil
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import numpy as np
import yaml

from mpcde.config.io import to_dict
from mpcde.errors import ConfigError, MpcdeError
from mpcde.flight.loop import RunResult
from mpcde.flight.plots import plot_min_distance, plot_observed_area, plot_top_down, plot_yaw

__all__ = ["RunFolder", "staged_output"]


class RunFolder:
    """Staging and publishing of one run's outputs."""

    def __init__(self, out: Path, overwrite: bool) -> None:
        self.out = Path(out)
        self.overwrite = overwrite
        if self.out.exists() and not self.out.is_dir():
            raise ConfigError("--out", str(out), "exists and is not a folder")
        if self.out.exists() and any(self.out.iterdir()) and not overwrite:
            raise ConfigError("--out", str(out), "exists and is not empty; pass --overwrite or choose another folder")
        parent = self.out.resolve().parent
        try:
            parent.mkdir(parents=True, exist_ok=True)
        except OSError as e:
            raise ConfigError("--out", str(out), f"cannot create its parent folder ({e.strerror})") from None
        if not os.access(parent, os.W_OK):
            raise ConfigError("--out", str(out), "its parent folder is not writable")
        self.staging = parent / f".{self.out.name}.partial-{os.getpid()}"
        shutil.rmtree(self.staging, ignore_errors=True)
        self.staging.mkdir()

    def path(self, name: str) -> Path:
        """Where to write ``name`` while staging."""
        return self.staging / name

    def write_result(self, result: RunResult) -> None:
        """Config, metrics, log, obstacles and plots."""
        cfg = result.config
        (self.staging / "config.yaml").write_text(yaml.safe_dump(to_dict(cfg), sort_keys=False))
        (self.staging / "metrics.json").write_text(json.dumps(result.metrics, indent=2, sort_keys=True) + "\n")
        arrays = result.log.arrays
        np.savez_compressed(self.staging / "states.npz", starts=result.starts, goals=result.goals, **arrays)
        obstacles = [to_dict(o) for o in result.obstacles]
        (self.staging / "obstacles.json").write_text(json.dumps(obstacles, indent=1) + "\n")
        if arrays["time_s"].size:
            plot_top_down(self.staging / "top_down.png", result.obstacles, arrays["pos_world"], result.starts, result.goals, cfg.world.arena_size_m, f"{cfg.name} (seed {cfg.seed})")
            plot_min_distance(self.staging / "min_distance.png", arrays["time_s"], arrays["pos_world"], 2 * cfg.physics.quadrotor.robot_radius_m)
            plot_yaw(self.staging / "yaw.png", arrays["time_s"], arrays["yaw"])
            if result.observed is not None:
                m = result.metrics
                plot_observed_area(
                    self.staging / "observed_area.png", result.observed.seen, result.observed.extent(), result.obstacles, arrays["pos_world"],
                    m["observed_area_m2"], m["observed_area_swarm_m2"], cfg.world.arena_size_m, f"{cfg.name} (seed {cfg.seed})",
                )

    def publish(self) -> Path:
        """Move the staged folder to ``out``.

        An old ``out`` is replaced only with ``overwrite`` (which the user
        asked for) or when it is an empty folder. One that appeared, or filled,
        while the run was flying is never deleted: the staged run is renamed
        ``<out>.kept-<pid>`` beside it and :class:`MpcdeError` says so.
        """
        if self.out.exists() or self.out.is_symlink():
            if self.overwrite and self.out.is_dir() and not self.out.is_symlink():
                shutil.rmtree(self.out)
            elif self.out.is_dir() and not self.out.is_symlink() and not any(self.out.iterdir()):
                self.out.rmdir()
            else:
                kept = self.out.with_name(f"{self.out.name}.kept-{os.getpid()}")
                os.replace(self.staging, kept)
                raise MpcdeError(f"--out={str(self.out)!r}: appeared during the run and is not empty, so it was left as it is; the run is in {kept}")
        os.replace(self.staging, self.out)
        return self.out

    def discard(self) -> None:
        """Remove the staging folder (on failure)."""
        shutil.rmtree(self.staging, ignore_errors=True)


@contextmanager
def staged_output(out: Path) -> Iterator[Path]:
    """Stage an evaluation's files and move them into ``out`` only when every one is written.

    The evaluations (``eval-dmpc``, ``eval-tracking``, ``eval-detector``,
    ``eval-mlr``) write into the yielded hidden sibling folder
    ``.<name>.partial-<pid>``. When the block ends normally, an absent or empty
    ``out`` is replaced by it in one rename; into an existing non-empty ``out``
    each staged entry is moved in turn (same names replaced, other files left),
    which those commands have always allowed. When the block raises (a failed
    flight, Ctrl-C), the staging folder is removed and ``out`` is not touched:
    nothing half-written.

    Args:
        out: the output folder (created if absent; its parent too).

    Yields:
        The staging folder to write into.
    """
    out = Path(out)
    parent = out.resolve().parent
    parent.mkdir(parents=True, exist_ok=True)
    staging = parent / f".{out.name}.partial-{os.getpid()}"
    shutil.rmtree(staging, ignore_errors=True)
    staging.mkdir()
    try:
        yield staging
    except BaseException:
        shutil.rmtree(staging, ignore_errors=True)
        raise
    if not out.exists() or (out.is_dir() and not any(out.iterdir())):
        if out.exists():
            out.rmdir()
        os.replace(staging, out)
        return
    for entry in sorted(staging.iterdir()):
        target = out / entry.name
        if target.is_dir() and not target.is_symlink():
            shutil.rmtree(target)
        elif target.exists() or target.is_symlink():
            target.unlink()
        os.replace(entry, target)
    staging.rmdir()
