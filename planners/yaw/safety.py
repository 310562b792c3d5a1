"""Safety metric, switching threshold and replanning trigger of MP-CDE Sec. IV-A (Eq. 1-2, Alg. 1).

The safe point P_s is the furthest sample of the current trajectory such that
it and every earlier sample lie in voxels the camera verified free; the safe
time tau_s is its look-ahead offset. For tau in [0, tau_s] the safety margin is

    S(tau) = min(d_free(P(tau)) / v_max, tau_s - tau)                 (Eq. 1)

with d_free the distance to the nearest voxel that is not verified free
(:meth:`perception.types.OccupancySnapshot.free_distance`). The mode switch
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

from perception.types import OccupancySnapshot
from planners.yaw.config import YawPlannerConfig
from planners.yaw.types import SafetyMargin, TrajectoryView

__all__ = ["needs_replan", "safe_regime", "safety_margin"]


def safety_margin(
    snapshot: OccupancySnapshot, trajectory: TrajectoryView, time_s: float, config: YawPlannerConfig
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
    """
    dt = config.safety_sample_s
    k = int(math.floor(config.safety_horizon_s / dt + 1e-9)) + 1
    taus = np.arange(k) * dt
    points = trajectory.positions(time_s + taus)
    free = snapshot.is_verified_free(points)
    n_free = k if bool(np.all(free)) else int(np.argmin(free))  # samples up to (excluding) the first not-free one
    if n_free == 0:  # the drone's own voxel is not verified free: no safe look-ahead at all
        return SafetyMargin(float(time_s), taus[:1], np.zeros(1), 0.0, points[0].copy(), False)
    tau_s = float(taus[n_free - 1])
    d_free = snapshot.free_distance(points[:n_free])
    margins = np.minimum(d_free / config.v_max_mps, tau_s - taus[:n_free])  # Eq. 1
    return SafetyMargin(float(time_s), taus[:n_free], margins, tau_s, points[n_free - 1].copy(), n_free == k)


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
