"""A sweep file: one base scenario, the axes to vary, the seeds, and what to keep of each flight.

    base: forest_swarm            # a built-in scenario, or a YAML path (relative to this file)
    seeds: 20                     # seeds 0..19; every cell flies every seed
                                  # or {first: 1000, count: 50}: seeds 1000..1049 (a held-out split)
    overrides:                    # optional: dotted scenario fields set in every cell
      duration_s: 30
    axes:                         # dotted scenario fields and their values; the cells are the product
      planner.kind: [mpcde, dmpc, auto]
      planner.cruise_speed_mps: [0.5, 1.0, 2.0]
      radio.jamming_windows_s: [[], [[3, 15]]]
    keep:                         # optional: metrics are always kept
      run_folders: false          # each flight's run folder under runs/
      videos: false               # with run_folders: video.mp4 in each

A cell is one combination of axis values (product order, the last axis
varying fastest). Every cell flies the same seeds, and a seed fixes the
scenario's whole draw (obstacles, noise, radio faults), so two cells' flights
of one seed are paired: they differ only in the cell's values, as ``mpcde
compare``'s modes do. The file is read by the strict reader and checked
before anything is written: every cell must load as a scenario
(:func:`mpcde.config.scenario.scenario_from_dict`), each refusal one line
naming the field (``axes.planner.kind[1]``).
"""

from __future__ import annotations

import hashlib
import itertools
import json
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from mpcde.config.scenario import SCENARIO_DIR, ScenarioConfig, scenario_from_dict
from mpcde.config.yaml_reader import read_yaml
from mpcde.errors import ConfigError

__all__ = ["Cell", "SweepSpec", "cell_label", "load_sweep", "set_dotted", "sweep_from_dict"]

MAX_SEEDS = 100_000
MAX_CELLS = 10_000
MAX_VALUES = 1_000
_KEYS = {"base", "seeds", "overrides", "axes", "keep"}
_KEEP = {"run_folders", "videos"}
_SEED_KEYS = {"first", "count"}


def cell_label(values: dict[str, Any]) -> str:
    """``planner.kind="mpcde", planner.cruise_speed_mps=0.5`` (``base`` for no values: a sweep without axes)."""
    return ", ".join(f"{k}={json.dumps(v)}" for k, v in values.items()) or "base"


@dataclass(frozen=True)
class Cell:
    """One combination of axis values: ``index`` in product order, ``values`` {dotted field: value}."""

    index: int
    values: dict[str, Any]

    @property
    def label(self) -> str:
        """:func:`cell_label` of its values."""
        return cell_label(self.values)


@dataclass(frozen=True)
class SweepSpec:
    """A checked sweep.

    Attributes:
        base: the base scenario's mapping (as read from its file), name set.
        base_name: the ``base`` entry as written.
        seeds: the seeds every cell flies (a file's ``seeds: N`` is 0 .. N-1).
        overrides: {dotted field: value} set in every cell.
        axes: ((dotted field, (values...)), ...) in file order.
        keep_run_folders, keep_videos: what to keep besides the metrics.
    """

    base: dict[str, Any]
    base_name: str
    seeds: tuple[int, ...]
    overrides: dict[str, Any]
    axes: tuple[tuple[str, tuple[Any, ...]], ...]
    keep_run_folders: bool = False
    keep_videos: bool = False

    def cells(self) -> list[Cell]:
        """Every cell, in product order."""
        names = [name for name, _ in self.axes]
        combos = itertools.product(*(values for _, values in self.axes))
        return [Cell(i, dict(zip(names, combo))) for i, combo in enumerate(combos)]

    def scenario(self, cell: Cell, seed: int) -> ScenarioConfig:
        """The checked scenario of ``cell`` flown with ``seed`` (ConfigError names the cell's field)."""
        data = json.loads(json.dumps(self.base))  # a deep copy of plain data
        for name, value in {**self.overrides, **cell.values, "seed": seed}.items():
            set_dotted(data, name, value)
        return scenario_from_dict(data)

    def to_dict(self) -> dict[str, Any]:
        """The sweep as plain data (what :attr:`digest` hashes; the store keeps it)."""
        return {
            "base": self.base, "base_name": self.base_name, "seeds": list(self.seeds), "overrides": self.overrides,
            "axes": [[name, list(values)] for name, values in self.axes],
            "keep": {"run_folders": self.keep_run_folders, "videos": self.keep_videos},
        }  # fmt: skip

    @property
    def digest(self) -> str:
        """SHA-256 of the sweep's content (the base scenario's fields included): a store belongs to one digest."""
        return hashlib.sha256(json.dumps(self.to_dict(), sort_keys=True).encode()).hexdigest()


def set_dotted(data: dict[str, Any], name: str, value: Any) -> None:
    """Set ``a.b.c`` in nested mapping ``data`` (creating sections), replacing what was there."""
    keys = name.split(".")
    node = data
    for k in keys[:-1]:
        if not isinstance(node.get(k), dict):
            node[k] = {}
        node = node[k]
    node[keys[-1]] = value


def load_sweep(path: str | Path, check_cells: bool = True) -> SweepSpec:
    """Read and check a sweep file (ConfigError names the field; nothing is written).

    ``check_cells`` False reads the file as a record, its keys, axes and seeds checked but its cells not loaded as
    scenarios: a kept store's file may name a cell that today's load rules refuse (``held_out_ring7.yaml``'s flight
    levels, refused since the ground-clearance rule that those flights found); flying one checks every cell.
    """
    p = Path(path)
    data = read_yaml(p, field="sweep")
    if not isinstance(data, dict):
        raise ConfigError("sweep", str(p), "a YAML mapping with base, seeds and axes")
    return sweep_from_dict(data, p.parent, check_cells)


def sweep_from_dict(data: dict[str, Any], folder: Path = Path("."), check_cells: bool = True) -> SweepSpec:
    """Check a sweep mapping; a ``base`` path is relative to ``folder`` (``check_cells``: :func:`load_sweep`)."""
    unknown = sorted(set(data) - _KEYS, key=str)
    if unknown:
        raise ConfigError(str(unknown[0]), data[unknown[0]], f"unknown key; allowed keys: {', '.join(sorted(_KEYS))}")
    base_name = data.get("base")
    if not isinstance(base_name, str) or not base_name:
        raise ConfigError("base", base_name, "a built-in scenario name or a YAML path")
    base = _read_base(base_name, folder)
    seeds = _seeds(data.get("seeds"))
    overrides = _mapping(data.get("overrides"), "overrides")
    axes_in = _mapping(data.get("axes"), "axes")
    axes = []
    for name, values in axes_in.items():
        if not isinstance(values, list) or not 1 <= len(values) <= MAX_VALUES:
            raise ConfigError(f"axes.{name}", values, f"a list of 1 to {MAX_VALUES} values")
        if len({json.dumps(v, sort_keys=True) for v in values}) != len(values):
            raise ConfigError(f"axes.{name}", values, "each value at most once")
        axes.append((name, tuple(values)))
    for name in list(overrides) + list(axes_in):
        if name == "seed":
            raise ConfigError(f"axes.{name}" if name in axes_in else f"overrides.{name}", None, "the sweep's seeds set it: use seeds")
        if name in overrides and name in axes_in:
            raise ConfigError(f"axes.{name}", axes_in[name], "set in overrides too: keep one")
    keep = _mapping(data.get("keep"), "keep")
    for k, v in keep.items():
        if k not in _KEEP:
            raise ConfigError(f"keep.{k}", v, f"unknown key; allowed keys: {', '.join(sorted(_KEEP))}")
        if not isinstance(v, bool):
            raise ConfigError(f"keep.{k}", v, "true or false")
    if keep.get("videos") and not keep.get("run_folders"):
        raise ConfigError("keep.videos", True, "needs keep.run_folders: true (the video is written into the run folder)")
    spec = SweepSpec(base, base_name, seeds, overrides, tuple(axes), bool(keep.get("run_folders")), bool(keep.get("videos")))
    cells = 1
    for _, values in spec.axes:
        cells *= len(values)
    if cells > MAX_CELLS:
        raise ConfigError("axes", f"{cells} cells", f"at most {MAX_CELLS} cells (the product of the axes' lengths)")
    for cell in spec.cells() if check_cells else ():  # every cell must be a valid scenario before anything flies
        try:
            spec.scenario(cell, 0)
        except ConfigError as e:
            field = next((n for n in cell.values if _names(e.field, n)), None)
            if field is not None:
                i = [v for n, v in spec.axes if n == field][0].index(cell.values[field])
                raise ConfigError(f"axes.{field}[{i}]", cell.values[field], f"{e.allowed} (cell {cell.label})") from None
            raise ConfigError(e.field, e.value, f"{e.allowed} (cell {cell.label})") from None
    return spec


def _seeds(value: Any) -> tuple[int, ...]:
    """``N`` (seeds 0 .. N-1) or ``{first: F, count: N}`` (seeds F .. F+N-1, a split disjoint from 0 .. F-1)."""
    if isinstance(value, dict):
        unknown = sorted(set(value) - _SEED_KEYS, key=str)
        if unknown:
            raise ConfigError(f"seeds.{unknown[0]}", value[unknown[0]], "unknown key; allowed keys: count, first")
        first, count = value.get("first"), value.get("count")
        if isinstance(first, bool) or not isinstance(first, int) or not 0 <= first <= 2**31 - MAX_SEEDS:
            raise ConfigError("seeds.first", first, f"an integer in [0, {2**31 - MAX_SEEDS}]")
        if isinstance(count, bool) or not isinstance(count, int) or not 1 <= count <= MAX_SEEDS:
            raise ConfigError("seeds.count", count, f"an integer in [1, {MAX_SEEDS}]")
        return tuple(range(first, first + count))
    if isinstance(value, bool) or not isinstance(value, int) or not 1 <= value <= MAX_SEEDS:
        raise ConfigError("seeds", value, f"an integer in [1, {MAX_SEEDS}] (seeds 0..N-1) or {{first: F, count: N}}")
    return tuple(range(value))


def _names(error_field: str, axis: str) -> bool:
    """Whether an error about ``error_field`` is about the axis field ``axis`` (the field, inside it, or its section)."""
    return error_field == axis or error_field.startswith((axis + ".", axis + "[")) or axis.startswith(error_field + ".")


def _mapping(value: Any, name: str) -> dict[str, Any]:
    if value is None:
        return {}
    if not isinstance(value, dict):
        raise ConfigError(name, value, "a mapping of dotted scenario fields")
    return value


def _read_base(name: str, folder: Path) -> dict[str, Any]:
    path = Path(name) if Path(name).is_absolute() else folder / name
    if not path.is_file() and (SCENARIO_DIR / f"{name}.yaml").is_file():
        path = SCENARIO_DIR / f"{name}.yaml"
    if not path.is_file():
        builtins = ", ".join(sorted(q.stem for q in SCENARIO_DIR.glob("*.yaml")))
        raise ConfigError("base", name, f"no such scenario file; built-in scenarios: {builtins}")
    data = read_yaml(path, field="base")
    if not isinstance(data, dict):
        raise ConfigError("base", name, "a scenario file (a YAML mapping of fields)")
    data.setdefault("name", path.stem)
    return data
