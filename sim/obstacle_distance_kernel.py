"""Exact point-to-obstacle distances, compiled (numba): the metrics' clearance at every physics tick.

The same geometry as :meth:`sim.obstacles.ObstacleField.distance_numpy` (the
tests' oracle): a tree is a vertical cylinder of radius r and height h on the
ground, a box a yawed box of half extents (a, b) and height h; the distance is
to the nearest surface, negative inside (the largest of the in-plane depths),
and the ground-level / top faces count through dz = max(z - h, 0) + max(-z, 0).
The numpy form builds (n, T) temporaries per call; this loops with none
(benchmarks/bench_sim.py).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

__all__ = ["obstacle_distances"]


@njit(cache=True)
def obstacle_distances(pts, tree_c, tree_r, tree_h, box_c, box_he, box_h, box_cos, box_sin):
    """Distance [m] (n,) from points (n, 3) to the nearest obstacle surface (inf without obstacles)."""
    n = pts.shape[0]
    out = np.full(n, np.inf)
    for i in range(n):
        x, y, z = pts[i, 0], pts[i, 1], pts[i, 2]
        best = np.inf
        for t in range(tree_r.shape[0]):
            radial = math.hypot(x - tree_c[t, 0], y - tree_c[t, 1]) - tree_r[t]
            dz = max(z - tree_h[t], 0.0) + max(-z, 0.0)
            d = radial if (radial < 0 and dz == 0) else math.hypot(max(radial, 0.0), dz)
            best = min(best, d)
        for b in range(box_h.shape[0]):
            dx, dy = x - box_c[b, 0], y - box_c[b, 1]
            qx = abs(box_cos[b] * dx + box_sin[b] * dy) - box_he[b, 0]
            qy = abs(-box_sin[b] * dx + box_cos[b] * dy) - box_he[b, 1]
            dz = max(z - box_h[b], 0.0) + max(-z, 0.0)
            if qx < 0 and qy < 0 and dz == 0:
                d = max(qx, qy)
            else:
                d = math.hypot(math.hypot(max(qx, 0.0), max(qy, 0.0)), dz)
            best = min(best, d)
        out[i] = best
    return out
