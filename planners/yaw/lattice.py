"""The yaw lattice of the exploring mode and its shortest path (MP-CDE Sec. IV-A, Eq. 5).

Nodes: layer i = 0 .. n (time now + i t_y), candidate k = 0 .. m - 1 with yaw
``yaw0 + k 2 pi / m`` (uniform over the circle, anchored at the current yaw
yaw0, so node (0, 0) is the current state and every layer holds the current
yaw). Edges join (i, j) to (i + 1, (j + h) mod m) for hops h = -q .. q with
``q = floor(yaw_rate_max t_y / (2 pi / m))``, i.e. only adjacent layers and
only yaw changes within the rate limit, wrapping around the circle. Along a
path the hops are summed, so the yaw sequence is continuous (unwrapped).

Edge cost (Eq. 5) from (i - 1, j) into (i, k):

    C = -(alpha E + beta V) + (alpha + beta) + turn_penalty |h| / q
      = alpha (1 - E) + beta (1 - V) + turn_penalty |h| / q  >= 0

with E, V in [0, 1]. Dijkstra needs non-negative costs; every path from the
start to the last layer has exactly n edges, so the constant (alpha + beta)
added to every edge adds n (alpha + beta) to every path and keeps the
optimum. The small turn penalty is not in the paper: a tie-breaker so that
the planner holds its yaw when nothing is to be gained.

:func:`shortest_path` is a textbook Dijkstra (binary heap) from node (0, 0)
that stops at the first node of the last layer taken from the heap.
"""

from __future__ import annotations

import heapq
from dataclasses import dataclass
from functools import lru_cache

import numpy as np

__all__ = ["LatticePath", "edge_costs", "shortest_path"]


@dataclass(frozen=True)
class LatticePath:
    """A path through the lattice from node (0, 0).

    Attributes:
        candidates: (n + 1,) candidate index per layer, in [0, m) (0 at layer 0).
        hops: (n,) hop h in [-q, q] per edge; the yaw offset from the current
            yaw at layer i is ``cumsum(hops)[i - 1] * 2 pi / m`` (unwrapped).
        cost: total edge cost of the path [-].
        expanded: nodes taken from the heap [-].
    """

    candidates: np.ndarray
    hops: np.ndarray
    cost: float
    expanded: int


def edge_costs(e: np.ndarray, v: np.ndarray, alpha: float, beta: float, turn_penalty: float) -> np.ndarray:
    """Non-negative edge costs (n, m, 2q + 1) from E (n, m, 2q + 1) and V (n, m), both in [0, 1] (Eq. 5).

    ``cost[i - 1, j, h]`` is the cost of the edge from (i - 1, j) into
    (i, (j + h - q) mod m); E belongs to the edge, V to its head node.
    """
    n, m, w = e.shape
    q = (w - 1) // 2
    k = (np.arange(m)[:, None] + np.arange(-q, q + 1)[None, :]) % m  # (m, 2q + 1) head candidates
    hop = np.abs(np.arange(-q, q + 1)) / max(q, 1)
    # C = -(alpha E + beta V) shifted by (alpha + beta) >= 0, plus the tie-breaking turn penalty
    return alpha * (1.0 - e) + beta * (1.0 - v[:, k]) + turn_penalty * hop


@lru_cache(maxsize=8)
def _heads(m: int, w: int) -> tuple[tuple[int, ...], ...]:
    """Head candidate of every hop slot of every candidate: ``(j + h - q) mod m``."""
    q = (w - 1) // 2
    return tuple(tuple((j + h - q) % m for h in range(w)) for j in range(m))


def shortest_path(cost: np.ndarray) -> LatticePath:
    """Dijkstra from node (0, 0) to the cheapest node of the last layer.

    Args:
        cost: (n, m, 2q + 1) non-negative edge costs; ``cost[i, j, h]`` is the
            edge from (i, j) to (i + 1, (j + h - q) mod m). Edges whose head
            would repeat a candidate (``2q + 1 > m``) are allowed; the cheaper wins.

    Raises:
        ValueError: a cost is negative or not finite.
    """
    cost = np.asarray(cost, float)
    if cost.ndim != 3 or cost.shape[2] % 2 != 1:
        raise ValueError(f"cost shape={cost.shape}: allowed (n, m, 2q + 1)")
    if not np.all(np.isfinite(cost)) or np.any(cost < 0.0):
        raise ValueError("cost: allowed finite values >= 0 (Dijkstra)")
    n, m, w = cost.shape
    q = (w - 1) // 2
    c = cost.ravel().tolist()  # flat list: the edge (i, j, h) is c[(i m + j) w + h]; no numpy scalars in the loop
    heads = _heads(m, w)
    size = (n + 1) * m
    inf = float("inf")
    dist = [inf] * size
    via = [-1] * size  # the edge (flat index into c) by which each node was last improved
    dist[0] = 0.0
    heap = [(0.0, 0)]
    expanded = 0
    last = n * m
    goal = -1
    heappop, heappush = heapq.heappop, heapq.heappush
    while heap:
        d, node = heappop(heap)
        if d > dist[node]:  # stale entry: the node was improved after this push
            continue
        expanded += 1
        if node >= last:  # first node of the last layer off the heap: optimal
            goal = node
            break
        base = node - node % m + m  # first node of the next layer
        edge = node * w
        for h, k in enumerate(heads[node % m]):
            nd = d + c[edge + h]
            nxt = base + k
            if nd < dist[nxt]:
                dist[nxt] = nd
                via[nxt] = edge + h
                heappush(heap, (nd, nxt))
    candidates = np.zeros(n + 1, dtype=np.int64)
    hops = np.zeros(n, dtype=np.int64)
    node = goal
    for i in range(n, 0, -1):
        candidates[i] = node % m
        node, h = divmod(via[node], w)  # the edge's tail node and hop slot
        hops[i - 1] = h - q
    return LatticePath(candidates, hops, float(dist[goal]), expanded)
