"""Visibility metric V of the exploring mode (MP-CDE Eq. 4).

For candidate yaw psi at lattice layer i (time t_i = now + i t_y, drone at
p_i on its trajectory) and the neighbours q of the set handed in (in the
exploring mode: A minus V, those not seen within t_hold, Alg. 1 line 8):

    V(i, psi) = w_i sum_q kappa_q(t_i) P_q(psi, t_i) / (d_q(t_i) + eps)      (Eq. 4)

* the time samples of Eq. 4 are the lattice's own layer times, and each node
  is scored at its own time, so the sum over t in Eq. 4 is the sum of the
  node rewards along a path;
* w_i = 1 - (i - 1) / n, the triangular kernel over the lattice horizon
  (1 at the first step, 1/n at the last): near-term visibility matters most;
* d_q = ||p_q(t_i) - p_i||, the predicted neighbour's distance [m];
* P_q(psi, t_i) is the indicator of Eq. 4 made soft by the track's
  uncertainty: the probability that the neighbour's bearing lies within the
  horizontal field of view, with the bearing Gaussian of standard deviation
  sigma_lat / d (sigma_lat: position standard deviation across the line of
  sight, from ``position_cov``), so centring an uncertain neighbour earns
  more than catching it at the edge of the image; times the hard indicators
  of the vertical field of view (camera level, +-fov_v/2) and of the
  detection range. Occlusion of the neighbour by obstacles is not modelled
  (Eq. 4's indicator is the field of view only);
* kappa_q = min(1 + sigma_q / sigma_ref, kappa_max) with
  sigma_q = sqrt(trace P_pos(t_i)): the inflated covariance of a stale track
  makes re-observing it more valuable (the paper's weight "reflects" the
  covariance; this is the form chosen here).

V is normalised to [0, 1] by its maximum over the lattice (when positive):
1 / (d + eps) has no natural scale of its own, and the best view this plan
can offer is the natural unit.
"""

from __future__ import annotations

from typing import Sequence

import numpy as np
from scipy.special import ndtr

from perception.types import NeighborPrediction
from planners.yaw.config import YawPlannerConfig

__all__ = ["layer_weights", "visibility_rewards", "wrap_angle"]


def wrap_angle(angle: np.ndarray | float) -> np.ndarray | float:
    """Angle(s) wrapped to [-pi, pi) [rad]."""
    return (np.asarray(angle) + np.pi) % (2.0 * np.pi) - np.pi


def layer_weights(n_steps: int) -> np.ndarray:
    """(n,) triangular weights w_i = 1 - (i - 1) / n of layers i = 1 .. n (Eq. 4's kernel)."""
    return 1.0 - np.arange(n_steps) / n_steps


def visibility_rewards(
    positions_world: np.ndarray,
    times_s: np.ndarray,
    candidate_yaws: np.ndarray,
    predictions: Sequence[NeighborPrediction],
    config: YawPlannerConfig,
) -> np.ndarray:
    """Normalised visibility V (n, m) in [0, 1] of every lattice node (MP-CDE Eq. 4).

    Args:
        positions_world: (n, 3) drone positions [m] at layers 1 .. n.
        times_s: (n,) absolute times [s] of layers 1 .. n.
        candidate_yaws: (m,) candidate yaws [rad] (the same at every layer).
        predictions: the neighbours to keep in view (may be empty: V = 0).
        config: ``fov_h_deg``, ``fov_v_deg``, ``detection_range_m``, ``distance_eps_m``,
            ``visibility_sigma_ref_m``, ``visibility_weight_max``.
    """
    n, m = len(times_s), len(candidate_yaws)
    if not predictions:
        return np.zeros((n, m))
    p = np.asarray(positions_world, float).reshape(n, 3)
    rel = np.stack([q.position(times_s) for q in predictions]) - p  # (Q, n, 3)
    cov = np.stack([q.position_cov(times_s) for q in predictions])  # (Q, n, 3, 3)
    d = np.linalg.norm(rel, axis=2)  # (Q, n)
    d_h = np.hypot(rel[..., 0], rel[..., 1])
    bearing = np.arctan2(rel[..., 1], rel[..., 0])
    in_v = np.abs(np.arctan2(rel[..., 2], d_h)) <= 0.5 * config.fov_v_rad
    in_range = d <= config.detection_range_m
    # sigma across the line of sight (horizontal unit normal u = (-sin b, cos b, 0)): u^T P u
    s, c = np.sin(bearing), np.cos(bearing)
    var_lat = s * s * cov[..., 0, 0] - 2.0 * s * c * cov[..., 0, 1] + c * c * cov[..., 1, 1]
    sigma_bearing = np.maximum(np.sqrt(np.maximum(var_lat, 0.0)) / np.maximum(d_h, 1e-6), 1e-6)
    sigma = np.sqrt(np.maximum(np.trace(cov, axis1=2, axis2=3), 0.0))
    kappa = np.minimum(1.0 + sigma / config.visibility_sigma_ref_m, config.visibility_weight_max)
    # P(|bearing - psi| <= fov/2) for bearing ~ N(b, sigma_b^2): (Q, n, m)
    off = wrap_angle(bearing[..., None] - np.asarray(candidate_yaws)[None, None, :])
    half = 0.5 * config.fov_h_rad
    sb = sigma_bearing[..., None]
    p_in = ndtr((half - off) / sb) - ndtr((-half - off) / sb)
    weight = (kappa * in_v * in_range / (d + config.distance_eps_m))[..., None]  # (Q, n, 1)
    v = layer_weights(n)[:, None] * np.sum(weight * p_in, axis=0)  # Eq. 4, (n, m)
    v_max = float(np.max(v))
    return v / v_max if v_max > 0.0 else v
