"""A sweep's results on disk: one JSON line per finished flight, appended the moment it finishes.

``DIR/results.jsonl`` holds one row per flight (keys :data:`ROW_KEYS`: the
cell, its values, the seed, ``status`` ``"ok"`` or ``"failed"`` with the
error, every metric of ``metrics.json``, wall time, package version and git
revision). pandas reads it with ``pandas.read_json(path, lines=True)``,
DuckDB with ``SELECT * FROM read_json_auto('DIR/results.jsonl')``. Each row is
one ``write`` of a whole line on a file opened for appending, then fsynced,
so a crash or Ctrl-C loses at most the flights in progress; a last line cut
short by a crash (no newline) is dropped when the store is opened again.
``DIR/sweep.json`` holds the sweep (:meth:`mpcde.sweep.spec.SweepSpec.to_dict`)
and its digest: a folder belongs to one sweep, and resuming with another
sweep file is refused.
"""

from __future__ import annotations

import json
import math
import os
from pathlib import Path
from typing import Any

from mpcde.errors import ConfigError
from mpcde.sweep.spec import SweepSpec

__all__ = ["MANIFEST", "RESULTS", "ROW_KEYS", "WALL_CLOCK_KEYS", "ResultsStore", "flight_row", "json_safe", "without_wall_clock"]

RESULTS = "results.jsonl"
MANIFEST = "sweep.json"
ROW_KEYS = ("cell", "values", "seed", "status", "error", "metrics", "wall_s", "version", "git_rev")
"""Keys of every row (``error`` null and ``metrics`` a dict when ``status`` is ``"ok"``; the reverse when failed)."""


WALL_CLOCK_KEYS = ("real_time_factor", "wall_time_s", "compute_time")
"""Metrics measured on the wall clock (and every key with ``_ms`` in it, the agents' timings): they differ between two flights of one task."""


def without_wall_clock(metrics: Any) -> Any:
    """``metrics`` less its wall-clock entries (:data:`WALL_CLOCK_KEYS`, keys with ``_ms``): what two flights of one task share exactly."""
    if isinstance(metrics, dict):
        return {k: without_wall_clock(v) for k, v in metrics.items() if k not in WALL_CLOCK_KEYS and "_ms" not in k}
    if isinstance(metrics, list):
        return [without_wall_clock(v) for v in metrics]
    return metrics


def flight_row(
    cell: int, values: dict[str, Any], seed: int, outcome: Any, version: str, git_rev: str | None
) -> dict[str, Any]:
    """The row (:data:`ROW_KEYS`) of one flight's :class:`mpcde.sweep.engine.FlightOutcome` in ``cell`` (its ``values``) with ``seed``."""
    return {
        "cell": cell, "values": values, "seed": seed, "status": "ok" if outcome.error is None else "failed",
        "error": outcome.error, "metrics": outcome.metrics, "wall_s": round(outcome.wall_s, 3), "version": version,
        "git_rev": git_rev,
    }  # fmt: skip


def json_safe(value: Any) -> Any:
    """``value`` with every non-finite float replaced by None (strict JSON, which DuckDB reads)."""
    if isinstance(value, float) and not math.isfinite(value):
        return None
    if isinstance(value, dict):
        return {str(k): json_safe(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [json_safe(v) for v in value]
    return value


class ResultsStore:
    """The rows of one sweep folder; :meth:`for_sweep` creates or resumes it, :meth:`read` opens it for a report."""

    def __init__(self, folder: Path, manifest: dict[str, Any]) -> None:
        self.folder = Path(folder)
        self.manifest = manifest
        self.path = self.folder / RESULTS

    @classmethod
    def for_sweep(cls, folder: str | Path, spec: SweepSpec) -> "ResultsStore":
        """The store of ``spec`` in ``folder``: created if absent or empty, resumed if it holds the same sweep."""
        folder = Path(folder)
        if folder.exists() and not folder.is_dir():
            raise ConfigError("--out", str(folder), "exists and is not a folder")
        manifest = {"digest": spec.digest, "sweep": spec.to_dict()}
        if (folder / MANIFEST).exists():
            store = cls.read(folder)
            if store.manifest.get("digest") != spec.digest:
                raise ConfigError("--out", str(folder), "holds the results of a different sweep file: choose another folder")
            store.drop_partial_line()
            return store
        if folder.exists() and any(folder.iterdir()):
            raise ConfigError("--out", str(folder), "exists, is not empty and holds no sweep (no sweep.json): choose another folder")
        try:
            folder.mkdir(parents=True, exist_ok=True)
            tmp = folder / f".{MANIFEST}.tmp"
            tmp.write_text(json.dumps(json_safe(manifest), indent=1, sort_keys=True) + "\n")
            os.replace(tmp, folder / MANIFEST)
        except OSError as e:
            raise ConfigError("--out", str(folder), f"cannot be written ({e.strerror})") from None
        return cls(folder, manifest)

    @classmethod
    def read(cls, folder: str | Path) -> "ResultsStore":
        """An existing store (ConfigError if ``folder`` holds none or its manifest is corrupt)."""
        folder = Path(folder)
        try:
            manifest = json.loads((folder / MANIFEST).read_text())
        except FileNotFoundError:
            raise ConfigError("store", str(folder), f"no {MANIFEST}: not a sweep folder") from None
        except (OSError, ValueError, UnicodeDecodeError):
            raise ConfigError("store", str(folder / MANIFEST), "unreadable or not JSON: the store is corrupt") from None
        if not isinstance(manifest, dict) or not isinstance(manifest.get("sweep"), dict) or "digest" not in manifest:
            raise ConfigError("store", str(folder / MANIFEST), "not a sweep manifest: the store is corrupt")
        return cls(folder, manifest)

    def rows(self) -> list[dict[str, Any]]:
        """Every complete row, in the order written (a last line cut short by a crash is left out)."""
        if not self.path.exists():
            return []
        try:
            text = self.path.read_text()
        except (OSError, UnicodeDecodeError):
            raise ConfigError("store", str(self.path), "unreadable: the store is corrupt") from None
        lines = text.split("\n")
        out = []
        for i, line in enumerate(lines[:-1], start=1):  # the part after the last newline is a partial row, if any
            try:
                row = json.loads(line)
            except ValueError:
                row = None
            if not isinstance(row, dict) or any(k not in row for k in ROW_KEYS):
                raise ConfigError(f"store line {i}", line[:60], f"not a results row: the store {self.path} is corrupt")
            out.append(row)
        return out

    def done(self) -> set[tuple[int, int]]:
        """(cell, seed) of every recorded flight, flown or failed."""
        return {(int(r["cell"]), int(r["seed"])) for r in self.rows()}

    def drop_partial_line(self) -> None:
        """Cut a last line that a crash left without its newline."""
        if not self.path.exists():
            return
        data = self.path.read_bytes()
        end = data.rfind(b"\n") + 1
        if end < len(data):
            with open(self.path, "r+b") as f:
                f.truncate(end)

    def append(self, row: dict[str, Any]) -> None:
        """Write ``row`` as one line, in one write, and make it durable."""
        line = (json.dumps(json_safe(row), sort_keys=True, allow_nan=False) + "\n").encode()
        fd = os.open(self.path, os.O_WRONLY | os.O_APPEND | os.O_CREAT, 0o644)
        try:
            written = 0
            while written < len(line):
                written += os.write(fd, line[written:])
            os.fsync(fd)
        finally:
            os.close(fd)
