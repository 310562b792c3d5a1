"""Vertical separating planes between a DMPC plan and the known static obstacles.

The on-demand DMPC paper (design goal 4) keeps each drone a safety radius
r_obs from every obstacle. For each step k of the previous plan the nearest
point of each obstacle's footprint gives a vertical plane
n_k^T p[k] >= n_k^T c_k + r_robot + margin (the tangent plane at the nearest
point, pushed out by the inflation), for the ``max_planes`` nearest obstacles.
How the QP uses them is :mod:`planners.dmpc.obstacle`.
"""

from __future__ import annotations

import math
from typing import Sequence

import numpy as np

from sim.types import ObstacleSpec

__all__ = ["obstacle_half_spaces"]


def obstacle_half_spaces(
    path_world: np.ndarray, obstacles: Sequence[ObstacleSpec], inflation_m: float, range_m: float, max_planes: int
) -> list[tuple[np.ndarray, np.ndarray]]:
    """Time-varying vertical half-spaces keeping a path clear of static obstacles.

    For each obstacle and each step k, with q_k the point of the obstacle's
    footprint nearest to ``path_world[k]`` and n_k the horizontal unit vector
    from q_k to the path point: n_k^T p[k] >= n_k^T q_k + inflation_m. The
    obstacle is convex, so this plane separates the whole footprint (grown by
    ``inflation_m``) from the free side. A path point inside the footprint uses
    the direction from the centre (trees) or of least penetration (boxes).

    Args:
        path_world: (K, 3) the drone's previous plan at the round's steps [m].
        obstacles: the known static obstacles.
        inflation_m: robot radius + margin [m].
        range_m: only obstacles with a footprint within this of the path [m].
        max_planes: at most this many obstacles, nearest first.

    Returns:
        Up to ``max_planes`` pairs ``(normal (K, 3), offset (K,))`` meaning
        normal[k]^T p[k] >= offset[k].
    """
    path_xy = np.asarray(path_world, float)[:, :2]
    candidates = []
    for ob in obstacles:
        c = np.asarray(ob.center_xy, float)
        if ob.kind == "tree":
            rel = path_xy - c
            dist_c = np.linalg.norm(rel, axis=1)
            n = np.where(dist_c[:, None] > 1e-9, rel / np.maximum(dist_c, 1e-9)[:, None], np.array([1.0, 0.0]))
            near = c + ob.radius_m * n  # nearest footprint point (or the exit point when inside)
            gap = dist_c - ob.radius_m
        else:
            cos, sin = math.cos(ob.yaw), math.sin(ob.yaw)
            R = np.array([[cos, -sin], [sin, cos]])  # box -> world
            local = (path_xy - c) @ R  # rows: R^T (p - c)
            he = np.asarray(ob.half_extents_xy, float)
            clamped = np.clip(local, -he, he)
            outside = np.any(np.abs(local) > he, axis=1)
            d_local = local - clamped
            gap_out = np.linalg.norm(d_local, axis=1)
            # inside: push out through the nearest face
            pen = he - np.abs(local)  # (K, 2) distance to the faces
            axis = np.argmin(pen, axis=1)
            n_in = np.zeros_like(local)
            n_in[np.arange(len(local)), axis] = np.where(local[np.arange(len(local)), axis] >= 0, 1.0, -1.0)
            face = local.copy()
            face[np.arange(len(local)), axis] = n_in[np.arange(len(local)), axis] * he[axis]
            n_local = np.where(outside[:, None], d_local / np.maximum(gap_out, 1e-9)[:, None], n_in)
            near_local = np.where(outside[:, None], clamped, face)
            n = n_local @ R.T
            near = c + near_local @ R.T
            gap = np.where(outside, gap_out, -pen[np.arange(len(local)), axis])
        if gap.min() < range_m:
            candidates.append((float(gap.min()), n, near))
    candidates.sort(key=lambda x: x[0])
    planes = []
    for _, n, near in candidates[:max_planes]:
        normal = np.c_[n, np.zeros(len(n))]  # vertical plane
        offset = np.einsum("kd,kd->k", n, near) + inflation_m  # n_k^T q_k + inflation
        planes.append((normal, offset))
    return planes

