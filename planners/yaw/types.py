"""Types of the yaw planner: what it reads about the own trajectory and what it returns.

* :class:`TrajectoryView`: the drone's current trajectory as two callables and
  an end time, so the caller can wrap its MINCO trajectory (or anything else).
* :class:`SafetyMargin`: the safe point, safe time and safety margin of
  MP-CDE Eq. 1.
* :class:`YawPlan`: the planned yaw sequence, the mode that produced it and
  what the caller needs for Alg. 1 line 13's replanning trigger.

Frames: world (z up, DESIGN.md section 2); yaw is the heading of the body x
axis about world z, counter-clockwise from world x [rad].
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import numpy as np

__all__ = ["MODES", "SafetyMargin", "TrajectoryView", "YawPlan"]

MODES = ("tracking", "exploring", "observing")
"""The values of :attr:`YawPlan.mode`: the three modes of MP-CDE Alg. 1."""


@dataclass(frozen=True)
class TrajectoryView:
    """The drone's current trajectory, read-only.

    Attributes:
        position_at: callable, absolute times (n,) [s] -> positions (n, 3) in world [m].
        velocity_at: callable, absolute times (n,) [s] -> velocities (n, 3) in world [m/s].
        end_time_s: absolute end time of the trajectory [s]; after it the drone
            holds the end position. The planner never asks the callables for a
            time after ``end_time_s`` (it clamps), so they need to be valid only
            up to it.
    """

    position_at: Callable[[np.ndarray], np.ndarray]
    velocity_at: Callable[[np.ndarray], np.ndarray]
    end_time_s: float

    def positions(self, times_s: np.ndarray) -> np.ndarray:
        """Positions (n, 3) [m] at absolute times (n,) [s], holding the end position after ``end_time_s``."""
        t = np.minimum(np.asarray(times_s, float).reshape(-1), self.end_time_s)
        return np.asarray(self.position_at(t), float).reshape(-1, 3)

    def velocities(self, times_s: np.ndarray) -> np.ndarray:
        """Velocities (n, 3) [m/s] at absolute times (n,) [s]; zero after ``end_time_s``."""
        t = np.asarray(times_s, float).reshape(-1)
        v = np.asarray(self.velocity_at(np.minimum(t, self.end_time_s)), float).reshape(-1, 3)
        return np.where((t > self.end_time_s)[:, None], 0.0, v)

    @staticmethod
    def hover(pos_world: np.ndarray) -> "TrajectoryView":
        """A drone holding ``pos_world`` (3,) [m] (no trajectory yet, or at its goal)."""
        p = np.asarray(pos_world, float).reshape(3).copy()
        return TrajectoryView(
            position_at=lambda t: np.broadcast_to(p, (np.size(t), 3)).copy(),
            velocity_at=lambda t: np.zeros((np.size(t), 3)),
            end_time_s=-np.inf,
        )


@dataclass(frozen=True)
class SafetyMargin:
    """The safety metric of MP-CDE Eq. 1 along the current trajectory.

    Attributes:
        time_s: absolute time of the evaluation (tau = 0) [s].
        taus_s: (k,) look-ahead offsets tau of the samples in [0, tau_s] [s];
            k >= 1 (tau = 0 is always present).
        margins_s: (k,) S(tau) = min(d_free(P(tau)) / v_max, tau_s - tau) [s].
        safe_time_s: tau_s, offset of the safe point [s]: the furthest sample
            such that it and every sample before it lie in verified free
            voxels; 0 when the drone's own voxel is not verified free. At most
            the configured ``safety_horizon_s``.
        safe_point_world: (3,) P_s = P(tau_s) [m].
        horizon_reached: True when every sample up to the sampling horizon was
            verified free, i.e. tau_s is the horizon, not the edge of free space.
    """

    time_s: float
    taus_s: np.ndarray
    margins_s: np.ndarray
    safe_time_s: float
    safe_point_world: np.ndarray
    horizon_reached: bool

    @property
    def margin_now_s(self) -> float:
        """S(0) [s]: the value Alg. 1 compares with tau_thr (mode switch, line 4, and replan trigger, line 13)."""
        return float(self.margins_s[0])


@dataclass(frozen=True)
class YawPlan:
    """A planned yaw sequence (MP-CDE Alg. 1).

    Attributes:
        mode: ``"tracking"``, ``"exploring"`` or ``"observing"`` (Alg. 1).
        times_s: (n + 1,) absolute times [s]: now, now + t_y, ..., now + n t_y.
        yaws: (n + 1,) yaw [rad] at ``times_s``, unwrapped (continuous) from
            ``yaws[0]``, the current yaw as given; consecutive values differ by
            at most yaw_rate_max * t_y.
        safety_margin_s: S(0) of Eq. 1 [s].
        safe_time_s: tau_s of Eq. 1 [s].
        tau_thr_s: the switching threshold of Eq. 2 [s].
        min_neighbour_distance_m: smallest Euclidean distance [m] from the
            drone's position now to the predicted positions now of all
            neighbours handed in (the set A); ``inf`` without neighbours.
        n_recent: |V|, neighbours seen within t_hold [-].
        n_active: |A|, neighbours handed in [-].

    Alg. 1 line 13's replanning trigger is
    ``needs_replan(plan.safety_margin_s, plan.tau_thr_s, plan.min_neighbour_distance_m, C_s)``
    (:func:`planners.yaw.safety.needs_replan`).
    """

    mode: str
    times_s: np.ndarray
    yaws: np.ndarray
    safety_margin_s: float
    safe_time_s: float
    tau_thr_s: float
    min_neighbour_distance_m: float
    n_recent: int
    n_active: int

    def __post_init__(self) -> None:
        if self.mode not in MODES:
            raise ValueError(f"YawPlan.mode={self.mode!r}: allowed one of {MODES}")
        n = np.shape(self.times_s)[0]
        if n < 2 or np.shape(self.yaws) != (n,):
            raise ValueError("YawPlan: times_s (n + 1,) and yaws (n + 1,) with n >= 1")

    def yaw_at(self, t: float) -> tuple[float, float]:
        """Yaw [rad] and yaw rate [rad/s] at absolute time ``t`` [s].

        Piecewise linear between the samples; before ``times_s[0]`` and after
        ``times_s[-1]`` the end value is held with zero rate.
        """
        ts, ys = self.times_s, self.yaws
        if t <= ts[0]:
            return float(ys[0]), 0.0 if t < ts[0] else float((ys[1] - ys[0]) / (ts[1] - ts[0]))
        if t >= ts[-1]:
            return float(ys[-1]), 0.0
        i = int(np.searchsorted(ts, t, side="right")) - 1
        rate = (ys[i + 1] - ys[i]) / (ts[i + 1] - ts[i])
        return float(ys[i] + rate * (t - ts[i])), float(rate)
