"""Where the DMPC QP's own limits let the drone be: reach boxes, and the half-spaces they imply.

Used to cull static-obstacle rows that no feasible plan can touch (see
:meth:`planners.dmpc.qp.DmpcProblem._fill_obstacles`). Every bound here holds
for EVERY input sequence that meets the QP's box constraints (per axis
|v[k]| <= v_max_mps at the samples k = 1..K, |u| <= a_max_mps2 for the double
integrator, |a[k]| <= a_max_mps2 and |j| <= j_max_mps3 for the triple one), so a
half-space that contains a whole reach box at step k is implied there by
those constraints and adding it changes neither the feasible set nor the
solution.

With t_k = k h, per axis, two boxes contain p[k]:

* velocity box, around p0. Under the zero-order hold the velocity is linear
  (double) or quadratic (triple) between samples, so
  p[k] - p[k-1] = h (v[k-1] + v[k]) / 2 exactly for the double integrator and
  up to the Simpson term - h^3 j / 12 for the triple one; with v[0] = v0:
      |p[k] - p0| <= h (|v0| + v_max_mps) / 2 + (k - 1) h v_max_mps  (+ k h^3 j_max_mps3 / 12);
* input box, around the free response f_k = p0 + t_k v0 (+ t_k^2 a0 / 2):
      |p[k] - f_k| <= a_max_mps2 t_k^2 / 2  (double)  or  j_max_mps3 t_k^3 / 6  (triple).

A half-space n^T p >= c contains a box of centre m and half-widths r iff
n^T m - sum_d |n_d| r_d >= c (the minimum of n^T p over the box).
"""

from __future__ import annotations

import numpy as np

from planners.dmpc.config import DmpcConfig

__all__ = ["ReachBox", "implied_half_spaces", "reach_boxes"]

ReachBox = tuple[np.ndarray, np.ndarray]  # (centre (K, 3), half-widths (K, 3)) [m]


def reach_boxes(config: DmpcConfig, x0: np.ndarray) -> list[ReachBox]:
    """The velocity box and the input box of p[1..K] (module docstring) from state ``x0``.

    Args:
        config: the QP's settings (model, K, h, limits).
        x0: (6,) ``[p, v]`` or (9,) ``[p, v, a]`` initial state [m, m/s, m/s^2].

    Returns:
        Two (centre (K, 3), half-widths (K, 3)) pairs [m].
    """
    K, h = config.horizon_steps, config.step_s
    x0 = np.asarray(x0, float)
    k = np.arange(1, K + 1, dtype=float)[:, None]
    t = k * h
    p0, v0 = x0[:3], x0[3:6]
    # |p[k] - p0| <= h (|v0| + v_max_mps) / 2 + (k - 1) h v_max_mps  (sum of trapezoids)
    half_v = h * (np.abs(v0)[None] + config.limits.v_max_mps) / 2 + (k - 1) * h * config.limits.v_max_mps
    if config.model == "double":
        centre_a = p0[None] + t * v0[None]
        half_a = np.broadcast_to(config.limits.a_max_mps2 * t**2 / 2, (K, 3))  # |p[k] - f_k| <= a_max_mps2 t_k^2 / 2
    else:
        half_v = half_v + k * h**3 * config.limits.j_max_mps3 / 12  # Simpson term of each step
        centre_a = p0[None] + t * v0[None] + t**2 * x0[6:9][None] / 2
        half_a = np.broadcast_to(config.limits.j_max_mps3 * t**3 / 6, (K, 3))  # |p[k] - f_k| <= j_max_mps3 t_k^3 / 6
    return [(np.broadcast_to(p0, (K, 3)), half_v), (centre_a, half_a)]


def implied_half_spaces(
    normals: np.ndarray, offsets: np.ndarray, boxes: list[ReachBox], margin_m: float
) -> np.ndarray:
    """Which half-spaces n^T p[k] >= c hold with ``margin_m`` to spare on a whole reach box.

    Args:
        normals: (O, K, 3) plane normals n (any length).
        offsets: (O, K) offsets c [m] (-inf = no plane).
        boxes: reach boxes from :func:`reach_boxes`; implied if it holds on any of them.
        margin_m: required spare n^T p - c >= margin [m].

    Returns:
        (O, K) bool, True where the row is implied (may be left out).
    """
    implied = np.zeros(np.shape(offsets), bool)
    for centre, half in boxes:
        lowest = np.einsum("okd,kd->ok", normals, centre) - np.einsum("okd,kd->ok", np.abs(normals), half)
        implied |= lowest >= offsets + margin_m  # min over the box of n^T p
    return implied
