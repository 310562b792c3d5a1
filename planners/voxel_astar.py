"""The front end's 26-connected A* on a voxel grid, compiled (numba): a binary heap, the octile heuristic, the search.

:func:`astar` is the search that :func:`planners.path_search.search_path` runs
on an occupancy window flattened in row-major order; that module's docstring
states the step costs, the heuristic ``h = voxel_m (d1 + (sqrt 2 - 1) d2 +
(sqrt 3 - sqrt 2) d3)`` with its tie-break factor ``1 + 1e-3``, and the escape
rule out of the clearance band. The heap lives in two growing arrays (keys
and voxel indices); a voxel is closed when it is first popped.
"""

from __future__ import annotations

import numpy as np
from numba import njit

__all__ = ["astar"]

_SQRT2 = float(np.sqrt(2.0))
_SQRT3 = float(np.sqrt(3.0))
_TIE_BREAK = 1.0 + 1e-3


@njit(cache=True)
def _heap_push(keys, vals, size, key, val):
    """Push (key, val) on a binary min-heap stored in ``keys``/``vals``; returns the new size."""
    i = size
    keys[i] = key
    vals[i] = val
    while i > 0:
        p = (i - 1) >> 1
        if keys[p] <= keys[i]:
            break
        keys[p], keys[i] = keys[i], keys[p]
        vals[p], vals[i] = vals[i], vals[p]
        i = p
    return size + 1


@njit(cache=True)
def _heap_pop(keys, vals, size):
    """Pop the minimum; returns (val, new size)."""
    top = vals[0]
    size -= 1
    keys[0] = keys[size]
    vals[0] = vals[size]
    i = 0
    while True:
        left = 2 * i + 1
        if left >= size:
            break
        c = left
        if left + 1 < size and keys[left + 1] < keys[left]:
            c = left + 1
        if keys[i] <= keys[c]:
            break
        keys[c], keys[i] = keys[i], keys[c]
        vals[c], vals[i] = vals[i], vals[c]
        i = c
    return top, size


@njit(cache=True)
def _octile(ix, iy, iz, gx, gy, gz):
    """Exact 26-connected grid distance [voxels] on an empty grid."""
    a = abs(ix - gx)
    b = abs(iy - gy)
    c = abs(iz - gz)
    if a < b:
        a, b = b, a
    if b < c:
        b, c = c, b
    if a < b:
        a, b = b, a
    return a + (_SQRT2 - 1.0) * b + (_SQRT3 - _SQRT2) * c


@njit(cache=True)
def astar(unknown, dist, ok, hard_ok, shape, start, goal, voxel_m, unknown_penalty, h_weight, max_expansions):
    """26-connected A*; returns (cells (n, 3), cumulative costs (n,) [m], expanded, code 0 ok / 1 none / 2 limit,
    closed (nx * ny * nz,) uint8: 1 for the voxels expanded, with code 1 every voxel reachable from ``start``).

    ``unknown``, ``dist`` [m], ``ok`` and ``hard_ok`` are (nx * ny * nz,) per voxel in row-major order (unknown,
    ESDF value, traversable, within the hard limits); ``shape`` (3,), ``start`` and ``goal`` (3,) are int64 voxel
    indices; ``voxel_m`` [m], ``unknown_penalty`` and ``h_weight`` [-] and ``max_expansions`` are those of
    :class:`planners.path_search.PathSearchConfig`.
    """
    nx, ny, nz = shape[0], shape[1], shape[2]
    n = nx * ny * nz
    g = np.full(n, np.inf)
    parent = np.full(n, -1, np.int64)
    closed = np.zeros(n, np.uint8)
    cap = 1024
    keys = np.empty(cap)
    vals = np.empty(cap, np.int64)
    s = (start[0] * ny + start[1]) * nz + start[2]
    t = (goal[0] * ny + goal[1]) * nz + goal[2]
    hw = h_weight * voxel_m * _TIE_BREAK
    g[s] = 0.0
    size = _heap_push(keys, vals, 0, hw * _octile(start[0], start[1], start[2], goal[0], goal[1], goal[2]), s)
    expanded = 0
    code = 1
    while size > 0:
        cur, size = _heap_pop(keys, vals, size)
        if closed[cur]:
            continue
        closed[cur] = 1
        if cur == t:
            code = 0
            break
        expanded += 1
        if expanded > max_expansions:
            code = 2
            break
        cx = cur // (ny * nz)
        cy = (cur // nz) % ny
        cz = cur % nz
        cur_ok = ok[cur]
        for dx in range(-1, 2):
            x = cx + dx
            if x < 0 or x >= nx:
                continue
            for dy in range(-1, 2):
                y = cy + dy
                if y < 0 or y >= ny:
                    continue
                for dz in range(-1, 2):
                    z = cz + dz
                    if z < 0 or z >= nz or (dx == 0 and dy == 0 and dz == 0):
                        continue
                    nb = (x * ny + y) * nz + z
                    if closed[nb]:
                        continue
                    if not ok[nb]:
                        # escape rule: climb strictly out of the clearance band, never along it
                        if cur_ok or not hard_ok[nb] or not dist[nb] > dist[cur]:
                            continue
                    m = abs(dx) + abs(dy) + abs(dz)
                    step = voxel_m if m == 1 else (voxel_m * _SQRT2 if m == 2 else voxel_m * _SQRT3)
                    if unknown[nb]:
                        step *= 1.0 + unknown_penalty
                    g_new = g[cur] + step
                    if g_new < g[nb]:
                        g[nb] = g_new
                        parent[nb] = cur
                        if size >= cap:
                            cap *= 2
                            keys2 = np.empty(cap)
                            vals2 = np.empty(cap, np.int64)
                            keys2[:size] = keys[:size]
                            vals2[:size] = vals[:size]
                            keys, vals = keys2, vals2
                        size = _heap_push(keys, vals, size, g_new + hw * _octile(x, y, z, goal[0], goal[1], goal[2]), nb)
    if code != 0:
        return np.empty((0, 3), np.int64), np.empty(0), expanded, code, closed
    count = 1
    c = t
    while c != s:
        c = parent[c]
        count += 1
    cells = np.empty((count, 3), np.int64)
    costs = np.empty(count)
    c = t
    for k in range(count - 1, -1, -1):
        cells[k, 0] = c // (ny * nz)
        cells[k, 1] = (c // nz) % ny
        cells[k, 2] = c % nz
        costs[k] = g[c]
        c = parent[c]
    return cells, costs, expanded, 0, closed
