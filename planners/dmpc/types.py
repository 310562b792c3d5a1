"""Types that leave the DMPC planner: :class:`DmpcPlan` (what a drone broadcasts).

A plan is sender-independent: absolute start time, step and sampled states.
Between samples the position is the cubic Hermite interpolant of (pos, vel),
which is *exact* for both prediction models: a double-integrator piece (constant
acceleration) is a quadratic and a triple-integrator piece (constant jerk) is a
cubic, and a cubic is fixed by its end positions and velocities. This is the
same interpolant as :class:`perception.types.NeighborPrediction`, so
:meth:`DmpcPlan.as_neighbor_prediction` loses nothing.

Tail convention (beyond the last sample): **constant velocity** from the last
sample (zero acceleration). Chosen over "hold the last position with zero
velocity" because (i) it is dynamically consistent for the double integrator
(the tail is the input u = 0, so a shifted plan is a feasible candidate for the
next QP), (ii) it equals NeighborPrediction's extrapolation, so a receiver sees
the same tail either way, and (iii) with ``terminal_halt`` (v[K] = 0) both
conventions coincide.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from perception.types import NeighborPrediction

__all__ = ["DmpcPlan", "freeze_array"]


def freeze_array(
    obj: object, name: str, dtype: type, valid: Callable[[np.ndarray], bool], expected: str, label: str | None = None
) -> np.ndarray:
    """Store field ``name`` of the frozen dataclass ``obj`` as a read-only ``dtype`` array copy, and return it.

    For what the DMPC variants exchange (:mod:`planners.dmpc.admm.types`, :mod:`planners.dmpc.mlr.types`,
    :class:`planners.dmpc.mlr.trajectory.ReferenceTrajectory`): a message, once built, cannot change
    under its receivers. Raises ValueError ``"<label> shape <shape>: expected <expected>"`` when
    ``valid(array)`` is false; ``label`` defaults to ``"<type>.<name>"``.
    """
    arr = np.array(getattr(obj, name), dtype=dtype)
    if not valid(arr):
        label = f"{type(obj).__name__}.{name}" if label is None else label
        raise ValueError(f"{label} shape {arr.shape}: expected {expected}")
    arr.setflags(write=False)
    object.__setattr__(obj, name, arr)
    return arr


@dataclass(frozen=True)
class DmpcPlan:
    """A planned trajectory sampled every ``h_s`` from ``t0_s``.

    Attributes:
        t0_s: absolute time [s] of the first sample (the state the plan starts from).
        h_s: sample step [s].
        pos_world: (K+1, 3) positions [m] at ``t0_s + k h_s``, k = 0..K.
        vel_world: (K+1, 3) velocities [m/s] at the same times.
        acc_world: (K+1, 3) accelerations [m/s^2] at the same times, right
            limits (for the double integrator ``acc_world[k]`` is the input held
            on [t_k, t_k+1) and the last sample is 0, the constant-velocity
            tail; for the triple integrator the samples are the states a[k], and
            :meth:`acceleration` returns 0 from the last sample on, the tail).
    """

    t0_s: float
    h_s: float
    pos_world: np.ndarray
    vel_world: np.ndarray
    acc_world: np.ndarray

    def __post_init__(self) -> None:
        n = np.shape(self.pos_world)[0] if np.ndim(self.pos_world) == 2 else 0
        if n < 2 or any(np.shape(a) != (n, 3) for a in (self.pos_world, self.vel_world, self.acc_world)):
            raise ValueError("DmpcPlan: pos_world, vel_world, acc_world must all be (K+1, 3) with K >= 1")
        if not (np.isfinite(self.h_s) and self.h_s > 0):
            raise ValueError(f"DmpcPlan.h_s={self.h_s!r}: must be > 0")

    @staticmethod
    def hover(t0_s: float, h_s: float, horizon_steps: int, pos_world: np.ndarray) -> "DmpcPlan":
        """A plan that holds ``pos_world`` (3,) [m] for K = ``horizon_steps`` steps."""
        p = np.tile(np.asarray(pos_world, float).reshape(1, 3), (horizon_steps + 1, 1))
        z = np.zeros_like(p)
        return DmpcPlan(float(t0_s), float(h_s), p, z, z.copy())

    @property
    def horizon_steps(self) -> int:
        """K (number of steps, one less than the number of samples)."""
        return self.pos_world.shape[0] - 1

    @property
    def times_s(self) -> np.ndarray:
        """(K+1,) absolute sample times [s]."""
        return self.t0_s + self.h_s * np.arange(self.pos_world.shape[0])

    @property
    def t_end_s(self) -> float:
        """Time [s] of the last sample."""
        return self.t0_s + self.h_s * self.horizon_steps

    def _evaluate(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Position, velocity, acceleration (n, 3) at times ``t`` (n,) [s]."""
        p, v = self.pos_world, self.vel_world
        h, K = self.h_s, self.horizon_steps
        pos, vel, acc = np.empty((t.size, 3)), np.empty((t.size, 3)), np.zeros((t.size, 3))
        tail = t >= self.t_end_s
        before = t < self.t0_s
        # Tail: constant velocity from the last sample (module docstring).
        pos[tail] = p[-1] + v[-1] * (t[tail] - self.t_end_s)[:, None]
        vel[tail] = v[-1]
        # Before the first sample: constant velocity backwards (like NeighborPrediction).
        pos[before] = p[0] + v[0] * (t[before] - self.t0_s)[:, None]
        vel[before] = v[0]
        mid = ~(tail | before)
        if np.any(mid):
            u = (t[mid] - self.t0_s) / h
            # Right limit at a sample time: round u up to an integer within 1e-9 before flooring.
            i = np.clip(np.floor(u + 1e-9).astype(int), 0, K - 1)
            s = np.clip(u - i, 0.0, 1.0)[:, None]
            p0, p1, v0, v1 = p[i], p[i + 1], v[i], v[i + 1]
            # Cubic Hermite: p(s) = h00 p0 + h10 h v0 + h01 p1 + h11 h v1, s in [0, 1)
            pos[mid] = (2 * s**3 - 3 * s**2 + 1) * p0 + (s**3 - 2 * s**2 + s) * h * v0
            pos[mid] += (-2 * s**3 + 3 * s**2) * p1 + (s**3 - s**2) * h * v1
            vel[mid] = ((6 * s**2 - 6 * s) * p0 + (6 * s**2 - 6 * s) * -p1) / h
            vel[mid] += (3 * s**2 - 4 * s + 1) * v0 + (3 * s**2 - 2 * s) * v1
            acc[mid] = ((12 * s - 6) * (p0 - p1)) / h**2 + ((6 * s - 4) * v0 + (6 * s - 2) * v1) / h
        return pos, vel, acc

    def position(self, t: np.ndarray | float) -> np.ndarray:
        """Planned position [m] at absolute times ``t`` (n,) -> (n, 3) (scalar -> (3,))."""
        scalar = np.ndim(t) == 0
        pos = self._evaluate(np.atleast_1d(np.asarray(t, float)))[0]
        return pos[0] if scalar else pos

    def velocity(self, t: np.ndarray | float) -> np.ndarray:
        """Planned velocity [m/s] at times ``t`` (n,) -> (n, 3) (scalar -> (3,))."""
        scalar = np.ndim(t) == 0
        vel = self._evaluate(np.atleast_1d(np.asarray(t, float)))[1]
        return vel[0] if scalar else vel

    def acceleration(self, t: np.ndarray | float) -> np.ndarray:
        """Planned acceleration [m/s^2] (right limit) at times ``t`` (n,) -> (n, 3)."""
        scalar = np.ndim(t) == 0
        acc = self._evaluate(np.atleast_1d(np.asarray(t, float)))[2]
        return acc[0] if scalar else acc

    def shifted(self, t_now: float) -> "DmpcPlan":
        """The same trajectory resampled from ``t_now`` [s]: samples t_now + k h, k = 0..K.

        Samples inside the plan are exact (Hermite, see module docstring); those
        past its end follow the constant-velocity tail. ``t_now`` may precede
        ``t0_s`` (then the head is extrapolated backwards at constant velocity).
        """
        t = float(t_now) + self.h_s * np.arange(self.horizon_steps + 1)
        pos, vel, acc = self._evaluate(t)
        return DmpcPlan(float(t_now), self.h_s, pos, vel, acc)

    def as_neighbor_prediction(self, neighbor_id: int, stamp_s: float) -> NeighborPrediction:
        """This plan as a receiver's :class:`NeighborPrediction` (source "radio", zero covariance).

        Args:
            neighbor_id: the sender's drone index.
            stamp_s: the message's send time [s] (receivers compute the age from it).
        """
        return NeighborPrediction(
            neighbor_id=int(neighbor_id),
            source="radio",
            stamp_s=float(stamp_s),
            times_s=self.times_s.copy(),
            pos_world=self.pos_world.copy(),
            vel_world=self.vel_world.copy(),
            cov_world=np.zeros((6, 6)),
        )
