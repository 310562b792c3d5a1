"""A sweep store as the paper's reports read it: the folder, each row's place in its sweep, the yaw mode shares.

The reports read a store as `mpcde report` does (:class:`mpcde.sweep.store.ResultsStore`: a last line cut short by
a crash is left out, so a sweep still running can be reported). What this module adds is the refusal, in one line
(:class:`~mpcde.errors.ConfigError`), of what `mpcde sweep` does not write: a packed kept store, a row whose cell
or seed is not one of its sweep's, a drone's mode shares outside [0, 1].
"""

from __future__ import annotations

import errno
import math
from pathlib import Path

from mpcde.errors import ConfigError
from mpcde.sweep.store import MANIFEST, RESULTS, ResultsStore

__all__ = ["MODES", "check_mode_fraction", "check_place", "is_finite", "read_store"]

MODES = ("exploring", "observing", "tracking")
"""MP-CDE's yaw modes (Alg. 1), the keys of a drone's ``yaw_mode_fraction``."""


def read_store(folder: Path | str) -> ResultsStore:
    """The sweep store in ``folder``.

    Raises:
        FileNotFoundError: it holds no sweep.json, or no results.jsonl yet (no flight recorded: a report of what
            is not flown yet leaves it out).
        ConfigError: it is corrupt, or holds only a kept store's packed results.jsonl.gz (one line).
    """
    folder = Path(folder)
    for name in (MANIFEST, RESULTS):
        if not (folder / name).is_file():
            if name == RESULTS and (folder / (RESULTS + ".gz")).is_file():
                raise ConfigError(f"store {folder}", RESULTS + ".gz", "an unpacked results.jsonl: gunzip it first (docs/results/stores/README.md)")
            raise FileNotFoundError(errno.ENOENT, "not in the store", str(folder / name))
    return ResultsStore.read(folder)


def check_place(r: dict, where: str, n_cells: int, seeds: object) -> None:
    """ConfigError (one line, prefixed ``where``) unless row ``r``'s cell and seed are integers >= 0, its cell one of
    the sweep's ``n_cells`` and its seed one the sweep names (``seeds``, when a list)."""
    for key in ("cell", "seed"):
        if not isinstance(r[key], int) or isinstance(r[key], bool) or r[key] < 0:
            raise ConfigError(f"{where}: {key}", r[key], "an integer >= 0")
    if r["cell"] >= n_cells:
        raise ConfigError(f"{where}: cell", r["cell"], f"a cell of the sweep, < {n_cells}")
    if isinstance(seeds, list) and r["seed"] not in seeds:
        raise ConfigError(f"{where}: seed", r["seed"], "a seed the sweep names (sweep.seeds)")


def check_mode_fraction(fraction: object, field: str) -> None:
    """ConfigError (one line, naming ``field``) unless a drone's ``yaw_mode_fraction`` is null or a share in [0, 1]
    for each of :data:`MODES`."""
    if fraction is not None and not (isinstance(fraction, dict) and all(is_finite(fraction.get(k)) and 0 <= fraction[k] <= 1 for k in MODES)):
        raise ConfigError(field, fraction, f"null or a share in [0, 1] for each of {', '.join(MODES)}")


def is_finite(x: object) -> bool:
    """Whether ``x`` is a finite real number (not a bool)."""
    return isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x)
