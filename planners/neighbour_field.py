"""Tracked neighbours as temporary obstacles for the front-end path search.

MINCO keeps the swarm clearance C_s from each neighbour's prediction at the
same instant (MP-CDE Eq. 16, :mod:`planners.trajectory_cost`), but it refines
the front end's path locally: when that path runs straight through a
neighbour (a head-on encounter, or a neighbour hovering on the line) the swarm
penalty's gradient points back along the path, symmetric about it, and L-BFGS
settles on the line with the clearance violated. The front end therefore sees
each tracked neighbour as an obstacle: the capsule swept by its prediction
from now to ``horizon_s`` ahead, of radius C_s, or 1.2 C_s for a neighbour
unseen for longer than ``t_hold_s`` (MP-CDE Sec. IV-A: "Neighbors that remain
unseen for more than t_hold are treated as dynamic obstacles with an inflated
clearance radius of 1.2 C_s"). The capsules enter only the copy of the
snapshot handed to the path search; the map itself and the ESDF MINCO reads
are unchanged. Distances are Euclidean (the path search's clearance is).
"""

from __future__ import annotations

from typing import Sequence

import numpy as np
from numba import njit

from perception.types import NeighborPrediction, OccupancySnapshot

__all__ = ["capsule_block_numpy", "with_neighbour_capsules"]


def with_neighbour_capsules(
    snapshot: OccupancySnapshot,
    neighbours: Sequence[NeighborPrediction],
    time_s: float,
    horizon_s: float,
    clearance_m: float,
    t_hold_s: float = 0.6,
    unseen_scale: float = 1.2,
    reach_m: float = 1.0,
) -> OccupancySnapshot:
    """A copy of ``snapshot`` whose ``distance_m`` also measures distance to the neighbours' capsules.

    Args:
        snapshot: the drone's map window.
        neighbours: track predictions (``stamp_s``: when each was last seen).
        time_s: now [s].
        horizon_s: length [s] of each capsule along its prediction, >= 0.
        clearance_m: capsule radius C_s [m], > 0.
        t_hold_s: a neighbour unseen for longer than this [s] gets ``unseen_scale`` x the radius.
        unseen_scale: radius factor for such a neighbour [-], >= 1.
        reach_m: distances are written only for voxels within this [m] of a
            capsule's surface (the path search reads the ESDF through its
            clearance threshold, so ``reach_m`` >= that clearance suffices and
            keeps the cost to a small box around each neighbour).

    Returns:
        ``snapshot`` itself if there are no neighbours; else a snapshot with
        ``distance_m = min(distance_m, d_capsule - r)`` (voxel centres, signed:
        negative inside a capsule). ``state`` and ``free_distance_m`` are shared.
    """
    if not horizon_s >= 0.0:
        raise ValueError(f"horizon_s={horizon_s!r}: allowed >= 0")
    if not clearance_m > 0.0:
        raise ValueError(f"clearance_m={clearance_m!r}: allowed > 0")
    if not unseen_scale >= 1.0:
        raise ValueError(f"unseen_scale={unseen_scale!r}: allowed >= 1")
    if not reach_m >= 0.0:
        raise ValueError(f"reach_m={reach_m!r}: allowed >= 0")
    if not neighbours:
        return snapshot
    dist = np.array(snapshot.distance_m, dtype=np.float32)
    shape = np.asarray(dist.shape)
    v, origin = snapshot.voxel_m, snapshot.origin_world
    for nb in neighbours:
        r = clearance_m * (unseen_scale if nb.age_s(time_s) > t_hold_s else 1.0)
        a, b = nb.position(np.array([time_s, time_s + horizon_s]))
        reach = r + reach_m
        lo = np.clip(np.floor((np.minimum(a, b) - reach - origin) / v).astype(int), 0, shape)
        hi = np.clip(np.ceil((np.maximum(a, b) + reach - origin) / v).astype(int) + 1, 0, shape)
        if np.any(hi <= lo):
            continue  # the capsule lies outside the window
        _capsule_block(dist, origin, v, lo, hi, a, b - a, max(float((b - a) @ (b - a)), 1e-12), r, reach_m)
    return snapshot.with_distance(dist)



@njit(cache=True)
def _capsule_block(dist, origin, v, lo, hi, a, ab, ab2, r, reach_m):  # pragma: no cover - compiled
    """``dist[box] = min(dist[box], d)`` over the voxel box ``lo:hi`` (3,) of one capsule; :func:`capsule_block_numpy` is the reference.

    ``d`` is the distance [m] from each voxel centre to the segment ``a + s ab``,
    ``s`` in [0, 1], less the radius ``r``, or inf beyond ``reach_m``; ``ab2`` is
    ``max(ab . ab, 1e-12)``. Written in place, in float32 as the map's ESDF.
    """
    for i in range(lo[0], hi[0]):
        x = origin[0] + v * (i + 0.5)
        px = x - a[0]
        for j in range(lo[1], hi[1]):
            y = origin[1] + v * (j + 0.5)
            py = y - a[1]
            for k in range(lo[2], hi[2]):
                z = origin[2] + v * (k + 0.5)
                pz = z - a[2]
                s = (px * ab[0] + py * ab[1] + pz * ab[2]) / ab2
                s = min(max(s, 0.0), 1.0)
                qx = x - (a[0] + s * ab[0])
                qy = y - (a[1] + s * ab[1])
                qz = z - (a[2] + s * ab[2])
                d = np.sqrt(qx * qx + qy * qy + qz * qz) - r
                if d <= reach_m:
                    d32 = np.float32(d)
                    if d32 < dist[i, j, k]:
                        dist[i, j, k] = d32


def capsule_block_numpy(dist: np.ndarray, origin: np.ndarray, v: float, lo: np.ndarray, hi: np.ndarray,
                        a: np.ndarray, b: np.ndarray, r: float, reach_m: float) -> None:
    """Vectorised numpy reference of the compiled capsule kernel (the tests compare them to the bit): the capsule
    a-b (3,) [m] of radius ``r`` into ``dist`` (float32, in place) over the voxel box ``lo:hi``.

    The front end once computed this with ``(P - a) @ ab``, a BLAS product whose rounding differs from
    the explicit sum here in the last float64 bit of ``s`` on a third of the voxels; after the float32 cast about
    one value in 10^9 differs (more often at the ``reach_m`` cut, where one side writes and the other does not)."""
    axes = [origin[k] + v * (np.arange(lo[k], hi[k]) + 0.5) for k in range(3)]
    X, Y, Z = np.meshgrid(*axes, indexing="ij")
    P = np.stack([X, Y, Z], axis=-1)
    ab = b - a
    Q = P - a
    # (P - a) . ab as an explicit sum: a matmul goes through BLAS, whose summation order (and FMA use)
    # depends on the machine; the kernel's is this one
    s = np.clip((Q[..., 0] * ab[0] + Q[..., 1] * ab[1] + Q[..., 2] * ab[2]) / max(float(ab @ ab), 1e-12), 0.0, 1.0)
    d = np.linalg.norm(P - (a + s[..., None] * ab), axis=-1) - r
    d[d > reach_m] = np.inf
    block = dist[lo[0] : hi[0], lo[1] : hi[1], lo[2] : hi[2]]
    np.minimum(block, d.astype(np.float32), out=block)
