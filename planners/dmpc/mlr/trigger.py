"""The distributed event trigger of MLR-DMPC (DMPC-Swarm Sec. 4.2.2, Eq. 11, Appendix A).

Each CU w computes an 8-bit priority J_{i,w}(k) for every UAV i and sends it
with its round-k message; in round k + 1 every CU unifies the priorities it
received by the maximum (Eq. 11), with the zero rule of Appendix A (zero if
any CU sent zero: that CU has just recomputed i), sorts the UAVs and keeps the
top M as A_ET(k + 1); CU w then computes the UAV at rank ((k + 1) + w) mod M.

Priorities (Appendix A), k the round, k_calc the round in which the
trajectory i follows was computed, p_i(T | (k-1)T) its position at the start
of round k from that trajectory:

* RR (A1): J = k - k_calc,
* DB (A2): J = ||p_target - p_i||,
* HT (A3): J = ||p_target - p_i|| (k - k_calc).

Quantisation (chosen; the paper only says 8-bit unsigned): J_q = clip(round(J
/ scale), 1, 255), so that 0 is reserved for "just recomputed" and a UAV at
its target still has priority 1. Ties are broken by the lower UAV id.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from planners.dmpc.mlr.config import TRIGGERS

__all__ = ["consensus", "event_set", "quantize", "raw_priorities", "selected_uav"]


def raw_priorities(kind: str, round_index: int, calc_rounds: np.ndarray, distances_m: np.ndarray) -> np.ndarray:
    """J_{i,w}(k) before quantisation (Appendix A, A1-A3) -> (N,).

    Args:
        kind: ``"rr"``, ``"db"`` or ``"ht"``.
        round_index: k.
        calc_rounds: (N,) k_calc of the (first) trajectory in each tracker.
        distances_m: (N,) ||p_target - p_i|| [m].
    """
    age = float(round_index) - np.asarray(calc_rounds, float)
    dist = np.asarray(distances_m, float)
    if kind == "rr":
        return age  # A1
    if kind == "db":
        return dist  # A2
    if kind == "ht":
        return dist * age  # A3
    raise ValueError(f"kind={kind!r}: one of {', '.join(TRIGGERS)}")


def quantize(raw: np.ndarray, scale: float) -> np.ndarray:
    """8-bit priorities clip(round(raw / scale), 1, 255) -> (N,) uint8 (0 is reserved, see module)."""
    return np.clip(np.round(np.asarray(raw, float) / scale), 1, 255).astype(np.uint8)


def consensus(vectors: Sequence[np.ndarray], n_uavs: int) -> np.ndarray:
    """J_i(k) = max_w J_{i,w}(k - 1), zero if any is zero (Eq. 11 with Appendix A) -> (N,) uint8.

    With no vector at all (every CU message lost) every priority is 0.
    """
    if not vectors:
        return np.zeros(n_uavs, np.uint8)
    stack = np.vstack([np.asarray(v, np.uint8) for v in vectors])
    return np.where(np.any(stack == 0, axis=0), 0, stack.max(axis=0)).astype(np.uint8)


def event_set(priorities: np.ndarray, n_cus: int) -> tuple[int, ...]:
    """A_ET: the M UAVs of highest unified priority, highest first, ties to the lower id."""
    order = np.argsort(-np.asarray(priorities, int), kind="stable")
    return tuple(int(i) for i in order[:n_cus])


def selected_uav(a_et: Sequence[int], round_index: int, cu_index: int, n_cus: int) -> int:
    """The UAV CU w computes: A_ET at rank ((k + w) mod M) (Sec. 4.2.2)."""
    return int(a_et[(int(round_index) + int(cu_index)) % int(n_cus)])
