"""Helpers for flight tests that compare and total the per-agent metrics (``metrics.json`` ``agents``)."""

from __future__ import annotations

from mpcde.sweep.store import without_wall_clock  # noqa: F401  (the metrics less wall-clock figures; re-exported for the flight tests)


def agent_total(metrics: dict, key: str) -> int:
    """``key`` summed over the agents."""
    return sum(a[key] for a in metrics["agents"])
