"""Helpers for flight tests that compare and total the per-agent metrics (``metrics.json`` ``agents``)."""

from __future__ import annotations

WALL_CLOCK = {"wall_time_s", "real_time_factor", "compute_time"}


def without_wall_clock(metrics: dict) -> dict:
    """The metrics less wall-clock figures (run time, and the agents' times in ms)."""
    out = {k: v for k, v in metrics.items() if k not in WALL_CLOCK}
    out["agents"] = [{k: v for k, v in a.items() if "_ms" not in k} for a in metrics["agents"]]
    return out


def agent_total(metrics: dict, key: str) -> int:
    """``key`` summed over the agents."""
    return sum(a[key] for a in metrics["agents"])
