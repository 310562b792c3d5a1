"""Safety metric, switching threshold and replanning trigger of MP-CDE Sec. IV-A (Eq. 1-2, Alg. 1).

The safe point P_s is the furthest sample of the current trajectory such that
it and every earlier sample lie in voxels the camera verified free (and, with
a finite :attr:`YawPlannerConfig.free_max_age_s`, saw within that time: the
"temporally validated" segment); the safe time tau_s is its look-ahead offset.
For tau in [0, tau_s] the safety margin is

    S(tau) = min(d_free(P(tau)) / v_max, tau_s - tau)                 (Eq. 1)

with d_free the distance to the nearest voxel that is not verified free. How
that distance is measured is :attr:`YawPlannerConfig.free_distance` (the
paper does not say):

* ``"horizontal"`` (default): in the horizontal plane, within the slab of
  +-``free_slab_half_height_m`` about the sample's altitude (a column cell of
  the slab is free if all its voxels are verified free; the outside of the
  window is not free, as in the map's own field). The drone flies level and
  brakes horizontally; measured in 3-D, the ground 1.5 m below and the
  unobserved space just above and below the camera's 58 deg vertical field
  of view cap d_free near 1.5 m, so S(0) = d_free / v_max could never
  exceed tau_thr = 1.2 pi / 2 = 1.88 s at v_max = 1 m/s and the planner would
  never leave the tracking mode (measured: docs/results/yaw_planner.md#free_distance-horizontal).
* ``"occupied"``: in the same slab, the distance to the nearest occupied
  cell (unknown space counts as free): the paper's literal wording, "the
  Euclidean signed-distance (ESDF) value of the map".
* ``"voxel"``: the map's 3-D verified-free distance
  (:meth:`perception.types.OccupancySnapshot.free_distance`).

The mode switch
reads S at the current time, tau = 0 (the paper writes S(tau) > tau_thr; the
margin that matters for the decision taken now is the one of the state the
drone is in now), against

    tau_thr = eps pi / yaw_rate_max                                   (Eq. 2)

(:attr:`YawPlannerConfig.tau_thr_s`, a half turn of the camera with slack eps)

with hysteresis: the exploring/observing regime is entered when
S(0) > tau_thr + hysteresis and left when S(0) < tau_thr (:func:`safe_regime`).
"""

from __future__ import annotations

import math

import numpy as np
from scipy.ndimage import distance_transform_edt

from perception.types import OccupancySnapshot
from planners.yaw.config import YawPlannerConfig
from planners.yaw.types import SafetyMargin, TrajectoryView

__all__ = ["horizontal_free_distance", "needs_replan", "safe_regime", "safety_margin"]


def horizontal_free_distance(
    snapshot: OccupancySnapshot, points_world: np.ndarray, half_height_m: float, occupied_only: bool = False
) -> np.ndarray:
    """Horizontal distance (n,) [m] from ``points_world`` (n, 3) to the nearest not-verified-free column cell.

    For each distinct slab of voxel layers within +-``half_height_m`` of a
    point's altitude, a column cell is free if every voxel of the slab above it
    is verified free; the 2-D Euclidean distance transform of the other cells
    (the outside of the window counts as not free) is read bilinearly at the
    point, centre-to-face like the map's own field (``- voxel / 2``, floored at 0).

    ``occupied_only``: the distance to the nearest column cell with an
    occupied voxel in the slab instead (unknown cells and the outside of the
    window count as free; ``inf`` when the slab holds no occupied voxel): the
    map's obstacle distance, MP-CDE's literal "ESDF value of the map".
    """
    p = np.asarray(points_world, float).reshape(-1, 3)
    v, o = snapshot.voxel_m, snapshot.origin_world
    nx, ny, nz = snapshot.shape
    k_lo = np.clip(np.floor((p[:, 2] - half_height_m - o[2]) / v).astype(np.int64), 0, nz)
    k_hi = np.clip(np.floor((p[:, 2] + half_height_m - o[2]) / v).astype(np.int64) + 1, 0, nz)
    out = np.zeros(p.shape[0])
    for lo, hi in set(zip(k_lo.tolist(), k_hi.tolist())):
        sel = (k_lo == lo) & (k_hi == hi)
        if hi <= lo:
            continue  # the slab lies above or below the window: nothing there is verified free
        if occupied_only:
            free2d = ~np.any(snapshot.state[:, :, lo:hi] == OccupancySnapshot.OCCUPIED, axis=2)
            if bool(np.all(free2d)):
                out[sel] = np.inf
                continue
        else:
            free2d = np.all(snapshot.state[:, :, lo:hi] == OccupancySnapshot.FREE, axis=2)
        not_free = np.pad(~free2d, 1, constant_values=not occupied_only)
        d = distance_transform_edt(~not_free)[1:-1, 1:-1] * v - 0.5 * v
        d = np.where(free2d, np.maximum(d, 0.0), 0.0)
        out[sel] = _bilinear(d, o[:2], v, p[sel, :2])
    return out


def _bilinear(field: np.ndarray, origin_xy: np.ndarray, voxel_m: float, points_xy: np.ndarray) -> np.ndarray:
    """Bilinear value (n,) of ``field`` (nx, ny) sampled at cell centres, clamped at the window's edge."""
    c = np.clip((points_xy - origin_xy) / voxel_m - 0.5, 0.0, np.asarray(field.shape) - 1.0)
    i0 = np.minimum(np.floor(c).astype(np.int64), np.asarray(field.shape) - 2)
    f = c - i0
    i, j = i0[:, 0], i0[:, 1]
    fx, fy = f[:, 0], f[:, 1]
    return (field[i, j] * (1 - fx) * (1 - fy) + field[i + 1, j] * fx * (1 - fy)
            + field[i, j + 1] * (1 - fx) * fy + field[i + 1, j + 1] * fx * fy)


def safety_margin(
    snapshot: OccupancySnapshot, trajectory: TrajectoryView, time_s: float, config: YawPlannerConfig,
    profile: bool = True,
) -> SafetyMargin:
    """Safe point, safe time and safety margin S(tau) along ``trajectory`` from ``time_s`` (MP-CDE Eq. 1).

    The trajectory is sampled every ``config.safety_sample_s`` over
    ``[time_s, time_s + config.safety_horizon_s]``; after its end the drone
    holds the end position, so a trajectory that ends (or a hover) inside
    verified free space is safe up to the horizon. tau_s is therefore exact to
    one sample and at most the horizon; capping it there does not change the
    mode, which only compares S(0) <= tau_s with tau_thr < horizon.

    Args:
        snapshot: the drone's map window.
        trajectory: the drone's current trajectory.
        time_s: now, absolute [s] (tau = 0).
        config: planner settings (``v_max_mps``, ``safety_sample_s``, ``safety_horizon_s``).
        profile: S(tau) at every sample in [0, tau_s] (True); False returns
            S(0) alone (``taus_s`` and ``margins_s`` of length 1), the only
            value Alg. 1 reads. tau_s is found the same way either way, so
            S(0) is identical; the samples' d_free, each slab a distance
            transform, are the cost saved (the planner passes False).
    """
    dt = config.safety_sample_s
    k = int(math.floor(config.safety_horizon_s / dt + 1e-9)) + 1
    taus = np.arange(k) * dt
    points = trajectory.positions(time_s + taus)
    free = snapshot.is_verified_free(points, config.free_max_age_s)
    n_free = k if bool(np.all(free)) else int(np.argmin(free))  # samples up to (excluding) the first not-free one
    if n_free == 0:  # the drone's own voxel is not verified free: no safe look-ahead at all
        return SafetyMargin(float(time_s), taus[:1], np.zeros(1), 0.0, points[0].copy(), False)
    tau_s = float(taus[n_free - 1])
    n_eval = n_free if profile else 1
    if config.free_distance == "voxel":
        d_free = snapshot.free_distance(points[:n_eval])
    else:
        d_free = horizontal_free_distance(snapshot, points[:n_eval], config.free_slab_half_height_m,
                                          occupied_only=config.free_distance == "occupied")
    margins = np.minimum(d_free / config.v_max_mps, tau_s - taus[:n_eval])  # Eq. 1
    return SafetyMargin(float(time_s), taus[:n_eval], margins, tau_s, points[n_free - 1].copy(), n_free == k)


def safe_regime(previous: bool, margin_s: float, tau_thr_s: float, hysteresis_s: float) -> bool:
    """Whether the planner is in the exploring/observing regime after this evaluation (Alg. 1 line 4).

    Enter when ``margin_s > tau_thr_s + hysteresis_s``, leave when
    ``margin_s < tau_thr_s``, keep ``previous`` in between (all [s]).
    """
    if margin_s > tau_thr_s + hysteresis_s:
        return True
    if margin_s < tau_thr_s:
        return False
    return previous


def needs_replan(
    safety_margin_s: float, tau_thr_s: float, min_neighbour_distance_m: float, swarm_clearance_m: float
) -> bool:
    """MP-CDE Alg. 1 line 13: replan when ``S(0) < tau_thr`` or ``min_q d_q(0) < C_s``.

    Args:
        safety_margin_s: S(0) [s] (:attr:`YawPlan.safety_margin_s`).
        tau_thr_s: tau_thr [s] (:attr:`YawPlan.tau_thr_s`).
        min_neighbour_distance_m: distance [m] to the nearest predicted
            neighbour now (:attr:`YawPlan.min_neighbour_distance_m`, ``inf``
            without neighbours); a caller with an ellipsoidal swarm metric may
            pass its own distance.
        swarm_clearance_m: C_s [m] (MP-CDE Table I: 0.7 m).
    """
    return bool(safety_margin_s < tau_thr_s or min_neighbour_distance_m < swarm_clearance_m)
