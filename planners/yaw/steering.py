"""Target yaws of the observing and tracking modes and the rate-limited steering towards them.

* Observing (MP-CDE Eq. 6): the distance-weighted mean bearing to the
  recently seen neighbours, weights lambda_q = 1 / (d_q + eps). Eq. 6 as
  printed averages the arctan2 values themselves; that fails across the
  +-pi cut (bearings of +179 deg and -179 deg average to 0 deg, the opposite
  direction). Here the bearings are averaged as a weighted sum of unit
  vectors (the weighted circular mean), whose direction is Eq. 6's intent
  and agrees with it whenever the bearings do not straddle the cut.
* Tracking: the direction of the trajectory's horizontal velocity.

Both compute a target per lattice layer (the neighbours and the drone move),
and :func:`rate_limited` turns the targets into a continuous yaw sequence
that starts at the current yaw and changes by at most yaw_rate_max t_y per
step, always turning the shorter way round.
"""

from __future__ import annotations

from typing import Sequence

import numpy as np

from perception.types import NeighborPrediction
from planners.yaw.visibility import wrap_angle

__all__ = ["mean_bearing", "observe_targets", "rate_limited", "sweep_offsets", "track_targets"]


def mean_bearing(observer_world: np.ndarray, targets_world: np.ndarray, distance_eps_m: float) -> float | None:
    """Weighted circular mean of the bearings from ``observer_world`` (3,) to ``targets_world`` (Q, 3) [m].

    Weights 1 / (d + eps) with d the 3-D distance [m] (MP-CDE Eq. 6). Returns
    the mean bearing in [-pi, pi] [rad], or None when it is undefined (no
    targets, or the weighted unit vectors cancel, e.g. two equally near
    neighbours on opposite sides).
    """
    rel = np.asarray(targets_world, float).reshape(-1, 3) - np.asarray(observer_world, float).reshape(3)
    if rel.shape[0] == 0:
        return None
    d = np.linalg.norm(rel, axis=1)
    d_h = np.hypot(rel[:, 0], rel[:, 1])
    lam = 1.0 / (d + distance_eps_m)  # lambda_q of Eq. 6
    ok = d_h > 1e-9  # a neighbour straight above or below has no bearing
    sx = float(np.sum(lam[ok] * rel[ok, 0] / d_h[ok]))
    sy = float(np.sum(lam[ok] * rel[ok, 1] / d_h[ok]))
    if np.hypot(sx, sy) <= 1e-9 * max(float(np.sum(lam)), 1e-300):
        return None
    return float(np.arctan2(sy, sx))


def observe_targets(
    positions_world: np.ndarray,
    times_s: np.ndarray,
    predictions: Sequence[NeighborPrediction],
    distance_eps_m: float,
    fallback_yaw: float,
) -> np.ndarray:
    """(n,) observing-mode target yaws [rad] at layers with drone positions (n, 3) [m] and times (n,) [s].

    Each is :func:`mean_bearing` to the predicted neighbour positions at that
    layer's time; where it is undefined the previous layer's target is kept
    (``fallback_yaw`` before the first).
    """
    n = len(times_s)
    neighbours = np.stack([q.position(times_s) for q in predictions], axis=1)  # (n, Q, 3)
    out = np.empty(n)
    prev = float(fallback_yaw)
    for i in range(n):
        b = mean_bearing(positions_world[i], neighbours[i], distance_eps_m)
        prev = prev if b is None else b
        out[i] = prev
    return out


def track_targets(velocities_world: np.ndarray, still_speed_mps: float, fallback_yaw: float) -> np.ndarray:
    """(n,) tracking-mode target yaws [rad]: the heading of the horizontal velocity (n, 3) [m/s].

    Where the horizontal speed is below ``still_speed_mps`` the previous
    target is kept (``fallback_yaw``, the current yaw, before the first).
    """
    v = np.asarray(velocities_world, float).reshape(-1, 3)
    heading = np.arctan2(v[:, 1], v[:, 0])
    moving = np.hypot(v[:, 0], v[:, 1]) >= still_speed_mps
    out = np.empty(len(v))
    prev = float(fallback_yaw)
    for i in range(len(v)):
        prev = float(heading[i]) if moving[i] else prev
        out[i] = prev
    return out


def sweep_offsets(times_s: np.ndarray, amplitude_rad: float, period_s: float) -> np.ndarray:
    """(n,) yaw offsets [rad] of the tracking-mode swing at absolute ``times_s`` (n,) [s].

    A triangle wave of amplitude ``amplitude_rad`` and period ``period_s``:
    ``A (2 / pi) asin(sin(2 pi t / P))``, zero at t = 0 and rising (all zero when A = 0).
    """
    t = np.asarray(times_s, float)
    return amplitude_rad * (2.0 / np.pi) * np.arcsin(np.sin(2.0 * np.pi * t / period_s))


def rate_limited(yaw0: float, targets: np.ndarray, max_step_rad: float) -> np.ndarray:
    """(n + 1,) yaws [rad] from ``yaw0`` towards ``targets`` (n,), each step within ``+-max_step_rad``.

    Step i moves by ``clip(wrap(target_i - yaw_{i-1}), -max_step, max_step)``:
    the shorter way round, unwrapped, so the sequence is continuous from yaw0.
    """
    out = np.empty(len(targets) + 1)
    out[0] = yaw0
    for i, target in enumerate(targets):
        err = float(wrap_angle(target - out[i]))
        out[i + 1] = out[i] + min(max(err, -max_step_rad), max_step_rad)
    return out
