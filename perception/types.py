"""Types that leave perception/ (frozen dataclasses).

:class:`NeighborPrediction` is the one type the planners consume about other
drones (DESIGN.md section 4, planners). It comes from either source:

* a received radio plan: samples of the neighbour's planned trajectory, exact
  (zero covariance), with the message's age;
* a perception track: a single sample (the filter's posterior at its last
  update ``t_k``) extrapolated at constant velocity, MP-CDE Eq. 12::

      p(t) = p_k + v_k (t - t_k),   P(t) = F(t - t_k) P_k F(t - t_k)^T

so the same planners run on either.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol, runtime_checkable

import numpy as np

__all__ = ["Detection", "DistanceField", "NeighborPrediction"]


@dataclass(frozen=True)
class Detection:
    """One detected drone in one image.

    Attributes:
        box_xyxy: (4,) box corners ``[u_min, v_min, u_max, v_max]`` in [px].
        score: detector confidence in [0, 1].
    """

    box_xyxy: np.ndarray
    score: float


@runtime_checkable
class DistanceField(Protocol):
    """Anything the planners can ask for obstacle clearance (an ESDF, an analytic field).

    ``distance_and_gradient(points_world)`` takes (n, 3) points in world [m]
    and returns the signed distance to the nearest obstacle (n,) in [m]
    (negative inside) and its gradient (n, 3) with respect to the points.
    """

    def distance_and_gradient(self, points_world: np.ndarray) -> tuple[np.ndarray, np.ndarray]: ...


@dataclass(frozen=True)
class NeighborPrediction:
    """Predicted position of one neighbour as a function of absolute time.

    Attributes:
        neighbor_id: the neighbour's identity (drone index for radio plans,
            track id for perception tracks).
        source: ``"radio"`` or ``"perception"``.
        stamp_s: time [s] of the information (message send time, or the track's
            last measurement time ``t_k``).
        times_s: (K,) increasing absolute sample times [s], K >= 1.
        pos_world: (K, 3) positions [m] at ``times_s``.
        vel_world: (K, 3) velocities [m/s] at ``times_s``.
        cov_world: (6, 6) covariance of ``[p, v]`` at ``times_s[-1]`` in
            [m^2, m^2/s, m^2/s^2]; zeros for an exact radio plan.

    Between samples the position is the cubic Hermite interpolant of
    (pos, vel); outside ``[times_s[0], times_s[-1]]`` it is extrapolated at
    constant velocity from the nearest sample (MP-CDE Eq. 12 for K = 1).
    """

    neighbor_id: int
    source: str
    stamp_s: float
    times_s: np.ndarray
    pos_world: np.ndarray
    vel_world: np.ndarray
    cov_world: np.ndarray

    def __post_init__(self) -> None:
        if self.source not in ("radio", "perception"):
            raise ValueError(f"NeighborPrediction.source={self.source!r}: allowed 'radio' or 'perception'")
        k = np.shape(self.times_s)[0]
        if k < 1 or np.shape(self.pos_world) != (k, 3) or np.shape(self.vel_world) != (k, 3):
            raise ValueError("NeighborPrediction: times_s (K,), pos_world (K, 3), vel_world (K, 3) with K >= 1")
        if np.shape(self.cov_world) != (6, 6):
            raise ValueError("NeighborPrediction.cov_world must be (6, 6)")

    @staticmethod
    def constant_velocity(
        neighbor_id: int, source: str, t_k: float, pos_world: np.ndarray, vel_world: np.ndarray, cov_world: np.ndarray
    ) -> "NeighborPrediction":
        """A single-sample prediction (a track's posterior at ``t_k``), MP-CDE Eq. 12."""
        return NeighborPrediction(
            neighbor_id=int(neighbor_id),
            source=source,
            stamp_s=float(t_k),
            times_s=np.array([float(t_k)]),
            pos_world=np.asarray(pos_world, float).reshape(1, 3),
            vel_world=np.asarray(vel_world, float).reshape(1, 3),
            cov_world=np.asarray(cov_world, float).reshape(6, 6),
        )

    def age_s(self, t_now: float) -> float:
        """Age [s] of the information at ``t_now`` [s]."""
        return float(t_now) - self.stamp_s

    def position(self, t: np.ndarray | float) -> np.ndarray:
        """Predicted position [m] at absolute times ``t`` (n,) -> (n, 3) (scalar -> (3,))."""
        scalar = np.ndim(t) == 0
        t = np.atleast_1d(np.asarray(t, float))
        ts, p, v = self.times_s, self.pos_world, self.vel_world
        out = np.empty((t.size, 3))
        lo = t <= ts[0]
        hi = t >= ts[-1]
        out[lo] = p[0] + v[0] * (t[lo] - ts[0])[:, None]
        out[hi] = p[-1] + v[-1] * (t[hi] - ts[-1])[:, None]
        mid = ~(lo | hi)
        if np.any(mid):
            i = np.clip(np.searchsorted(ts, t[mid]) - 1, 0, ts.size - 2)
            h = (ts[i + 1] - ts[i])[:, None]
            s = (t[mid] - ts[i])[:, None] / h
            h00, h10 = 2 * s**3 - 3 * s**2 + 1, s**3 - 2 * s**2 + s
            h01, h11 = -2 * s**3 + 3 * s**2, s**3 - s**2
            out[mid] = h00 * p[i] + h10 * h * v[i] + h01 * p[i + 1] + h11 * h * v[i + 1]
        return out[0] if scalar else out

    def position_cov(self, t: np.ndarray | float) -> np.ndarray:
        """Position covariance (n, 3, 3) [m^2] at times ``t`` (n,).

        Beyond the last sample: the position block of F P F^T with
        F = [[I, dt I], [0, I]] (MP-CDE Eq. 12); before it, the block of P.
        """
        t = np.atleast_1d(np.asarray(t, float))
        dt = np.maximum(t - self.times_s[-1], 0.0)[:, None, None]
        P = self.cov_world
        Ppp, Ppv, Pvv = P[:3, :3], P[:3, 3:], P[3:, 3:]
        # P_pos(t) = Ppp + dt (Ppv + Ppv^T) + dt^2 Pvv
        return Ppp + dt * (Ppv + Ppv.T) + dt**2 * Pvv

    def uncertainty_radius(self, t: np.ndarray | float, n_sigma: float = 1.0) -> np.ndarray:
        """Conservative radius [m] ``n_sigma * sqrt(trace P_pos(t))`` at times ``t`` (n,) -> (n,)."""
        cov = self.position_cov(t)
        return n_sigma * np.sqrt(np.maximum(np.trace(cov, axis1=1, axis2=2), 0.0))
